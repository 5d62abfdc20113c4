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
    """Correlation tests of residuals ε against whiteness and the input.

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
        N·Σ r_εu² over all 2M+1 lags and inputs ~ χ²; NaN without input.
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
        }


def residual_analysis(
    residuals: ArrayLike,
    u: ArrayLike | None = None,
    max_lag: int = 25,
    confidence: float = 0.99,
) -> ResidualAnalysis:
    """Test residuals for whiteness and for correlation with the input.

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
    """
    e = np.asarray(residuals, dtype=float).ravel()
    n = e.size
    if not 0 < confidence < 1:
        raise DataError(f"confidence must lie in (0, 1), got {confidence}")
    if max_lag < 1 or max_lag >= n // 2:
        raise DataError(f"max_lag must lie in [1, {n // 2 - 1}] for {n} residuals, got {max_lag}")
    e = e - e.mean()
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
        cross = np.vstack([_xcorr(col - col.mean(), e, max_lag) for col in uu.T])
        # Under the null (ε white, independent of u) each √N·r_εu(τ) is ~N(0, 1).
        p_indep = float(stats.chi2.sf(n * np.sum(cross**2), cross.size))
    bound = float(stats.norm.ppf(0.5 + confidence / 2) / np.sqrt(n))
    return ResidualAnalysis(lags, auto, cross_lags, cross, bound, confidence, p_white, p_indep, n)


def _xcorr(a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    # r_ab(τ) = Σ_t a(t)·b(t+τ) / √(Σa² Σb²) for τ = −M…M (biased estimate, as in Ljung).
    n = a.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.conj(np.fft.rfft(a, nfft)) * np.fft.rfft(b, nfft)
    full = np.fft.irfft(spec, nfft)
    r = np.concatenate([full[nfft - max_lag :], full[: max_lag + 1]])
    norm = np.sqrt(np.dot(a, a) * np.dot(b, b))
    return r / norm if norm > 0 else np.zeros_like(r)
