"""Residual tests: whiteness and independence from the input.

The tests use the correlations at a few dozen lags only: r_ε(τ) for
τ = 0…M, r_εu(τ) for τ = −M…M, and, for the null covariance of r_εu, the
input's own lagged products up to 2M (up to 6M with coloured residuals).
They are direct sums Σ_t a(t)·b(t + τ) over the lags used, computed by
compiled kernels that walk the record in blocks of :data:`BLOCK` samples:
O(N·lags) time with a small constant and O(lags + BLOCK) memory — not an
FFT of the whole record padded to 2N, of which all but the used lags would
be discarded. The signals are centred and scaled to below unit peak (by a
power of two, exactly) block by block inside the kernels, so no centred
copy of the record is made: the correlations do not depend on scale, and
it keeps products of data near 1e150 from overflowing. With one input, a
single sweep forms every lag the white-residual tests need (ε·ε, u·ε, ε·u
and u·u, their loads shared). A long record is swept in two halves at once,
one per core, and the halves are added in a fixed order, so the sums are
the same with or without the second thread (:func:`_split_sums`)."""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError
from .._lazy import stats
from ._kernels import add_signal_stats

__all__ = ["BLOCK", "ResidualAnalysis", "residual_analysis"]

#: Samples per block of the correlation kernel (two blocks stay in L1 cache).
BLOCK = 2048
#: Residuals from which the lag sums run in two halves, one per core (:func:`_split_sums`).
_SPLIT = 1 << 17


@dataclass(frozen=True, eq=False)
class ResidualAnalysis:
    """Residual tests for whiteness and independence of the input.

    Attributes
    ----------
    lags : ndarray
        Lags 0…M of the autocorrelation.
    autocorrelation : ndarray
        Normalised autocorrelation r_ε(τ), r_ε(0) = 1.
    cross_lags : ndarray
        Lags −M…M of the cross-correlation (positive: input leads residual).
    cross_correlation : ndarray, shape (n_inputs, 2M + 1)
        Normalised cross-correlation r_εu(τ) per input.
    bound : float
        ±z/√N band a white, input-independent ε stays inside with the confidence level.
    confidence : float
        Confidence level of the band and of the verdicts.
    whiteness_pvalue : float
        Ljung–Box test on lags 1…M: Q = N(N+2)Σ r²(τ)/(N−τ) ~ χ²(M).
    independence_pvalue : float
        N·rᵀP⁺r ~ χ²(rank P) over all 2M+1 lags and inputs, with P the covariance
        of √N·r_εu under the null (ε white, independent of u), built from the
        input's own correlations, so a coloured input (a PRBS held for several
        samples) is not mistaken for dependence; NaN without input.
    causal : bool
        Whether only the lags τ ≥ 0 (input leading) were tested (closed loop).
    """

    lags: NDArray[np.int64]
    autocorrelation: NDArray[np.float64]
    cross_lags: NDArray[np.int64]
    cross_correlation: NDArray[np.float64]
    bound: float
    confidence: float
    whiteness_pvalue: float
    independence_pvalue: float
    n_samples: int
    causal: bool = False

    @property
    def is_white(self) -> bool:
        """Whiteness not rejected at the confidence level."""
        return bool(self.whiteness_pvalue > 1 - self.confidence)

    @property
    def is_independent(self) -> bool:
        """Independence from the input not rejected (True without input)."""
        return bool(np.isnan(self.independence_pvalue) or self.independence_pvalue > 1 - self.confidence)

    @property
    def fraction_outside(self) -> float:
        """Share of autocorrelation lags 1…M outside the band."""
        return float(np.mean(np.abs(self.autocorrelation[1:]) > self.bound))

    def to_dict(self) -> dict[str, object]:
        """Plain data for JSON."""
        return {
            "lags": self.lags.tolist(),
            "autocorrelation": self.autocorrelation.tolist(),
            "cross_lags": self.cross_lags.tolist(),
            "cross_correlation": self.cross_correlation.tolist(),
            "bound": self.bound,
            "confidence": self.confidence,
            "whiteness_pvalue": self.whiteness_pvalue,
            "independence_pvalue": None if np.isnan(self.independence_pvalue) else self.independence_pvalue,
            "is_white": self.is_white,
            "is_independent": self.is_independent,
            "n_samples": self.n_samples,
            "causal": self.causal,
        }


def residual_analysis(
    residuals: ArrayLike,
    u: ArrayLike | None = None,
    max_lag: int = 25,
    confidence: float = 0.99,
    causal: bool = False,
) -> ResidualAnalysis:
    """Test residuals for whiteness and correlation with the input.

    Parameters
    ----------
    residuals : array_like, shape (N,)
        Prediction errors on (preferably validation) data.
    u : array_like, shape (N,) or (N, n_inputs), optional
        Input(s) over the same samples.
    max_lag : int
        Largest lag M [samples].
    confidence : float
        Level of the band (0.99 gives ±2.58/√N) and of the verdicts.
    causal : bool
        Test independence only at lags τ = 0…M (the input leading the
        residual).  In closed loop the input depends on past residuals
        through the controller, so the negative lags are correlated by the
        loop, not by a wrong model (Ljung, *System Identification*, §16.6).

    Notes
    -----
    Memory: about 0 N × 8 bytes beyond the inputs (the signals are centred
    block by block inside the kernels; O(M + 2048) floats of buffers).

    Time O(N·M·(1 + n_inputs²)): about 7 ms for N = 10⁶, M = 25 and one
    input with white residuals on the reference machine, 10 ms on one
    thread (``benchmarks/bench_scaling.py``; from 131 072 residuals the
    sums run in two halves on two threads, the same numbers either way);
    coloured residuals add the input's lagged products up to 6M for the
    null covariance (about twice that).
    """
    return analyse_residuals(residuals, u, max_lag, confidence, causal, None)


def analyse_residuals(
    residuals: ArrayLike,
    u: ArrayLike | None,
    max_lag: int,
    confidence: float,
    causal: bool,
    known_sums: NDArray[np.float64] | None,
) -> ResidualAnalysis:
    """:func:`residual_analysis`, with the sums and ranges known or not.

    ``known_sums`` (rows: the residuals, then each input or none; columns:
    sum, min, max), when a pass that formed the residuals summed them
    already, replaces the pass over the signals it covers.
    """
    e_raw = as_array("residuals", residuals, finite=False).ravel()
    n = e_raw.size
    e_stats = _stats_of([e_raw], None if known_sums is None else known_sums[:1])
    e_mean = _known_mean(e_stats, 0, n)
    if not np.isfinite(e_mean):
        e_mean = _mean(e_raw)
    if not np.isfinite(e_mean):
        raise DataError(
            f"residuals have {int(np.sum(~np.isfinite(e_raw)))} non-finite value(s) of {n}: the "
            "model's prediction diverged or the data hold NaN; a whiteness test would be meaningless"
        )
    uu = None if u is None else as_array("u", u, finite=False)
    if uu is not None and uu.size % max(n, 1):
        raise DataError(f"u must have {n} samples per input (one per residual), got shape "
                        f"{uu.shape}")
    u_raw = [] if uu is None else [
        np.ascontiguousarray(col, dtype=np.float64) for col in uu.reshape(n, -1).T
    ]
    known = known_sums is not None and known_sums.shape[0] == 1 + len(u_raw)
    u_stats = _stats_of(u_raw, known_sums[1:] if known else None)
    u_means = [
        m if np.isfinite(m := _known_mean(u_stats, i, n)) else _mean(col)
        for i, col in enumerate(u_raw)
    ]
    if not np.all(np.isfinite(u_means)):
        raise DataError("the input for the cross-correlation test has non-finite values")
    if not 0 < confidence < 1:
        raise DataError(f"confidence must lie in (0, 1), got {confidence}")
    if max_lag < 1 or max_lag >= n // 2:
        raise DataError(f"max_lag must lie in [1, {n // 2 - 1}] for {n} residuals, got {max_lag}")
    # correlations do not depend on scale: work on unit-scale data so that values near 1e160
    # cannot overflow the products into inf and turn the tests into "white, p = 1". The
    # centred, scaled signals (x − mean)·2^−k, 2^k the power of two above the peak, are formed
    # block by block inside the kernels (no N-sample copies; scaling by a power of two is
    # exact, so it leaves the correlations as they are); the means are finite, so every value is.
    e = _Centred.of(e_raw, e_mean, _known_range(e_stats, 0, e_mean))
    cols = [
        _Centred.of(col, m, _known_range(u_stats, i, m))
        for i, (col, m) in enumerate(zip(u_raw, u_means, strict=True))
    ]
    single = len(cols) == 1
    if single:  # the common case: every lag the white-residual tests use, in one pass
        e_sums, ue, eu, uu_sums = _fused_sums(e, cols[0], max_lag)
    else:
        e_sums = _centred_lags(e, e, 0, max_lag)
    auto = _normalised(e_sums, e_sums[0], e_sums[0])
    lags = np.arange(max_lag + 1)
    q = n * (n + 2) * np.sum(auto[1:] ** 2 / (n - lags[1:]))
    p_white = float(stats.chi2.sf(q, max_lag))
    cross_lags = np.arange(-max_lag, max_lag + 1)
    if not cols:
        cross = np.empty((0, cross_lags.size))
        p_indep = np.nan
    else:
        # Coloured residuals (an output-error model leaves the noise colour in them) widen the
        # spread of r_εu under the null; then the residuals' own correlation enters its
        # covariance (Ljung, System Identification, 2nd ed., eq. 16.69), else the exact white one.
        colour = None
        if not p_white > 1 - confidence:
            k_max = _colour_lags(n, max_lag)
            more = _centred_lags(e, e, max_lag + 1, k_max)  # empty when K ≤ M
            colour = _bartlett(np.concatenate([e_sums[: k_max + 1], more]))
        reach = 2 * max_lag + (0 if colour is None else (colour.size - 1) // 2)
        if single:
            one = np.concatenate([uu_sums, _centred_lags(cols[0], cols[0], 2 * max_lag + 1, reach)])
            sums = {(0, 0): np.concatenate([one[:0:-1], one])}
            two_sided = [np.concatenate([eu[1:][::-1], ue])]  # Σ u(t)·e(t + d), d = −M…M
        else:
            sums = _input_sums(cols, reach)
            two_sided = [_centred_two_sided(col, e, max_lag) for col in cols]
        energy = np.array([sums[i, i][reach] for i in range(len(cols))])
        cross = np.vstack([
            _normalised(two_sided[i], energy[i], e_sums[0]) for i in range(len(cols))
        ])
        p_indep = _independence_pvalue(cross, cols, sums, energy, max_lag, colour, causal)
    bound = float(stats.norm.ppf(0.5 + confidence / 2) / np.sqrt(n))
    return ResidualAnalysis(lags, auto, cross_lags, cross, bound, confidence, p_white, p_indep, n,
                            causal)


class _Centred(NamedTuple):
    """A signal x with its mean and scale: stands for (x − mean)·scale.

    ``scale`` is the power of two 2^−k with 2^(k−1) ≤ max|x − mean| < 2^k (1 for a
    constant signal), so the values lie in (−1, 1) and the scaling itself is exact.
    The kernels and :meth:`at` form the values where they are used, with the same
    two operations, so every use sees the same numbers.
    """

    raw: NDArray[np.float64]
    mean: float
    scale: float

    @classmethod
    def of(cls, x: NDArray[np.float64], mean: float,
           known: tuple[float, float] | None = None) -> _Centred:
        x = np.ascontiguousarray(x, dtype=np.float64)
        # x is finite (its mean is): min and max are exact
        lo, hi = _range_kernel(x) if known is None else known
        # |x − mean| is largest at the largest or the smallest x (rounding is monotonic),
        # so this is max|x − mean| to the bit
        peak = max(float(hi - mean), float(mean - lo), 0.0)
        # 2^−k, capped at 2^1023 (a peak below ~1e-308 still comes out near 1e-2 or above)
        scale = math.ldexp(1.0, min(-math.frexp(peak)[1], 1023)) if peak > 0 else 1.0
        return cls(x, float(mean), scale)

    @property
    def size(self) -> int:
        return int(self.raw.size)

    def at(self, index: NDArray[np.int64]) -> NDArray[np.float64]:
        """The centred values at ``index``, zero outside the record."""
        inside = (index >= 0) & (index < self.raw.size)
        x = (self.raw[np.clip(index, 0, self.raw.size - 1)] - self.mean) * self.scale
        return np.where(inside, x, 0.0)


def _centred_lags(a: _Centred, b: _Centred, first: int, last: int) -> NDArray[np.float64]:
    """Σ_{t=0}^{N−1−τ} a(t)·b(t + τ) for τ = first…last of the centred signals."""
    if last < first:
        return np.zeros(0)
    return _split_sums(_pair_kernel, a.size, a.raw, a.mean, a.scale, b.raw, b.mean, b.scale,
                       int(first), int(last), BLOCK)


def _centred_two_sided(a: _Centred, b: _Centred, max_lag: int) -> NDArray[np.float64]:
    """Σ_t a(t)·b(t + d) for d = −L…L of the centred signals (b leading a for d < 0)."""
    if a is b:
        one = _centred_lags(a, a, 0, max_lag)
        return np.concatenate([one[:0:-1], one])
    return np.concatenate([_centred_lags(b, a, 1, max_lag)[::-1], _centred_lags(a, b, 0, max_lag)])


def _fused_sums(
    e: _Centred, u: _Centred, max_lag: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Σe(t)e(t+τ), Σu(t)e(t+τ), Σe(t)u(t+τ) for τ = 0…M and Σu(t)u(t+τ) for τ = 0…2M."""
    return _split_sums(_fused_kernel, e.size, e.raw, e.mean, e.scale, u.raw, u.mean, u.scale,
                       int(max_lag), BLOCK)


def _split_sums(kernel: Any, n: int, *args: Any) -> Any:
    """``kernel(*args, lo, hi)`` summed over t in [0, n): in two halves for a long record.

    The halves run at once, the second on a worker thread, unless numba is
    held to one thread (``NUMBA_NUM_THREADS=1``, as fleet workers are); they
    are added in the same order either way, so the sums do not depend on it.
    """
    if n < _SPLIT:
        return kernel(*args, 0, n)
    mid = (n // 2 // BLOCK) * BLOCK
    pool = _worker()
    if pool is None:
        first, second = kernel(*args, 0, mid), kernel(*args, mid, n)
    else:
        later = pool.submit(kernel, *args, mid, n)
        first, second = kernel(*args, 0, mid), later.result()
    if isinstance(first, tuple):
        return tuple(a + b for a, b in zip(first, second, strict=True))
    return first + second


_POOL: tuple[int, ThreadPoolExecutor] | None = None


def _worker() -> ThreadPoolExecutor | None:
    """The one worker thread of this process, or None when numba may use one thread."""
    global _POOL
    if numba.config.NUMBA_NUM_THREADS < 2:
        return None
    if _POOL is None or _POOL[0] != os.getpid():  # a forked child has no worker thread
        _POOL = (os.getpid(), ThreadPoolExecutor(1, thread_name_prefix="servoid-sums"))
    return _POOL[1]


def _xcorr(a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    # r_ab(τ) = Σ_t a(t)·b(t+τ) / √(Σa² Σb²) for τ = −M…M (biased estimate, as in Ljung).
    return _normalised(_two_sided(a, b, max_lag), float(a @ a), float(b @ b))


def _lagged_sums(
    a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int
) -> NDArray[np.float64]:
    # Σ_t a(t)·b(t + d) for d = −L…L (zero outside the record), unnormalised.
    return _two_sided(a, b, max_lag)


def _stats_of(signals: list[NDArray[np.float64]],
              known: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """Sum, min and max of each signal (rows): ``known``, or one compiled pass each."""
    if known is not None:
        return known
    st = np.zeros((len(signals), 3))
    st[:, 1], st[:, 2] = np.inf, -np.inf
    for i, x in enumerate(signals):
        add_signal_stats(x, st, i)
    return st


def _known_mean(sums: NDArray[np.float64] | None, row: int, n: int) -> float:
    """The mean from a known sum; NaN when there is none (or it is not finite)."""
    if sums is None or n == 0:
        return math.nan
    with np.errstate(over="ignore", invalid="ignore"):
        return float(sums[row, 0] / n)


def _known_range(sums: NDArray[np.float64] | None, row: int,
                 mean: float) -> tuple[float, float] | None:
    """The known (min, max), when its sum was finite (the mean it gave was used)."""
    if sums is None or not np.isfinite(sums[row, 0]) or not np.isfinite(mean):
        return None
    return float(sums[row, 1]), float(sums[row, 2])


def _mean(x: NDArray[np.float64]) -> float:
    """Mean of x: NaN when x holds NaN or inf (so no separate finiteness pass is needed)."""
    with np.errstate(over="ignore", invalid="ignore"):
        m = float(np.mean(x))
    if np.isinf(m) and np.all(np.isfinite(x)):  # finite values whose sum overflows
        peak = float(np.max(np.abs(x)))
        m = float(np.mean(x / peak)) * peak
    return m


def _unit_scale(x: NDArray[np.float64]) -> NDArray[np.float64]:
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    return x / peak if peak > 0 else x


def _bartlett_autocorrelation(e: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """ρ̂_ε(k)·(1 − |k|/(K+1)) for k = −K…K, K = min(4M, N/4): a non-negative spectrum."""
    return _bartlett(_lag_products(e, e, 0, _colour_lags(e.size, max_lag)))


def _colour_lags(n: int, max_lag: int) -> int:
    return int(min(4 * max_lag, n // 4))


def _bartlett(sums: NDArray[np.float64]) -> NDArray[np.float64]:
    # sums: Σ e(t)e(t + k) for k = 0…K → the tapered two-sided autocorrelation
    k_max = sums.size - 1
    rho = _normalised(np.concatenate([sums[:0:-1], sums]), sums[0], sums[0])
    return rho * (1.0 - np.abs(np.arange(-k_max, k_max + 1)) / (k_max + 1))


def _normalised(r: NDArray[np.float64], energy_a: float, energy_b: float) -> NDArray[np.float64]:
    norm = np.sqrt(energy_a * energy_b)
    return r / norm if norm > 0 else np.zeros_like(r)


def _two_sided(
    a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int
) -> NDArray[np.float64]:
    """Σ_t a(t)·b(t + d) for d = −L…L: the negative lags are b leading a."""
    if a is b:
        one = _lag_products(a, a, 0, max_lag)
        return np.concatenate([one[:0:-1], one])
    return np.concatenate([_lag_products(b, a, 1, max_lag)[::-1], _lag_products(a, b, 0, max_lag)])


def _input_sums(
    cols: list[_Centred], reach: int
) -> dict[tuple[int, int], NDArray[np.float64]]:
    """S_ij(d) = Σ_t u_i(t)·u_j(t + d), d = −reach…reach, for every pair of inputs."""
    sums = {}
    for i, a in enumerate(cols):
        for j in range(i, len(cols)):
            sums[i, j] = _centred_two_sided(a, a if i == j else cols[j], reach)
            sums[j, i] = sums[i, j][::-1]
    return sums


def _lag_products(
    a: NDArray[np.float64], b: NDArray[np.float64], first: int, last: int
) -> NDArray[np.float64]:
    """Σ_{t=0}^{N−1−τ} a(t)·b(t + τ) for τ = first…last (empty when last < first)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if last < first:
        return np.zeros(0)
    # the centred kernel with mean 0 and scale 1: (x − 0)·1 is x exactly
    return _pair_kernel(a, 0.0, 1.0, b, 0.0, 1.0, int(first), int(last), BLOCK, 0, a.size)


def _independence_pvalue(
    cross: NDArray[np.float64], cols: list[_Centred],
    sums: dict[tuple[int, int], NDArray[np.float64]], energy: NDArray[np.float64],
    max_lag: int, colour: NDArray[np.float64] | None = None, causal: bool = False,
) -> float:
    # With ε white and independent of u, r_εu(i, τ) = Σ_s ε(s)·x_iτ(s)/(‖u_i‖‖ε‖) with
    # x_iτ(s) = u_i(s − τ) (zero outside the record), so Cov(√N·r) = P with
    # P[(i,τ),(j,τ')] = Σ_{s=0}^{N−1} u_i(s − τ)·u_j(s − τ')/(‖u_i‖‖u_j‖). Treating the
    # lags as independent (N·Σr² ~ χ²(2M+1)) holds only for a white input: a PRBS held
    # for 10 samples is then rejected in ~15 % of runs at the 1 % level.
    n = cols[0].size
    k = len(cols)
    m_lag = max_lag
    norms = np.sqrt(energy)
    if not np.all(norms > 0):
        return float("nan")
    lags = np.arange(-m_lag, m_lag + 1)
    d_all = np.arange(-2 * m_lag, 2 * m_lag + 1)
    reach = (sums[0, 0].size - 1) // 2
    # entry (τ, τ') sums p_d(t) = u_i(t)·u_j(t + d), d = τ − τ', over t ∈ [−τ, N − τ): the full
    # lagged product minus at most M terms at the head (τ < 0) or the tail (τ > 0)
    tau = lags[:, None] + np.zeros(lags.size, dtype=int)[None, :]
    d_idx = (lags[:, None] - lags[None, :]) + 2 * m_lag
    head_len = np.maximum(-tau, 0)
    tail_len = np.maximum(tau, 0)
    t_head = np.arange(m_lag)
    t_tail = np.arange(n - m_lag, n)
    cov = np.empty((k * lags.size, k * lags.size))
    for i in range(k):
        for j in range(k):
            s_ij = sums[i, j]
            if colour is None:
                full = s_ij[reach - 2 * m_lag : reach + 2 * m_lag + 1]
                # u_j(t + d) at the first and last M samples t, zero outside the record
                head = cols[i].at(t_head) * cols[j].at(t_head[None, :] + d_all[:, None])
                tail = cols[i].at(t_tail) * cols[j].at(t_tail[None, :] + d_all[:, None])
                head_sum = np.concatenate([np.zeros((d_all.size, 1)), np.cumsum(head, axis=1)],
                                          axis=1)
                tail_sum = np.concatenate(
                    [np.zeros((d_all.size, 1)), np.cumsum(tail[:, ::-1], axis=1)], axis=1
                )
                block = full[d_idx] - head_sum[d_idx, head_len] - tail_sum[d_idx, tail_len]
            else:
                # Cov = Σ_k ρ_ε(k)·S_ij(k + τ − τ'), S_ij(m) = Σ_s u_i(s)u_j(s + m); the end
                # corrections above are dropped here (they are O(M/N) of each term)
                mixed = np.correlate(s_ij, colour, mode="valid")  # index d + 2M, d = τ − τ'
                block = mixed[d_idx]
            rows = slice(i * lags.size, (i + 1) * lags.size)
            cols_ = slice(j * lags.size, (j + 1) * lags.size)
            cov[rows, cols_] = block / (norms[i] * norms[j])
    r = cross.ravel()
    if causal:  # keep τ = 0…M of every input
        keep_lags = np.tile(lags >= 0, k)
        r, cov = r[keep_lags], cov[np.ix_(keep_lags, keep_lags)]
    eig, vec = np.linalg.eigh(cov)
    keep = eig > eig[-1] * cov.shape[0] * np.finfo(float).eps  # numerical rank, as matrix_rank
    proj = vec[:, keep].T @ r
    stat = n * float(np.sum(proj**2 / eig[keep]))
    return float(stats.chi2.sf(stat, int(keep.sum())))


def _shifted(x: NDArray[np.float64], index: NDArray[np.int64]) -> NDArray[np.float64]:
    """x[index], zero where the index falls outside the record."""
    inside = (index >= 0) & (index < x.size)
    return np.where(inside, x[np.clip(index, 0, x.size - 1)], 0.0)


@numba.njit(cache=True, nogil=True, fastmath={"nnan", "ninf", "nsz"})
def _range_kernel(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    # min and max of finite x (the flags let the compares vectorise)
    lo = np.inf
    hi = -np.inf
    for v in x:
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _fill(x, mean, scale, start, buf):  # type: ignore[no-untyped-def]  # pragma: no cover
    # buf[i] = (x[start + i] − mean)·scale, zero past the record (a multiply: a divide per
    # sample cost as much as a quarter of the lagged products)
    n = x.size
    avail = min(buf.size, n - start)
    for i in range(avail):
        buf[i] = (x[start + i] - mean) * scale
    for i in range(max(avail, 0), buf.size):
        buf[i] = 0.0


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
def _pair_kernel(a, ma, sa, b, mb, sb, first, last, block, lo, hi):  # type: ignore[no-untyped-def]  # pragma: no cover
    # out[τ − first] = Σ_t a_c(t)·b_c(t + τ) over t in [lo, hi), x_c = (x − m)·s formed per
    # block in two small buffers (b's reaches `last` samples further, into the record past
    # hi and zero past its end, so no end cases)
    out = np.zeros(last - first + 1)
    ab = np.empty(block)
    bb = np.empty(block + last + 4)
    for start in range(lo, hi, block):
        w = min(block, hi - start)
        _fill(a, ma, sa, start, ab)
        _fill(b, mb, sb, start, bb)
        tau = first
        # 0-based slices: an index t + τ the compiler cannot prove non-negative (τ starts
        # at `first`) keeps numba's wraparound check in the loop and stops vectorisation
        while tau + 3 <= last:  # four lags per sweep: one load of a per four products
            b0 = bb[tau : tau + w]
            b1 = bb[tau + 1 : tau + 1 + w]
            b2 = bb[tau + 2 : tau + 2 + w]
            b3 = bb[tau + 3 : tau + 3 + w]
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for t in range(w):
                x = ab[t]
                s0 += x * b0[t]
                s1 += x * b1[t]
                s2 += x * b2[t]
                s3 += x * b3[t]
            out[tau - first] += s0
            out[tau - first + 1] += s1
            out[tau - first + 2] += s2
            out[tau - first + 3] += s3
            tau += 4
        while tau <= last:
            b0 = bb[tau : tau + w]
            s0 = 0.0
            for t in range(w):
                s0 += ab[t] * b0[t]
            out[tau - first] += s0
            tau += 1
    return out


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
def _fused_kernel(e, me, se, u, mu, su, m, block, lo, hi):  # type: ignore[no-untyped-def]  # pragma: no cover
    # For τ = 0…M: ee[τ] = Σ e_c(t)e_c(t+τ), ue[τ] = Σ u_c(t)e_c(t+τ), eu[τ] = Σ e_c(t)u_c(t+τ),
    # uu[τ] = Σ u_c(t)u_c(t+τ); uu also for τ = M+1…2M; t in [lo, hi). One sweep over blocks
    # of the centred signals (formed in small buffers, zero past the record). Three lags per inner
    # loop share the loads of e_c(t) and u_c(t): 12 products for 8 loads, which keeps the
    # two FMA units busy (two lags left it waiting on loads, four spilled registers); the
    # input's far lags go eight at a time. Lags past M or 2M are summed and dropped.
    r = 2 * m
    eb = np.empty(block + r + 12)
    ub = np.empty(block + r + 12)
    ee = np.zeros(m + 3)
    ue = np.zeros(m + 3)
    eu = np.zeros(m + 3)
    uu = np.zeros(r + 10)
    for start in range(lo, hi, block):
        w = min(block, hi - start)
        _fill(e, me, se, start, eb)
        _fill(u, mu, su, start, ub)
        tau = 0
        while tau <= m:
            e0 = eb[tau : tau + w]
            e1 = eb[tau + 1 : tau + 1 + w]
            e2 = eb[tau + 2 : tau + 2 + w]
            u0 = ub[tau : tau + w]
            u1 = ub[tau + 1 : tau + 1 + w]
            u2 = ub[tau + 2 : tau + 2 + w]
            s00 = s01 = s02 = s03 = 0.0
            s10 = s11 = s12 = s13 = 0.0
            s20 = s21 = s22 = s23 = 0.0
            for t in range(w):
                x = eb[t]
                v = ub[t]
                s00 += x * e0[t]
                s01 += v * e0[t]
                s02 += x * u0[t]
                s03 += v * u0[t]
                s10 += x * e1[t]
                s11 += v * e1[t]
                s12 += x * u1[t]
                s13 += v * u1[t]
                s20 += x * e2[t]
                s21 += v * e2[t]
                s22 += x * u2[t]
                s23 += v * u2[t]
            ee[tau] += s00
            ue[tau] += s01
            eu[tau] += s02
            uu[tau] += s03
            ee[tau + 1] += s10
            ue[tau + 1] += s11
            eu[tau + 1] += s12
            uu[tau + 1] += s13
            ee[tau + 2] += s20
            ue[tau + 2] += s21
            eu[tau + 2] += s22
            uu[tau + 2] += s23
            tau += 3
        # τ is now the first lag of uu not yet summed (M + 1 … M + 3)
        while tau <= r:
            b0 = ub[tau : tau + w]
            b1 = ub[tau + 1 : tau + 1 + w]
            b2 = ub[tau + 2 : tau + 2 + w]
            b3 = ub[tau + 3 : tau + 3 + w]
            b4 = ub[tau + 4 : tau + 4 + w]
            b5 = ub[tau + 5 : tau + 5 + w]
            b6 = ub[tau + 6 : tau + 6 + w]
            b7 = ub[tau + 7 : tau + 7 + w]
            s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
            for t in range(w):
                v = ub[t]
                s0 += v * b0[t]
                s1 += v * b1[t]
                s2 += v * b2[t]
                s3 += v * b3[t]
                s4 += v * b4[t]
                s5 += v * b5[t]
                s6 += v * b6[t]
                s7 += v * b7[t]
            uu[tau] += s0
            uu[tau + 1] += s1
            uu[tau + 2] += s2
            uu[tau + 3] += s3
            uu[tau + 4] += s4
            uu[tau + 5] += s5
            uu[tau + 6] += s6
            uu[tau + 7] += s7
            tau += 8
    return ee[: m + 1], ue[: m + 1], eu[: m + 1], uu[: r + 1]
