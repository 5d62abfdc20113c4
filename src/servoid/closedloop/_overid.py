"""Closed-loop IV: the over-identification test of its instruments (Sargan / Hansen J).

CLIV is consistent only when its instruments, filters of the recorded
reference r, are uncorrelated with the noise.  That fails when the recorded
r carries the output's noise: crosstalk in the acquisition
(``r_rec = r + α·v``) or a reference computed from the measured y.  Then
the estimate is biased, and nothing in the fit shows it.

:func:`overidentification` tests it with more instruments than parameters
(Sargan, *Econometrica* 26(3), 1958; Hansen, *Econometrica* 50(4), 1982):

1. the CLIV equation residual ``e = y − φᵀθ`` is coloured, so an AR(p)
   model ``L(q)`` of it (p ≤ :data:`_MAX_AR`, by AIC) prewhitens y, u and r;
2. on the filtered record the plant is refitted by two-stage least squares
   with the instruments ``r_f(t), r_f(t−1)…, r_f(t−K)``, the plain lags of
   the filtered reference, lag 0 included;
3. ``J = N·R²`` of that residual on the instruments is χ² with
   (rank of the instruments − number of parameters) degrees of freedom when
   r is independent of the noise.

With valid instruments the prewhitened residual is white and independent
of r, so ``z(t)·ε(t)`` is uncorrelated over t and the plain n·R² form holds
without a long-run covariance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._lazy import signal as sps
from .._lazy import stats

__all__ = ["Overidentification", "overidentification"]

#: Longest AR model tried for the residual's prewhitening filter.
_MAX_AR = 20
#: Lags of the filtered reference beyond the number of parameters.
_EXTRA = 6
#: Level at which the test rejects.
LEVEL = 0.01


@dataclass(frozen=True)
class Overidentification:
    """The Sargan statistic, its degrees of freedom and p-value."""

    statistic: float
    dof: int
    p_value: float
    ar_order: int

    @property
    def rejects(self) -> bool:
        """True when the instruments appear correlated with the noise at :data:`LEVEL`."""
        return self.p_value < LEVEL

    def to_dict(self) -> dict[str, float | int]:
        """Plain numbers for the estimate's options."""
        return {"statistic": self.statistic, "dof": self.dof, "p_value": self.p_value,
                "prewhitening_ar_order": self.ar_order}


def overidentification(signals: Sequence[tuple[NDArray[np.float64], ...]],
                       theta: NDArray[np.float64], na: int, nb: int, nk: int
                       ) -> Overidentification | None:
    """Sargan's test of the reference as an instrument, on (r, u, y) segments.

    Parameters
    ----------
    signals : sequence of (r, u, y) arrays
        The record's segments.
    theta : ndarray
        The CLIV estimate ``(a1…, b0…)``.
    na, nb, nk : int
        The ARX orders and delay.

    Returns
    -------
    Overidentification or None
        None when the record is too short or the instruments too few for a test.
    """
    p = na + nb
    lags = p + _EXTRA
    first = max(na, nk + nb - 1, lags)
    resid = [_equation_residual(r, u, y, theta, na, nb, nk, first) for r, u, y in signals]
    if sum(e.size for e in resid) < 20 * (lags + _MAX_AR):
        return None
    ell, order = _prewhitener(resid)
    phis, ys, zs = [], [], []
    for r, u, y in signals:
        rf, uf, yf = (sps.lfilter(ell, [1.0], s) for s in (r, u, y))
        rows = np.arange(first + order, y.size)
        if rows.size <= 0:
            continue
        phis.append(np.column_stack([-yf[rows - j] for j in range(1, na + 1)]
                                    + [uf[rows - nk - j] for j in range(nb)]))
        ys.append(yf[rows])
        zs.append(np.column_stack([rf[rows - j] for j in range(lags + 1)]))
    phi, yv, z = np.vstack(phis), np.concatenate(ys), np.vstack(zs)
    phi, yv, z = phi - phi.mean(axis=0), yv - yv.mean(), z - z.mean(axis=0)
    left, sing, _ = np.linalg.svd(z, full_matrices=False)
    qz = left[:, sing > 1e-8 * max(float(sing[0]), 1e-300)]
    dof = qz.shape[1] - p
    if dof <= 0:
        return None
    phi_hat = qz @ (qz.T @ phi)
    theta2 = np.linalg.lstsq(phi_hat, yv, rcond=None)[0]
    eps = yv - phi @ theta2
    proj = qz.T @ eps
    stat = float(yv.size * (proj @ proj) / max(float(eps @ eps), 1e-300))
    return Overidentification(stat, int(dof), float(stats.chi2.sf(stat, dof)), order)


def _equation_residual(r: NDArray[np.float64], u: NDArray[np.float64],
                       y: NDArray[np.float64], theta: NDArray[np.float64],
                       na: int, nb: int, nk: int, first: int) -> NDArray[np.float64]:
    """``y(t) + a1 y(t−1)… − b0 u(t−nk)…`` on the rows from `first` on."""
    rows = np.arange(first, y.size)
    if rows.size == 0:
        return np.zeros(0)
    e = y[rows].copy()
    for j in range(1, na + 1):
        e += theta[j - 1] * y[rows - j]
    for j in range(nb):
        e -= theta[na + j] * u[rows - nk - j]
    return e - e.mean()


def _prewhitener(resid: Sequence[NDArray[np.float64]]) -> tuple[NDArray[np.float64], int]:
    """``L = [1, −c1, …]`` of an AR(p) model of the residual, p by AIC (≤ _MAX_AR)."""
    best: tuple[float, NDArray[np.float64], int] | None = None
    for order in range(_MAX_AR + 1):
        rows_x, rows_y = [], []
        for e in resid:
            if e.size <= order + 1:
                continue
            idx = np.arange(order, e.size)
            rows_y.append(e[idx])
            rows_x.append(np.column_stack([e[idx - j] for j in range(1, order + 1)])
                          if order else np.zeros((idx.size, 0)))
        x, yv = np.vstack(rows_x), np.concatenate(rows_y)
        c = np.linalg.lstsq(x, yv, rcond=None)[0] if order else np.zeros(0)
        rss = float(np.sum((yv - x @ c) ** 2)) if order else float(yv @ yv)
        aic = yv.size * np.log(max(rss / yv.size, 1e-300)) + 2 * order
        if best is None or aic < best[0]:
            best = (aic, np.concatenate([[1.0], -c]), order)
    assert best is not None
    return best[1], best[2]
