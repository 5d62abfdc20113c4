"""Compiled inner loops of the one-step fit (numba).

The one-step fit evaluates its criterion a few hundred times per record:
build the exact sampled closed loop for θ (:mod:`._sampling`), simulate it
from the reference, and project out the rest level and output offset
(:func:`._onestep._level_fit`).  In numpy each of these costs tens of
microseconds of Python for a few microseconds of arithmetic; here each is
one compiled call, so a fleet of records is bound by the arithmetic.

The kernels do the same arithmetic as the numpy code they replace (the
same Taylor series for the matrix exponential, the same direct-form
filter as :func:`scipy.signal.lfilter`, the same least-squares problem),
so results agree to rounding.  Inner helpers trust their inputs: the
callers check them.

numba compiles each kernel on its first call and caches it on disk
(``cache=True``); a Dask worker loads the cache instead of compiling.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["first_order_cost", "hold_weights", "level_residuals", "lfilter_pair",
           "polynomial_hold", "tustin_costs", "warm_up"]

#: numba may reorder sums (vectorised reductions) but keeps NaN and inf semantics.
_REORDER = {"reassoc", "contract"}
# status codes of polynomial_hold
OK, BAD_COEFFICIENTS, STATIC, IMPROPER, OVERFLOW = range(5)


@numba.njit(cache=True, nogil=True)
def _matmul(a, b):  # type: ignore[no-untyped-def]  # pragma: no cover
    n, m = a.shape
    p = b.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(p):
                    out[i, j] += aik * b[k, j]
    return out


@numba.njit(cache=True, nogil=True)
def _expm(mat):  # type: ignore[no-untyped-def]  # pragma: no cover
    # servoid.estimate._hybrid._expm: scaling to 1-norm <= 1/4, 16 Taylor terms, squaring
    n = mat.shape[0]
    norm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(mat[i, j])
        norm = max(norm, col)
    s = 0
    if norm > 0.25:
        s = max(0, math.ceil(math.log2(norm / 0.25)))
    a = mat / 2.0**s
    term = np.eye(n)
    out = np.eye(n)
    for k in range(1, 17):
        term = _matmul(term, a) / k
        out += term
    for _ in range(s):
        out = _matmul(out, out)
    return out


@numba.njit(cache=True, nogil=True)
def polynomial_hold(num, den, dt, weights, m_min, m_max):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Sampled model of num(s)/den(s) for a polynomial input course.

    The arithmetic of :func:`servoid.plants.ehsa._sampling._polynomial_hold`:
    `weights` is ``j!·V⁻¹`` for the nodes ``m_min … m_max`` (V their
    Vandermonde matrix), degree = m_max − m_min.  Returns ``(b, a, status)``:
    numerator padded to the denominator's length (the form
    :func:`scipy.signal.lfilter` takes), monic denominator, and a status
    (``OK`` or what is wrong).
    """
    empty = np.zeros(0)
    for v in den:
        if not math.isfinite(v):
            return empty, empty, BAD_COEFFICIENTS
    for v in num:
        if not math.isfinite(v):
            return empty, empty, BAD_COEFFICIENTS
    i0 = 0
    while i0 < den.size and den[i0] == 0.0:
        i0 += 1
    j0 = 0
    while j0 < num.size and num[j0] == 0.0:
        j0 += 1
    if i0 == den.size or j0 == num.size:
        return empty, empty, BAD_COEFFICIENTS
    den = den[i0:]
    num = num[j0:]
    n = den.size - 1
    if n < 1:
        return empty, empty, STATIC
    if num.size > den.size:
        return empty, empty, IMPROPER
    # companion form in time measured in samples (s = s'/dt)
    dd = np.empty(n + 1)
    nn = np.zeros(n + 1)
    for i in range(n + 1):
        dd[i] = den[i] * dt**i
    off = n + 1 - num.size
    for i in range(num.size):
        nn[off + i] = num[i] * dt ** (off + i)
    lead = dd[0]
    for i in range(n + 1):
        nn[i] /= lead
        dd[i] /= lead
    d = nn[0]
    degree = m_max - m_min
    size = n + degree + 1
    big = np.zeros((size, size))
    for i in range(n - 1):
        big[i, i + 1] = 1.0
    for j in range(n):
        big[n - 1, j] = -dd[n - j]
    big[n - 1, n] = 1.0
    for i in range(degree):
        big[n + i, n + 1 + i] = 1.0
    e = _expm(big)
    phi = np.ascontiguousarray(e[:n, :n])
    g = np.ascontiguousarray(e[:n, n:])
    for v in e.ravel()[: n * size]:
        if not math.isfinite(v):
            return empty, empty, OVERFLOW
    c = np.empty(n)
    for i in range(n):
        c[i] = nn[n - i] - d * dd[n - i]
    gammas = _matmul(g, weights)
    advance = max(m_max - 1, 0)
    length = n + m_max - m_min + 1
    n_rows = length + m_max + 1
    rows = np.empty((n_rows, n))
    rows[0] = c
    for k in range(1, n_rows):
        for j in range(n):
            acc = 0.0
            for i in range(n):
                acc += rows[k - 1, i] * phi[i, j]
            rows[k, j] = acc
    table = _matmul(rows, gammas)
    h = np.zeros(length + 1)
    for col in range(degree + 1):
        m = m_min + col
        for jp in range(length + 1):
            ex = jp - advance - 1 + m
            if 0 <= ex < n_rows:
                h[jp] += table[ex, col]
    h[advance] += d
    # D = det(zI − Φ) from Φ's eigenvalues (numpy.poly), N = first terms of D·h
    eig = np.linalg.eigvals(phi.astype(np.complex128))
    poly = np.zeros(n + 1, dtype=np.complex128)
    poly[0] = 1.0
    for k in range(n):
        for i in range(k + 1, 0, -1):
            poly[i] = poly[i] - eig[k] * poly[i - 1]
    size_out = max(length, n + 1)
    a_out = np.zeros(size_out)
    for i in range(n + 1):
        a_out[i] = poly[i].real
    b_out = np.zeros(size_out)
    for k in range(length):
        acc = 0.0
        for i in range(min(k, n) + 1):
            acc += a_out[i] * h[k - i]
        b_out[k] = acc
    return b_out, a_out, OK


@numba.njit(cache=True, nogil=True)
def _orders(b, a):  # type: ignore[no-untyped-def]  # pragma: no cover
    # lengths without trailing zeros: the sampled models pad a with poles at z = 0
    mb = b.size
    while mb > 1 and b[mb - 1] == 0.0:
        mb -= 1
    ma = a.size
    while ma > 1 and a[ma - 1] == 0.0:
        ma -= 1
    return mb, ma


@numba.njit(cache=True, nogil=True)
def _fir(b, mb, x):  # type: ignore[no-untyped-def]  # pragma: no cover
    n = x.size
    v = np.zeros(n)
    for i in range(min(mb, n)):
        bi = b[i]
        head = v[i:]  # slices, so that numba sees no overlap and vectorises the loop
        lagged = x[: n - i]
        for k in range(n - i):
            head[k] += bi * lagged[k]
    return v


@numba.njit(cache=True, nogil=True)
def _all_pole(a, ma, v):  # type: ignore[no-untyped-def]  # pragma: no cover
    # y(k) = v(k) − Σ a_i·y(k − i), in place; the newest output enters last (a shorter chain)
    n = v.size
    if ma == 4:  # third order, the reduced loop: the outputs stay in registers
        a1, a2, a3 = a[1], a[2], a[3]
        y1 = y2 = y3 = 0.0
        for k in range(n):
            y0 = (v[k] - a3 * y3 - a2 * y2) - a1 * y1
            v[k] = y0
            y3, y2, y1 = y2, y1, y0
        return v
    for k in range(n):
        acc = v[k]
        for i in range(min(ma - 1, k), 0, -1):
            acc -= a[i] * v[k - i]
        v[k] = acc
    return v


@numba.njit(cache=True, nogil=True)
def lfilter_pair(b, a, x):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``lfilter(b, a, x)`` and ``lfilter(b, a, ones)`` (a[0] = 1, same lengths).

    As the FIR ``b`` followed by the all-pole ``1/a``: the sampled models
    carry many poles at z = 0 (trailing zeros of ``a``), which this form
    skips, where lfilter's direct form II transposed pays for them.
    """
    mb, ma = _orders(b, a)
    n = x.size
    ones = np.empty(n)
    acc = 0.0
    for k in range(n):
        if k < mb:
            acc += b[k]
        ones[k] = acc
    return _all_pole(a, ma, _fir(b, mb, x)), _all_pole(a, ma, ones)


@numba.njit(cache=True, nogil=True, fastmath=_REORDER)
def level_residuals(b, a, r, y, s0, level):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Output error from sample `s0` with the rest level and output offset projected out.

    The least-squares problem of :func:`servoid.plants.ehsa._onestep._level_fit`
    for one record, solved in closed form (a regression on the decay of the
    step response with an intercept).  Returns ``(e[s0:], level, offset)``,
    e a view of the one record-length buffer the simulation was formed in
    (with the step response, 2 N × 8 bytes in all).
    """
    n = r.size
    sim, step = lfilter_pair(b, a, r)
    e = sim  # the error overwrites the simulation: no third record-length array
    check = 0.0
    for k in range(n):
        e[k] = y[k] - sim[k]
        check += 0.0 * step[k]  # NaN once any step sample is not finite
    lv = 0.0
    off = 0.0
    if level and check == 0.0:
        last = step[n - 1]
        # scaled by their largest values, so that a diverging trial model (outputs near the
        # overflow limit) still gives finite sums, as an SVD-based least squares would
        sd = 0.0
        se = 0.0
        for k in range(n):
            sd = max(sd, abs(last - step[k]))
            if k >= s0:
                se = max(se, abs(e[k]))
        sd = sd if sd > 0.0 else 1.0
        se = se if se > 0.0 else 1.0
        head = 0.0
        tail = 0.0
        em = 0.0
        dm = 0.0
        for k in range(s0):
            dk = (last - step[k]) / sd
            head += dk * dk
        for k in range(s0, n):
            dk = (last - step[k]) / sd
            tail += dk * dk
            em += e[k] / se
            dm += dk
        cnt = n - s0
        em /= cnt
        dm /= cnt
        if tail < 1e-6 * (head + tail):  # the decay is over before s0: the offset alone
            off = em * se
        else:
            sdd = 0.0
            sde = 0.0
            for k in range(s0, n):
                dk = (last - step[k]) / sd - dm
                sdd += dk * dk
                sde += dk * (e[k] / se - em)
            slope = sde / sdd if sdd > 0.0 else 0.0
            lv = slope * se / sd
            off = (em - slope * dm) * se
        for k in range(s0, n):  # in place: each sample is read before it is written
            e[k] = e[k] - lv * (last - step[k]) - off
        return e[s0:], lv, off
    return e[s0:], lv, off


@numba.njit(cache=True, nogil=True)
def tustin_costs(nums, dens, r, y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ (y − lfilter(b_i, a_i, r))² for each model i (rows of `nums`, `dens`, a[0] = 1)."""
    out = np.empty(nums.shape[0])
    for j in range(nums.shape[0]):
        b = nums[j]
        a = dens[j]
        mb, ma = _orders(b, a)
        sim = _all_pole(a, ma, _fir(b, mb, r))
        total = 0.0
        for k in range(r.size):
            d = y[k] - sim[k]
            total += d * d
        out[j] = total
    return out


@numba.njit(cache=True, nogil=True)
def first_order_cost(p, g, r, y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ (y − ŷ)² for ŷ(k) = p·ŷ(k−1) + g·r(k−1) from rest (``lfilter([0, g], [1, −p], r)``)."""
    total = 0.0
    state = 0.0  # g·r(k−1) + p·ŷ(k−1): lfilter's delay line
    for k in range(r.size):
        d = y[k] - state
        total += d * d
        state = g * r[k] + p * state
    return total


def warm_up() -> None:
    """Call every kernel once on tiny inputs (loads numba's cache, or compiles)."""
    b, a = np.array([0.5, 0.0]), np.array([1.0, -0.5])
    x = np.ones(4)
    polynomial_hold(np.array([1.0]), np.array([1.0, 1.0]), 0.1, hold_weights(0, 1), 0, 1)
    level_residuals(b, a, x, x, 1, True)
    tustin_costs(b[None, :], a[None, :], x, x)
    first_order_cost(0.5, 0.5, x, x)


def hold_weights(m_min: int, m_max: int) -> NDArray[np.float64]:
    """``j!·V⁻¹`` for the interpolation nodes ``m_min … m_max``."""
    nodes = np.arange(m_min, m_max + 1, dtype=float)
    degree = m_max - m_min
    coef = np.linalg.inv(np.vander(nodes, degree + 1, increasing=True))
    factorial = np.array([math.factorial(j) for j in range(degree + 1)], dtype=float)
    return np.ascontiguousarray(factorial[:, None] * coef)
