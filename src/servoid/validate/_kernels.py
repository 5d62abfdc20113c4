"""Compiled passes of the validation.

The measured-start ARX simulation, its one-pass companion and the free
responses.

They replace chains of ``lfilter`` calls and N-sample temporaries:

* :func:`arx_from_data` runs ``A y_sim = Σ B_i u_i`` with the first ``m``
  samples of y as the initial conditions, writing y_sim once;
* :func:`arx_pass` gives, for ``validate``, that simulation, the k-step
  prediction, the one-step residuals and the residuals' sum and range in
  one blocked pass (six filter passes and four reductions before);
* :func:`decay_length` finds where the impulse response h of ``1/den``
  has died out, so the free responses (the lags of h) and their least
  squares fit need only that many rows instead of N.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["arx_from_data", "arx_pass", "decay_length", "impulse"]

#: Samples per block of :func:`arx_pass`: its FIR sums run tap by tap over a block
#: (vectorised) while the block's inputs and buffers stay in the L1/L2 cache.
_BLOCK = 2048


@numba.njit(cache=True, nogil=True)
def arx_from_data(a, y, m, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The measured-start ARX recursion, in place.

    ``out`` holds v = Σ_i B_i u_i: set ``out[:m] = y[:m]`` and run
    ``out(t) = v(t) − Σ_k a_k out(t − k)`` for t >= m in place (``a`` monic,
    ``m >= len(a) − 1``); up to order 4 the past lives in scalars.
    """
    n = y.size
    na = a.size
    for t in range(m):
        out[t] = y[t]
    if na > 5:
        for t in range(m, n):
            acc = out[t]
            for k in range(na - 1, 0, -1):
                acc -= a[k] * out[t - k]
            out[t] = acc
        return
    if na == 1:
        return
    a1 = a[1]
    a2 = a[2] if na > 2 else 0.0
    a3 = a[3] if na > 3 else 0.0
    a4 = a[4] if na > 4 else 0.0
    w1 = y[m - 1] if m >= 1 else 0.0
    w2 = y[m - 2] if m >= 2 else 0.0
    w3 = y[m - 3] if m >= 3 else 0.0
    w4 = y[m - 4] if m >= 4 else 0.0
    for t in range(m, n):
        acc = out[t] - a4 * w4 - a3 * w3 - a2 * w2 - a1 * w1
        w4 = w3
        w3 = w2
        w2 = w1
        w1 = acc
        out[t] = acc


@numba.njit(cache=True, nogil=True)
def _fir(c, x, t0, t1, w):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``w = c(q) x`` over the block [t0, t1), x zero before t = 0.

    The terms in the order of ``models._kernels.iir`` (tap 0 first, then
    tap by tap), so the sums are the same to the last bit (for finite x; a
    zero tap, whose terms are exact zeros, is skipped).
    """
    m = t1 - t0
    c0 = c[0]
    wb = w[:m]
    xs = x[t0:t1]
    if c0 == 0.0:  # zero taps (a delay, the predictor's first k) add exact zeros: skip them
        for i in range(m):
            wb[i] = 0.0
    else:
        for i in range(m):
            wb[i] = c0 * xs[i]
    for j in range(1, c.size):
        cj = c[j]
        lo = max(t0, j)
        if lo >= t1 or cj == 0.0:
            continue
        ww = w[lo - t0 : m]  # slices indexed from 0: the loop vectorises
        xx = x[lo - j : t1 - j]
        for t in range(t1 - lo):
            ww[t] += cj * xx[t]


@numba.njit(cache=True, nogil=True, fastmath={"reassoc"})
def _block_sum(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    # reassociated (vectorised); a NaN or inf still comes through
    acc = 0.0
    for i in range(x.size):  # an index loop: ``for v in x`` did not vectorise
        acc += x[i]
    return acc


@numba.njit(cache=True, nogil=True, fastmath={"nnan", "ninf", "nsz"})
def _block_range(x, lo, hi):  # type: ignore[no-untyped-def]  # pragma: no cover
    # min and max, meaningful for finite x (the flags let the compares vectorise)
    for i in range(x.size):
        lo = min(lo, x[i])
        hi = max(hi, x[i])
    return lo, hi


@numba.njit(cache=True, nogil=True)
def _add_stats(x, st, row):  # type: ignore[no-untyped-def]  # pragma: no cover
    if x.size:
        st[row, 0] += _block_sum(x)
        st[row, 1], st[row, 2] = _block_range(x, st[row, 1], st[row, 2])


@numba.njit(cache=True, nogil=True)
def arx_pass(a, bks, r1, rk, pk, y, u, m, sim, pred, eps, first, st):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Simulation, k-step prediction and residuals of an ARX model, one pass.

    Block by block, with ``v = Σ_i B_i u_i`` (``bks`` row i, delay
    included) shared: ``sim`` the measured-start recursion ``A sim = v``
    with ``sim[:m] = y[:m]`` (as :func:`arx_from_data`), ``pred`` the
    k-step predictor ``rk(q) y + Σ_i pk_i(q) u_i`` and ``eps = y − (r1(q) y
    + v)`` the one-step residuals (the FIR filters of
    ``PolynomialModel._predictor_filters``).  ``u`` is (n_inputs, N).
    The sums follow the unfused filters' order term for term.  ``st`` (1 +
    n_inputs rows, zeros then ±inf on entry) receives the sum, min and max
    of eps and of each input from sample ``first`` on, which the residual
    tests centre and scale by (min and max are meaningful only when the
    sum is finite).
    """
    n = y.size
    na = a.size
    nu = u.shape[0]
    v = np.empty(_BLOCK)
    w = np.empty(_BLOCK)
    tmp = np.empty(_BLOCK)
    a1 = a[1] if na > 1 else 0.0
    a2 = a[2] if na > 2 else 0.0
    a3 = a[3] if na > 3 else 0.0
    a4 = a[4] if na > 4 else 0.0
    w1 = 0.0
    w2 = 0.0
    w3 = 0.0
    w4 = 0.0
    for t0 in range(0, n, _BLOCK):
        t1 = min(t0 + _BLOCK, n)
        nb = t1 - t0
        # v = Σ_i B_i u_i, summed input by input as simulate_from_data does
        _fir(bks[0], u[0], t0, t1, v)
        for i in range(1, nu):
            _fir(bks[i], u[i], t0, t1, tmp)
            for t in range(nb):
                v[t] += tmp[t]
        # one-step residuals: ŷ1 = r1 y, then + B_i u_i input by input
        _fir(r1, y, t0, t1, w)
        yb = y[t0:t1]
        eb = eps[t0:t1]
        if nu == 1:
            for t in range(nb):
                eb[t] = yb[t] - (w[t] + v[t])
        else:
            for i in range(nu):
                _fir(bks[i], u[i], t0, t1, tmp)
                for t in range(nb):
                    w[t] += tmp[t]
            for t in range(nb):
                eb[t] = yb[t] - w[t]
        s0 = max(first - t0, 0)
        if s0 < nb:
            _add_stats(eb[s0:], st, 0)
            for i in range(nu):
                _add_stats(u[i][t0 + s0 : t1], st, i + 1)
        # k-step prediction
        _fir(rk, y, t0, t1, w)
        for i in range(nu):
            _fir(pk[i], u[i], t0, t1, tmp)
            for t in range(nb):
                w[t] += tmp[t]
        pb = pred[t0:t1]
        for t in range(nb):
            pb[t] = w[t]
        # the measured-start simulation
        sb = sim[t0:t1]
        start = 0
        while start < nb and t0 + start < m:  # the initial conditions, first block(s) only
            acc = y[t0 + start]
            w4 = w3
            w3 = w2
            w2 = w1
            w1 = acc
            sb[start] = acc
            start += 1
        if na > 5:
            for t in range(t0 + start, t1):
                acc = v[t - t0]
                for k in range(na - 1, 0, -1):
                    acc -= a[k] * sim[t - k]
                sim[t] = acc
        else:
            vv = v[start:nb]
            ss = sb[start:]
            for i in range(nb - start):
                acc = vv[i] - a4 * w4 - a3 * w3 - a2 * w2 - a1 * w1
                w4 = w3
                w3 = w2
                w2 = w1
                w1 = acc
                ss[i] = acc


@numba.njit(cache=True, nogil=True)
def decay_length(den, n, tiny):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Samples T after which the impulse response of 1/den has died out.

    The first T >= order such that h stays below ``tiny·max|h|`` over the last ``order`` samples before T (the state of the
    recursion is then that small); N when it never does.
    """
    order = den.size - 1
    hist = np.zeros(max(order, 1))
    peak = 0.0
    quiet = 0
    for t in range(n):
        acc = 1.0 if t == 0 else 0.0
        for k in range(1, order + 1):
            acc -= den[k] * hist[k - 1]
        for k in range(order - 1, 0, -1):
            hist[k] = hist[k - 1]
        if order > 0:
            hist[0] = acc
        v = abs(acc)
        peak = max(peak, v)
        if v <= tiny * peak:
            quiet += 1
            if quiet >= order and t + 1 >= order:
                return t + 1
        else:
            quiet = 0
    return n


@numba.njit(cache=True, nogil=True)
def impulse(den, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The first n samples of the impulse response of 1/den."""
    order = den.size - 1
    h = np.zeros(n)
    for t in range(n):
        acc = 1.0 if t == 0 else 0.0
        for k in range(1, min(order, t) + 1):
            acc -= den[k] * h[t - k]
        h[t] = acc
    return h
