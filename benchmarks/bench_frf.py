"""Measured frequency responses: estimate_frf on 1e6 samples against scipy / numpy baselines.

Target: "FRF of 1e6 samples ≤ 100 ms" (issue 8).

Cases
-----
welch
    White Gaussian u through a 2nd-order discrete system plus white output
    noise, fixed seed; N = 1e6 (1e5 under --quick).  The default segment
    length (N/8 rounded down to a power of 2, at most 16384: 121 segments of
    16384 for 1e6), a short one (4096, 487 segments) and a long one (65536,
    29 segments); Hann window, 50 % overlap.
periodic
    A PRBS repeated over the record (n = 10: period 1023 = 3·11·31; n = 13:
    period 8191, a prime) and a multisine of period 10000, through the
    same system; skip_periods = 1.

Methods
-------
servoid.estimate.estimate_frf
    Welch: H1, coherence, variance per line, equivalent averages (blocked
    segments, one FFT per signal and segment).  Periodic: per-period DFTs
    (u and y packed in one complex FFT), means and centred moments per line
    merged block by block, excited-line detection, variance per line and the
    nonlinear-distortion test.  The Experiment is built outside the timed
    region.
scipy csd + welch (H1)
    ``scipy.signal.csd(u, y)`` and ``scipy.signal.welch(u)``, H1 = S_uy/S_uu:
    what a user would write for the estimate alone, no coherence.
scipy csd + 2×welch (H1 + coherence)
    The same plus ``welch(y)`` for the coherence: the like-for-like baseline.
numpy reshape + rfft (periodic)
    Two ``np.fft.rfft`` of the (M, P) period matrices, the mean ratio and the
    per-line variance of Y over periods, no line detection or distortion
    test.
fit_frf (info)
    ``fit_frf`` of a 2nd-order model to the 1023-period FRF's 511 lines.

Accuracy: ``rel_diff`` = max_k |Ĝ_k − Ĝ_scipy,k| / |Ĝ_scipy,k| (Welch) or against the numpy
baseline (periodic); rounding only, ~1e-13.
"""

from __future__ import annotations

import warnings

import numpy as np
from _harness import Result, measure_memory, time_call
from scipy import signal as sps

from servoid import ServoidWarning
from servoid.data import Experiment
from servoid.estimate import estimate_frf, fit_frf
from servoid.signals import multisine, prbs

SUITE = "frf"
DT = 1e-4
SEED = 20261124
SYSTEM = ([0.02, 0.01], [1.0, -1.6, 0.67])  # a resonant 2nd-order discrete system


def _record(u: np.ndarray, seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = sps.lfilter(*SYSTEM, u) + 0.05 * rng.standard_normal(u.size)
    return u, y


def _row(case: str, n: int, method: str, fn, repeats: int, quick: bool,  # type: ignore[no-untyped-def]
         rel: float | None = None, note: str = "") -> Result:
    t = time_call(fn, repeats=repeats)
    peak = rss = None
    if not quick:
        mem = measure_memory(fn)
        peak = mem.tracemalloc_peak / 2**20
        rss = None if mem.rss_peak_delta is None else mem.rss_peak_delta / 2**20
    return Result(SUITE, case, n, method, t.median * 1e3, t.best * 1e3, len(t.times),
                  peak_mb=peak, rss_mb=rss, rel_diff=rel, minflt=t.minor_faults_per_call,
                  note=note)


def _welch_rows(n: int, quick: bool, repeats: int) -> list[Result]:
    u, y = _record(np.random.default_rng(SEED + 1).standard_normal(n))
    exp = Experiment.from_arrays(DT, u=u, y=y)
    rows = []
    for nperseg in (None, 4096, 65536):
        seg = nperseg or min(2 ** int(np.floor(np.log2(n / 8))), 2**14)
        frd = estimate_frf(exp, nperseg=nperseg)
        _, s_uy = sps.csd(u, y, nperseg=seg)
        _, s_uu = sps.welch(u, nperseg=seg)
        h1 = (s_uy / s_uu)[1 : seg // 2]
        rel = float(np.max(np.abs(frd.response - h1) / np.abs(h1)))
        case = f"welch nperseg={seg}{' (default)' if nperseg is None else ''}"
        rows.append(_row(case, n, "servoid.estimate.estimate_frf",
                         lambda nperseg=nperseg: estimate_frf(exp, nperseg=nperseg),
                         repeats, quick, rel, "H1 + coherence + variance"))
        rows.append(_row(case, n, "scipy csd + welch (H1)",
                         lambda seg=seg: (sps.csd(u, y, nperseg=seg), sps.welch(u, nperseg=seg)),
                         repeats, quick, note="H1 only"))
        rows.append(_row(case, n, "scipy csd + 2×welch (H1 + coherence)",
                         lambda seg=seg: (sps.csd(u, y, nperseg=seg), sps.welch(u, nperseg=seg),
                                          sps.welch(y, nperseg=seg)),
                         repeats, quick, note="like for like"))
    return rows


def _numpy_periodic(u: np.ndarray, y: np.ndarray, period: int) -> tuple[np.ndarray, np.ndarray]:
    m = u.size // period
    uu = np.fft.rfft(u[period : m * period].reshape(m - 1, period), axis=1)
    yy = np.fft.rfft(y[period : m * period].reshape(m - 1, period), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # the empty lines of a multisine
        g = yy.mean(axis=0) / uu.mean(axis=0)
        var = yy.var(axis=0, ddof=1) / ((m - 1) * np.abs(uu.mean(axis=0)) ** 2)
    return g, var


def _periodic_rows(n: int, quick: bool, repeats: int) -> list[Result]:
    rows = []
    designs = [("prbs n=10", 1023, None), ("prbs n=13 (prime period)", 8191, None),
               ("multisine", 10_000, None)]
    frd_1023 = None
    for label, period, _ in designs:
        periods = max(n // period, 3)
        if label.startswith("prbs"):
            u = prbs(int(np.log2(period + 1)), periods=periods, dt=DT).values
        else:
            u = multisine(period, DT, 1.0, 2000.0, periods=periods, phases="random",
                          rng=SEED).values
        u, y = _record(u)
        exp = Experiment.from_arrays(DT, u=u, y=y)
        frd = estimate_frf(exp, period=period)
        g_ref, _ = _numpy_periodic(u, y, period)
        k = np.rint(frd.frequency * period * DT).astype(int)
        rel = float(np.max(np.abs(frd.response - g_ref[k]) / np.abs(g_ref[k])))
        case = f"periodic {label} P={period}"
        rows.append(_row(case, u.size, "servoid.estimate.estimate_frf",
                         lambda exp=exp, period=period: estimate_frf(exp, period=period),
                         repeats, quick, rel, f"{frd.n_lines} lines, M = {frd.n_averages}"))
        rows.append(_row(case, u.size, "numpy reshape + rfft (periodic)",
                         lambda u=u, y=y, period=period: _numpy_periodic(u, y, period),
                         repeats, quick, note="no line detection, no distortion test"))
        if period == 1023:
            frd_1023 = frd
    if frd_1023 is not None:
        band = frd_1023.select(f_max=2000.0)

        def fit() -> None:
            # the system is discrete, so a continuous 2-pole model is rejected by the data (a
            # warning); only the time is of interest here
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ServoidWarning)
                fit_frf(band, 2, 1)

        rows.append(_row(f"fit_frf 2 poles, {band.n_lines} lines", band.n_lines,
                         "servoid.estimate.fit_frf", fit, repeats, quick,
                         note="Levy + SK + LM, info"))
    return rows


def run(quick: bool) -> list[Result]:
    """estimate_frf on 1e6 samples (1e5 under --quick) against scipy / numpy."""
    n = 10**5 if quick else 10**6
    repeats = 3 if quick else 9
    return _welch_rows(n, quick, repeats) + _periodic_rows(n, quick, repeats)
