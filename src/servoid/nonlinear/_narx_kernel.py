"""Compiled loops of polynomial NARX: regressors, free run, k-step prediction.

A term is a product of at most ``D`` lagged signals. It is encoded as a row
of two ``(T, D)`` integer tables, ``sig`` (0 = the output y, i ≥ 1 = input
i) and ``lag`` [samples], with ``sig = -1`` padding the unused factors; the
constant term has no factor. The signals travel as one ``(1 + n_u, N)``
array ``z`` whose row 0 is y. Every loop reads ``z`` in place; the
regressor kernel fills a caller's block of rows, so a record of any length
is summed block by block without forming the whole regressor matrix.

numba compiles each kernel on its first call and caches it on disk
(``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["DIVERGED", "fill_regressors", "forward_select", "predict_k", "simulate_free"]

#: A free run whose output leaves ±DIVERGED has diverged (its square would overflow
#: double precision within a few more products).
DIVERGED = 1e150


def fill_regressors(
    z: NDArray[np.float64], sig: NDArray[np.int64], lag: NDArray[np.int64], t0: int,
    out: NDArray[np.float64],
) -> None:
    """Write term j at times ``t0 … t0 + b − 1`` into ``out[j, :b]`` (row per term)."""
    _fill(z, sig, lag, t0, out)


def simulate_free(
    z: NDArray[np.float64], sig: NDArray[np.int64], lag: NDArray[np.int64],
    theta: NDArray[np.float64], start: int,
) -> int:
    """Overwrite ``z[0, start:]`` with the free run; return the divergence index or -1."""
    return int(_simulate(z, sig, lag, theta, start, DIVERGED))


def predict_k(
    z: NDArray[np.float64], sig: NDArray[np.int64], lag: NDArray[np.int64],
    theta: NDArray[np.float64], start: int, horizon: int, out: NDArray[np.float64],
) -> None:
    """``out[t]`` = ŷ(t | t − horizon) for t ≥ start (measured y up to t − horizon)."""
    _predict(z, sig, lag, theta, start, horizon, out)


@numba.njit(cache=True, nogil=True)
def _fill(z, sig, lag, t0, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    # Term by term over a block of times: each inner loop is a contiguous product of
    # shifted signal rows, which the compiler vectorises.
    n_terms, depth = sig.shape
    b = out.shape[1]
    for j in range(n_terms):
        row = out[j]
        if sig[j, 0] < 0:
            row[:] = 1.0
            continue
        src = z[sig[j, 0]]
        off = t0 - lag[j, 0]
        for r in range(b):
            row[r] = src[off + r]
        for f in range(1, depth):
            s = sig[j, f]
            if s < 0:
                break
            src = z[s]
            off = t0 - lag[j, f]
            for r in range(b):
                row[r] *= src[off + r]


@numba.njit(cache=True, nogil=True)
def _term_sum(z, sig, lag, theta, t):  # type: ignore[no-untyped-def]  # pragma: no cover
    n_terms, depth = sig.shape
    acc = 0.0
    for j in range(n_terms):
        p = theta[j]
        for f in range(depth):
            s = sig[j, f]
            if s < 0:
                break
            p *= z[s, t - lag[j, f]]
        acc += p
    return acc


@numba.njit(cache=True, nogil=True)
def _simulate(z, sig, lag, theta, start, limit):  # type: ignore[no-untyped-def]  # pragma: no cover
    n = z.shape[1]
    for t in range(start, n):
        v = _term_sum(z, sig, lag, theta, t)
        if not abs(v) <= limit:  # also catches NaN
            for k in range(t, n):
                z[0, k] = np.nan
            return t
        z[0, t] = v
    return -1


@numba.njit(cache=True, nogil=True)
def _predict(z, sig, lag, theta, start, horizon, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    # For each t the samples t − k + 1 … t are simulated in a local window from the
    # measured past; an output lag that lands in the window reads the simulated value.
    n = z.shape[1]
    n_terms, depth = sig.shape
    buf = np.empty(horizon)
    for t in range(start, n):
        lo = max(t - horizon + 1, start)
        for s_t in range(lo, t + 1):
            acc = 0.0
            for j in range(n_terms):
                p = theta[j]
                for f in range(depth):
                    s = sig[j, f]
                    if s < 0:
                        break
                    k = s_t - lag[j, f]
                    if s == 0 and k >= lo:
                        p *= buf[k - lo]
                    else:
                        p *= z[s, k]
                acc += p
            buf[s_t - lo] = acc
        out[t] = buf[t - lo]


def forward_select(
    g: NDArray[np.float64], c: NDArray[np.float64], yy: float, n_rows: int, max_terms: int,
    penalty: float, tolerance: float, patience: int, dependent: float, floor: float,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], int]:
    """Forward orthogonal selection on the scaled Gram matrix (modified in place).

    Returns the selected columns in order, their error reduction ratios,
    the residual sum of squares after each, and the number of terms that
    minimises ``n_rows·ln(RSS_k/n_rows) + penalty·k`` (``penalty`` < 0:
    stop instead when RSS_k ≤ ``tolerance``·yᵀy, the ERR threshold).
    """
    return _forward(g, c, float(yy), int(n_rows), int(max_terms), float(penalty),
                    float(tolerance), int(patience), float(dependent), float(floor))


@numba.njit(cache=True, nogil=True)
def _forward(g, c, yy, n_rows, max_terms, penalty, tolerance, patience, dependent, floor):  # type: ignore[no-untyped-def]  # pragma: no cover
    # g is Φᵀ Φ scaled to a unit diagonal and c = Φᵀ y scaled alike. Eliminating a selected
    # column s from the others (one symmetric Gauss step on g and c) leaves in g[j, j] the
    # squared norm of what is left of candidate j after its projection on the selected
    # terms (w_jᵀ w_j of the Gram–Schmidt recursion) and in c[j] its product with y (w_jᵀ y):
    # the error reduction ratio of j is c[j]²/(g[j, j]·yᵀy) (Chen, Billings & Luo 1989).
    m = g.shape[0]
    active = np.ones(m, dtype=np.bool_)
    order = np.empty(max_terms, dtype=np.int64)
    err = np.empty(max_terms)
    rss_path = np.empty(max_terms)
    rss = yy
    best = n_rows * np.log(max(rss, floor) / n_rows)
    best_k = 0
    n_sel = 0
    for step in range(max_terms):
        s = -1
        top = -1.0
        for j in range(m):
            if active[j] and g[j, j] > dependent:
                e = c[j] * c[j] / g[j, j]
                if e > top:
                    top = e
                    s = j
        if s < 0:
            break
        active[s] = False
        order[step] = s
        err[step] = top / yy
        rss -= top
        rss_path[step] = rss
        gss = g[s, s]
        cs = c[s]
        for i in range(m):
            if not active[i]:
                continue
            f = g[i, s] / gss
            if f == 0.0:
                continue
            for j in range(m):
                if active[j]:
                    g[i, j] -= f * g[s, j]
            c[i] -= f * cs
        n_sel = step + 1
        if penalty >= 0.0:
            value = n_rows * np.log(max(rss, floor) / n_rows) + penalty * n_sel
            if value < best:
                best = value
                best_k = n_sel
            elif n_sel - best_k >= patience:
                break
        else:
            best_k = n_sel
            if rss <= tolerance * yy:
                break
    return order[:n_sel], err[:n_sel], rss_path[:n_sel], best_k
