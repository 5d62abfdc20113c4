"""Covariance of an output-error fit whose residual is coloured.

An OE model fitted from a signal the noise does not reach (the reference r,
or its projection u_r) is consistent whatever the noise spectrum, but its
usual covariance ``σ̂²(ΨᵀΨ)⁻¹`` assumes a white residual.  In closed loop
the residual is the sensitivity-filtered noise, far from white, so the
covariance is the sandwich (Ljung, *System Identification*, 2nd ed.,
§9.3, eq. 9.42 with the noise model fixed at 1)::

    P = (ΨᵀΨ)⁻¹ · ΨᵀΣ_wΨ · (ΨᵀΨ)⁻¹

where ψ(t) = ∂ŷ(t)/∂θ depends only on the noise-free input and Σ_w is the
covariance of the residual.  Σ_w comes from an AR model ``D(q) w = e`` of
the residual (order by AIC): ``Σ_w = σ_e²·L·Lᵀ`` with L the lower
triangular Toeplitz matrix of 1/D, so ``ΨᵀΣ_wΨ = σ_e²·ZᵀZ`` with
``Z = Lᵀ Ψ``, the columns of Ψ filtered by 1/D backwards in time.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from ..models import PolynomialModel
from ._channels import aic_order, lag_matrix, ls_fit

__all__ = ["oe_covariance", "oe_gradient", "sandwich"]

#: Largest AR order tried for the residual spectrum.
_MAX_AR = 40


def oe_covariance(
    model: PolynomialModel,
    inputs: Sequence[NDArray[np.float64]],
    outputs: Sequence[NDArray[np.float64]],
) -> tuple[NDArray[np.float64], int]:
    """Return the coloured-noise covariance of an OE fit and the AR order.

    Parameters
    ----------
    model : PolynomialModel
        Single-input OE model ``y = B/F u(t − nk)`` (parameters b0…, f1…).
    inputs, outputs : sequence of ndarray
        The input and output of each segment, as fitted from rest.

    Returns
    -------
    covariance : ndarray
        Sandwich covariance of (b0…, f1…).
    ar_order : int
        Order of the AR model of the residual.
    """
    b, f, nk = model.b[0], model.f[0], model.nk[0]  # type: ignore[index]
    psis, resids = [], []
    for u, y in zip(inputs, outputs, strict=True):
        yhat, psi = oe_gradient(b, f, nk, u)
        psis.append(psi)
        resids.append(np.asarray(y - yhat, dtype=float))
    return sandwich(psis, resids)


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
    """``R⁻¹·M·R⁻¹`` with R = ΣΨᵀΨ and M = ΨᵀΣ_wΨ from an AR model of the residual."""
    d, sigma2, p = _ar_whitener(resids)
    n = psis[0].shape[1]
    hess = np.zeros((n, n))
    meat = np.zeros_like(hess)
    for psi in psis:
        hess += psi.T @ psi
        z = sps.lfilter([1.0], d, psi[::-1], axis=0)[::-1]
        meat += z.T @ z
    inv = np.linalg.pinv(hess)
    cov = sigma2 * inv @ meat @ inv
    return 0.5 * (cov + cov.T), p


def _delay(x: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    if k == 0:
        return x
    return np.concatenate([np.zeros(k), x[:-k]])


def _ar_whitener(
    resids: Sequence[NDArray[np.float64]],
) -> tuple[NDArray[np.float64], float, int]:
    """Monic D with D(q)·w ≈ white, the innovation variance and the order."""
    total = sum(w.size for w in resids)
    p_max = int(min(_MAX_AR, max(total // 50, 0)))
    if p_max == 0:
        return np.ones(1), float(np.mean(np.concatenate(resids) ** 2)), 0
    phi, target = [], []
    for w in resids:
        rows = np.arange(p_max, w.size)
        if rows.size:
            phi.append(lag_matrix(w, rows, range(1, p_max + 1)))
            target.append(w[rows])
    x, t = np.vstack(phi), np.concatenate(target)
    p = aic_order(x, t, list(range(p_max + 1)))
    if p == 0:
        return np.ones(1), float(t @ t / t.size), 0
    coef, e, _ = ls_fit(x[:, :p], t)
    return _stable(np.concatenate([[1.0], -coef])), float(e @ e / t.size), p


def _stable(d: NDArray[np.float64]) -> NDArray[np.float64]:
    # least squares AR fits are stable in practice; a root outside would blow up the filter
    roots = np.roots(d)
    outside = np.abs(roots) >= 1.0
    if not outside.any():
        return d
    roots[outside] = 1.0 / np.conj(roots[outside])
    return np.real(np.poly(roots))
