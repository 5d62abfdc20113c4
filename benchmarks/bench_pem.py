"""OE(4, 3) by the prediction-error method: servoid against scipy and SIPPY.

Case
----
oe(4,3) 40 dB
    A 3rd-order discrete plant, poles 0.9 and 0.8·e^{±0.3j}, numerator
    B = [0.1, 0.25, −0.05, 0.08] after one sample of delay — the shape of a
    3rd-order continuous plant sampled with a fractional input dead time,
    which is what makes nb = 4 with nf = 3 (the issue's "OE(4,3)").  Input:
    a random binary ±1 sequence; output noise white at 40 dB SNR (1 % of
    the output's RMS, a servo position sensor); fixed seed; N = 1e4 and 1e5.
    The issue's target: ≤ 10 ms / ≤ 100 ms with a fit ≥ 99.9 % of the
    noise-free output.  That fit is a property of the data as much as of
    the solver: at the prediction-error minimum the model's error is about
    σ_v·√(d/N), so at 30 dB and N = 1e4 every method that reaches the
    minimum (servoid, scipy LM, scipy TRF alike) scores 99.895 % on this
    seed (measured), and from about 31 dB up it is above 99.9 %.

Methods
-------
fit_oe
    ``servoid.estimate.fit_oe(exp, 4, 3, 1)`` with the Experiment built
    outside the timed region: IV start, Gauss–Newton on the exact gradient,
    covariance and the Estimate (residuals are lazy).
fit_oe start only
    The same call with ``max_iter=0``: how much of the time is the IV start.
scipy least_squares lm, analytic jacobian
    A strong hand-written baseline: the same OE residual through
    ``scipy.signal.lfilter``, its exact Jacobian from filtered signals,
    MINPACK Levenberg–Marquardt, started from an ARX least-squares fit.
scipy least_squares trf, 2-point jacobian
    The "twenty lines of scipy" a user writes first: finite differences.
SIPPY OE (sippy_unipi)
    ``system_identification(y, u, "OE", OE_orders=[4, 3, 1])`` (CasADi /
    IPOPT), N = 1e4 only and only in the full run (the issue measured
    > 120 s at 1e5); its fit uses the model output it returns (``Yid``).
sysidentpy has no output-error estimator (its linear models are
equation-error ARX/NARX), so it has no row.

Columns: ``rel_diff`` = max |θ − θ_lm| / |θ_lm| against the scipy LM
optimum (the same minimum reached twice); ``extra["fit_pct"]`` = simulation
fit [%] of the estimated model to the noise-free output.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from collections.abc import Callable

import numpy as np
from _harness import Result, measure_memory, rel_diff, time_call
from scipy import optimize
from scipy import signal as sps

SUITE = "pem"
SEED = 20261124
F_TRUE = np.real(np.poly([0.9, 0.8 * np.exp(0.3j), 0.8 * np.exp(-0.3j)]))
B_TRUE = np.array([0.1, 0.25, -0.05, 0.08])
NB, NF, NK = 4, 3, 1
SNR_DB = 40.0


def make_record(n: int, seed: int = SEED):  # type: ignore[no-untyped-def]
    """(u, y, y0): binary input, OE output, white output noise at SNR_DB."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y0 = sps.lfilter(np.concatenate([np.zeros(NK), B_TRUE]), F_TRUE, u)
    y = y0 + rng.standard_normal(n) * y0.std() / 10 ** (SNR_DB / 20)
    return u, y, y0


def fit_percent(y0: np.ndarray, y_sim: np.ndarray) -> float:
    """100·(1 − ‖y0 − ŷ‖/‖y0 − mean y0‖)."""
    return float(100 * (1 - np.linalg.norm(y0 - y_sim) / np.linalg.norm(y0 - y0.mean())))


def _simulate(theta: np.ndarray, u: np.ndarray) -> np.ndarray:
    b, f = theta[:NB], np.concatenate([[1.0], theta[NB:]])
    return sps.lfilter(np.concatenate([np.zeros(NK), b]), f, u)


def _arx_start(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    n, start = y.size, max(NF, NK + NB - 1)
    cols = [-y[start - k: n - k] for k in range(1, NF + 1)]
    cols += [u[start - NK - j: n - NK - j] for j in range(NB)]
    theta = np.linalg.lstsq(np.column_stack(cols), y[start:], rcond=None)[0]
    return np.concatenate([theta[NF:], theta[:NF]])  # (b, f) order


def scipy_lm(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """least_squares LM on the OE residual with its exact Jacobian."""
    def residual(theta: np.ndarray) -> np.ndarray:
        return y - _simulate(theta, u)

    def jacobian(theta: np.ndarray) -> np.ndarray:
        f = np.concatenate([[1.0], theta[NB:]])
        uf = sps.lfilter([1.0], f, u)
        wf = sps.lfilter([1.0], f, _simulate(theta, u))
        jac = np.empty((y.size, NB + NF))
        for j in range(NB):
            jac[:, j] = -np.concatenate([np.zeros(NK + j), uf[: y.size - NK - j]])
        for k in range(1, NF + 1):
            jac[:, NB + k - 1] = np.concatenate([np.zeros(k), wf[: y.size - k]])
        return jac

    return optimize.least_squares(residual, _arx_start(u, y), jac=jacobian, method="lm",
                                  xtol=1e-10, ftol=1e-10).x


def scipy_trf_2point(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """least_squares with its defaults (TRF, finite-difference Jacobian)."""
    return optimize.least_squares(lambda t: y - _simulate(t, u), _arx_start(u, y)).x


def _sippy(u: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    try:
        from sippy_unipi import system_identification
    except ImportError:
        return None
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = system_identification(y, u, "OE", OE_orders=[NB, NF, NK])
    return np.asarray(model.Yid, dtype=float).ravel()


def _row(n: int, method: str, fn: Callable[[], object], repeats: int, memory: bool,
         note: str = "", warmup: bool = True) -> tuple[Result, object]:
    last: list[object] = []

    def call() -> None:
        last[:] = [fn()]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if warmup:  # numba cache load, first-call costs
            call()
        timing = time_call(call, repeats, warmup=0)
        out = last[0]
        mem = measure_memory(call) if memory else None
    row = Result(SUITE, f"oe({NB},{NF}) {SNR_DB:.0f} dB", n, method, timing.median * 1e3,
                 timing.best * 1e3, repeats, note=note,
                 peak_mb=None if mem is None else mem.tracemalloc_peak / 2**20,
                 rss_mb=None if mem is None or mem.rss_peak_delta is None
                 else mem.rss_peak_delta / 2**20)
    row.minflt = timing.minor_faults_per_call
    row.extra["times_ms"] = [round(t * 1e3, 4) for t in timing.times]
    return row, out


def run(quick: bool = False) -> list[Result]:
    """Run the PEM suite; ``quick`` uses fewer repeats and skips the slow baselines."""
    rows: list[Result] = []
    for n in (10**4, 10**5):
        rows += _size_rows(n, quick)
    return rows


def _size_rows(n: int, quick: bool) -> list[Result]:
    from servoid import Experiment
    from servoid.estimate import fit_oe

    u, y, y0 = make_record(n)
    exp = Experiment.from_arrays(1.0, u=u, y=y)
    repeats = 3 if quick else (21 if n <= 10**4 else 11)
    rows: list[Result] = []
    ref_row, ref = _row(n, "scipy least_squares lm, analytic jacobian",
                        lambda: scipy_lm(u, y), max(3, repeats // 3), False, "reference θ")
    ref = np.asarray(ref)
    ref_row.rel_diff = 0.0
    ref_row.extra["fit_pct"] = fit_percent(y0, _simulate(ref, u))
    row, est = _row(n, "fit_oe", lambda: fit_oe(exp, NB, NF, NK), repeats, not quick,
                    "target ≤ 10 ms (1e4) / ≤ 100 ms (1e5), fit ≥ 99.9 %")
    row.rel_diff = rel_diff(est.parameters, ref)
    row.extra["fit_pct"] = fit_percent(y0, est.model.simulate(u))
    row.extra["iterations"] = est.options["iterations"]
    row.solver = "gauss-newton"
    rows.append(row)
    start_row, start = _row(n, "fit_oe start only (max_iter=0)",
                            lambda: fit_oe(exp, NB, NF, NK, max_iter=0), repeats, False)
    start_row.rel_diff = rel_diff(start.parameters, ref)
    start_row.extra["fit_pct"] = fit_percent(y0, start.model.simulate(u))
    start_row.solver = "IV"
    rows += [start_row, ref_row]
    if not quick or n <= 10**4:
        trf_row, trf = _row(n, "scipy least_squares trf, 2-point jacobian",
                            lambda: scipy_trf_2point(u, y), 3, False)
        trf_row.rel_diff = rel_diff(np.asarray(trf), ref)
        trf_row.extra["fit_pct"] = fit_percent(y0, _simulate(np.asarray(trf), u))
        rows.append(trf_row)
    if not quick and n <= 10**4:
        sippy_row, y_sippy = _row(n, "SIPPY OE (sippy_unipi, OPT)", lambda: _sippy(u, y), 1,
                                  False, "one call; fit from its returned model output",
                                  warmup=False)
        if y_sippy is not None:
            sippy_row.extra["fit_pct"] = fit_percent(y0, np.asarray(y_sippy))
            rows.append(sippy_row)
    return rows

if __name__ == "__main__":
    from _harness import format_table

    print(format_table(run(quick=False)))
