"""Goodness-of-fit metrics between measured and model outputs.

Each metric is a ratio of a few column sums — Σ(y − ŷ)², Σ(y − ȳ)², Σy²,
Σ(d − d̄)² with d = y − ŷ — which a compiled kernel forms in one or two
passes over y and ŷ without temporaries (the centred sums take the means
from a first pass, as numpy's ``var`` does). A NaN or inf in either
output makes the sums non-finite; only then are the values scanned for
the error message.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ServoidWarning

__all__ = ["fit_percent", "nrmse", "relative_error", "rmse", "vaf"]

_BLOCK = 1024  # samples summed locally first: error ~ε·(1024 + N/1024), not ~ε·N


def _pair(y: ArrayLike, y_hat: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    y = as_array("y", y, finite=False)
    y_hat = as_array("y_hat", y_hat, finite=False)
    if y.ndim == 0 or y_hat.ndim == 0:
        raise DataError(f"y and y_hat must be arrays of samples (N,) or (N, outputs), got "
                        f"shapes {y.shape} and {y_hat.shape}")
    if y.shape != y_hat.shape:
        raise DataError(f"measured and model outputs differ in shape: {y.shape} vs {y_hat.shape}")
    if y.shape[0] < 2:
        raise DataError(f"metrics need at least 2 samples, got {y.shape[0]}")
    return y, y_hat


class _Sums(NamedTuple):
    """Column sums of y and d = y − ŷ (arrays of one entry per output column)."""

    n: int
    error2: NDArray[np.float64]  # Σ d²
    power: NDArray[np.float64]  # Σ y²
    spread2: NDArray[np.float64] | None  # Σ (y − ȳ)²
    error_spread2: NDArray[np.float64] | None  # Σ (d − d̄)²


def _sums(y: NDArray[np.float64], y_hat: NDArray[np.float64], centred: bool) -> _Sums:
    """The sums the metrics need, in one pass (two with the centred ones)."""
    y2 = y.reshape(y.shape[0], -1)
    h2 = y_hat.reshape(y.shape[0], -1)
    zero = np.zeros(y2.shape[1])
    first = _column_sums(y2, h2, zero, zero, _BLOCK)
    # Σy and Σd are finite unless a value is not (or the sums overflow, beyond ~1e300)
    if not np.all(np.isfinite(first[:2])) and not (
        np.all(np.isfinite(y)) and np.all(np.isfinite(y_hat))
    ):
        raise DataError(
            "measured or model output has non-finite values (a diverged simulation?); "
            "metrics would be meaningless"
        )
    spread2 = error_spread2 = None
    if centred:
        n = y2.shape[0]
        second = _column_sums(y2, h2, first[0] / n, first[1] / n, _BLOCK)
        spread2, error_spread2 = second[3], second[4]
    return _Sums(y2.shape[0], first[2], first[3], spread2, error_spread2)


def _shaped(x: NDArray[np.float64], like: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-column results as numpy's axis-0 reductions shape them (a scalar for (N,))."""
    return x.reshape(like.shape[1:])


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
    sums = _sums(y, y_hat, centred=True)
    spread = _shaped(np.sqrt(sums.spread2), y)
    _warn_degenerate(spread, "the normalised error")
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(_shaped(np.sqrt(sums.error2), y) / spread)


def fit_percent(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Fit 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) [%] (per column); 100 is perfect."""
    return _out(100.0 * (1.0 - np.asarray(nrmse(y, y_hat))))


def rmse(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Root-mean-square error, in the unit of y (per column)."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat, centred=False)
    return _out(_shaped(np.sqrt(sums.error2 / sums.n), y))


def vaf(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Variance accounted for, 100·(1 − var(y − ŷ)/var(y)) [%]."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat, centred=True)
    _warn_degenerate(_shaped(sums.spread2, y), "VAF")
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(_shaped(100.0 * (1.0 - sums.error_spread2 / sums.spread2), y))


def relative_error(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Relative error 100·‖y − ŷ‖/‖y‖ [%] per column."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat, centred=False)
    if np.any(~(sums.power > 0)):
        warnings.warn("the relative error is undefined for an all-zero measured output",
                      ServoidWarning, stacklevel=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(_shaped(100.0 * np.sqrt(sums.error2) / np.sqrt(sums.power), y))



def metric_set(y: ArrayLike, y_hat: ArrayLike) -> dict[str, float]:
    """Fit %, NRMSE, RMSE, VAF and relative error from one set of sums.

    The same values (bit for bit) and warnings as the five functions, for
    one output column, with two passes over the data instead of ten.
    """
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat, centred=True)
    spread = np.sqrt(sums.spread2)
    _warn_degenerate(spread, "the normalised error")
    _warn_degenerate(sums.spread2, "VAF")
    if np.any(~(sums.power > 0)):
        warnings.warn("the relative error is undefined for an all-zero measured output",
                      ServoidWarning, stacklevel=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.sqrt(sums.error2) / spread
        return {
            "fit_percent": float(100.0 * (1.0 - e[0])),
            "nrmse": float(e[0]),
            "rmse": float(np.sqrt(sums.error2 / sums.n)[0]),
            "vaf": float((100.0 * (1.0 - sums.error_spread2 / sums.spread2))[0]),
            "relative_error": float((100.0 * np.sqrt(sums.error2) / np.sqrt(sums.power))[0]),
        }


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
def _column_sums(y, y_hat, mean_y, mean_d, block):  # type: ignore[no-untyped-def]  # pragma: no cover
    # rows: Σy, Σd, Σd², Σ(y − mean_y)², Σ(d − mean_d)², d = y − ŷ; per column of (N, k).
    # Reassociation vectorises the sums; without nnan/ninf a NaN or inf still comes through.
    n, k = y.shape
    out = np.zeros((5, k))
    for c in range(k):
        my = mean_y[c]
        md = mean_d[c]
        for start in range(0, n, block):
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            s4 = 0.0
            for t in range(start, min(start + block, n)):
                v = y[t, c]
                d = v - y_hat[t, c]
                s0 += v
                s1 += d
                s2 += d * d
                s3 += (v - my) * (v - my)
                s4 += (d - md) * (d - md)
            out[0, c] += s0
            out[1, c] += s1
            out[2, c] += s2
            out[3, c] += s3
            out[4, c] += s4
    return out
