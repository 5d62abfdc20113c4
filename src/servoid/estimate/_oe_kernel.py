"""Streamed prediction errors and Gauss–Newton sums (no C, D).

Noise-free prediction-error models, one pass per evaluation.

For ``A y = Σ_i B_i/F_i u_i(t − nk_i) + e`` (no C, D: output error when
na = 0) the prediction error and its gradient ψ = −∂ε/∂θ are (Ljung,
*System Identification*, 2nd ed., §10.3)

    uf_i = u_i / F_i,   w_i = B_i q^{−nk_i} uf_i,   wf_i = w_i / F_i,
    ε = A y − Σ_i w_i,
    ψ = [−y(t − k) | uf_i(t − nk_i − j), −wf_i(t − k) per input].

One compiled pass over the record runs these recursions sample by sample
with their recent past in small ring buffers and adds ψψᵀ, ψε and ε² into
block sums (blocks of 1024 samples, then a total: rounding ~ε·(1024 +
N/1024) rather than ~ε·N).  Nothing of length N is allocated: the memory
is the record itself plus O(p²), and the time is linear in N at any
length, where the buffered predictor (:mod:`._pem_predictor`) touched
six N-sample arrays per evaluation and paid their page faults again at
every call.  The robust covariance's ``Ψ̃ᵀΨ̃`` (columns filtered by
``1/A_v``) is the same pass with y, uf_i and wf_i filtered on the fly
(a causal filter from rest commutes with the lags).

:class:`StreamProblem` has the interface of :class:`._pem_predictor.Problem`
that the search and the covariance use; :func:`._pem._fit` takes it for
noise-free structures with zero initial conditions.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from ._pem_orders import PemOrders, SignalData

__all__ = ["StreamProblem", "oe_errors", "oe_gram", "oe_gram_columns"]

_BLOCK = 1024


@numba.njit(cache=True, nogil=True)
def _recursions(t, mask, us, bmat, nb, nk, fmat, nf, ruf, rwf):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Advance uf_i and wf_i to sample t (rings); return Σ_i w_i(t)."""
    wsum = 0.0
    for i in range(len(us)):
        acc = us[i][t]
        for k in range(1, nf[i] + 1):
            acc -= fmat[i, k] * ruf[i, (t - k) & mask]
        ruf[i, t & mask] = acc
        w = 0.0
        for j in range(nb[i]):
            w += bmat[i, j] * ruf[i, (t - nk[i] - j) & mask]
        acc = w
        for k in range(1, nf[i] + 1):
            acc -= fmat[i, k] * rwf[i, (t - k) & mask]
        rwf[i, t & mask] = acc
        wsum += w
    return wsum


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _accumulate(z, lag, sig, lags, sign, errs, lo, cnt, h, g):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Add one block's ψψᵀ and ψε into h and g.

    h[r, q] += Σ_j ψ_r(j) ψ_q(j), g[r] += Σ_j ψ_r(j) ε(j), j = lo…cnt − 1.

    ψ_r(j) = sign_r · z[sig_r, lag + j − lag_r]: dots of contiguous slices,
    which reassociation lets the compiler vectorise (only the rounding of
    a block's sum changes).
    """
    p = sig.size
    w = cnt - lo
    e = errs[lo:cnt]
    for r in range(p):
        a = z[sig[r], lag + lo - lags[r] : lag + cnt - lags[r]]
        acc = 0.0
        for i in range(w):
            acc += a[i] * e[i]
        g[r] += sign[r] * acc
        for q in range(r, p):
            b = z[sig[q], lag + lo - lags[q] : lag + cnt - lags[q]]
            acc = 0.0
            for i in range(w):
                acc += a[i] * b[i]
            h[r, q] += sign[r] * sign[q] * acc


@numba.njit(cache=True, nogil=True)
def _ring_size(a, nb, nk, nf, nar):  # type: ignore[no-untyped-def]  # pragma: no cover
    lag = a.size - 1
    for i in range(nb.size):
        lag = max(lag, nk[i] + nb[i] - 1, nf[i])
    size = 1
    while size <= max(lag, nar) + 1:
        size *= 2
    return size


@numba.njit(cache=True, nogil=True)
def oe_errors(a, bmat, nb, nk, fmat, nf, us, y, start, eps_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ_{t >= start} ε(t)² of one segment.

    ε(t) goes into ``eps_out`` (all t) when it is not empty.
    """
    m = len(us)
    n = y.size
    na = a.size - 1
    size = _ring_size(a, nb, nk, nf, 0)
    mask = size - 1
    ruf = np.zeros((m, size))
    rwf = np.zeros((m, size))
    write = eps_out.size > 0
    total = 0.0
    block = 0.0
    count = 0
    for t in range(n):
        wsum = _recursions(t, mask, us, bmat, nb, nk, fmat, nf, ruf, rwf)
        v = y[t]
        for k in range(1, min(na, t) + 1):
            v += a[k] * y[t - k]
        e = v - wsum
        if write:
            eps_out[t] = e
        if t >= start:
            block += e * e
            count += 1
            if count == _BLOCK:
                total += block
                block = 0.0
                count = 0
    return total + block


@numba.njit(cache=True, nogil=True)
def oe_gram(a, bmat, nb, nk, fmat, nf, us, y, start, ar):  # type: ignore[no-untyped-def]  # pragma: no cover
    """(ΨᵀΨ, Ψᵀε) of one segment over t >= start.

    With ``ar`` longer than [1] every base signal (y, uf_i, wf_i) is
    filtered by 1/ar from rest at t = 0 first (Ψ̃ᵀΨ̃; g is then
    meaningless): the columns of the buffered predictor's filtered Gram.

    The base signals of a block of samples go into a buffer that keeps the
    last ``lag`` samples of the previous block in front, so every column of
    Ψ over the block is a slice of it and ΨᵀΨ is a set of dot products.
    """
    m = len(us)
    n = y.size
    na = a.size - 1
    nar = ar.size - 1
    lag = na
    p = na
    for i in range(m):
        p += nb[i] + nf[i]
        lag = max(lag, nk[i] + nb[i] - 1, nf[i])
    # the columns: (base signal, lag, sign); base 0 = y, 1 + i = uf_i, 1 + m + i = wf_i
    sig = np.empty(p, dtype=np.int64)
    lags = np.empty(p, dtype=np.int64)
    sign = np.empty(p)
    c = 0
    for k in range(1, na + 1):
        sig[c], lags[c], sign[c] = 0, k, -1.0
        c += 1
    for i in range(m):
        for j in range(nb[i]):
            sig[c], lags[c], sign[c] = 1 + i, nk[i] + j, 1.0
            c += 1
        for k in range(1, nf[i] + 1):
            sig[c], lags[c], sign[c] = 1 + m + i, k, -1.0
            c += 1
    size = _ring_size(a, nb, nk, nf, nar)
    mask = size - 1
    ruf = np.zeros((m, size))
    rwf = np.zeros((m, size))
    ryf = np.zeros(size)  # filtered copies: y/ar, uf_i/ar, wf_i/ar
    rufr = np.zeros((m, size))
    rwfr = np.zeros((m, size))
    z = np.zeros((1 + 2 * m, lag + _BLOCK))
    errs = np.zeros(_BLOCK)
    h = np.zeros((p, p))
    g = np.zeros(p)
    for t0 in range(0, n, _BLOCK):
        cnt = min(_BLOCK, n - t0)
        for j in range(cnt):
            t = t0 + j
            wsum = _recursions(t, mask, us, bmat, nb, nk, fmat, nf, ruf, rwf)
            v = y[t]
            for k in range(1, min(na, t) + 1):
                v += a[k] * y[t - k]
            errs[j] = v - wsum
            if nar == 0:
                z[0, lag + j] = y[t]
                for i in range(m):
                    z[1 + i, lag + j] = ruf[i, t & mask]
                    z[1 + m + i, lag + j] = rwf[i, t & mask]
            else:
                acc = y[t]
                for k in range(1, nar + 1):
                    acc -= ar[k] * ryf[(t - k) & mask]
                ryf[t & mask] = acc
                z[0, lag + j] = acc
                for i in range(m):
                    acc = ruf[i, t & mask]
                    for k in range(1, nar + 1):
                        acc -= ar[k] * rufr[i, (t - k) & mask]
                    rufr[i, t & mask] = acc
                    z[1 + i, lag + j] = acc
                    acc = rwf[i, t & mask]
                    for k in range(1, nar + 1):
                        acc -= ar[k] * rwfr[i, (t - k) & mask]
                    rwfr[i, t & mask] = acc
                    z[1 + m + i, lag + j] = acc
        lo = max(start - t0, 0)
        if lo < cnt:
            _accumulate(z, lag, sig, lags, sign, errs, lo, cnt, h, g)
        for s in range(z.shape[0]):  # the last `lag` samples become the next block's past
            for k in range(lag):
                z[s, k] = z[s, cnt + k]
    for r in range(p):
        for q in range(r):
            h[r, q] = h[q, r]
    return h, g


@numba.njit(cache=True, nogil=True)
def oe_gram_columns(a, bmat, nb, nk, fmat, nf, us, y, start, ar):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Ψ̃ᵀΨ̃ of one segment, each column of Ψ filtered by 1/ar from t = start.

    The convention of a Jacobian whose rows start at ``start``: the rows
    before it do not exist, so each column's filter starts from rest there
    (:func:`oe_gram` filters the base signals from t = 0 instead).  Used
    once per fit, for the robust covariance of the grey-box fit.
    """
    m = len(us)
    n = y.size
    na = a.size - 1
    nar = ar.size - 1
    p = na
    for i in range(m):
        p += nb[i] + nf[i]
    size = _ring_size(a, nb, nk, nf, 0)
    mask = size - 1
    ruf = np.zeros((m, size))
    rwf = np.zeros((m, size))
    ring = 1
    while ring <= nar:
        ring *= 2
    rmask = ring - 1
    cols = np.zeros((p, ring))  # the filtered columns' recent past
    psi = np.zeros(p)
    h = np.zeros((p, p))
    g = np.zeros(p)  # unused: no errors here
    zc = np.zeros((p, _BLOCK))  # the block's filtered columns, one row per column
    errs = np.zeros(_BLOCK)
    ident = np.arange(p)
    no_lag = np.zeros(p, dtype=np.int64)
    plus = np.ones(p)
    count = 0
    for t in range(n):
        _recursions(t, mask, us, bmat, nb, nk, fmat, nf, ruf, rwf)
        if t < start:
            continue
        c = 0
        for k in range(1, na + 1):
            psi[c] = -y[t - k] if t >= k else 0.0
            c += 1
        for i in range(m):
            for j in range(nb[i]):
                psi[c] = ruf[i, (t - nk[i] - j) & mask]
                c += 1
            for k in range(1, nf[i] + 1):
                psi[c] = -rwf[i, (t - k) & mask]
                c += 1
        s = t - start
        for r in range(p):
            acc = psi[r]
            for k in range(1, min(nar, s) + 1):
                acc -= ar[k] * cols[r, (s - k) & rmask]
            cols[r, s & rmask] = acc
            zc[r, count] = acc
        count += 1
        if count == _BLOCK:
            _accumulate(zc, 0, ident, no_lag, plus, errs, 0, count, h, g)
            count = 0
    if count:
        _accumulate(zc, 0, ident, no_lag, plus, errs, 0, count, h, g)
    for r in range(p):
        for q in range(r):
            h[r, q] = h[q, r]
    return h


_NONE = np.zeros(0)
_ONE = np.ones(1)


class StreamProblem:
    """Streamed errors and normal equations of a noise-free model.

    The interface of :class:`._pem_predictor.Problem` for
    ``initial="zero"``; no buffer of the record's length is kept.
    """

    def __init__(self, orders: PemOrders, data: SignalData, start: int) -> None:
        self.orders = orders
        self.start = start
        self.estimate = False
        self.n_theta = orders.n_parameters
        self.n_ic = 0
        self.ic_rank = 0
        self._segments = [(np.ascontiguousarray(y, dtype=float),
                           tuple(np.ascontiguousarray(u, dtype=float) for u in us))
                          for y, us in zip(data.y, data.u, strict=True) if y.size > start]
        m = orders.n_inputs
        self._nb = np.array(orders.nb, dtype=np.int64)
        self._nk = np.array(orders.nk, dtype=np.int64)
        self._nf = np.array(orders.nf, dtype=np.int64)
        self._bmat = np.zeros((m, max(orders.nb)))
        self._fmat = np.zeros((m, max(orders.nf) + 1))

    @staticmethod
    def supports(orders: PemOrders, estimate: bool) -> bool:
        """Whether the streamed pass covers the structure (no C, D)."""
        return orders.noise_free and not estimate

    def _coefs(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        p = self.orders.split(np.asarray(theta, dtype=float))
        self._bmat[:] = 0.0
        self._fmat[:] = 0.0
        for i, (b, f) in enumerate(zip(p.b, p.f, strict=True)):
            self._bmat[i, : b.size] = b
            self._fmat[i, : f.size] = f
        return np.ascontiguousarray(p.a, dtype=float)

    def _run(self, theta: NDArray[np.float64], mode: int,
             ar: NDArray[np.float64] = _ONE) -> tuple[float, NDArray[np.float64],
                                                      NDArray[np.float64],
                                                      list[NDArray[np.float64]]]:
        """mode 0: cost; 1: cost and ε; 2: ΨᵀΨ, Ψᵀε; 3: Ψ̃ᵀΨ̃ with 1/ar."""
        a = self._coefs(theta)
        n = self.n_theta
        cost, h, g, errors = 0.0, np.zeros((n, n)), np.zeros(n), []
        with np.errstate(over="ignore", invalid="ignore"):
            for y, us in self._segments:
                args = (a, self._bmat, self._nb, self._nk, self._fmat, self._nf, us, y,
                        self.start)
                if mode <= 1:
                    out = np.empty(y.size) if mode == 1 else _NONE
                    cost += oe_errors(*args, out)
                    if mode == 1:
                        errors.append(out[self.start:])
                else:
                    hs, gs = oe_gram(*args, _ONE if mode == 2 else ar)
                    h += hs
                    g += gs
        return cost, h, g, errors

    def cost(self, theta: NDArray[np.float64]) -> float:
        """Σ ε(t)² over t >= start of every segment."""
        return float(self._run(theta, 0)[0])

    def normal_equations(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                     NDArray[np.float64]]:
        """ΨᵀΨ and Ψᵀε at θ."""
        _, h, g, _ = self._run(theta, 2)
        return h, g

    def residuals(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """ε(t), t >= start, of every segment, concatenated."""
        errors = self._run(theta, 1)[3]
        return np.concatenate(errors) if len(errors) > 1 else (errors[0] if errors
                                                                else np.zeros(0))

    def errors_at(self, theta: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """ε(t), t >= start, per segment at θ."""
        return self._run(theta, 1)[3]

    def filtered_gram(self, theta: NDArray[np.float64],
                      ar: NDArray[np.float64]) -> NDArray[np.float64]:
        """Σ_segments Ψ̃ᵀΨ̃ at θ, Ψ̃ = Ψ/ar(q)."""
        h = self._run(theta, 3, np.ascontiguousarray(ar, dtype=float))[1]
        return 0.5 * (h + h.T)
