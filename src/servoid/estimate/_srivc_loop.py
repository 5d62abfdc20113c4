"""Closed-loop instruments for CLSRIVC: the noise-free input of the loop.

Two routes to the input the loop would apply without noise, û:

- the digital controller C is known (the loop ``u = C·(r − y)``):
  ``û = C/(1 + C·G_d)·r`` with G_d the exact ZOH equivalent of the current
  plant estimate and its delay (Gilson, Garnier, Young & Van den Hof 2008,
  ch. 5 of Garnier & Wang (eds.), *Identification of Continuous-time Models
  from Sampled Data*);
- the controller is unknown: û is the least-squares projection of u on
  r(t), …, r(t − M), a causal FIR filter of order M (Forssell & Ljung, "A
  projection method for closed-loop system identification", IEEE TAC
  45(11), 2000).  The noise does not reach r, so û is free of it up to the
  O(M/N) estimation error of the filter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..models import TransferFunction
from ._hybrid import piece_transition

__all__ = ["fir_projection", "loop_sensitivity", "projection_order", "zoh_plant"]


def loop_sensitivity(controller: TransferFunction, a: NDArray[np.float64],
                     b: NDArray[np.float64], h: float, delay: float) -> TransferFunction:
    """Return C/(1 + C·G_d), the map r → u of the loop with the plant B/A.

    ``a``, ``b`` are the plant's coefficients in a time unit where the
    sample period is ``h``; the z-domain result does not depend on that unit.
    ``delay`` is in samples.
    """
    assert controller.dt is not None
    num, den = zoh_plant(a, b, h, delay)
    return controller.feedback(TransferFunction(num, den, controller.dt))


def zoh_plant(a: NDArray[np.float64], b: NDArray[np.float64], h: float,
              delay: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator in z of the ZOH equivalent of ``B(p)/A(p)·e^{−p·delay·h}``."""
    n = a.size - 1
    a_asc = a[::-1][:n]
    b_asc = np.concatenate([b[::-1], np.zeros(n + 1 - b.size)])
    comp = np.zeros((n, n))
    comp[np.arange(n - 1), np.arange(1, n)] = 1.0
    comp[-1, :] = -a_asc
    unit = np.zeros(n)
    unit[-1] = 1.0
    c = b_asc[:n] - b_asc[n] * a_asc
    d = b_asc[n]
    whole = round(delay)
    if abs(delay - whole) <= 1e-9 * max(1.0, delay):
        frac = 0.0
    else:
        whole = math.floor(delay)
        frac = delay - whole
    if frac == 0.0:
        phi, gamma = piece_transition(comp, unit, h, 1.0, 0)
        a_d, b_d, c_d, d_d = phi, gamma[:, 0], c, d
    else:  # the previous input drives the first part of each period: one more state
        e1, g1 = piece_transition(comp, unit, h, frac, 0)
        e2, g2 = piece_transition(comp, unit, h, 1.0 - frac, 0)
        a_d = np.zeros((n + 1, n + 1))
        a_d[:n, :n] = e2 @ e1
        a_d[:n, n] = e2 @ g1[:, 0]
        b_d = np.concatenate([g2[:, 0], [1.0]])
        c_d, d_d = np.concatenate([c, [d]]), 0.0
    den = np.real(np.poly(np.linalg.eigvals(a_d)))
    # C(zI − A)⁻¹B = (det(zI − A + BC) − det(zI − A))/det(zI − A), as scipy's ss2tf
    num = np.real(np.poly(np.linalg.eigvals(a_d - np.outer(b_d, c_d)))) + (d_d - 1.0) * den
    return num, np.concatenate([den, np.zeros(whole)])


def projection_order(shortest: int) -> int:
    """FIR order M of the r → u projection: long enough for a loop, short against N.

    M = N/20 within [20, 200] (N the shortest segment): 100 samples at N = 2000,
    which covers the loop's settling in the tests (~75 samples) and keeps the
    filter's estimation error, O(M/N), at a few per cent of the noise.
    """
    return int(min(200, max(20, shortest // 20)))


def fir_projection(pairs: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
                   order: int) -> list[NDArray[np.float64]]:
    """Fit one causal FIR r → u over all (r, u) segments; return its output per segment."""
    gram = np.zeros((order + 1, order + 1))
    cross = np.zeros(order + 1)
    for r, u in pairs:
        g, c = lagged_normal_equations(r, u, order)
        gram += g
        cross += c
    # the normal equations: only the fitted û = R·ĥ is used, and RᵀR of lagged copies of
    # one signal comes from its lagged products in O(N·M), never forming R
    d = np.sqrt(np.diag(gram))
    d[d == 0.0] = 1.0
    scaled = gram / np.outer(d, d) + 1e-12 * np.eye(d.size)  # a whisper of ridge: rank safety
    coef = np.linalg.solve(scaled, cross / d) / d
    return [np.convolve(r, coef)[: r.size] for r, _ in pairs]


def lagged_normal_equations(
    r: NDArray[np.float64], u: NDArray[np.float64], order: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """RᵀR and Rᵀu for the columns r(t − k), k = 0..order, zero before the record."""
    n = r.size
    gram = np.zeros((order + 1, order + 1))
    for lag in range(min(order, n - 1) + 1):
        # Σ_{t=j}^{N−1} r(t − j + lag)·r(t − j) for the column pair (j − lag, j)
        partial = np.concatenate([[0.0], np.cumsum(r[: n - lag] * r[lag:])])
        j = np.arange(lag, order + 1)
        values = partial[np.clip(n - j, 0, n - lag)]
        gram[j - lag, j] = values
        gram[j, j - lag] = values
    cross = np.array([r[: n - k] @ u[k:] if k < n else 0.0 for k in range(order + 1)])
    return gram, cross
