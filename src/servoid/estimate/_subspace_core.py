"""Numerical core of subspace identification, on the block-Hankel Gram matrix.

The data matrix of subspace methods stacks block-Hankel matrices of future
inputs U_f, past inputs U_p, past outputs Y_p and future outputs Y_f, one
column per time t; with past horizon p and future horizon f it has
k = (p + f)(m + ny) rows and N − p − f + 1 columns.  Every quantity the
methods use — the (weighted) oblique projection O_f = Y_f /_{U_f} Z_p with
Z_p = [U_p; Y_p], its singular values, the state sequences and the
residual covariances of the Kalman-filter step — is a linear combination of
the rows of that matrix, so it is determined by the k × k Gram matrix
G = H Hᵀ alone.  G is built in one pass over the record by
:func:`~servoid.estimate._gram.lagged_gram` (each entry is a lagged product
of two signals), so the N-column Hankel matrix is never formed: memory is
O(k²) whatever N is.  The projections then follow from Schur complements of
G (the Gram form of the LQ factorisation used by Van Overschee & De Moor,
*Subspace Identification for Linear Systems*, Kluwer 1996, ch. 4 and 6, and
Verhaegen & Verdult, *Filtering and System Identification*, CUP 2007,
ch. 9).  Working on G doubles the exponent of the condition number compared
with an LQ of H; the signals are scaled to unit RMS first, and pseudo-inverses
with a relative eigenvalue floor keep noise-free (rank-deficient) data usable.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._lazy import linalg
from ._gram import lagged_gram

__all__ = [
    "HankelLayout",
    "Weighting",
    "hankel_gram",
    "innovation_covariances",
    "observability",
    "state_regression",
    "state_rows",
    "system_matrices",
]

Weighting = Literal["moesp", "cva", "n4sid"]

#: Relative eigenvalue floor of the pseudo-inverses: directions of a Gram block below
#: this fraction of its largest eigenvalue are rounding noise (noise-free data make the
#: past-data block exactly rank deficient); 1e-12 ≈ 4500·ε leaves margin above ε·k.
_PINV_RTOL = 1e-12


@dataclass(frozen=True, eq=False)
class HankelLayout:
    """Row layout of the block-Hankel data matrix [U_f; U_p; Y_p; Y_f].

    Signal indices: inputs ``0 … m−1``, outputs ``m … m+ny−1``.  A column
    is anchored at its last future sample, so row (signal s, lag l) holds
    z_s(τ − l) with τ = start … N − 1 and ``start = past + future − 1``.
    """

    n_inputs: int
    n_outputs: int
    past: int
    future: int

    @property
    def start(self) -> int:
        """First anchor time τ (the longest lag)."""
        return self.past + self.future - 1

    @property
    def n_rows(self) -> int:
        """Rows k = (past + future)(m + ny)."""
        return (self.past + self.future) * (self.n_inputs + self.n_outputs)

    def columns(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Signal index and lag of every row, in the order U_f, U_p, Y_p, Y_f."""
        m, ny, p, f = self.n_inputs, self.n_outputs, self.past, self.future
        sig: list[int] = []
        lag: list[int] = []
        for first, width, blocks, lag_of in (
            (0, m, f, lambda i: f - 1 - i),  # U_f block i: u(t + i)
            (0, m, p, lambda k: f - 1 + p - k),  # U_p block k: u(t − p + k)
            (m, ny, p, lambda k: f - 1 + p - k),  # Y_p
            (m, ny, f, lambda i: f - 1 - i),  # Y_f
        ):
            for b in range(blocks):
                sig += list(range(first, first + width))
                lag += [lag_of(b)] * width
        return np.array(sig, dtype=np.int64), np.array(lag, dtype=np.int64)

    def rows(self, part: Literal["uf", "up", "yp", "yf"], blocks: range | None = None
             ) -> NDArray[np.int64]:
        """Row indices of one part, optionally only some of its block rows."""
        m, ny, p, f = self.n_inputs, self.n_outputs, self.past, self.future
        offset, width, count = {
            "uf": (0, m, f),
            "up": (f * m, m, p),
            "yp": (f * m + p * m, ny, p),
            "yf": (f * m + p * (m + ny), ny, f),
        }[part]
        chosen = range(count) if blocks is None else blocks
        return np.array(
            [offset + b * width + c for b in chosen for c in range(width)], dtype=np.int64
        )


def hankel_gram(
    segments: Sequence[tuple[NDArray[np.float64], ...]],
    layout: HankelLayout,
    scale: NDArray[np.float64],
) -> tuple[NDArray[np.float64], int]:
    """Return the scaled Gram matrix of the block-Hankel data and its column count.

    Parameters
    ----------
    segments : sequence of tuples of ndarray
        Per segment the signals ``(u_0, …, u_{m−1}, y_0, …)``, each shape (N,).
    layout : HankelLayout
        Horizons and channel counts.
    scale : ndarray, shape (m + ny,)
        RMS of each signal; the Gram is that of the signals divided by it.

    Returns
    -------
    gram : ndarray, shape (k, k)
        ``H Hᵀ / j`` of the scaled signals, summed over segments.
    j : int
        Number of Hankel columns over all segments.
    """
    sig, lag = layout.columns()
    start = layout.start
    gram = np.zeros((sig.size, sig.size))
    j = 0
    for z in segments:
        if z[0].size <= start:  # no whole window in this segment
            continue
        gram += lagged_gram(z, sig, lag, start)
        j += z[0].size - start
    s = scale[sig]
    return gram / np.outer(s, s) / max(j, 1), j


def observability(
    gram: NDArray[np.float64], layout: HankelLayout, weighting: Weighting
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return the weighted singular vectors and values of the projection.

    The oblique projection O_f = Y_f /_{U_f} Z_p = Θ Z_p has Θ = S_yz S_zz⁺,
    with S the Gram of [Z_p; Y_f] conditioned on U_f (a Schur complement).
    Its weighted versions W₁ O_f W₂ (Van Overschee & De Moor 1996, thm. 2):

    - ``"n4sid"``: W₁ = I, W₂ = I, so W₁OW₂(W₁OW₂)ᵀ = Θ G_zz Θᵀ;
    - ``"moesp"``: W₂ = Π_{U_f}^⊥, giving Θ S_zz Θᵀ = S_yz S_zz⁺ S_zy
      (the PO-MOESP matrix L₃₂L₃₂ᵀ of Verhaegen 1994);
    - ``"cva"``: also W₁ = S_yy^{−1/2}; the singular values are then the
      canonical correlations between future outputs and the past, given
      the future inputs.

    Parameters
    ----------
    gram : ndarray, shape (k, k)
        From :func:`hankel_gram`.
    layout : HankelLayout
        Its row layout.
    weighting : {"moesp", "cva", "n4sid"}
        The weighting.

    Returns
    -------
    left : ndarray, shape (f·ny, r)
        Left singular vectors of the weighted projection.
    sv : ndarray, shape (r,)
        Its singular values, descending (per √column: independent of N).
    unweight : ndarray, shape (f·ny, f·ny)
        W₁⁻¹: the extended observability matrix is ``unweight @ left[:, :n] · √sv``.
    """
    uf, zp, yf = _parts(layout)
    theta, s_zz, s_yy = _oblique(gram, target=yf, along=uf, onto=zp, with_target=True)
    if weighting == "n4sid":
        root = _psd_root(gram[np.ix_(zp, zp)])
        unweight = np.eye(yf.size)
    else:
        root = _psd_root(s_zz)
        unweight = np.eye(yf.size)
        if weighting == "cva":
            w, v = linalg.eigh(s_yy)
            keep = w > _PINV_RTOL * max(w[-1], np.finfo(float).tiny)
            unweight = (v[:, keep] * np.sqrt(w[keep])) @ v[:, keep].T
            inv_root = (v[:, keep] / np.sqrt(w[keep])) @ v[:, keep].T
            theta = inv_root @ theta
    left, sv, _ = linalg.svd(theta @ root, full_matrices=False)
    return left, sv, unweight


def system_matrices(
    left: NDArray[np.float64], sv: NDArray[np.float64], unweight: NDArray[np.float64],
    n: int, n_outputs: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return Γ_f, A and C from the leading n singular directions.

    C is the first block row of Γ_f = W₁⁻¹ U₁ Σ₁^{1/2}; A solves the shift
    equation Γ_f[ny:] = Γ_f[:−ny] A in least squares (Verhaegen & Verdult
    2007, sec. 9.2.4).
    """
    gamma = unweight @ (left[:, :n] * np.sqrt(sv[:n]))
    c = gamma[:n_outputs]
    a = linalg.lstsq(gamma[:-n_outputs], gamma[n_outputs:], cond=None)[0]
    return gamma, a, c


def state_rows(
    gram: NDArray[np.float64], layout: HankelLayout, gamma: NDArray[np.float64]
) -> tuple[NDArray[np.float64], ...]:
    """Coefficients of X̂_i, X̂_{i+1}, u_i and y_i on the rows of the data matrix.

    The state sequences X̂_i = Γ_f⁺ (Y_f /_{U_f} Z_p) and, with the horizons
    shifted by one sample, X̂_{i+1} = Γ_{f−1}⁺ (Y_f⁻ /_{U_f⁻} Z_p⁺) are row
    combinations E·H of the data matrix H (Van Overschee & De Moor 1996,
    sec. 4.3.1), so products of them are ``E G Eᵀ``.

    Returns
    -------
    tuple of ndarray
        ``(e_now, e_next, e_u, e_y)``, shapes (n, k), (n, k), (m, k), (ny, k).
    """
    m, ny, f = layout.n_inputs, layout.n_outputs, layout.future
    n = gamma.shape[1]
    k = gram.shape[0]
    uf, zp, yf = _parts(layout)
    theta = _oblique(gram, target=yf, along=uf, onto=zp)[0]
    e_now = np.zeros((n, k))
    e_now[:, zp] = linalg.pinv(gamma) @ theta
    # shifted partition: the first future block row joins the past
    uf_next = layout.rows("uf", range(1, f))
    yf_next = layout.rows("yf", range(1, f))
    zp_next = np.concatenate([layout.rows("up"), layout.rows("uf", range(1)),
                              layout.rows("yp"), layout.rows("yf", range(1))])
    theta_next = _oblique(gram, target=yf_next, along=uf_next, onto=zp_next)[0]
    e_next = np.zeros((n, k))
    e_next[:, zp_next] = linalg.pinv(gamma[:-ny]) @ theta_next
    e_u = np.zeros((m, k))
    e_u[np.arange(m), layout.rows("uf", range(1))] = 1.0
    e_y = np.zeros((ny, k))
    e_y[np.arange(ny), layout.rows("yf", range(1))] = 1.0
    return e_now, e_next, e_u, e_y


def state_regression(
    gram: NDArray[np.float64], rows: tuple[NDArray[np.float64], ...], a: NDArray[np.float64],
    c: NDArray[np.float64], feedthrough: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """B and D by least squares on ``[X̂_{i+1} − A X̂_i; y_i − C X̂_i] = [B; D] u_i``.

    The route of Van Overschee & De Moor (1996, sec. 4.3.1) with A and C
    fixed: it needs no simulation, so it also serves an unstable A.
    """
    e_now, e_next, e_u, e_y = rows
    target = np.vstack([e_next - a @ e_now, e_y - c @ e_now])
    coef = linalg.solve(e_u @ gram @ e_u.T, e_u @ gram @ target.T, assume_a="pos").T
    n = a.shape[0]
    d = coef[n:] if feedthrough else np.zeros((c.shape[0], e_u.shape[0]))
    return coef[:n], d


def innovation_covariances(
    gram: NDArray[np.float64],
    rows: tuple[NDArray[np.float64], ...],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    c: NDArray[np.float64],
    d: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Return the joint covariance of the state and output residuals.

    ``w = X̂_{i+1} − A X̂_i − B u_i`` and ``v = y_i − C X̂_i − D u_i`` (see
    :func:`state_rows`); all in the scaled signal units of `gram`.

    Returns
    -------
    ndarray, shape (n + ny, n + ny)
        ``[[Q, S], [Sᵀ, R]]``.
    """
    e_now, e_next, e_u, e_y = rows
    resid = np.vstack([e_next - a @ e_now - b @ e_u, e_y - c @ e_now - d @ e_u])
    cov = resid @ gram @ resid.T
    return (cov + cov.T) / 2


# -- private helpers ------------------------------------------------------------------------------


def _parts(layout: HankelLayout) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    zp = np.concatenate([layout.rows("up"), layout.rows("yp")])
    return layout.rows("uf"), zp, layout.rows("yf")


def _oblique(
    gram: NDArray[np.float64],
    target: NDArray[np.int64],
    along: NDArray[np.int64],
    onto: NDArray[np.int64],
    with_target: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Θ with target /_{along} onto = Θ·onto, and the conditional Grams used.

    The coefficient of `onto` in the joint regression of `target` on
    [along; onto] equals the partial regression on the residual of `onto`
    given `along` (Frisch–Waugh), hence Θ = S_ty S_yy⁺ with S the Gram
    conditioned on `along`.
    """
    rest = np.concatenate([onto, target])
    chol = linalg.cholesky(gram[np.ix_(along, along)], lower=True)
    x = linalg.solve_triangular(chol, gram[np.ix_(along, rest)], lower=True)
    cond = gram[np.ix_(rest, rest)] - x.T @ x
    n_onto = onto.size
    s_oo = cond[:n_onto, :n_onto]
    s_to = cond[n_onto:, :n_onto]
    theta = s_to @ _psd_pinv(s_oo)
    s_tt = cond[n_onto:, n_onto:] if with_target else np.empty((0, 0))
    return theta, s_oo, s_tt


def _psd_pinv(s: NDArray[np.float64]) -> NDArray[np.float64]:
    w, v = linalg.eigh(s)
    keep = w > _PINV_RTOL * max(w[-1], np.finfo(float).tiny)
    return (v[:, keep] / w[keep]) @ v[:, keep].T


def _psd_root(s: NDArray[np.float64]) -> NDArray[np.float64]:
    """R with R Rᵀ = S on the numerically non-null eigenspace of S."""
    w, v = linalg.eigh(s)
    keep = w > _PINV_RTOL * max(w[-1], np.finfo(float).tiny)
    return v[:, keep] * np.sqrt(w[keep])
