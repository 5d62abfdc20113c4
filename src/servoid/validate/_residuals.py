"""Residual tests: whiteness and independence from the input."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from .._errors import DataError

__all__ = ["ResidualAnalysis", "residual_analysis"]


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
    """
    e = np.asarray(residuals, dtype=float).ravel()
    n = e.size
    if not np.all(np.isfinite(e)):
        raise DataError(
            f"residuals have {int(np.sum(~np.isfinite(e)))} non-finite value(s) of {n}: the "
            "model's prediction diverged or the data hold NaN; a whiteness test would be meaningless"
        )
    if u is not None and not np.all(np.isfinite(np.asarray(u, dtype=float))):
        raise DataError("the input for the cross-correlation test has non-finite values")
    if not 0 < confidence < 1:
        raise DataError(f"confidence must lie in (0, 1), got {confidence}")
    if max_lag < 1 or max_lag >= n // 2:
        raise DataError(f"max_lag must lie in [1, {n // 2 - 1}] for {n} residuals, got {max_lag}")
    # correlations do not depend on scale: work on unit-scale data so that values near 1e160
    # cannot overflow the products into inf and turn the tests into "white, p = 1"
    e = _unit_scale(e - e.mean())
    auto = _xcorr(e, e, max_lag)[max_lag:]
    lags = np.arange(max_lag + 1)
    q = n * (n + 2) * np.sum(auto[1:] ** 2 / (n - lags[1:]))
    p_white = float(stats.chi2.sf(q, max_lag))
    cross_lags = np.arange(-max_lag, max_lag + 1)
    if u is None:
        cross = np.empty((0, cross_lags.size))
        p_indep = np.nan
    else:
        uu = np.asarray(u, dtype=float).reshape(n, -1)
        uu = np.column_stack([_unit_scale(col - col.mean()) for col in uu.T])
        cross = np.vstack([_xcorr(col - col.mean(), e, max_lag) for col in uu.T])
        # Coloured residuals (an output-error model leaves the noise colour in them) widen the
        # spread of r_εu under the null; then the residuals' own correlation enters its
        # covariance (Ljung, System Identification, 2nd ed., eq. 16.69), else the exact white one.
        colour = None if p_white > 1 - confidence else _bartlett_autocorrelation(e, max_lag)
        p_indep = _independence_pvalue(cross, uu - uu.mean(axis=0), max_lag, colour, causal)
    bound = float(stats.norm.ppf(0.5 + confidence / 2) / np.sqrt(n))
    return ResidualAnalysis(lags, auto, cross_lags, cross, bound, confidence, p_white, p_indep, n,
                            causal)


def _xcorr(a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    # r_ab(τ) = Σ_t a(t)·b(t+τ) / √(Σa² Σb²) for τ = −M…M (biased estimate, as in Ljung).
    n = a.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.conj(np.fft.rfft(a, nfft)) * np.fft.rfft(b, nfft)
    full = np.fft.irfft(spec, nfft)
    r = np.concatenate([full[nfft - max_lag :], full[: max_lag + 1]])
    norm = np.sqrt(np.dot(a, a) * np.dot(b, b))
    return r / norm if norm > 0 else np.zeros_like(r)


def _unit_scale(x: NDArray[np.float64]) -> NDArray[np.float64]:
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    return x / peak if peak > 0 else x


def _bartlett_autocorrelation(e: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """ρ̂_ε(k)·(1 − |k|/(K+1)) for k = −K…K, K = min(4M, N/4): a non-negative spectrum."""
    k_max = int(min(4 * max_lag, e.size // 4))
    rho = _xcorr(e, e, k_max)
    return rho * (1.0 - np.abs(np.arange(-k_max, k_max + 1)) / (k_max + 1))


def _independence_pvalue(
    cross: NDArray[np.float64], u: NDArray[np.float64], max_lag: int,
    colour: NDArray[np.float64] | None = None, causal: bool = False,
) -> float:
    # With ε white and independent of u, r_εu(i, τ) = Σ_s ε(s)·x_iτ(s)/(‖u_i‖‖ε‖) with
    # x_iτ(s) = u_i(s − τ) (zero outside the record), so Cov(√N·r) = P with
    # P[(i,τ),(j,τ')] = Σ_{s=0}^{N−1} u_i(s − τ)·u_j(s − τ')/(‖u_i‖‖u_j‖). Treating the
    # lags as independent (N·Σr² ~ χ²(2M+1)) holds only for a white input: a PRBS held
    # for 10 samples is then rejected in ~15 % of runs at the 1 % level.
    n, k = u.shape
    m_lag = max_lag
    norms = np.linalg.norm(u, axis=0)
    if not np.all(norms > 0):
        return float("nan")
    lags = np.arange(-m_lag, m_lag + 1)
    d_all = np.arange(-2 * m_lag, 2 * m_lag + 1)
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
            pad = np.concatenate([np.zeros(2 * m_lag), u[:, j], np.zeros(2 * m_lag)])
            full = _lagged_sums(u[:, i], u[:, j], 2 * m_lag)
            head = u[t_head, i] * pad[t_head[None, :] + d_all[:, None] + 2 * m_lag]
            tail = u[t_tail, i] * pad[t_tail[None, :] + d_all[:, None] + 2 * m_lag]
            head_sum = np.concatenate([np.zeros((d_all.size, 1)), np.cumsum(head, axis=1)], axis=1)
            tail_sum = np.concatenate(
                [np.zeros((d_all.size, 1)), np.cumsum(tail[:, ::-1], axis=1)], axis=1
            )
            block = full[d_idx] - head_sum[d_idx, head_len] - tail_sum[d_idx, tail_len]
            if colour is not None:
                # Cov = Σ_k ρ_ε(k)·S_ij(k + τ − τ'), S_ij(m) = Σ_s u_i(s)u_j(s + m); the end
                # corrections above are dropped here (they are O(M/N) of each term)
                k_max = (colour.size - 1) // 2
                wide = _lagged_sums(u[:, i], u[:, j], 2 * m_lag + k_max)
                mixed = np.correlate(wide, colour, mode="valid")  # index d + 2M, d = τ − τ'
                block = mixed[d_idx]
            rows = slice(i * lags.size, (i + 1) * lags.size)
            cols = slice(j * lags.size, (j + 1) * lags.size)
            cov[rows, cols] = block / (norms[i] * norms[j])
    r = cross.ravel()
    if causal:  # keep τ = 0…M of every input
        keep_lags = np.tile(lags >= 0, k)
        r, cov = r[keep_lags], cov[np.ix_(keep_lags, keep_lags)]
    eig, vec = np.linalg.eigh(cov)
    keep = eig > eig[-1] * cov.shape[0] * np.finfo(float).eps  # numerical rank, as matrix_rank
    proj = vec[:, keep].T @ r
    stat = n * float(np.sum(proj**2 / eig[keep]))
    return float(stats.chi2.sf(stat, int(keep.sum())))


def _lagged_sums(a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    # Σ_t a(t)·b(t + d) for d = −L…L (zero outside the record), unnormalised.
    n = a.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    full = np.fft.irfft(np.conj(np.fft.rfft(a, nfft)) * np.fft.rfft(b, nfft), nfft)
    return np.concatenate([full[nfft - max_lag :], full[: max_lag + 1]])
