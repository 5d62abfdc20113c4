"""Where the linear EHSA model meets Merritt's flow law: coverage, silence and the check.

Cases
-----
the flow law at ±0.05, ±0.1, ±0.2 mm; a linear valve; c 0.3 % high; a 14-bit read-back: 100 seeds each (``--quick``: 4)
    ``tests/plants/ehsa/merritt_rig.py``, a generator servoid does not share:
    Set B's piston and load pressure in scipy ``solve_ivp`` (DOP853) fed by
    Merritt's valve flow ``Q = C_d·w·x_s·√((P_s − sgn(x_s)·P_L)/ρ)`` (or its
    linearisation), its own PRBS (n = 10, 10 samples per bit), a
    4th-order Butterworth anti-alias filter at 0.2·f_acq, white sensor
    noise at 30 dB and scipy's Kaiser decimation 5 kHz → 1 kHz.  Each seed
    fits the reduced one-step model (``fit_one_step``, ``"auto"``) on the
    first half and runs the flow-law and DC-gain checks on it.

Method
------
One pass: ``median_ms`` = ``best_ms`` = wall time per seed (fit and
check; each rig is integrated once, ~10 s, outside the timing).  ``extra``
per case: the peak |P_L|/P_s the generator reached; the reduced model's
95 % coverage of K, ω_hp, δ_hp and mean z; among the seeds where a
reduced interval misses, the share the flow-law verdict names
(the flow law ``biased`` or the DC gain a ``mismatch``) and the number
that stay silent; the coverage of the first-order corrected estimates;
the share of seeds where the flow law is seen (on the linear valve: its
false-alarm rate, level 1 %) and where the DC gain mismatches.

0 (control), 5, 12.5 and 20 µs channel skew (linear valve), 100 seeds each (``--quick``: 3)
    The rig reads the position late; each seed fits the reduced model and
    the ``reduced+skew`` structure and compares them (level 0.005 over the
    two tests: the workflow's share per test).  ``extra``: coverage of the
    reduced and of the skew structure's intervals, the misses named (the
    skew structure preferred) and silent, and τ_d's z against the truth;
    with ``[loop] skew_tolerance = 20 µs`` (:mod:`servoid.plants.ehsa._skew`,
    the skew fit conditioned on τ_d ~ N(0, (20 µs)²)): the coverage, the
    interval width against the reduced one and the share flagged beyond
    the tolerance.  At 0 µs ``skew_found`` is the structure test's false
    alarm rate.  Without a tolerance: ``caution_fires``, the share of records
    where the workflow's unresolved-skew caution fires (a skew of 1.96 σ_τ
    moves a parameter by > 1 reduced σ, :func:`servoid.plants.ehsa._skew.
    unresolved_skew`; at 0 µs the rate on true-structure data), the misses
    named by the structure test or the caution, and the mean move of ω_hp.

One 2 Hz sine; a valve command clipped at ±1 rms under a PRBS and a multisine (linear valve), 100 seeds each (``--quick``: 3)
    Each seed fits the reduced model and runs what the workflow runs on
    it: the record's limits (``_data_check.record_notes``), the flow-law
    and DC-gain checks and their saturation note, and the validation's
    higher-order correlation tests on the held-back half.  ``extra``:
    coverage, the misses named by any of them and silent, and the share
    of records each fires on.

OE 8/8 and 2/2 on a 2nd-order plant, 100 seeds each (``--quick``: 3)
    White input, 1000 samples, 30 dB.  ``extra``: the share of fits with
    the cancellation note, the share suggesting the true 2/2, and the
    fits that stopped with a ConvergenceError.

``--skew-only`` and ``--data-only`` run those parts alone (JSON on stdout).
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np
from _harness import Result

SUITE = "ehsa-validity"
TESTS = Path(__file__).resolve().parent.parent / "tests" / "plants" / "ehsa"
#: (label, Merritt-rig settings): the flow law at three amplitudes, a linear valve, a reference
#: gain 0.3 % above the stated c, an undithered 14-bit read-back of the reference.
CASES = (
    ("flow law ±0.05 mm", {"amplitude": 0.05e-3}),
    ("flow law ±0.1 mm", {"amplitude": 0.1e-3}),
    ("flow law ±0.2 mm", {"amplitude": 0.2e-3}),
    ("linear valve ±0.2 mm", {"amplitude": 0.2e-3, "flow_law": False}),
    ("c 0.3 % high, linear valve", {"amplitude": 0.2e-3, "flow_law": False, "c_true": 0.01003}),
    ("14-bit read-back, linear valve", {"amplitude": 0.2e-3, "flow_law": False, "bits": 14}),
)
NAMES = ("K", "omega_hp", "delta_hp")


def case(settings: dict[str, object], seeds: int) -> dict[str, object]:
    """Run one rig over `seeds` seeds and summarise."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    from merritt_rig import Rig, peak_load_pressure, record

    from servoid.data import Experiment
    from servoid.plants.ehsa import FeedbackLoop, fit_one_step
    from servoid.plants.ehsa._dc_gain import check_dc_gain
    from servoid.plants.ehsa._first_order import first_order_fit
    from servoid.plants.ehsa._flow_check import flow_law_of

    rig = Rig(register=10, **settings)  # type: ignore[arg-type]
    truth = rig.truth()
    ratio = peak_load_pressure(rig)
    loop = FeedbackLoop(0.01, 0.01)
    z_red, cov_red, cov_cor, seen, biased, dc = [], [], [], [], [], []
    t0 = time.perf_counter()
    for seed in range(seeds):
        r, y = record(rig, 30.0, seed)
        half = Experiment.from_arrays(1e-3, r=r[: r.size // 2], y=y[: r.size // 2])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit = fit_one_step(half, loop)
        first = first_order_fit(fit, half)
        check = flow_law_of(first)
        dc.append(check_dc_gain(first, 1.0).mismatch)
        est = fit.estimate
        z = (est.parameters - truth) / est.std
        z_red.append(z)
        cov_red.append(np.abs(z) <= 1.96)
        cov_cor.append(np.abs((np.array(check.parameters) - truth) / np.array(check.std)) <= 1.96)
        seen.append(check.seen)
        biased.append(check.biased)
    per_seed = (time.perf_counter() - t0) / seeds
    cov_red_a, cov_cor_a = np.array(cov_red), np.array(cov_cor)
    miss = ~cov_red_a.all(axis=1)
    named = (np.array(biased) | np.array(dc))[miss]
    return {
        "settings": settings, "seeds": seeds,
        "peak_load_pressure_over_supply": ratio,
        "reduced_coverage": dict(zip(NAMES, cov_red_a.mean(axis=0).tolist(), strict=True)),
        "reduced_mean_z": dict(zip(NAMES, np.mean(z_red, axis=0).tolist(), strict=True)),
        "misses": int(miss.sum()),
        "misses_named": float(named.mean()) if named.size else None,
        "misses_silent": int((~named).sum()),
        "corrected_coverage": dict(zip(NAMES, cov_cor_a.mean(axis=0).tolist(), strict=True)),
        "seen": float(np.mean(seen)),
        "flow_law_biased": float(np.mean(biased)),
        "dc_gain_mismatch": float(np.mean(dc)),
        "per_seed_ms": per_seed * 1e3,
    }


#: Channel skews of the position against the reference [s] (the rig reads y late: y(t + skew));
#: 0 is the true-structure control (the false-alarm rate and the width a stated tolerance costs).
SKEWS = (0.0, 5e-6, 12.5e-6, 20e-6)
#: ``[loop] skew_tolerance`` of the study [s]: a multiplexed ADC that may skew by up to ~20 µs.
TOLERANCE = 20e-6


def skew_case(skew: float, seeds: int) -> dict[str, object]:
    """The reduced fit and the reduced+skew structure on a skewed linear rig."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    from merritt_rig import Rig, record

    from servoid.data import Experiment
    from servoid.plants.ehsa import FeedbackLoop, compare_structures, fit_one_step
    from servoid.plants.ehsa._skew import skew_prior, unresolved_skew
    from servoid.plants.ehsa._structures import skew_structure

    rig = Rig(register=10, amplitude=0.2e-3, flow_law=False, skew=skew)
    truth = rig.truth()
    loop = FeedbackLoop(0.01, 0.01)
    structure = skew_structure(0.01)
    cov_red, cov_skew, named, tau_z = [], [], [], []
    cov_tol, width_tol, beyond = [], [], []
    caution, shift_w = [], []
    t0 = time.perf_counter()
    for seed in range(seeds):
        r, y = record(rig, 30.0, seed)
        half = Experiment.from_arrays(1e-3, r=r[: r.size // 2], y=y[: r.size // 2])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit = fit_one_step(half, loop)
            wide = fit_one_step(half, loop, (*fit.estimate.parameters, 0.0), structure=structure)
            # level 0.005 over two tests: the share 0.0025 each test gets in the workflow's
            # structure test (level 0.01 over three structures and the independence test)
            test = compare_structures({"reduced": fit, "reduced+skew": wide}, half,
                                      level=0.005, structures={"reduced+skew": structure})
        cov_red.append(np.abs((fit.estimate.parameters - truth) / fit.estimate.std) <= 1.96)
        cov_skew.append(np.abs((wide.estimate.parameters - truth) / wide.estimate.std) <= 1.96)
        named.append(test.rejected and test.preferred == "reduced+skew")
        adj = skew_prior(wide, TOLERANCE)
        cov_tol.append(np.abs((adj.result.estimate.parameters - truth)
                              / adj.result.estimate.std) <= 1.96)
        width_tol.append(adj.result.estimate.std / fit.estimate.std)
        beyond.append(adj.beyond)
        unresolved = unresolved_skew(wide, fit)
        # the workflow's caution: an unresolved skew moves a parameter by > 1σ, unless the
        # structure test already names the skew
        caution.append(unresolved.fires and not named[-1])
        shift_w.append(abs(unresolved.shifts["omega_hp"]))
        tau_z.append((wide.source["tau_d"] + skew) / wide.source.std[3])
    per_seed = (time.perf_counter() - t0) / seeds
    cov_red_a = np.array(cov_red)
    miss = ~cov_red_a.all(axis=1)
    named_a = np.array(named)
    either = named_a | np.array(caution)
    return {
        "skew_us": skew * 1e6, "seeds": seeds,
        "reduced_coverage": dict(zip(NAMES, cov_red_a.mean(axis=0).tolist(), strict=True)),
        "skew_structure_coverage": dict(zip(NAMES, np.mean(cov_skew, axis=0).tolist(),
                                            strict=True)),
        "misses": int(miss.sum()),
        "misses_named": float(named_a[miss].mean()) if miss.any() else None,
        "misses_silent": int((~named_a[miss]).sum()),
        "skew_found": float(named_a.mean()),
        "caution_fires": float(np.mean(caution)),
        "misses_named_or_caution": float(either[miss].mean()) if miss.any() else None,
        "misses_silent_with_caution": int((~either[miss]).sum()),
        "omega_hp_shift_sigma_mean": float(np.mean(shift_w)),
        "tolerance_us": TOLERANCE * 1e6,
        "tolerance_coverage": dict(zip(NAMES, np.mean(cov_tol, axis=0).tolist(), strict=True)),
        "tolerance_width_ratio": dict(zip(NAMES, np.mean(width_tol, axis=0).tolist(),
                                          strict=True)),
        "tolerance_beyond": float(np.mean(beyond)),
        "tau_d_mean_z": float(np.mean(tau_z)), "tau_d_z_rms": float(np.sqrt(np.mean(
            np.square(tau_z)))),
        "per_seed_ms": per_seed * 1e3,
    }


#: (label, Merritt-rig settings) of the data-limit cases: one 2 Hz sine, a valve command clipped
#: at ±1 rms of the reference (PRBS and a random-phase multisine), linear valve.
DATA_CASES = (
    ("one 2 Hz sine", {"reference": "sine", "amplitude": 0.2e-3, "flow_law": False}),
    ("command clipped at ±1 rms, PRBS", {"amplitude": 0.2e-3, "flow_law": False, "clip": 1.0}),
    ("command clipped at ±1 rms, multisine",
     {"reference": "noise", "amplitude": 0.1e-3, "flow_law": False, "clip": 1.0}),
)


def data_case(settings: dict[str, object], seeds: int) -> dict[str, object]:
    """The reduced fit's coverage and what the workflow's checks say on a limited record."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    from merritt_rig import Rig, record

    from servoid.data import Experiment
    from servoid.plants.ehsa import FeedbackLoop, fit_one_step
    from servoid.plants.ehsa._data_check import record_notes, saturation_note
    from servoid.plants.ehsa._dc_gain import check_dc_gain
    from servoid.plants.ehsa._first_order import first_order_fit
    from servoid.plants.ehsa._flow_check import flow_law_of
    from servoid.validate import validate

    rig = Rig(register=10, **settings)  # type: ignore[arg-type]
    truth = rig.truth()
    loop = FeedbackLoop(0.01, 0.01)
    cov, limit, sat, nonlin, any_check = [], [], [], [], []
    t0 = time.perf_counter()
    for seed in range(seeds):
        r, y = record(rig, 30.0, seed)
        n = r.size // 2
        half = Experiment.from_arrays(1e-3, r=r[:n], y=y[:n])
        held = Experiment.from_arrays(1e-3, r=r[n:], y=y[n:])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit = fit_one_step(half, loop)
            first = first_order_fit(fit, half)
            flow, dc = flow_law_of(first), check_dc_gain(first, 1.0)
            val = validate(fit.closed_loop.to_polynomial("oe"), fit.align(held), input="r",
                           initial="estimate")
        cov.append(np.abs((fit.estimate.parameters - truth) / fit.estimate.std) <= 1.96)
        limit.append(bool(record_notes(half, fit, loop)) or bool(fit.flags))
        sat.append(bool(saturation_note(flow, dc)))
        nonlin.append(bool(val.nonlinearity is not None and val.nonlinearity.detected))
        any_check.append(limit[-1] or sat[-1] or nonlin[-1] or flow.biased or dc.mismatch)
    per_seed = (time.perf_counter() - t0) / seeds
    cov_a = np.array(cov)
    miss = ~cov_a.all(axis=1)
    named = np.array(any_check)[miss]
    return {
        "settings": settings, "seeds": seeds,
        "reduced_coverage": dict(zip(NAMES, cov_a.mean(axis=0).tolist(), strict=True)),
        "misses": int(miss.sum()),
        "misses_named": float(named.mean()) if named.size else None,
        "misses_silent": int((~named).sum()),
        "data_limit_noted": float(np.mean(limit)), "saturation_named": float(np.mean(sat)),
        "nonlinearity_detected": float(np.mean(nonlin)),
        "per_seed_ms": per_seed * 1e3,
    }


def oe_case(nb: int, nf: int, seeds: int) -> dict[str, object]:
    """OE nb/nf on a 2nd-order plant (white input, 1000 samples, 30 dB): cancellation notes."""
    from scipy import signal

    from servoid import ConvergenceError
    from servoid.data import Experiment
    from servoid.estimate import fit_oe

    noted, suggested, failed = [], [], 0
    t0 = time.perf_counter()
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(1000)
        y0 = signal.lfilter([0.0, 0.1, 0.05], [1.0, -1.5, 0.7], u)
        y = y0 + rng.standard_normal(u.size) * y0.std() * 10 ** (-30 / 20)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                est = fit_oe(Experiment.from_arrays(1.0, u=u, y=y), nb, nf, 1)
            except ConvergenceError:  # "… lower orders": no interval printed either
                failed += 1
                continue
        notes = est.options.get("cancellations", [])
        noted.append(bool(notes))
        suggested.append(bool(notes) and "fit nb = 2, nf = 2" in notes[0])
    return {"nb": nb, "nf": nf, "seeds": seeds, "failed_to_converge": failed,
            "noted": float(np.mean(noted)) if noted else None,
            "suggests_2_2": float(np.mean(suggested)) if noted else None,
            "per_seed_ms": (time.perf_counter() - t0) / seeds * 1e3}


def run(quick: bool = False) -> list[Result]:
    """Every case of the module docstring (4 seeds each under ``quick``)."""
    seeds = 4 if quick else 100
    rows = []
    for label, settings in CASES:
        stats = case(settings, seeds)
        cov = stats["reduced_coverage"]
        note = (f"|P_L|/P_s {stats['peak_load_pressure_over_supply']:.2f}; reduced coverage "
                f"K {cov['K']:.2f} ω {cov['omega_hp']:.2f} δ {cov['delta_hp']:.2f}; misses "
                f"{stats['misses']}, named {stats['misses_named']}, silent "
                f"{stats['misses_silent']}; flow law seen {stats['seen']:.2f}, DC gain mismatch "
                f"{stats['dc_gain_mismatch']:.2f}")
        row = Result(SUITE, f"Merritt rig, {label}, 30 dB, {seeds} seeds",
                     5115, "fit_one_step + check_flow_law", stats["per_seed_ms"],
                     stats["per_seed_ms"], 1, note=note)
        row.extra.update(stats)
        rows.append(row)
    for skew in SKEWS:
        stats = skew_case(skew, 3 if quick else 100)
        cov = stats["reduced_coverage"]
        note = (f"reduced coverage K {cov['K']:.2f} ω {cov['omega_hp']:.2f} δ "
                f"{cov['delta_hp']:.2f}; misses {stats['misses']}, named "
                f"{stats['misses_named']}, silent {stats['misses_silent']}; skew found "
                f"{stats['skew_found']:.2f}; caution {stats['caution_fires']:.2f}, misses named "
                f"with it {stats['misses_named_or_caution']}; reduced+skew coverage "
                f"{stats['skew_structure_coverage']}; skew_tolerance 20 µs: coverage "
                f"{stats['tolerance_coverage']}, interval width × "
                f"{stats['tolerance_width_ratio']}")
        row = Result(SUITE, f"Merritt rig, {skew * 1e6:g} µs skew, 30 dB", 5115,
                     "fit_one_step reduced and reduced+skew, compare_structures",
                     stats["per_seed_ms"], stats["per_seed_ms"], 1, note=note)
        row.extra.update(stats)
        rows.append(row)
    n = 3 if quick else 100
    for label, settings in DATA_CASES:
        stats = data_case(settings, n)
        cov = stats["reduced_coverage"]
        row = Result(SUITE, f"Merritt rig, {label}, 30 dB, {n} seeds", 5115,
                     "fit_one_step + the workflow's record, flow-law, DC-gain, higher-order checks",
                     stats["per_seed_ms"], stats["per_seed_ms"], 1,
                     note=(f"coverage K {cov['K']:.2f} ω {cov['omega_hp']:.2f} δ "
                           f"{cov['delta_hp']:.2f}; misses {stats['misses']}, named "
                           f"{stats['misses_named']}, silent {stats['misses_silent']}"))
        row.extra.update(stats)
        rows.append(row)
    for nb, nf in ((8, 8), (2, 2)):
        stats = oe_case(nb, nf, n)
        row = Result(SUITE, f"OE {nb}/{nf} on a 2nd-order plant, {n} seeds", 1000,
                     "fit_oe cancellation note", stats["per_seed_ms"], stats["per_seed_ms"], 1,
                     note=f"noted {stats['noted']}, suggests 2/2 {stats['suggests_2_2']}, "
                          f"not converged {stats['failed_to_converge']}")
        row.extra.update(stats)
        rows.append(row)
    return rows


if __name__ == "__main__":
    import json

    if "--data-only" in sys.argv:
        n = 3 if "--quick" in sys.argv else 100
        for label, settings in DATA_CASES:
            print(json.dumps({"case": label, **data_case(settings, n)}), flush=True)
        for nb, nf in ((8, 8), (2, 2)):
            print(json.dumps(oe_case(nb, nf, n)), flush=True)
        raise SystemExit(0)
    if "--skew-only" in sys.argv:
        out = [skew_case(skew, 3 if "--quick" in sys.argv else 100) for skew in SKEWS]
        print(json.dumps(out, indent=1))
        raise SystemExit(0)
    results = run(quick="--quick" in sys.argv)
    for r in results:
        print(r.case, "|", r.note)
    if "--json" in sys.argv:
        print(json.dumps([r.extra for r in results], indent=1))
