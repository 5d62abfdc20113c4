"""Goodness-of-fit metrics between measured and model outputs.

Each metric is a ratio of a few moments of y and d = y − ŷ — Σd², Σy²,
Σ(y − ȳ)², Σ(d − d̄)² — which one compiled pass forms per output column
without temporaries (block by block, each block about its own means,
merged as Chan, Golub & LeVeque do; ``_kernels.add_moments``). A pass
that makes ŷ can form them on the way (``validate`` does). A NaN or inf
in either output makes the means non-finite; only then are the values
scanned for the error message.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ServoidWarning
from .._warn import warn
from ._kernels import MOMENTS, add_moments

__all__ = ["fit_percent", "nrmse", "relative_error", "rmse", "vaf"]


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
    spread2: NDArray[np.float64]  # Σ (y − ȳ)²
    error_spread2: NDArray[np.float64]  # Σ (d − d̄)²

    @classmethod
    def of(cls, moments: NDArray[np.float64], y: NDArray[np.float64],
           y_hat: NDArray[np.float64]) -> _Sums:
        """From rows of moments (one per column) of the samples y and ŷ."""
        # the means are finite unless a value is not (or a block's sum overflows, ~1e305)
        if not np.all(np.isfinite(moments[:, 1:3])) and not (
            np.all(np.isfinite(y)) and np.all(np.isfinite(y_hat))
        ):
            raise DataError(
                "measured or model output has non-finite values (a diverged simulation?); "
                "metrics would be meaningless"
            )
        return cls(int(moments[0, 0]), moments[:, 5], moments[:, 6], moments[:, 3],
                   moments[:, 4])


def _sums(y: NDArray[np.float64], y_hat: NDArray[np.float64]) -> _Sums:
    """The sums the metrics need, in one pass per output column."""
    y2 = y.reshape(y.shape[0], -1)
    h2 = y_hat.reshape(y.shape[0], -1)
    moments = np.zeros((y2.shape[1], MOMENTS))
    for c in range(y2.shape[1]):
        add_moments(np.ascontiguousarray(y2[:, c], dtype=np.float64),
                    np.ascontiguousarray(h2[:, c], dtype=np.float64), moments[c])
    return _Sums.of(moments, y, y_hat)


def _shaped(x: NDArray[np.float64], like: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-column results as numpy's axis-0 reductions shape them (a scalar for (N,))."""
    return x.reshape(like.shape[1:])


def _warn_degenerate(spread: NDArray[np.float64], what: str) -> None:
    if np.any(~(np.asarray(spread) > 0)):
        warn(
            f"{what} is undefined for a constant measured output (zero spread about its mean); "
            "the result is NaN or ±inf",
            ServoidWarning,
        )


def _out(x: NDArray[np.float64]) -> float | NDArray[np.float64]:
    return float(x) if np.ndim(x) == 0 else x


def nrmse(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Normalised RMS error ‖y − ŷ‖ / ‖y − ȳ‖ (per column)."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat)
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
    sums = _sums(y, y_hat)
    return _out(_shaped(np.sqrt(sums.error2 / sums.n), y))


def vaf(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Variance accounted for, 100·(1 − var(y − ŷ)/var(y)) [%]."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat)
    _warn_degenerate(_shaped(sums.spread2, y), "VAF")
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(_shaped(100.0 * (1.0 - sums.error_spread2 / sums.spread2), y))


def relative_error(y: ArrayLike, y_hat: ArrayLike) -> float | NDArray[np.float64]:
    """Relative error 100·‖y − ŷ‖/‖y‖ [%] per column."""
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat)
    if np.any(~(sums.power > 0)):
        warn("the relative error is undefined for an all-zero measured output",
             ServoidWarning)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(_shaped(100.0 * np.sqrt(sums.error2) / np.sqrt(sums.power), y))


def metric_set(y: ArrayLike, y_hat: ArrayLike,
               moments: NDArray[np.float64] | None = None) -> dict[str, float]:
    """Fit %, NRMSE, RMSE, VAF and relative error from one set of sums.

    The same values (bit for bit) and warnings as the five functions, for
    one output column, with one pass over the data instead of five; none
    when ``moments`` (a row of ``_kernels.MOMENTS``) come from a pass that
    formed ŷ (y and ŷ then serve only a non-finite value's message).
    """
    y, y_hat = _pair(y, y_hat)
    sums = _sums(y, y_hat) if moments is None else _Sums.of(moments[None], y, y_hat)
    spread = np.sqrt(sums.spread2)
    _warn_degenerate(spread, "the normalised error")
    _warn_degenerate(sums.spread2, "VAF")
    if np.any(~(sums.power > 0)):
        warn("the relative error is undefined for an all-zero measured output",
             ServoidWarning)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.sqrt(sums.error2) / spread
        return {
            "fit_percent": float(100.0 * (1.0 - e[0])),
            "nrmse": float(e[0]),
            "rmse": float(np.sqrt(sums.error2 / sums.n)[0]),
            "vaf": float((100.0 * (1.0 - sums.error_spread2 / sums.spread2))[0]),
            "relative_error": float((100.0 * np.sqrt(sums.error2) / np.sqrt(sums.power))[0]),
        }


def fit_of_moments(y: ArrayLike, y_hat: ArrayLike, moments: NDArray[np.float64]) -> float:
    """:func:`fit_percent` of one column from the moments a pass formed.

    ``moments`` is a row of ``_kernels.MOMENTS`` of (y, ŷ); y and ŷ serve
    only a non-finite value's message.  Same value and warning.
    """
    sums = _Sums.of(moments[None], *_pair(y, y_hat))
    spread = np.sqrt(sums.spread2)
    _warn_degenerate(spread, "the normalised error")
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(100.0 * (1.0 - (np.sqrt(sums.error2) / spread)[0]))
