"""Covariance of a two-step estimate whose second step uses the first's output.

The two-stage method fits the FIR ``û_r = Σ_k ŝ_k r(t − k)`` by least
squares, then the output-error plant from ``û_r`` to y.  The stage-1 error
``ŝ − s`` moves ``û_r`` and with it the plant; on records where the
reference explains the input well but slowly (a slow PRBS through a PI
loop) it is the larger part of the plant's error.  Linearising both
estimating equations (the two-step M-estimator, Newey & McFadden,
*Handbook of Econometrics* IV, 1994, §6)::

    θ̂ − θ ≈ H⁻¹ Σ_t s(t),    s(t) = ψ(t) ε(t) − A (ΦᵀΦ)⁻¹ φ(t) e₁(t)

with ψ = ∂ŷ/∂θ of the OE model, ε its residual, ``H = ΨᵀΨ``, φ(t) the
stage-1 regressor (lags of r), e₁ its residual and
``A = Σ_t ψ(t) (G φ)(t)ᵀ`` the sensitivity of the stage-2 score to the
FIR taps (∂ŷ/∂s_k is the plant driven by the k-th lag of r).  Both noise
terms come from the loop noise and are coloured, and correlated with each
other, while ψ and φ come from r alone.  The long-run covariance of ``Σ s``
is therefore ``Σ_τ w(τ) Σ_ab r̂_ab(τ) Σ_t Z_a(t) Z_b(t − τ)ᵀ`` with the
noises' (cross-)covariances r̂_ab averaged over the record and Bartlett
weights w over four times the noises' memory (:func:`structured_long_run`;
the lag-window estimator of Newey & West, *Econometrica* 55(3), 1987, with
the regressors' products summed exactly).  The result is
``P = H⁻¹ Ŝ H⁻¹``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._lazy import signal as sps
from ._coloured import oe_gradient

__all__ = ["Stage1", "two_stage_covariance"]


@dataclass(frozen=True, eq=False)
class Stage1:
    """The stage-1 FIR fit of r → u, per segment and pooled."""

    coef: NDArray[np.float64]  # taps in the order of `lags`
    lags: tuple[int, ...]  # lag k of each tap: r(t − k); negative = future
    r0: tuple[NDArray[np.float64], ...]  # centred reference per segment
    rows: tuple[NDArray[np.int64], ...]  # samples of each segment in the stage-1 regression
    e1: tuple[NDArray[np.float64], ...]  # stage-1 residuals on those rows
    ur: tuple[NDArray[np.float64], ...]  # û_r per segment (with the mean of u)
    gram: NDArray[np.float64]  # ΦᵀΦ
    order: int
    explained: float


def two_stage_covariance(
    stage1: Stage1, ys: Sequence[NDArray[np.float64]], b: NDArray[np.float64],
    f: NDArray[np.float64], nk: int,
) -> tuple[NDArray[np.float64], int]:
    """Covariance of the stage-2 OE parameters (b0…, f1…), stage 1 counted.

    Returns the covariance and the lag window's half-width [samples].
    """
    bq = np.concatenate([np.zeros(nk), b])
    hess, cross = 0.0, 0.0
    psis = []
    for r0, ur, y in zip(stage1.r0, stage1.ur, ys, strict=True):
        yhat, psi = oe_gradient(b, f, nk, ur)
        psis.append((psi, y - yhat))
        hess = hess + psi.T @ psi
        # ∂ŷ/∂s_k: the plant driven by the k-th lag of r (zero outside the record)
        g_cols = np.column_stack([sps.lfilter(bq, f, _shift(r0, k)) for k in stage1.lags])
        cross = cross + psi.T @ g_cols
    m = np.asarray(cross) @ np.linalg.pinv(stage1.gram)
    regressors, noises = [], []
    for (psi, eps), r0, rows, e1 in zip(psis, stage1.r0, stage1.rows, stage1.e1, strict=True):
        mt = np.zeros_like(psi)
        phi = np.column_stack([r0[rows - k] for k in stage1.lags])
        mt[rows] = -(phi @ m.T)
        noise1 = np.zeros(eps.size)
        noise1[rows] = e1
        regressors.append((psi, mt))
        noises.append((eps, noise1))
    meat, bandwidth = structured_long_run(regressors, noises)
    inv = np.linalg.pinv(np.asarray(hess))
    cov = inv @ meat @ inv
    return 0.5 * (cov + cov.T), bandwidth


def structured_long_run(
    regressors: Sequence[tuple[NDArray[np.float64], ...]],
    noises: Sequence[tuple[NDArray[np.float64], ...]],
) -> tuple[NDArray[np.float64], int]:
    """Long-run covariance of ``s(t) = Σ_a Z_a(t) n_a(t)`` with Z_a free of noise.

    ``Σ_τ w(τ) Σ_ab r̂_ab(τ) Σ_t Z_a(t) Z_b(t − τ)ᵀ``: the noise
    (cross-)covariances r̂_ab are averaged over the whole record, so a lag
    window as long as the noise's memory costs little variance (the
    estimator of :mod:`servoid.estimate` for one noise term, with sample
    covariances in place of its AR extension).  The window is Bartlett's,
    four times the lag at which the noises' autocorrelations fall inside
    their ±2/√N band.
    """
    n = sum(ns[0].size for ns in noises)
    k = len(noises[0])
    shortest = min(ns[0].size for ns in noises)
    # the noise memory: the last lag with an autocorrelation outside ±2/√N
    memory = 1
    band = 2.0 / np.sqrt(n)
    for a in range(k):
        acf = sum(_xcorr(ns[a], ns[a], shortest // 2) for ns in noises)
        acf = acf / max(acf[0], 1e-300)
        outside = np.flatnonzero(np.abs(acf) > band)
        run = int(np.argmax(np.diff(outside) > 1)) if np.any(np.diff(outside) > 1) else -1
        memory = max(memory, int(outside[run]) if outside.size else 1)
    bandwidth = int(min(4 * memory, shortest // 4))
    lags = np.arange(-bandwidth, bandwidth + 1)
    weights = 1.0 - np.abs(lags) / (bandwidth + 1)
    p = regressors[0][0].shape[1]
    meat = np.zeros((p, p))
    for zs, ns in zip(regressors, noises, strict=True):
        size = zs[0].shape[0]
        for a in range(k):
            for b in range(k):
                # Σ_τ c(τ) Σ_t za(t) zb(t − τ)ᵀ = zaᵀ (c ∗ zb): one filter, one Gram
                c = weights * _xcorr_signed(ns[a], ns[b], bandwidth) / n
                full = sps.fftconvolve(zs[b], c[:, None], axes=0)
                meat += zs[a].T @ full[bandwidth: bandwidth + size]
    return 0.5 * (meat + meat.T), bandwidth


def _xcorr(x: NDArray[np.float64], y: NDArray[np.float64], lags: int) -> NDArray[np.float64]:
    """Σ_t x(t) y(t − τ) for τ = 0…lags."""
    return _xcorr_signed(x, y, lags)[lags:]


def _xcorr_signed(x: NDArray[np.float64], y: NDArray[np.float64],
                  lags: int) -> NDArray[np.float64]:
    """Σ_t x(t) y(t − τ) for τ = −lags…lags."""
    size = 1 << int(np.ceil(np.log2(2 * x.size)))
    full = np.fft.irfft(np.fft.rfft(x, size) * np.conj(np.fft.rfft(y, size)), size)
    return np.concatenate([full[size - lags:], full[: lags + 1]]) if lags else full[:1]


def _shift(x: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """x(t − k), zero outside the record (k < 0 looks ahead)."""
    out = np.zeros_like(x)
    if k >= 0:
        out[k:] = x[: x.size - k]
    else:
        out[: x.size + k] = x[-k:]
    return out
