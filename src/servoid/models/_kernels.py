"""Compiled difference equations of the polynomial models.

One pass per filter, no temporaries.

``scipy.signal.lfilter`` is fast but allocates its output and state for
every call and every input column; a validation of a long record called it
a dozen times.  The kernel here runs ``out = num(q)/den(q) x`` from rest
(direct form, ``den`` monic) and can add into an existing output, so a
multi-input simulation or a predictor fills one array.  Loaded on first
use: ``import servoid.models`` does not import numba.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["all_finite", "filter_into", "iir"]


#: Samples per block: the FIR part of a block is summed tap by tap over slices (a loop
#: the compiler vectorises) while the block stays in the L1/L2 cache.
_BLOCK = 2048


@numba.njit(cache=True, nogil=True)
def iir(num, den, x, out, add):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``out (+)= num(q)/den(q) x`` from rest; ``den[0] == 1``.

    Block by block: ``w = num(q) x`` summed one tap at a time over the
    block, then the recursion ``w(t) −= Σ_k den_k w(t − k)`` over it, its
    past kept apart from ``out`` (so with ``add`` the output may already
    hold other terms).  Up to order 4 that past lives in scalars: the
    recursion's latency, not memory, then bounds a long record.
    """
    nn = num.size
    nd = den.size
    n = x.size
    w = np.empty(_BLOCK)
    hist = np.zeros(max(nd - 1, 4))  # w(t − 1), w(t − 2), …
    d1 = den[1] if nd > 1 else 0.0
    d2 = den[2] if nd > 2 else 0.0
    d3 = den[3] if nd > 3 else 0.0
    d4 = den[4] if nd > 4 else 0.0
    for t0 in range(0, n, _BLOCK):
        t1 = min(t0 + _BLOCK, n)
        m = t1 - t0
        wb = w[:m]
        if nn == 0:
            wb[:] = 0.0
        else:
            c0 = num[0]
            xs = x[t0:t1]
            for t in range(m):
                wb[t] = c0 * xs[t]
        for j in range(1, nn):
            c = num[j]
            lo = max(t0, j)  # samples before t = 0 are zero
            if lo >= t1:
                continue
            ww = w[lo - t0 : m]
            xx = x[lo - j : t1 - j]
            for t in range(t1 - lo):
                ww[t] += c * xx[t]
        if nd > 5:
            for i in range(m):
                acc = wb[i]
                for k in range(nd - 1, 0, -1):
                    acc -= den[k] * hist[k - 1]
                for k in range(nd - 2, 0, -1):
                    hist[k] = hist[k - 1]
                hist[0] = acc
                wb[i] = acc
        elif nd > 1:
            w1, w2, w3, w4 = hist[0], hist[1], hist[2], hist[3]
            for i in range(m):
                # the most recent output last: the other terms are ready earlier
                acc = wb[i] - d4 * w4 - d3 * w3 - d2 * w2 - d1 * w1
                w4 = w3
                w3 = w2
                w2 = w1
                w1 = acc
                wb[i] = acc
            hist[0], hist[1], hist[2], hist[3] = w1, w2, w3, w4
        ob = out[t0:t1]
        if add:
            for i in range(m):
                ob[i] += wb[i]
        else:
            for i in range(m):
                ob[i] = wb[i]


@numba.njit(cache=True, nogil=True, fastmath={"reassoc"})
def all_finite(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether every value is finite, without a boolean temporary.

    Σ x·0 is 0 for finite x and NaN as soon as one value is NaN or ±inf;
    every term is an exact zero, so reassociating the sum (vectorised)
    cannot change it.
    """
    acc = 0.0
    for t in range(x.size):
        acc += x[t] * 0.0
    return acc == 0.0


def filter_into(num: np.ndarray, den: np.ndarray, x: np.ndarray, out: np.ndarray,
                add: bool) -> None:
    """Call :func:`iir` with contiguous float arrays (``den`` monic)."""
    iir(np.ascontiguousarray(num, dtype=np.float64), np.ascontiguousarray(den, dtype=np.float64),
        np.ascontiguousarray(x, dtype=np.float64), out, add)
