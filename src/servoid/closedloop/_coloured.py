"""Covariance of an output-error fit whose residual is coloured.

An OE model fitted from a signal the noise does not reach (the reference r,
or its projection u_r) is consistent whatever the noise spectrum, but its
usual covariance ``σ̂²(ΨᵀΨ)⁻¹`` assumes a white residual.  In closed loop
the residual is the sensitivity-filtered noise, far from white, so the
covariance is the sandwich (Ljung, *System Identification*, 2nd ed.,
§9.3, eq. 9.42 with the noise model fixed at 1)::

    P = (ΨᵀΨ)⁻¹ · Σ_τ r_w(τ) Σ_t ψ(t) ψ(t−τ)ᵀ · (ΨᵀΨ)⁻¹

where ψ(t) = ∂ŷ(t)/∂θ depends only on the noise-free input and r_w is the
autocovariance of the residual, extended by an AR model chosen by AIC.
The formula and its estimate are those of every other estimator's robust
covariance, :func:`servoid.estimate._covariance.sandwich_covariance`; this
module only supplies ψ for the OE model of the closed loop, which the
one-step indirect refinement parameterises by the plant.  Fits made with
:func:`~servoid.estimate.fit_oe` carry the same covariance already.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .._lazy import signal as sps
from ..estimate import filtered_gram, sandwich_covariance

__all__ = ["oe_gradient", "sandwich"]


def oe_gradient(
    b: NDArray[np.float64], f: NDArray[np.float64], nk: int, u: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Simulated output ``B/F u(t − nk)`` from rest and ψ = ∂ŷ/∂(b0…, f1…)."""
    bq = np.concatenate([np.zeros(nk), b])
    yhat = sps.lfilter(bq, f, u)
    filt_u = sps.lfilter([1.0], f, u)
    filt_y = sps.lfilter([1.0], f, yhat)
    cols = [_delay(filt_u, nk + j) for j in range(b.size)]
    cols += [-_delay(filt_y, j) for j in range(1, f.size)]
    return np.asarray(yhat, dtype=float), np.column_stack(cols)


def sandwich(
    psis: Sequence[NDArray[np.float64]], resids: Sequence[NDArray[np.float64]]
) -> tuple[NDArray[np.float64], int]:
    """Robust covariance of an OE fit from ψ and its residuals.

    Returns the sandwich ``(ΨᵀΨ)⁻¹·Ψᵀ R̂_w Ψ·(ΨᵀΨ)⁻¹`` and the order of the
    residual AR model behind R̂_w.
    """
    hess = sum(psi.T @ psi for psi in psis)
    n = sum(w.size for w in resids)
    dof = max(n - hess.shape[0], 1)
    sigma2 = float(sum(w @ w for w in resids)) / dof
    result = sandwich_covariance("robust", np.asarray(hess), sigma2, dof, lambda: resids,
                                 lambda ar: filtered_gram(psis, ar), gram_bread=True)
    return result.covariance, int(result.ar_order or 0)


def _delay(x: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    if k == 0:
        return x
    return np.concatenate([np.zeros(k), x[:-k]])
