"""Subspace identification (n4sid) of order 3: servoid against python-control and SIPPY.

Case
----
servo 3rd order, 20 dB
    A 20 Hz resonance (ζ = 0.2) behind a 5 Hz lag, ZOH-sampled at 500 Hz
    (discrete |z| = 0.951, 0.951, 0.939), white Gaussian input, recorded by
    ``servoid.bench.simulate_lti`` (exact analog simulation at 20× the rate)
    with white output noise at 20 dB SNR, fixed seeds; N = 1e4, 1e5, 1e6.
    Issue 8 target: order 3 on 1e6 samples ≤ 2 s.

Methods
-------
fit_n4sid order=3 moesp / cva
    ``servoid.estimate.fit_n4sid(exp, 3, weighting=...)`` with the default
    adaptive horizon (a first pass at 20, a second at 28 for these poles):
    block-Hankel Gram in one pass (numba), projections on the Gram, B, D,
    x0 by a one-pass regression, Kalman gain, PEM covariance. Residuals
    are lazy (not computed).
fit_n4sid order=3 horizon=20
    One pass at fixed horizons: the cost of the adaptive second pass.
fit_n4sid order chosen
    ``fit_n4sid(exp)``: max_order 10, so horizons 20 then 28.
python-control markov(m=100) + era(r=3)
    ``control.markov(y, u, m=100)`` (least squares on an N × 100 Toeplitz
    matrix) then ``control.era(H, 3, m=49, n=50)`` (all 99 Markov parameters): ERA needs Markov
    parameters, which it must estimate from the data first.
SIPPY N4SID f=p=20
    ``sippy_unipi.system_identification(y, u, "N4SID", SS_fixed_order=3,
    SS_f=20, SS_p=20)`` when ``sippy-unipi`` is installed (not a servoid
    dependency). Its prints are discarded.

Accuracy: ``rel_diff`` is the largest error of the frequency response on
60 lines up to 95 % of Nyquist, relative to the peak of the true ZOH model
(not a parameter difference); ``extra["pole_error"]`` the largest distance
of a pole from the true one (matched pairs). The baselines at 1e6 run once
(no warm-up, no memory pass): they take minutes.
"""

from __future__ import annotations

import contextlib
import io
import time
import warnings
from collections.abc import Callable

import numpy as np
from _harness import Result, Timing, measure_memory, time_call

SUITE = "subspace"
DT = 2e-3
SNR_DB = 20.0
SEED = 20261124
OMEGA = np.linspace(1.0, 0.95 * np.pi / DT, 60)


def _plant():  # type: ignore[no-untyped-def]
    from servoid.models import TransferFunction

    w_res, w_lag = 2 * np.pi * 20, 2 * np.pi * 5
    return TransferFunction(
        [w_res**2 * w_lag], np.polymul([1, 2 * 0.2 * w_res, w_res**2], [1, w_lag])
    )


def make_record(n: int):  # type: ignore[no-untyped-def]
    """The rig's record of the plant: (Experiment, true discrete model)."""
    from servoid.bench import simulate_lti
    from servoid.models import c2d

    plant = _plant()
    u = np.random.default_rng(SEED).standard_normal(n)
    clean = simulate_lti(plant, u, DT)
    noise_std = float(np.std(clean["y"])) / 10 ** (SNR_DB / 20)
    return simulate_lti(plant, u, DT, noise_std=noise_std, rng=SEED + 1), c2d(plant, DT)


def _accuracy(poles, freqresp, truth) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    from scipy.optimize import linear_sum_assignment

    gt = truth.freqresp(OMEGA)
    tf_err = float(np.max(np.abs(freqresp(OMEGA) - gt)) / np.max(np.abs(gt)))
    cost = np.abs(np.asarray(poles)[:, None] - truth.poles()[None, :])
    rows, cols = linear_sum_assignment(cost)
    return tf_err, float(cost[rows, cols].max()) if cost.shape[0] == cost.shape[1] else np.nan


def _ss_freqresp(a, b, c, d):  # type: ignore[no-untyped-def]
    def fr(w):  # type: ignore[no-untyped-def]
        z = np.exp(1j * w * DT)
        n = a.shape[0]
        return np.array([(c @ np.linalg.solve(zi * np.eye(n) - a, b) + d)[0, 0] for zi in z])

    return fr


def _row(case: str, n: int, method: str, fn: Callable[[], object], repeats: int, warmup: int,
         memory: bool) -> tuple[Result, object]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the baselines warn about their own numerics
        if repeats == 1 and warmup == 0:  # a call of minutes: time it once, keep its output
            t0 = time.perf_counter()
            out = fn()
            timing = Timing([time.perf_counter() - t0])
        else:
            timing = time_call(fn, repeats, warmup=warmup)
            out = fn()
        mem = measure_memory(fn) if memory else None
    res = Result(
        suite=SUITE,
        case=case,
        n=n,
        method=method,
        median_ms=timing.median * 1e3,
        best_ms=timing.best * 1e3,
        repeats=repeats,
        peak_mb=None if mem is None else mem.tracemalloc_peak / 2**20,
        rss_mb=None if mem is None or mem.rss_peak_delta is None else mem.rss_peak_delta / 2**20,
    )
    res.minflt = timing.minor_faults_per_call
    res.extra["times_ms"] = [round(t * 1e3, 3) for t in timing.times]
    return res, out


def _servoid_rows(case: str, n: int, exp, truth, quick: bool) -> list[Result]:  # type: ignore[no-untyped-def]
    from servoid.estimate import fit_n4sid

    repeats = 3 if quick else (15 if n <= 10**4 else 7 if n <= 10**5 else 5)
    rows = []
    for method, fn in (
        ("fit_n4sid order=3 moesp", lambda: fit_n4sid(exp, 3)),
        ("fit_n4sid order=3 cva", lambda: fit_n4sid(exp, 3, weighting="cva")),
        ("fit_n4sid order=3 horizon=20", lambda: fit_n4sid(exp, 3, horizon=20)),
        ("fit_n4sid order chosen", lambda: fit_n4sid(exp)),
    ):
        fn()  # numba compile / cache load, outside the timing
        res, est = _row(case, n, method, fn, repeats, 1, memory=not quick or n <= 10**5)
        tf_err, pole_err = _accuracy(est.model.poles(), est.model.freqresp, truth)  # type: ignore[attr-defined]
        res.rel_diff = tf_err
        res.extra["pole_error"] = pole_err
        res.extra["order"] = est.options["order"]  # type: ignore[attr-defined]
        res.extra["horizon"] = est.options["horizon"]  # type: ignore[attr-defined]
        res.solver = est.options["solver"]  # type: ignore[attr-defined]
        res.note = f"order {est.options['order']}, horizon {est.options['horizon']}"  # type: ignore[attr-defined]
        rows.append(res)
    return rows


def _baseline_rows(case: str, n: int, exp, truth, quick: bool) -> list[Result]:  # type: ignore[no-untyped-def]
    y, u = np.array(exp["y"]), np.array(exp["u"])
    big = n >= 10**6
    repeats, warmup = (1, 0) if big else ((1, 1) if quick else (3, 1))
    rows = []
    try:
        import control
    except ImportError:
        control = None
    if control is not None:

        def era():  # type: ignore[no-untyped-def]
            h = control.markov(y, u, m=100)
            return control.era(h, 3, m=49, n=50)[0]

        res, sys_ = _row(case, n, "python-control markov(m=100) + era(r=3)", era, repeats,
                         warmup, memory=not quick and not big)
        tf_err, pole_err = _accuracy(np.linalg.eigvals(sys_.A),
                                     _ss_freqresp(sys_.A, sys_.B, sys_.C, sys_.D), truth)
        res.rel_diff, res.extra["pole_error"] = tf_err, pole_err
        res.solver = f"control {control.__version__}"
        res.note = "once, no memory pass" if big else ""
        rows.append(res)
    try:
        import sippy_unipi
    except ImportError:
        rows.append(Result(SUITE, case, n, "SIPPY N4SID (not installed)", float("nan"),
                           float("nan"), 0, note="pip install sippy-unipi to compare"))
        return rows

    def sippy():  # type: ignore[no-untyped-def]
        with contextlib.redirect_stdout(io.StringIO()):
            return sippy_unipi.system_identification(y, u, "N4SID", SS_fixed_order=3, SS_f=20,
                                                     SS_p=20, tsample=DT)

    res, r = _row(case, n, "SIPPY N4SID f=p=20", sippy, repeats, warmup,
                  memory=not quick and not big)
    tf_err, pole_err = _accuracy(np.linalg.eigvals(r.A), _ss_freqresp(r.A, r.B, r.C, r.D), truth)
    res.rel_diff, res.extra["pole_error"] = tf_err, pole_err
    res.solver = "sippy-unipi"
    res.note = "once, no memory pass" if big else ""
    rows.append(res)
    return rows


def run(quick: bool = False) -> list[Result]:
    """Run the subspace suite; ``quick`` uses N ≤ 1e5, few repeats, baselines at 1e4 only."""
    case = f"servo 3rd order, {SNR_DB:g} dB"
    sizes = (10**4, 10**5) if quick else (10**4, 10**5, 10**6)
    results: list[Result] = []
    for n in sizes:
        exp, truth = make_record(n)  # outside every timed region
        results += _servoid_rows(case, n, exp, truth, quick)
        if not quick or n <= 10**4:
            results += _baseline_rows(case, n, exp, truth, quick)
    return results
