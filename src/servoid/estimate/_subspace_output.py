"""B, D and the initial state by least squares once A and C are known.

With A and C fixed, the output of ``x(t+1) = A x + B u, y = C x + D u`` is
linear in B, D and x(0):

    y(t) = C Aᵗ x(0) + Σ_{k<t} C A^{t−1−k} B u(k) + D u(t)

(Verhaegen & Verdult 2007, sec. 9.2.4.2; Van Overschee & De Moor 1996,
sec. 4.3).  The regressor of B_ij for output o is r_oj(t)_i with the row
recursion ``r_oj(t+1) = r_oj(t) A + u_j(t) c_o`` (c_o the o-th row of C),
so one compiled pass per segment accumulates the normal equations without
storing the regressor matrix.  The pass keeps the products of every pair of
outputs, so the residual covariance of the simulated output follows from
the same sums (no second simulation).  When the normal equations are too
ill-conditioned the pass is repeated storing the rows and QR solves it
(see :mod:`._ls`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from .._errors import IdentifiabilityError
from ._ls import LeastSquaresResult, lstsq, solve_gram

__all__ = ["OutputFit", "fit_input_matrices"]

#: The free response C·Aᵗ is set to zero below this: it would only add subnormal numbers
#: (100× slower arithmetic) whose squares underflow anyway.
_TINY = 1e-150
#: Samples buffered per Gram update: a few hundred columns of a few KB stay in the L1/L2 cache.
_CHUNK = 256


@dataclass(frozen=True, eq=False)
class OutputFit:
    """B, D, the initial state per segment and the residual sums."""

    b: NDArray[np.float64]
    d: NDArray[np.float64]
    x0: tuple[NDArray[np.float64], ...]
    residual_products: NDArray[np.float64]  # Σ_t e(t) e(t)ᵀ, shape (ny, ny)
    solver: str
    condition: float


def fit_input_matrices(
    a: NDArray[np.float64],
    c: NDArray[np.float64],
    segments: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    feedthrough: bool,
) -> OutputFit:
    """Return B, D (zero unless `feedthrough`) and x(0) per segment.

    Parameters
    ----------
    a, c : ndarray
        State and output matrices, shapes (n, n) and (ny, n).
    segments : sequence of (u, y)
        Per segment u of shape (N, m) and y of shape (N, ny), C-contiguous.
    feedthrough : bool
        Estimate D; otherwise D = 0.

    Raises
    ------
    IdentifiabilityError
        The regression is rank deficient or overflows (an unstable A
        simulated over a long record).
    """
    n = a.shape[0]
    ny = c.shape[0]
    m = segments[0][0].shape[1]
    n_shared = n * m + (ny * m if feedthrough else 0)
    n_local = n_shared + n  # columns of one segment's regressor
    width = n_local + 1  # … and the target
    n_seg = len(segments)
    n_par = n_shared + n * n_seg
    names = tuple(
        [f"B[{i},{j}]" for j in range(m) for i in range(n)]
        + ([f"D[{o},{j}]" for j in range(m) for o in range(ny)] if feedthrough else [])
        + [f"x0[{s}][{i}]" for s in range(n_seg) for i in range(n)]
    )
    n_rows = sum(u.shape[0] for u, _ in segments) * ny
    # products[s][o, o2] = Σ_t [φ_o(t) y_o(t)]ᵀ [φ_o2(t) y_o2(t)] over segment s
    products = []
    empty = np.zeros((0, 0))
    for u, y in segments:
        local = np.zeros((ny * width, ny * width))
        _regression(a, c, u, y, feedthrough, False, empty, empty, local)
        products.append(local.reshape(ny, width, ny, width).transpose(0, 2, 1, 3))
    if not all(np.all(np.isfinite(p)) for p in products):
        raise _overflow(a)
    gram = np.zeros((n_par + 1, n_par + 1))
    for s, prod in enumerate(products):
        idx = _global_columns(s, n_shared, n, n_par)
        gram[np.ix_(idx, idx)] += np.einsum("ooij->ij", prod)
    result: LeastSquaresResult | None = solve_gram(gram, n_rows, names)
    if result is not None:
        theta = result.theta
        resid = np.zeros((ny, ny))
        for s, prod in enumerate(products):
            w = np.append(-theta[_global_columns(s, n_shared, n, n_par)[:-1]], 1.0)
            resid += np.einsum("i,abij,j->ab", w, prod, w)  # Σ e_a e_b with e = y − φθ
    else:  # too ill-conditioned for the normal equations: store the rows, QR
        phi = np.zeros((n_rows, n_par))
        target = np.empty(n_rows)
        row = 0
        for s, (u, y) in enumerate(segments):
            rows = u.shape[0] * ny
            local_rows = np.empty((rows, n_local))
            _regression(a, c, u, y, feedthrough, True, local_rows, target[row : row + rows],
                        empty)
            phi[row : row + rows, _global_columns(s, n_shared, n, n_par)[:-1]] = local_rows
            row += rows
        result = lstsq(phi, target, names)
        theta = result.theta
        e = (target - phi @ theta).reshape(-1, ny)
        resid = e.T @ e
    b = theta[: n * m].reshape(m, n).T
    d = theta[n * m : n_shared].reshape(m, ny).T if feedthrough else np.zeros((ny, m))
    x0 = tuple(theta[n_shared + s * n : n_shared + (s + 1) * n] for s in range(n_seg))
    return OutputFit(b, d, x0, (resid + resid.T) / 2, result.method, result.condition)


def _global_columns(s: int, n_shared: int, n: int, n_par: int) -> NDArray[np.int64]:
    """Global column of each local column (shared B/D, segment s's x0, target)."""
    return np.concatenate([np.arange(n_shared), n_shared + s * n + np.arange(n), [n_par]])


def _overflow(a: NDArray[np.float64]) -> IdentifiabilityError:
    radius = float(np.max(np.abs(np.linalg.eigvals(a)))) if a.size else 0.0
    return IdentifiabilityError(
        f"the estimated A is unstable (largest pole magnitude {radius:.6g}) and its simulation "
        "over the record overflows, so B and D cannot be fitted. Remove drift (detrend), use "
        "a lower order, or identify in closed loop"
    )


@numba.njit(cache=True, nogil=True)
def _regression(a, c, u, y, feedthrough, store, phi, target, gram):  # type: ignore[no-untyped-def]  # pragma: no cover
    # Local columns: B[i, j] at j·n + i, then D[o, j] at n·m + j·ny + o (if feedthrough), then
    # x0[i]. Row (t, o) is output o at time t. The Gram mode accumulates, per time t, the outer
    # product of the stacked vector [φ_0(t), y_0(t), φ_1(t), y_1(t), …] (all output pairs); the
    # vectors of _CHUNK samples are buffered column-wise and reduced by contiguous dot products.
    n = a.shape[0]
    ny = c.shape[0]
    m = u.shape[1]
    n_b = n * m
    n_d = ny * m if feedthrough else 0
    n_col = n_b + n_d + n
    width = n_col + 1
    size = ny * width
    n_t = u.shape[0]
    r = np.zeros((ny, m, n))  # r[o, j] = Σ_{k<t} u_j(k) c_o A^{t−1−k}
    r_next = np.zeros(n)
    free = c.copy()  # C Aᵗ
    free_next = np.zeros(n)
    buf = np.zeros((size, _CHUNK))
    for lo in range(0, n_t, _CHUNK):
        hi = min(lo + _CHUNK, n_t)
        for t in range(lo, hi):
            k = t - lo
            for o in range(ny):
                base = o * width
                for j in range(m):
                    for i in range(n):
                        buf[base + j * n + i, k] = r[o, j, i]
                if feedthrough:
                    for q in range(n_d):
                        buf[base + n_b + q, k] = 0.0
                    for j in range(m):
                        buf[base + n_b + j * ny + o, k] = u[t, j]
                for i in range(n):
                    buf[base + n_b + n_d + i, k] = free[o, i]
                buf[base + n_col, k] = y[t, o]
            for o in range(ny):
                for j in range(m):
                    for i in range(n):
                        acc = u[t, j] * c[o, i]
                        for l_ in range(n):
                            acc += r[o, j, l_] * a[l_, i]
                        r_next[i] = acc
                    for i in range(n):
                        r[o, j, i] = r_next[i]
                for i in range(n):
                    acc = 0.0
                    for l_ in range(n):
                        acc += free[o, l_] * a[l_, i]
                    free_next[i] = acc if abs(acc) > _TINY else 0.0
                for i in range(n):
                    free[o, i] = free_next[i]
        if store:
            for t in range(lo, hi):
                for o in range(ny):
                    row = t * ny + o
                    for q in range(n_col):
                        phi[row, q] = buf[o * width + q, t - lo]
                    target[row] = buf[o * width + n_col, t - lo]
        else:
            _accumulate(buf, hi - lo, gram)
    if not store:
        for p_ in range(size):
            for q in range(p_):
                gram[p_, q] = gram[q, p_]


@numba.njit(cache=True, nogil=True, fastmath=True)
def _accumulate(buf, count, gram):  # type: ignore[no-untyped-def]  # pragma: no cover
    # gram[p, q] += Σ_k buf[p, k]·buf[q, k] over the first `count` columns (upper triangle)
    size = buf.shape[0]
    for p_ in range(size):
        xp = buf[p_, :count]
        for q in range(p_, size):
            xq = buf[q, :count]
            acc = 0.0
            for k in range(count):
                acc += xp[k] * xq[k]
            gram[p_, q] += acc
