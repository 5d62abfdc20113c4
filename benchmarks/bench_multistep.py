"""Multi-step identification S0–S6 of the servopneumatic actuator.

Case
----
10 s at 10 kHz
    One 10 s closed-loop record at 10 kHz (1 Hz, 20 mm reference sine plus a
    ±60 N external-force square at 0.75 Hz, noise as in
    ``tests/multistep/pneumatic_records.py``) serves as the thermo, flow and
    friction tests (100 000 samples each); the valve test is a 0.4 s ±5 V,
    25 Hz rectangle at 20 kHz and the validation record a 10 s, 2 Hz, 50 mm
    closed-loop sine.  Timed: :func:`servoid.plants.pneumatic.identify_multistep`
    (S0 p_krit separable search, S0 ẋ_krit map, S1–S5, and the S6 closed-loop
    simulation of the 10 s validation record), once per derivative source,
    after a warm-up call (numba compilation and caches excluded).  The
    records are simulated outside the timing.

Target: ≤ 5 s per identification.  ``rel_diff`` is the largest relative
error of the 14 identified parameters against the simulator's truth.
"""

from __future__ import annotations

import warnings

import numpy as np
from _harness import Result, time_call

from servoid.data import Experiment
from servoid.plants.pneumatic import (
    PNEUMATIC_NOMINAL,
    REFINABLE,
    KnownConstants,
    PneumaticResponse,
    PositionController,
    identify_multistep,
    simulate_pneumatic,
)

SUITE = "multistep"
DT = 1e-4
TARGET_S = 5.0
NOISE = {"x_k": 2e-6, "x_v": 5e-7, "p_I": 200.0, "p_II": 200.0, "mdot_I": 1e-5,
         "mdot_II": 1e-5, "v_k": 1e-3, "a_k": 0.05}


def run(quick: bool) -> list[Result]:
    """Run the suite; ``quick`` uses 2 s records and one repeat."""
    duration = 2.0 if quick else 10.0
    repeats = 1 if quick else 3
    records = _records(duration)
    known = KnownConstants.from_parameters(PNEUMATIC_NOMINAL)
    rows = []
    for derivatives in ("svf", "measured"):
        def call(d: str = derivatives) -> object:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return identify_multistep(records, known, derivatives=d)

        result = call()
        timing = time_call(call, repeats, warmup=1)
        err = max(abs(getattr(result.parameters, k) / getattr(PNEUMATIC_NOMINAL, k) - 1)
                  for k in REFINABLE)
        fits = result.validation.fit
        rows.append(Result(
            SUITE, f"{duration:g} s at 10 kHz", records["thermo"].n_samples,
            f"S0–S6 ({derivatives})", timing.median * 1e3, timing.best * 1e3, repeats,
            rel_diff=float(err),
            note=f"target ≤ {TARGET_S:g} s; S6 fit p_I {fits['p_I']:.1f} %, "
                 f"p_II {fits['p_II']:.1f} %",
            extra={"meets_target": timing.median <= TARGET_S, "fit_percent": dict(fits)},
        ))
    return rows


def _records(duration: float) -> dict[str, Experiment]:
    rng = np.random.default_rng(1)
    p = PNEUMATIC_NOMINAL
    t = np.arange(round(duration / DT)) * DT
    force = np.where(np.sin(2 * np.pi * 0.75 * t) >= 0, 60.0, -60.0)
    main = simulate_pneumatic(p, None, DT, r=0.02 * np.sin(2 * np.pi * t), f_ext=force,
                              controller=PositionController())
    val = simulate_pneumatic(p, None, DT, r=0.05 * np.sin(2 * np.pi * 2 * t),
                             controller=PositionController())
    tv = np.arange(8000) * 5e-5
    valve = simulate_pneumatic(p, np.where(np.sin(2 * np.pi * 25 * tv + 1e-9) >= 0, 5.0, -5.0),
                               5e-5)
    one = _record(main, "main", rng)
    return {"valve": _record(valve, "valve", rng), "thermo": one, "flow": one, "friction": one,
            "validation": _record(val, "validation", rng)}


def _record(res: PneumaticResponse, name: str, rng: np.random.Generator) -> Experiment:
    side = {"x_v": res.x_v, "p_I": res.p_I, "p_II": res.p_II, "T_I": res.T_I,
            "T_II": res.T_II, "mdot_I": res.m_dot_I, "mdot_II": res.m_dot_II,
            "v_k": res.x_k_dot, "a_k": res.x_k_ddot, "f_ext": res.f_ext}
    side = {k: v + NOISE.get(k, 0.0) * rng.standard_normal(v.size) for k, v in side.items()}
    for k in ("mdot_I", "mdot_II"):
        side[k] = np.clip(side[k], -4e-3, 4e-3)
    y = res.x_k + NOISE["x_k"] * rng.standard_normal(res.x_k.size)
    kw: dict[str, object] = {"u": res.u, "y": y, "side": side, "names": {"u": "u", "y": "x_k", "r": "x_ref"}}
    if res.r is not None:
        kw["r"] = res.r
    return Experiment.from_arrays(res.dt, name=name, **kw)


if __name__ == "__main__":
    for row in run(quick=False):
        print(f"{row.case:18s} {row.method:20s} n={row.n:>7d}  {row.median_ms:9.1f} ms  "
              f"max rel. err {row.rel_diff:.2e}  {row.note}")
