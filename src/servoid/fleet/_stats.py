"""Population statistics of a fleet: control limits, outliers and drift.

- **Control limits** are the population's centre ± 3 spreads, robust to
  the outliers they are meant to find: the median and the normalised
  median absolute deviation ``1.4826·MAD`` (σ for a normal population).
- **Outliers** have a robust z-score ``(θ − median)/(1.4826·MAD)`` beyond
  3.5 (Iglewicz and Hoaglin's cut-off), whether inside the acceptance
  limits or not.
- **Drift** over a life test is the least-squares slope of the parameter
  against the test date (or the run order), each unit weighted by the
  inverse variance of its estimate plus the population scatter, with a
  95 % Student-t interval; the drift is significant when the interval
  excludes zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import stats

__all__ = ["ControlLimits", "Drift", "control_limits", "drift", "robust_z"]

_MAD_TO_SIGMA = 1.4826
OUTLIER_Z = 3.5


@dataclass(frozen=True)
class ControlLimits:
    """Centre, spread and the ±3-spread control limits of a parameter."""

    centre: float
    spread: float
    low: float
    high: float


@dataclass(frozen=True)
class Drift:
    """Slope of a parameter against the trend axis, with its 95 % interval.

    ``slope`` is per unit of the axis (per day for dates, per run for the
    run order); ``significant`` when the interval excludes zero.
    """

    slope: float
    std: float
    ci_low: float
    ci_high: float
    n: int
    axis: str

    @property
    def significant(self) -> bool:
        """True when the 95 % interval of the slope excludes zero."""
        return self.ci_low > 0 or self.ci_high < 0


def _spread(x: NDArray[np.float64]) -> tuple[float, float]:
    centre = float(np.median(x))
    spread = _MAD_TO_SIGMA * float(np.median(np.abs(x - centre)))
    if spread == 0.0 and x.size > 1:  # more than half identical: fall back to the std
        spread = float(np.std(x, ddof=1))
    return centre, spread


def control_limits(values: ArrayLike) -> ControlLimits:
    """Median ± 3·(1.4826·MAD) of the finite values."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return ControlLimits(math.nan, math.nan, math.nan, math.nan)
    centre, spread = _spread(x)
    return ControlLimits(centre, spread, centre - 3 * spread, centre + 3 * spread)


def robust_z(values: ArrayLike) -> NDArray[np.float64]:
    """Robust z-score of each value (NaN where the value is not finite)."""
    x = np.asarray(values, dtype=float)
    finite = x[np.isfinite(x)]
    if finite.size < 3:
        return np.full(x.shape, np.nan)
    centre, spread = _spread(finite)
    if spread == 0.0:
        return np.where(np.isfinite(x), 0.0, np.nan)
    return (x - centre) / spread


def drift(axis: ArrayLike, values: ArrayLike, stds: ArrayLike | None = None,
          axis_name: str = "run") -> Drift | None:
    """Weighted least-squares slope of `values` against `axis`, or None (< 3 points).

    Each point is weighted by ``1/(std² + s²)`` with ``s²`` the scatter the
    estimates' own variances do not explain (a random-effects fit), so a
    fleet whose units differ more than their intervals still gets an
    honest slope interval.
    """
    t = np.asarray(axis, dtype=float)
    y = np.asarray(values, dtype=float)
    v = np.zeros_like(y) if stds is None else np.asarray(stds, dtype=float) ** 2
    ok = np.isfinite(t) & np.isfinite(y) & np.isfinite(v)
    t, y, v = t[ok], y[ok], v[ok]
    if t.size < 3 or np.ptp(t) == 0:
        return None
    x = np.column_stack([np.ones_like(t), t - t.mean()])
    extra = 0.0
    for _ in range(50):  # fixed point of the between-unit variance (method of moments)
        w = 1.0 / np.maximum(v + extra, 1e-300)
        beta = np.linalg.lstsq(x * np.sqrt(w)[:, None], y * np.sqrt(w), rcond=None)[0]
        resid = y - x @ beta
        new = max(float(np.sum(resid**2) / (t.size - 2) - np.mean(v)), 0.0)
        if abs(new - extra) <= 1e-9 * max(new, 1e-300):
            break
        extra = new
    w = 1.0 / np.maximum(v + extra, 1e-300)
    xtwx = (x * w[:, None]).T @ x
    resid = y - x @ beta
    # χ²/dof is 1 at the fixed point; above 1 only when no between-unit variance was needed
    scale = max(float(np.sum(w * resid**2)) / (t.size - 2), 1.0)
    cov = np.linalg.inv(xtwx) * scale
    std = float(math.sqrt(max(cov[1, 1], 0.0)))
    q = float(stats.t.ppf(0.975, t.size - 2))
    slope = float(beta[1])
    return Drift(slope, std, slope - q * std, slope + q * std, int(t.size), axis_name)
