"""Compiled kernels of the prediction-error search: filters and a stability test.

Every signal of the predictor lives in a *padded* buffer: ``pad`` zeros,
then the N samples.  A filter then reads its past through plain negative
offsets without a bounds test, and the zeros are the "signals before
t = 0 are zero" convention of the zero-initial-condition predictor.  The
same buffers go straight into :func:`servoid.estimate._gram.lagged_gram`'s
kernels, whose lags also reach into the padding.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["EMPTY", "ar_filter", "filt", "is_stable", "reflect", "sum_squares"]

#: A zero-length pulse: "no initial-condition pulse" for :func:`filt`.
EMPTY = np.zeros(0)


@numba.njit(cache=True, nogil=True)
def filt(num, den, x, out, pad, shift, pulse):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``out = (q^{-shift}·num(q)·x + pulse)/den(q)`` from rest, in padded buffers.

    ``den`` is monic; ``pulse[k]`` is added to the numerator sum at t = k (it
    sets an initial condition).  Needs ``pad >= shift + len(num) - 1`` and
    ``pad >= len(den) - 1`` with ``out[:pad] == 0``.
    """
    nn = num.size
    nd = den.size
    np_ = pulse.size
    n = x.size
    for t in range(pad, n):
        acc = 0.0
        base = t - shift
        for j in range(nn):
            acc += num[j] * x[base - j]
        if t - pad < np_:
            acc += pulse[t - pad]
        for k in range(1, nd):
            acc -= den[k] * out[t - k]
        out[t] = acc


@numba.njit(cache=True, fastmath=True, nogil=True)
def ar_filter(a, x, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``out = x / a(q)`` from rest at index 0 (``a`` monic, any length).

    Unlike :func:`filt` it needs no padding: the recursion only reads
    ``out[t − k]`` for ``k <= t``, so an AR polynomial longer than the
    predictor's padding is fine.  ``fastmath`` lets the compiler vectorise
    the sum over k (only its rounding changes); the recursion over t stays
    sequential.
    """
    p = a.size - 1
    for t in range(x.size):
        acc = x[t]
        for k in range(1, min(p, t) + 1):
            acc -= a[k] * out[t - k]
        out[t] = acc


@numba.njit(cache=True, nogil=True)
def sum_squares(x, lo):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ_{t >= lo} x(t)² in one thread.

    Not ``np.dot``: a multithreaded BLAS dot on a loaded two-core machine
    can wait milliseconds for its second thread, more than the whole sum.
    """
    acc = 0.0
    for t in range(lo, x.size):
        acc += x[t] * x[t]
    return acc


@numba.njit(cache=True, nogil=True)
def is_stable(poly):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether the monic polynomial in q⁻¹ has all roots strictly inside |z| = 1.

    Schur–Cohn step-down recursion: the polynomial is stable iff every
    reflection coefficient has magnitude < 1 (Söderström & Stoica, *System
    Identification*, 1989, Complement C6.1).
    """
    p = poly.copy()
    n = p.size - 1
    while n > 0:
        k = p[n]
        if not abs(k) < 1.0:
            return False
        scale = 1.0 - k * k
        q = np.empty(n)
        for i in range(n):
            q[i] = (p[i] - k * p[n - i]) / scale
        p = q
        n -= 1
    return True


def reflect(poly: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """Reflect the roots outside the unit circle to 1/conj(z); count them.

    The polynomial is monic in q⁻¹; roots exactly on the circle are left
    where they are (their reflection is themselves).
    """
    if poly.size < 2 or is_stable(poly):
        return poly, 0
    roots = np.roots(poly)
    outside = np.abs(roots) > 1.0
    count = int(outside.sum())
    if count == 0:
        return poly, 0
    roots[outside] = 1.0 / np.conj(roots[outside])
    return np.real(np.poly(roots)), count
