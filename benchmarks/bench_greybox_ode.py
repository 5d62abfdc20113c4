"""Grey-box ODE fit of a two-state model on 1e4 samples: compiled against plain Python.

Case
----
tanks 1e4
    The example of ``examples/greybox``: two tanks in cascade fed by a pump
    (states h1, h2; Torricelli outflows), the upper tank overflowing at its
    rim (a declared state clamp) and the pump saturating at 8 V (a declared
    input saturation); the lower level measured with 1 mm of white noise.
    Truth by the example's own generator (numpy RK4 at 20 steps per sample,
    overflow by projection), N = 1e4 samples at 1 s, outside the timed
    region.  Fitted: k, a1, a2 and both initial levels (5 parameters; A
    fixed), started from the example's values, one RK4 step per sample,
    robust covariance, the identifiability checks on.  The issue's target:
    ≤ 2 s for the fit.

Methods
-------
fit_ode compiled
    ``servoid.estimate._ode_model.fit_ode`` with the numba-compiled
    integrator (the workflow's ``method = "greybox"`` path), compilation
    done before the timed calls.
numba compile (once per model file)
    ``make_system`` compiling the user's rhs and output with the RK4 kernel
    around them: what a first run pays once (a run in the same process
    with the same file reuses it).
fit_ode Python integrator
    The same fit with ``compile = false``: the same integrator source run by
    the Python interpreter (what a model numba cannot compile gets).

Columns: ``rel_diff`` = max |θ − θ_true| / |θ_true| over k, a1, a2;
``extra["z_max"]`` = the largest |θ − θ_true|/σ over all five;
``extra["nfev"]`` = the solver's function evaluations (each one simulation of the record;
the finite-difference Jacobians, n_free + 1 simulations per iteration, not counted).
"""

from __future__ import annotations

import importlib.util
import time
import warnings
from pathlib import Path

import numpy as np
from _harness import Result, Timing, rel_diff, time_call

SUITE = "greybox-ode"
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "greybox"
H0 = (0.12, 0.06)


def _example(name: str):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(f"bench_greybox_{name}", EXAMPLE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def run(quick: bool = False) -> list[Result]:
    """Run the suite; ``quick`` fits 2e3 samples and times fewer repeats."""
    from servoid.data import Experiment
    from servoid.estimate import GreyboxParameter
    from servoid.estimate._ode import make_system
    from servoid.estimate._ode_model import fit_ode

    gen, tanks = _example("make_data"), _example("tanks")
    n = 2000 if quick else 10_000
    _, u, y, _ = gen.record(n, 20261124, H0)
    exp = Experiment.from_arrays(gen.DT, u=u, y=y)
    params = [GreyboxParameter("k", 1.5e-5, 1e-7, 1e-3), GreyboxParameter("a1", 2.5e-5, 1e-7, 1e-3),
              GreyboxParameter("a2", 2.5e-5, 1e-7, 1e-3),
              GreyboxParameter("A", gen.TRUE["A"], fixed=True)]
    truth = np.array([gen.TRUE["k"], gen.TRUE["a1"], gen.TRUE["a2"], *H0])

    def system(compile: bool):  # type: ignore[no-untyped-def]
        return make_system(
            tanks.rhs, tanks.level, x0=np.array([0.1, 0.1]), u=u[:, None],
            p=np.array([p.value for p in params]), state_lower=np.array([0.0, 0.0]),
            state_upper=np.array([gen.RIM, np.inf]), input_lower=np.array([0.0]),
            input_upper=np.array([gen.U_MAX]), source="tanks.py:rhs", compile=compile)

    def fit(s):  # type: ignore[no-untyped-def]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fit_ode(exp, s, params, states=["h1", "h2"], output="y", x0=[0.1, 0.1],
                           estimate_initial=["h1", "h2"])

    rows = []
    compile_timing = time_call(lambda: system(True), 1 if quick else 3)
    rows.append(_row(n, "numba compile (once per model file)", compile_timing, "", None))
    compiled = system(True)
    assert compiled.compiled, compiled.note
    timing = time_call(lambda: fit(compiled), 3 if quick else 7)
    est = fit(compiled)
    rows.append(_row(n, "fit_ode compiled", timing, "target ≤ 2 s", est, truth))
    plain = system(False)
    t0 = time.perf_counter()  # one call: it takes a minute at 1e4 samples
    est_plain = fit(plain)
    timing = Timing([time.perf_counter() - t0])
    rows.append(_row(n, "fit_ode Python integrator", timing, "compile = false", est_plain,
                     truth))
    return rows


def _row(n, method, timing, note, est, truth=None):  # type: ignore[no-untyped-def]
    row = Result(SUITE, f"tanks {n:.0e}".replace("+0", ""), n, method,
                 median_ms=1e3 * timing.median, best_ms=1e3 * timing.best,
                 repeats=len(timing.times), note=note)
    if est is not None:
        row.rel_diff = rel_diff(est.parameters[:3], truth[:3])
        row.extra["z_max"] = float(np.max(np.abs(est.parameters - truth) / est.std))
        row.extra["nfev"] = int(est.options["nfev"])
        row.extra["compiled"] = bool(est.options["compiled"])
    return row
