"""Frequency-domain identification: the LPM on 1e6 samples, an ML fit on 1e4 lines.

Targets (issue 26): "LPM on 1e6 samples ≤ 1 s; an ML fit of a 4th-order model on 1e4 lines
≤ 0.5 s", side by side with a plain numpy LPM and a scipy least-squares fit.

Cases
-----
lpm
    White Gaussian u through a resonant 4th-order discrete system (from rest: a transient)
    plus white output noise, fixed seed; N = 1e6 samples (1e5 under --quick), every line
    from DC to Nyquist (N/2 lines), R = 2, n = 6 (13-line windows, q = 7).
ml
    A continuous 4th-order model (two resonances, 3 zeros) on 1e4 lines (2e3 under --quick)
    from 0.1 to 100 Hz, the response plus circular complex noise of 1 % of its median
    magnitude, known variance.

Methods
-------
servoid.frequency.estimate_lpm
    FFT of u and y, then the compiled per-line kernel: the transient block eliminated once
    (its Schur complement), a 3 × 3 Hermitian Cholesky solve per window, G, its variance and
    the residual (co)variance per line.
numpy LPM (batched normal equations)
    The textbook LPM in numpy: sliding windows of the spectra, the (13 × 6) complex regressor
    per line, its normal equations solved by ``np.linalg.solve`` in blocks of 65 536 lines,
    G and the residual variance per line.  ``rel_diff``: max |ΔG|/|G| against it.
servoid.frequency.fit_ml
    The WLS/GTLS/BTLS starts, the best by its cost, then Levenberg–Marquardt with the
    analytic Jacobian; the covariance and the cost test.
scipy least_squares (TRF, finite differences)
    ``scipy.optimize.least_squares`` on the same normalised residual from the same start
    (fit_ml's WLS start), Jacobian by finite differences: what a user writes without the
    Jacobian.  ``rel_diff``: the relative cost difference against fit_ml's minimum.
"""

from __future__ import annotations

import math

import numpy as np
from _harness import Result, time_call
from scipy import optimize
from scipy import signal as sps

from servoid.data import Experiment
from servoid.frequency import FrfMeasurement, estimate_lpm, fit_ml
from servoid.models import TransferFunction

SUITE = "frequency"
SEED = 20261128
DT = 1e-3


def _lpm_record(n: int) -> Experiment:
    rng = np.random.default_rng(SEED)
    u = rng.standard_normal(n)
    z1 = 0.98 * np.exp(1j * 0.3)
    z2 = 0.95 * np.exp(1j * 1.1)
    den = np.real(np.poly([z1, np.conj(z1), z2, np.conj(z2)]))
    y = sps.lfilter([0.0, 0.05, 0.02, -0.01], den, u) + 0.05 * rng.standard_normal(n)
    return Experiment.from_arrays(DT, u=u, y=y)


def numpy_lpm(u: np.ndarray, y: np.ndarray, n: int = 6, degree: int = 2,
              block: int = 65536) -> tuple[np.ndarray, np.ndarray]:
    """The plain numpy LPM: G and the noise variance of every line 1..(N−1)//2."""
    count = u.size
    scale = 1 / math.sqrt(count)
    x = np.fft.rfft(u) * scale
    z = np.fft.rfft(y) * scale
    top = (count - 1) // 2
    width = 2 * n + 1
    lines = np.arange(1, top + 1)
    starts = np.clip(lines - n, 1, top - width + 1)
    r = (np.arange(width) - n) / n
    powers = r[:, None] ** np.arange(degree + 1)[None, :]
    g = np.empty(lines.size, dtype=complex)
    var = np.empty(lines.size)
    q = width - 2 * (degree + 1)
    for b in range(0, lines.size, block):
        s = starts[b:b + block]
        idx = s[:, None] + np.arange(width)[None, :]
        xw, zw = x[idx], z[idx]
        k = np.concatenate([xw[:, :, None] * powers[None], np.broadcast_to(
            powers, (s.size, width, degree + 1)).astype(complex)], axis=2)
        kh = np.conj(np.swapaxes(k, 1, 2))
        gram = kh @ k
        theta = np.linalg.solve(gram, kh @ zw[:, :, None])[:, :, 0]
        r0 = (lines[b:b + block] - (s + n)) / n
        g[b:b + block] = np.sum(theta[:, :degree + 1] * r0[:, None] ** np.arange(degree + 1),
                                axis=1)
        res = zw - np.einsum("bwc,bc->bw", k, theta)
        var[b:b + block] = np.sum(np.abs(res) ** 2, axis=1) / q
    return g, var


def _ml_measurement(lines: int) -> FrfMeasurement:
    w1, w2 = 2 * np.pi * 8.0, 2 * np.pi * 40.0
    plant = TransferFunction(np.polymul([1 / w1**2, 0.2 / w1, 1.0], [0.0, 1 / w2, 1.0]) * 5.0,
                             np.polymul([1.0, 2 * 0.1 * w1, w1**2], [1.0, 2 * 0.3 * w2, w2**2])
                             / (w1**2 * w2**2))
    f = np.geomspace(0.1, 100.0, lines)
    g = plant.freqresp(2 * np.pi * f)
    sigma = 0.01 * float(np.median(np.abs(g)))
    rng = np.random.default_rng(SEED)
    noise = sigma * (rng.standard_normal(lines) + 1j * rng.standard_normal(lines)) / math.sqrt(2)
    var = np.full(lines, sigma**2)
    return FrfMeasurement(f, g + noise, var, var, None, math.inf, math.inf, 1, "periodic")


def run(quick: bool) -> list[Result]:
    out: list[Result] = []
    n = 100_000 if quick else 1_000_000
    exp = _lpm_record(n)
    reps = 3 if quick else 5
    frm = estimate_lpm(exp)
    g_np, _ = numpy_lpm(exp["u"], exp["y"])
    rel = float(np.max(np.abs(frm.response - g_np[:frm.n_lines]) / np.abs(g_np[:frm.n_lines])))
    t = time_call(lambda: estimate_lpm(exp), repeats=reps)
    out.append(Result(SUITE, "lpm", n, "servoid estimate_lpm (compiled kernel)", t.median * 1e3,
                      t.best * 1e3, len(t.times), rel_diff=rel,
                      note=f"{frm.n_lines} lines, R = 2, 13-line windows"))
    t = time_call(lambda: numpy_lpm(exp["u"], exp["y"]), repeats=max(1, reps // 2))
    out.append(Result(SUITE, "lpm", n, "numpy LPM (batched normal equations)", t.median * 1e3,
                      t.best * 1e3, len(t.times), rel_diff=0.0))
    lines = 2000 if quick else 10_000
    meas = _ml_measurement(lines)
    fit = fit_ml(meas, 4, 3)
    t = time_call(lambda: fit_ml(meas, 4, 3), repeats=reps)
    out.append(Result(SUITE, "ml", lines, "servoid fit_ml (starts + LM, analytic Jacobian)",
                      t.median * 1e3, t.best * 1e3, len(t.times), rel_diff=0.0,
                      note=f"V = {fit.cost:.5g} (expected {fit.expected_cost:.5g}), "
                           f"start {fit.start}"))
    wls = fit_ml(meas, 4, 3, start="wls")
    # the same normalised residual, scaled as fit_ml scales it, from the WLS start
    w_s = math.sqrt(meas.omega[0] * meas.omega[-1])
    g_s = float(np.median(np.abs(meas.response)))
    x = 1j * meas.omega / w_s
    sig = np.sqrt(meas.variance) / g_s
    gm = meas.response / g_s
    scale = np.concatenate([g_s * w_s ** (4 - np.arange(4.0)), w_s ** np.arange(1, 5.0)])

    def residual(theta: np.ndarray) -> np.ndarray:
        b = np.polyval(theta[3::-1], x)
        a = np.polyval(np.concatenate([[1.0], theta[4:]]), x)
        e = (b / a - gm) / sig
        return np.concatenate([e.real, e.imag])

    theta0 = wls.parameters / scale
    sol = optimize.least_squares(residual, theta0, method="trf")
    cost = float(np.sum(sol.fun**2))
    t = time_call(lambda: optimize.least_squares(residual, theta0, method="trf"),
                  repeats=max(1, reps // 2))
    out.append(Result(SUITE, "ml", lines, "scipy least_squares (TRF, finite differences)",
                      t.median * 1e3, t.best * 1e3, len(t.times),
                      rel_diff=abs(cost - fit.cost) / fit.cost,
                      note=f"V = {cost:.5g} from fit_ml's WLS start, {sol.nfev} evaluations"))
    return out


if __name__ == "__main__":
    import sys

    from _harness import format_table

    print(format_table(run("--quick" in sys.argv)))
