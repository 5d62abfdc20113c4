"""Compiled passes of recursive least squares (:func:`~servoid.estimate.fit_rls`).

Two passes over the record, neither of which copies it:

* :func:`gram_pass` — ΦᵀΦ (column norms, rank test, λ = 1 covariance) and,
  with forgetting, H = Σ λ^{N−1−t} φφᵀ and G = Σ λ^{2(N−1−t)} φφᵀ of the
  covariance sandwich. Sums run in blocks of :data:`BLOCK` rows (error
  ~ε·(BLOCK + N/BLOCK) instead of ~ε·N).
* :func:`rls_pass` — the recursion, in the units of θ: normalising the
  columns is the prior P₀ = p₀·diag(1/‖φ_i‖²), the scaled recursion with
  P₀ = p₀·I in other coordinates, so Φ is never scaled or copied.

**Pipelining.** The textbook update forms q = P_t φ_t, then d = λ + φ_tᵀq,
then 1/d, then P_{t+1}, and the next sample waits for all of it. Here the
next q and d come from quantities available before 1/d_t
(P_{t+1} = (P_t − k_t q_t q_tᵀ)/λ substituted, k_t = 1/d_t)::

    r = P_t φ_{t+1},  a = φ_{t+1}ᵀ r,  b = q_tᵀ φ_{t+1}
    q_{t+1} = (r − q_t·b·k_t)/λ,   d_{t+1} = λ + (a − b²·k_t)/λ

so a multiply–add and the division are all that remains between samples.
When the covariance guard rescales P, q and d are rescaled with it; when it
resets P they are recomputed from P₀.

**Generated kernels.** For n ≤ :data:`UNROLL_MAX` parameters the recursion
runs code generated for that n, with P, θ and q in scalars (no array
traffic) and the storage options and the guard fixed at generation, so the
hot loop holds only the recursion: about 2× faster than the loop over
arrays. It performs the same floating-point operations in the same order as
:func:`_rls_loop` (no fast-math there), so the two return the same bits. The
unweighted Gram pass is generated likewise up to :data:`GRAM_UNROLL_MAX`
columns. The source is compiled with this file's name, which numba's on-disk
cache (``cache=True``) needs to find and stamp it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "BLOCK",
    "GRAM_UNROLL_MAX",
    "GUARD_CODES",
    "UNROLL_MAX",
    "RlsPass",
    "gram_pass",
    "rls_pass",
    "weighted_rss",
]

#: Rows summed locally before they join the totals (:func:`gram_pass`).
BLOCK = 512
#: Largest parameter count with a generated recursion; above it, the loop over arrays.
UNROLL_MAX = 8
#: Largest column count with a generated (unweighted) Gram pass; above it, and for the
#: weighted sums, whose many accumulators no longer fit the registers, the blocked kernel.
GRAM_UNROLL_MAX = 6
#: Guard name → the code the kernels take.
GUARD_CODES = {"bound": 0, "reset": 1, "none": 2}


class RlsPass(NamedTuple):
    """What one recursion pass returns (θ and P in the units of θ)."""

    theta: NDArray[np.float64]
    p: NDArray[np.float64]
    cost: float  # J_N = min Σ λ^{N−1−t} e_t² + λ^N (θ − θ₀)ᵀP₀⁻¹(θ − θ₀), by recursion
    events: int


def gram_pass(
    phi: NDArray[np.float64], lam: float
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """ΦᵀΦ and, for λ < 1, H = Σ λ^{N−1−t} φφᵀ and G = Σ λ^{2(N−1−t)} φφᵀ.

    A non-finite value in Φ makes the diagonal non-finite (as does a square
    beyond the double range); the caller checks it. Memory: O(n²), plus
    2·n·BLOCK values in the blocked kernel.
    """
    n = phi.shape[1]
    if lam == 1.0 and n <= GRAM_UNROLL_MAX:
        return _generated("gram", n)(phi, BLOCK), None, None
    weighted = lam < 1.0
    weights = lam ** np.arange(BLOCK - 1, -1, -1, dtype=float) if weighted else np.empty(0)
    gram, h, g = _gram_blocked(phi, weights, float(lam), weighted, BLOCK)
    return gram, (h if weighted else None), (g if weighted else None)


def rls_pass(
    phi: NDArray[np.float64],
    y: NDArray[np.float64],
    theta0: NDArray[np.float64],
    p0_diag: NDArray[np.float64],
    trace_weight: NDArray[np.float64],
    lam: float,
    cap: float,
    guard: int,
    prior: NDArray[np.float64],
    post: NDArray[np.float64],
    hist: NDArray[np.float64],
    traces: NDArray[np.float64],
) -> RlsPass:
    """Run the recursion once over the record.

    Parameters
    ----------
    phi, y : ndarray
        Regressors (N, n) and left-hand side (N,), in their own units.
    theta0 : ndarray, shape (n,)
        Initial θ.
    p0_diag : ndarray, shape (n,)
        P₀ = diag(p0_diag); also what the ``"reset"`` guard restores.
    trace_weight : ndarray, shape (n,)
        The guard watches Σ_i P_ii·trace_weight_i (the trace in scaled units).
    lam, cap, guard
        Forgetting factor, trace cap, guard code (:data:`GUARD_CODES`).
    prior, post : ndarray, shape (N,) or (0,)
        Filled with the a priori and a posteriori errors when of length N.
    hist, traces : ndarray, shape (N, n) and (N,), or empty
        Filled with θ_t and the watched trace when of length N.
    """
    n_rows, n = phi.shape
    if n > UNROLL_MAX:
        kernel: Callable[..., Any] = _rls_loop
    else:
        # With λ = 1 every update only subtracts from P's diagonal (k·q_i² ≥ 0, and IEEE
        # rounding is monotone), so the trace never exceeds its start: a guard whose cap is
        # at least that can never act and is left out of the loop.
        start = float(np.sum(p0_diag * trace_weight))
        can_act = guard != GUARD_CODES["none"] and (lam < 1.0 or start > cap)
        kernel = _generated("rls", n, prior.size == n_rows, traces.size == n_rows, can_act)
    theta, p, cost, events = kernel(
        phi, y, theta0, p0_diag, trace_weight, lam, cap, guard, prior, post, hist, traces
    )
    return RlsPass(theta, p, float(cost), int(events))


def weighted_rss(
    phi: NDArray[np.float64], y: NDArray[np.float64], theta: NDArray[np.float64], lam: float
) -> float:
    """Σ λ^{N−1−t} (y_t − φ_tᵀθ)², in one pass without temporaries."""
    return float(_weighted_rss(phi, y, theta, float(lam)))


# -- kernels over arrays (any n) ---------------------------------------------------------------


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
def _gram_blocked(phi, weights, lam, weighted, block):  # type: ignore[no-untyped-def]  # pragma: no cover
    # Each block is transposed into an L1-sized buffer so every entry is a contiguous dot
    # product the compiler vectorises (reassociation); without nnan/ninf a NaN or an inf
    # still reaches the diagonal.
    n_rows, n = phi.shape
    gram = np.zeros((n, n))
    h = np.zeros((n, n))
    g = np.zeros((n, n))
    buf = np.empty((n, block))
    wbuf = np.empty((n, block) if weighted else (0, block))
    for start in range(0, n_rows, block):
        m = min(block, n_rows - start)
        for t in range(m):
            for i in range(n):
                buf[i, t] = phi[start + t, i]
        for i in range(n):
            for j in range(i, n):
                s = 0.0
                for t in range(m):
                    s += buf[i, t] * buf[j, t]
                gram[i, j] += s
        if weighted:
            off = block - m  # a short last block takes the newest m weights
            decay = lam**m
            for i in range(n):
                for t in range(m):
                    wbuf[i, t] = weights[off + t] * buf[i, t]
            for i in range(n):
                for j in range(i, n):
                    sh = 0.0
                    sg = 0.0
                    for t in range(m):
                        sh += wbuf[i, t] * buf[j, t]
                        sg += wbuf[i, t] * wbuf[j, t]
                    h[i, j] = h[i, j] * decay + sh
                    g[i, j] = g[i, j] * (decay * decay) + sg
    for i in range(n):
        for j in range(i + 1, n):
            gram[j, i] = gram[i, j]
            h[j, i] = h[i, j]
            g[j, i] = g[i, j]
    return gram, h, g


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _weighted_rss(phi, y, theta, lam):  # type: ignore[no-untyped-def]  # pragma: no cover
    n_rows, n = phi.shape
    acc = 0.0
    for t in range(n_rows):
        e = y[t]
        for i in range(n):
            e -= phi[t, i] * theta[i]
        acc = lam * acc + e * e
    return acc


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _rls_loop(phi, y, theta0, p0_diag, tw, lam, cap, guard, prior, post, hist, traces):  # type: ignore[no-untyped-def]  # pragma: no cover
    # The reference form of the pipelined recursion (module notes); _rls_source emits the
    # same operations in the same order for a fixed n.
    n_rows, n = phi.shape
    keep_resid = prior.size == n_rows
    keep_hist = traces.size == n_rows
    ilam = 1.0 / lam
    theta = theta0.copy()
    p = np.zeros((n, n))
    for i in range(n):
        p[i, i] = p0_diag[i]
    q = np.empty(n)
    r = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += p[i, j] * phi[0, j]
        q[i] = acc
    d = lam
    for i in range(n):
        d += phi[0, i] * q[i]
    cost = 0.0
    events = 0
    last = n_rows - 1
    for t in range(n_rows):
        k = 1.0 / d
        alpha = y[t]
        for i in range(n):
            alpha -= phi[t, i] * theta[i]
        ka = k * alpha
        for i in range(n):
            theta[i] += q[i] * ka
        # J_t = λJ_{t−1} + α·e with e = λα/d the a posteriori error: a sum of non-negative
        # terms, so the residual sum of squares comes without cancellation
        cost = lam * cost + alpha * (alpha * (lam * k))
        if keep_resid:
            e = y[t]
            for i in range(n):
                e -= phi[t, i] * theta[i]
            prior[t] = alpha
            post[t] = e
        nxt = t + 1 if t < last else t  # the last step's look-ahead is computed and unused
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += p[i, j] * phi[nxt, j]
            r[i] = acc
        a = 0.0
        for i in range(n):
            a += phi[nxt, i] * r[i]
        b = 0.0
        for i in range(n):
            b += q[i] * phi[nxt, i]
        kl = k * ilam
        for i in range(n):
            w = q[i] * kl
            for j in range(i, n):
                v = p[i, j] * ilam - w * q[j]
                p[i, j] = v
                p[j, i] = v
        tr = 0.0
        for i in range(n):
            tr += p[i, i] * tw[i]
        bk = b * kl
        for i in range(n):
            q[i] = r[i] * ilam - q[i] * bk
        d = (lam + a * ilam) - (b * b) * kl
        if guard != 2 and tr > cap:
            events += 1
            if guard == 0:
                s = cap / tr
                for i in range(n):
                    for j in range(n):
                        p[i, j] *= s
                for i in range(n):
                    q[i] *= s
                d = lam + (d - lam) * s
            else:
                p[:, :] = 0.0
                for i in range(n):
                    p[i, i] = p0_diag[i]
                for i in range(n):
                    q[i] = p0_diag[i] * phi[nxt, i]
                d = lam
                for i in range(n):
                    d += phi[nxt, i] * q[i]
            tr = 0.0
            for i in range(n):
                tr += p[i, i] * tw[i]
        if keep_hist:
            for i in range(n):
                hist[t, i] = theta[i]
            traces[t] = tr
    return theta, p, cost, events


# -- generated kernels ---------------------------------------------------------------------------


@functools.cache
def _generated(kind: str, n: int, *flags: bool) -> Callable[..., Any]:
    """Compile (or load from numba's cache) the generated kernel ``kind`` for n columns."""
    name = f"_{kind}_{n}_" + "".join(str(int(f)) for f in flags)
    source = _rls_source(n, name, *flags) if kind == "rls" else _gram_source(n, name)
    namespace: dict[str, Any] = {"np": np, "__name__": __name__}
    exec(compile(source, __file__, "exec"), namespace)  # noqa: S102 - source generated here
    fastmath = {"contract"} if kind == "gram" else False
    return numba.njit(cache=True, nogil=True, error_model="numpy", fastmath=fastmath)(
        namespace[name]
    )


def _pv(i: int, j: int) -> str:
    """Scalar holding entry (i, j) of a symmetric matrix (one per upper-triangle entry)."""
    return f"p{min(i, j)}_{max(i, j)}"


def _chain(start: str, terms: list[str], op: str = "+") -> str:
    """``((start op t0) op t1) op …`` — the loops' order; a start of 0.0 is dropped (exact)."""
    out = start
    for term in terms:
        out = term if out == "0.0" and op == "+" else f"({out} {op} {term})"
    return out


def _rls_source(n: int, name: str, keep_resid: bool, keep_hist: bool, guarded: bool) -> str:
    """Source of :func:`_rls_loop` for a fixed n, loops unrolled into scalars."""
    idx = range(n)
    upper = [(i, j) for i in idx for j in range(i, n)]

    def p_times(vec: str) -> list[str]:  # (P v)_i summed as the loop sums it
        return [_chain("0.0", [f"{_pv(i, j)} * {vec}{j}" for j in idx]) for i in idx]

    trace = _chain("0.0", [f"{_pv(i, i)} * tw{i}" for i in idx])
    head = ["n_rows = phi.shape[0]", "ilam = 1.0 / lam", "last = n_rows - 1"]
    head += [f"th{i} = theta0[{i}]" for i in idx]
    head += [f"tw{i} = tw[{i}]" for i in idx]
    head += [f"pd{i} = p0_diag[{i}]" for i in idx]
    head += [f"{_pv(i, j)} = pd{i}" if i == j else f"{_pv(i, j)} = 0.0" for i, j in upper]
    head += [f"f{i} = phi[0, {i}]" for i in idx]
    head += [f"q{i} = {e}" for i, e in enumerate(p_times("f"))]
    head += ["d = " + _chain("lam", [f"f{i} * q{i}" for i in idx]), "cost = 0.0", "events = 0"]
    body = ["k = 1.0 / d", "alpha = " + _chain("y[t]", [f"f{i} * th{i}" for i in idx], "-")]
    body += ["ka = k * alpha"] + [f"th{i} += q{i} * ka" for i in idx]
    body += ["cost = lam * cost + alpha * (alpha * (lam * k))"]
    if keep_resid:
        body += ["prior[t] = alpha"]
        body += ["post[t] = " + _chain("y[t]", [f"f{i} * th{i}" for i in idx], "-")]
    body += ["nxt = t + 1 if t < last else t"] + [f"g{i} = phi[nxt, {i}]" for i in idx]
    body += [f"r{i} = {e}" for i, e in enumerate(p_times("g"))]
    body += ["a = " + _chain("0.0", [f"g{i} * r{i}" for i in idx])]
    body += ["b = " + _chain("0.0", [f"q{i} * g{i}" for i in idx])]
    body += ["kl = k * ilam"]
    for i in idx:
        body += [f"w{i} = q{i} * kl"]
        body += [f"{_pv(i, j)} = {_pv(i, j)} * ilam - w{i} * q{j}" for j in range(i, n)]
    if guarded or keep_hist:
        body += [f"tr = {trace}"]
    body += ["bk = b * kl"] + [f"q{i} = r{i} * ilam - q{i} * bk" for i in idx]
    body += ["d = (lam + a * ilam) - (b * b) * kl"]
    if guarded:
        body += ["if guard != 2 and tr > cap:", "    events += 1", "    if guard == 0:"]
        body += ["        s = cap / tr"] + [f"        {_pv(i, j)} *= s" for i, j in upper]
        body += [f"        q{i} *= s" for i in idx] + ["        d = lam + (d - lam) * s"]
        body += ["    else:"]
        body += [
            f"        {_pv(i, j)} = pd{i}" if i == j else f"        {_pv(i, j)} = 0.0"
            for i, j in upper
        ]
        body += [f"        q{i} = pd{i} * g{i}" for i in idx]
        body += ["        d = " + _chain("lam", [f"g{i} * q{i}" for i in idx])]
        body += [f"    tr = {trace}"]
    if keep_hist:
        body += [f"hist[t, {i}] = th{i}" for i in idx] + ["traces[t] = tr"]
    body += [f"f{i} = g{i}" for i in idx]
    tail = [f"theta = np.empty({n})"] + [f"theta[{i}] = th{i}" for i in idx]
    tail += [f"p = np.empty(({n}, {n}))"] + [f"p[{i}, {j}] = {_pv(i, j)}" for i in idx for j in idx]
    tail += ["return theta, p, cost, events"]
    lines = [
        f"def {name}(phi, y, theta0, p0_diag, tw, lam, cap, guard, prior, post, hist, traces):"
    ]
    lines += ["    " + x for x in head] + ["    for t in range(n_rows):"]
    lines += ["        " + x for x in body] + ["    " + x for x in tail]
    return "\n".join(lines) + "\n"


def _gram_source(n: int, name: str) -> str:
    """Source of the unweighted Gram pass for a fixed n: one read of each row, sums in scalars."""
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    head = ["n_rows = phi.shape[0]"] + [f"t{i}_{j} = 0.0" for i, j in upper]
    blk = [f"s{i}_{j} = 0.0" for i, j in upper]
    blk += ["for t in range(start, min(start + block, n_rows)):"]
    blk += [f"    x{i} = phi[t, {i}]" for i in range(n)]
    blk += [f"    s{i}_{j} += x{i} * x{j}" for i, j in upper]
    blk += [f"t{i}_{j} += s{i}_{j}" for i, j in upper]
    tail = [f"gram = np.empty(({n}, {n}))"]
    for i, j in upper:
        tail += [f"gram[{i}, {j}] = t{i}_{j}", f"gram[{j}, {i}] = t{i}_{j}"]
    tail += ["return gram"]
    lines = [f"def {name}(phi, block):"] + ["    " + x for x in head]
    lines += ["    for start in range(0, n_rows, block):"] + ["        " + x for x in blk]
    lines += ["    " + x for x in tail]
    return "\n".join(lines) + "\n"
