"""Least squares and instrumental variables sharing one robust covariance.

The identification solves three regressions on the same rows (the same
sample instants): the electrical equation, the force balance of the whole
drive train and the deflection of the screw.  Their errors are filtered
sensor noise — coloured by the state-variable filter, and correlated across
the equations where they share a sensor — so the covariance is the
sandwich over all of them at once (Newey and West, *Econometrica* 55,
1987, Bartlett weights)::

    θ̂_e = (Z_eᵀΦ_e)⁻¹ Z_eᵀ y_e              (Z_e = Φ_e: least squares)
    Cov = B⁻¹ S B⁻ᵀ,  B = blockdiag(Z_eᵀΦ_e),
    S = (I − A)⁻¹ S_w (I − A)⁻ᵀ,  g_t = [z_e,t ε_e,t]_e,  w_t = g_t − A g_{t−1}
    S_w = Σ_|l|≤L (1 − |l|/(L+1)) Σ_t w_t w_{t−l}ᵀ

(A the least-squares VAR(1) of the scores: prewhitening, Andrews and
Monahan, *Econometrica* 60, 1992), with ``n/(n − p)`` for the degrees of
freedom.  Measured on the bench (``docs/ema.md``): without prewhitening
the Bartlett sum understates the standard deviations by up to 25 %.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._errors import IdentifiabilityError

__all__ = ["Regression", "joint_covariance", "solve"]

_MAX_RADIUS = 0.97


@dataclass(frozen=True, eq=False)
class Regression:
    """One equation ``y = Φθ + ε`` solved by LS (or IV with instruments Z).

    Attributes
    ----------
    name : str
        What it is, for messages.
    names : tuple of str
        Parameter names (the columns of Φ).
    phi, y, z : ndarray
        Regressors, left-hand side and instruments (``z is phi`` for LS).
    theta : ndarray
        The estimate.
    residuals : ndarray
        ``y − Φθ̂``.
    condition : float
        Condition number of the column-scaled ``ZᵀΦ``.
    """

    name: str
    names: tuple[str, ...]
    phi: NDArray[np.float64]
    y: NDArray[np.float64]
    z: NDArray[np.float64]
    theta: NDArray[np.float64]
    residuals: NDArray[np.float64]
    condition: float

    @property
    def fit_percent(self) -> float:
        """``100·(1 − ‖ε‖/‖y − ȳ‖)`` of the equation [%]."""
        spread = float(np.linalg.norm(self.y - self.y.mean()))
        return 100.0 * (1.0 - float(np.linalg.norm(self.residuals)) / spread) if spread else 0.0


def solve(name: str, names: Sequence[str], phi: NDArray[np.float64], y: NDArray[np.float64],
          z: NDArray[np.float64] | None = None) -> Regression:
    """Solve one equation by least squares, or by IV when instruments are given.

    Raises
    ------
    IdentifiabilityError
        The (instrumented) regressors are rank deficient: the record does
        not separate the named parameters.
    """
    zz = phi if z is None else z
    scale = np.sqrt(np.einsum("ij,ij->j", phi, phi))
    zscale = np.sqrt(np.einsum("ij,ij->j", zz, zz))
    if np.any(scale == 0) or np.any(zscale == 0):
        dead = [n for n, s, q in zip(names, scale, zscale, strict=True) if s == 0 or q == 0]
        raise IdentifiabilityError(f"{name}: the record does not move {', '.join(dead)} (its "
                                   "column is zero); excite the actuator over its range")
    m = (zz / zscale).T @ (phi / scale)
    sv = np.linalg.svd(m, compute_uv=False)
    condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
    if not condition < 1e12:
        raise IdentifiabilityError(
            f"{name}: the regressors of {', '.join(names)} are linearly dependent on this "
            f"record (condition {condition:.3g}); the excitation does not separate them")
    theta = np.linalg.solve(m, (zz / zscale).T @ y) / scale
    return Regression(name, tuple(names), phi, y, zz, theta, y - phi @ theta, condition)


def joint_covariance(regressions: Sequence[Regression], lags: int) -> NDArray[np.float64]:
    """The sandwich covariance of all the regressions' parameters, stacked.

    Parameters
    ----------
    regressions : sequence of Regression
        Equations on the same rows (one per sample instant, same order).
    lags : int
        Bartlett bandwidth L [rows].

    Returns
    -------
    ndarray
        Covariance of ``[θ_1, θ_2, ...]``.
    """
    # columns scaled to unit norm, so the bread is well conditioned whatever the units
    xs = [np.sqrt(np.einsum("ij,ij->j", r.phi, r.phi)) for r in regressions]
    zs = [np.sqrt(np.einsum("ij,ij->j", r.z, r.z)) for r in regressions]
    scores = np.hstack([(r.z / q) * r.residuals[:, None] for r, q in zip(regressions, zs,
                                                                          strict=True)])
    p = scores.shape[1]
    n = scores.shape[0]
    # prewhitening by a VAR(1) of the scores (Andrews and Monahan, Econometrica 60, 1992):
    # the filtered residuals are correlated over the filter's memory, which a truncated
    # Bartlett sum alone underweights
    g0, g1 = scores[1:], scores[:-1]
    a = np.linalg.lstsq(g1, g0, rcond=None)[0].T
    radius = float(np.max(np.abs(np.linalg.eigvals(a))))
    if radius > _MAX_RADIUS:  # keep (I − A)⁻¹ bounded, as they advise
        a *= _MAX_RADIUS / radius
    white = g0 - g1 @ a.T
    s = white.T @ white
    for lag in range(1, min(lags, white.shape[0] - 1) + 1):
        gam = white[lag:].T @ white[:-lag]
        s += (1.0 - lag / (lags + 1.0)) * (gam + gam.T)
    back = np.linalg.inv(np.eye(p) - a)
    s = back @ s @ back.T
    bread = np.zeros((p, p))
    at = 0
    for r, x, q in zip(regressions, xs, zs, strict=True):
        k = r.theta.size
        bread[at:at + k, at:at + k] = (r.z / q).T @ (r.phi / x)
        at += k
    inv = np.linalg.inv(bread) / np.concatenate(xs)[:, None]
    cov = inv @ s @ inv.T * (n / max(n - p, 1))
    return np.asarray(0.5 * (cov + cov.T))
