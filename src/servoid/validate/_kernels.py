"""Compiled passes of the validation.

The measured-start ARX simulation and the free responses.

Both replace chains of ``lfilter`` calls and N-sample temporaries:

* :func:`arx_from_data` runs ``A y_sim = Σ B_i u_i`` with the first ``m``
  samples of y as the initial conditions, writing y_sim once;
* :func:`decay_length` finds where the impulse response h of ``1/den``
  has died out, so the free responses (the lags of h) and their least
  squares fit need only that many rows instead of N.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["arx_from_data", "decay_length", "impulse"]


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
