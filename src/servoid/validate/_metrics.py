"""Goodness-of-fit metrics between measured and model outputs."""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import DataError, ServoidWarning

__all__ = ["fit_percent", "nrmse", "relative_error", "rmse", "vaf"]


def _pair(y: ArrayLike, y_hat: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    if y.shape != y_hat.shape:
        raise DataError(f"measured and model outputs differ in shape: {y.shape} vs {y_hat.shape}")
    if y.shape[0] < 2:
        raise DataError(f"metrics need at least 2 samples, got {y.shape[0]}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(y_hat))):
        raise DataError(
            "measured or model output has non-finite values (a diverged simulation?); "
            "metrics would be meaningless"
        )
    return y, y_hat


def _warn_degenerate(spread: NDArray[np.float64], what: str) -> None:
    if np.any(~(np.asarray(spread) > 0)):
        warnings.warn(
            f"{what} is undefined for a constant measured output (zero spread about its mean); "
            "the result is NaN or ±inf",
            ServoidWarning,
            stacklevel=3,
        )


def _out(x: NDArray[np.float64]) -> float | NDArray[np.float64]:
    return float(x) if np.ndim(x) == 0 else x


def nrmse(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Normalised RMS error ‖y − ŷ‖ / ‖y − ȳ‖ (per column)."""
    y, y_hat = _pair(y, y_hat)
    spread = np.linalg.norm(y - y.mean(axis=0), axis=0)
    _warn_degenerate(spread, "the normalised error")
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(np.linalg.norm(y - y_hat, axis=0) / spread)


def fit_percent(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Fit 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) [%] (per column); 100 is perfect."""
    return _out(100.0 * (1.0 - np.asarray(nrmse(y, y_hat))))


def rmse(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Root-mean-square error, in the unit of y (per column)."""
    y, y_hat = _pair(y, y_hat)
    return _out(np.sqrt(np.mean((y - y_hat) ** 2, axis=0)))


def vaf(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Variance accounted for, 100·(1 − var(y − ŷ)/var(y)) [%]."""
    y, y_hat = _pair(y, y_hat)
    _warn_degenerate(np.var(y, axis=0), "VAF")
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(100.0 * (1.0 - np.var(y - y_hat, axis=0) / np.var(y, axis=0)))


def relative_error(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Relative error 100·‖y − ŷ‖/‖y‖ [%] per column."""
    y, y_hat = _pair(y, y_hat)
    if np.any(~(np.linalg.norm(y, axis=0) > 0)):
        warnings.warn("the relative error is undefined for an all-zero measured output",
                      ServoidWarning, stacklevel=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(100.0 * np.linalg.norm(y - y_hat, axis=0) / np.linalg.norm(y, axis=0))
