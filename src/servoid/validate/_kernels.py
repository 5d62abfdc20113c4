"""Compiled passes of the validation.

The measured-start ARX simulation, its one-pass companion and the free
responses.

They replace chains of ``lfilter`` calls and N-sample temporaries:

* :func:`arx_from_data` runs ``A y_sim = Σ B_i u_i`` with the first ``m``
  samples of y as the initial conditions, writing y_sim once;
* :func:`arx_pass` gives, for ``validate``, that simulation, the k-step
  prediction, the one-step residuals, the residuals' sum and range and
  the moments of the fit metrics in one blocked pass (six filter passes
  and eight reductions before);
* :func:`add_moments` forms the moments every fit metric is a ratio of,
  and :func:`error_pass` those of an output-error model with its
  residuals and their sum and range, in one pass each;
* :func:`decay_length` finds where the impulse response h of ``1/den``
  has died out, so the free responses (the lags of h) and their least
  squares fit need only that many rows instead of N.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["MOMENTS", "add_moments", "add_signal_stats", "arx_from_data", "arx_pass",
           "decay_length", "error_pass", "impulse"]

#: Entries of a moments row (:func:`add_moments`): the count, the means of y and of
#: d = y − ŷ less the shifts in the last two entries, Σ(y − ȳ)², Σ(d − d̄)², Σd², Σy²,
#: and the shifts (the first samples of y and d).
MOMENTS = 9

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


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
def _block_moments(y, h, acc):  # type: ignore[no-untyped-def]  # pragma: no cover
    # A block's moments about its own means (two sweeps of the block, which is in cache),
    # merged into ``acc`` by Chan, Golub & LeVeque's update (1983). The values are first
    # shifted by the first sample of y and of d (kept in ``acc``), so a signal that sits
    # far from zero (1e8 ± 1) keeps the means, and so the merge, exact to its spread: a
    # running mean near 1e8 would carry a rounding of 1e-8 into every merge. As exact as
    # two passes over the record about the global means, for one pass's memory traffic.
    # Reassociated (vectorised); a NaN or inf still comes through to the means.
    nb = y.size
    if nb == 0:
        return
    if acc[0] == 0.0:
        acc[7] = y[0]
        acc[8] = y[0] - h[0]
    ky = acc[7]
    kd = acc[8]
    sy = 0.0
    sd = 0.0
    for i in range(nb):
        v = y[i]
        sy += v - ky
        sd += (v - h[i]) - kd
    my = sy / nb
    md = sd / nb
    qy = 0.0
    qd = 0.0
    e2 = 0.0
    p = 0.0
    for i in range(nb):
        v = y[i]
        d = v - h[i]
        x = (v - ky) - my
        z = (d - kd) - md
        qy += x * x
        qd += z * z
        e2 += d * d
        p += v * v
    na = acc[0]
    n = na + nb
    dy = my - acc[1]
    dd = md - acc[2]
    w = nb / n
    acc[1] += dy * w
    acc[2] += dd * w
    acc[3] += qy + dy * dy * na * w
    acc[4] += qd + dd * dd * na * w
    acc[5] += e2
    acc[6] += p
    acc[0] = n


@numba.njit(cache=True, nogil=True)
def add_moments(y, h, acc):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Merge the moments of measured y and model ŷ = h into ``acc``.

    ``acc`` is a zeroed row of :data:`MOMENTS` entries (or one that holds
    the moments of other samples): the count, the means of y and of d = y
    − ŷ less their shifts, Σ(y − ȳ)², Σ(d − d̄)², Σd², Σy², and the
    shifts (the first samples of y and d).  One pass over blocks of 1024
    samples; the means are NaN or ±inf when a value is not finite (or a
    block's sum overflows, beyond ~1e305).
    """
    _moments_between(y, h, 0, y.size, acc)


@numba.njit(cache=True, nogil=True)
def _moments_between(y, h, lo, hi, acc):  # type: ignore[no-untyped-def]  # pragma: no cover
    # the moments of samples lo…hi − 1, merged into acc in blocks of 1024 from lo
    for t0 in range(lo, hi, 1024):
        t1 = min(t0 + 1024, hi)
        _block_moments(y[t0:t1], h[t0:t1], acc)


@numba.njit(cache=True, nogil=True)
def add_signal_stats(x, st, row):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Add the sum of x to ``st[row, 0]`` and widen its range in columns 1–2.

    One pass in blocks of :data:`_BLOCK` (error ~ε·(2048 + N/2048)); min
    and max are meaningful only when the sum is finite.
    """
    for t0 in range(0, x.size, _BLOCK):
        _add_stats(x[t0 : min(t0 + _BLOCK, x.size)], st, row)


@numba.njit(cache=True, nogil=True)
def error_pass(y, h, first, e, mo, st):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Residuals, fit moments and their sum and range, one pass.

    From sample ``first`` on: ``e[t − first] = y[t] − h[t]`` (as numpy
    subtracts), the moments of (y, h) merged into ``mo`` as by
    :func:`add_moments`, and the sum, min and max of e into ``st[0]`` as by
    :func:`add_signal_stats`.
    """
    n = y.size
    for t0 in range(first, n, _BLOCK):
        t1 = min(t0 + _BLOCK, n)
        eb = e[t0 - first : t1 - first]
        yb = y[t0:t1]
        hb = h[t0:t1]
        for i in range(t1 - t0):
            eb[i] = yb[i] - hb[i]
        _moments_between(y, h, t0, t1, mo)
        _add_stats(eb, st, 0)


@numba.njit(cache=True, nogil=True)
def arx_pass(a, bks, r1, rk, pk, y, u, m, sim, pred, eps, first, st, p0, mo):  # type: ignore[no-untyped-def]  # pragma: no cover
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
    sum is finite).  ``mo`` (two zeroed rows of :data:`MOMENTS`) receives
    the moments of (y, sim) from sample ``first`` on and of (y, pred) from
    ``p0`` on, for the fit metrics.
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
        # k-step prediction, formed in place
        pb = pred[t0:t1]
        _fir(rk, y, t0, t1, pb)
        for i in range(nu):
            _fir(pk[i], u[i], t0, t1, tmp)
            for t in range(nb):
                pb[t] += tmp[t]
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
        # the fit metrics' moments, while the block is in cache
        _moments_between(y, sim, max(first, t0), t1, mo[0])
        _moments_between(y, pred, max(p0, t0), t1, mo[1])


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
