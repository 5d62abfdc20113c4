"""Sampled outputs of continuous filters driven by a held, delayed input.

The continuous-time estimators filter sampled signals through continuous
filters ``P_i(p)/D(p)`` (p = d/dt) that share one denominator.  With the
input's behaviour between samples known (a *hold*), the filter's state
at the next sample follows exactly from its state now and the input's
course over the period, the hybrid filtering of Garnier, Gilson & Young
(2008, ch. 1 of Garnier & Wang (eds.), *Identification of Continuous-time
Models from Sampled Data*, Springer):

- ``"zoh"``: the input is held constant over each period (a DAC);
- ``"foh"``: straight lines between the samples;
- ``"bandlimited"``: the cubic through the four nearest samples (two
  samples of look-ahead, harmless offline), for a smooth signal whose
  course between samples is unknown; its error is O((ω·dt)⁴) for a
  component at ω (compare the state-variable filter notes in
  :mod:`servoid.estimate._svf`).

An input delay τ is a shift of that course by τ/dt samples, fractional
included: a period of the delayed input is made of the last part of one
input period and the first part of the next, each a polynomial, and the
propagation over each part is exact (Van Loan's block exponential with a
polynomial generator).  Before the record the input is zero (the filter
starts at rest).

The denominator is realised in companion form in the caller's time unit;
callers scale time so that its coefficients are of order one.
"""

from __future__ import annotations

import math
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from .._errors import DataError

__all__ = ["HOLDS", "Hold", "filter_bank", "piece_transition"]

Hold = Literal["zoh", "foh", "bandlimited"]
HOLDS: tuple[Hold, ...] = ("zoh", "foh", "bandlimited")

_DEGREE = {"zoh": 0, "foh": 1, "bandlimited": 3}


def filter_bank(
    den: NDArray[np.float64],
    numerators: NDArray[np.float64],
    x: NDArray[np.float64],
    h: float,
    hold: Hold,
    delay: float = 0.0,
) -> NDArray[np.float64]:
    """Return ``P_i(p)/D(p)·x(t − delay)`` at the sample instants.

    Parameters
    ----------
    den : ndarray, shape (q + 1,)
        Monic D(p), descending powers, q >= 1.
    numerators : ndarray, shape (r, q + 1)
        P_i(p), descending powers, degree <= q (zero-padded on the left).
    x : ndarray, shape (N,)
        Input samples.
    h : float
        Sample period in the time unit of the coefficients.
    hold : {"zoh", "foh", "bandlimited"}
        The input's course between samples.
    delay : float
        Input delay [samples], >= 0.

    Returns
    -------
    ndarray, shape (N, r)
        Column i is the i-th filter's output, from rest.
    """
    q = den.size - 1
    d_asc = den[::-1][:q]  # D(p) = p^q + Σ_j d_asc[j]·p^j
    a = np.zeros((q, q))
    a[np.arange(q - 1), np.arange(1, q)] = 1.0
    a[-1, :] = -d_asc
    b = np.zeros(q)
    b[-1] = 1.0
    # states are p^j·w, w = x/D; p^q·w = x − Σ_j d_asc[j]·p^j·w is the feed-through
    p_asc = numerators[:, ::-1]
    c = p_asc[:, :q] - p_asc[:, q : q + 1] * d_asc[None, :]
    ff = p_asc[:, q]
    phi, forced, at_samples = _forced(a, b, x, h, hold, delay)
    states = _propagate(phi, forced)
    return states @ c.T + at_samples[:, None] * ff[None, :]


def _forced(
    a: NDArray[np.float64], b: NDArray[np.float64], x: NDArray[np.float64], h: float,
    hold: Hold, delay: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return Φ, the forced term of each period and the delayed input at the samples."""
    coef = _interval_polynomials(x, hold)
    whole = round(delay)
    if abs(delay - whole) <= 1e-9 * max(1.0, delay):
        d, frac = int(whole), 0.0
    else:
        d = math.floor(delay)
        frac = delay - d
    deg = coef.shape[1] - 1
    e_late, g_late = piece_transition(a, b, h, 1.0 - frac, deg)
    late = _taylor(_shifted(coef, d), 0.0)  # period k uses input interval k − d from its start
    forced = late @ g_late.T
    if frac:
        e_early, g_early = piece_transition(a, b, h, frac, deg)
        phi = e_late @ e_early
        early = _taylor(_shifted(coef, d + 1), 1.0 - frac)  # the end of interval k − d − 1
        forced += early @ (e_late @ g_early).T
        at_samples = early[:, 0]
    else:
        phi = e_late
        at_samples = late[:, 0]
    return phi, np.ascontiguousarray(forced), at_samples


def _interval_polynomials(x: NDArray[np.float64], hold: Hold) -> NDArray[np.float64]:
    """Coefficients (ascending in σ ∈ [0, 1]) of the input over each period [k, k + 1]."""
    n = x.size
    if hold == "zoh":
        return x[:, None].copy()
    if hold == "foh":
        slope = np.zeros(n)
        slope[:-1] = np.diff(x)  # the last period lies beyond the record: held
        return np.column_stack([x, slope])
    # cubic through 4 neighbouring samples: nodes −1..2 inside, 0..3 at the start, −2..1 at the end
    out = np.zeros((n, 4))
    if n < 4:
        raise DataError("the band-limited hold needs at least 4 samples; use a longer record")
    inner = np.linalg.inv(np.vander(np.arange(-1.0, 3.0), 4, increasing=True))
    windows = np.lib.stride_tricks.sliding_window_view(x, 4)  # rows x[j−1 .. j+2], j = 1..n−3
    out[1 : n - 2] = windows @ inner.T
    first = np.linalg.inv(np.vander(np.arange(0.0, 4.0), 4, increasing=True))
    out[0] = first @ x[:4]
    last = np.linalg.inv(np.vander(np.arange(-2.0, 2.0), 4, increasing=True))
    out[n - 2] = last @ x[-4:]
    out[n - 1] = out[n - 2] @ _shift_matrix(1.0)  # beyond the record: the same cubic continued
    return out


def _shift_matrix(s: float) -> NDArray[np.float64]:
    """Matrix T with (c @ T) the coefficients of P(σ + s) for a cubic P with coefficients c."""
    t = np.zeros((4, 4))
    for r in range(4):
        for j in range(r + 1):
            t[r, j] = math.comb(r, j) * s ** (r - j)
    return t


def _shifted(coef: NDArray[np.float64], d: int) -> NDArray[np.float64]:
    """Row k = coefficients of interval k − d (zero before the record)."""
    if d == 0:
        return coef
    out = np.zeros_like(coef)
    if d < coef.shape[0]:
        out[d:] = coef[: coef.shape[0] - d]
    return out


def _taylor(coef: NDArray[np.float64], sigma0: float) -> NDArray[np.float64]:
    """Derivatives d^j/dσ^j of each polynomial at σ0, j = 0..deg."""
    deg = coef.shape[1] - 1
    m = np.zeros((deg + 1, deg + 1))  # κ_j = Σ_r c_r · r!/(r−j)! · σ0^(r−j)
    for j in range(deg + 1):
        for r in range(j, deg + 1):
            m[r, j] = math.factorial(r) / math.factorial(r - j) * sigma0 ** (r - j)
    return coef @ m


def piece_transition(
    a: NDArray[np.float64], b: NDArray[np.float64], h: float, length: float, deg: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Transition over a piece and the map from the input's derivatives at its start.

    The input over the piece is Σ_j κ_j·s^j/j! in sample time s; the chain
    κ_j' = κ_{j+1} generates it (the block exponential of Van Loan, "Computing
    integrals involving the matrix exponential", IEEE TAC 23(3), 1978).
    """
    q = a.shape[0]
    big = np.zeros((q + deg + 1, q + deg + 1))
    big[:q, :q] = a * h * length
    big[:q, q] = b * h * length
    if deg:
        big[q + np.arange(deg), q + 1 + np.arange(deg)] = length
    e = _expm(big)
    return e[:q, :q], e[:q, q:]


def _expm(mat: NDArray[np.float64]) -> NDArray[np.float64]:
    """Matrix exponential of a small matrix: scaling and squaring with Taylor terms.

    For the few-state matrices here this is much faster than
    :func:`scipy.linalg.expm` (measured here: 0.5 ms against 12 ms for 5×5 with
    scipy 1.17), which sits in every filter pass.  The scaled matrix has
    1-norm <= 1/4, where 16 Taylor terms leave a truncation error below
    0.25^17/17! ≈ 4e-25 relative; squaring then costs ~s·ε.
    """
    norm = float(np.max(np.sum(np.abs(mat), axis=0)))
    s = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    a = mat / 2.0**s
    term = np.eye(mat.shape[0])
    out = term.copy()
    for k in range(1, 17):
        term = term @ a / k
        out += term
    for _ in range(s):
        out = out @ out
    return out


@numba.njit(cache=True, nogil=True)
def _propagate(phi, forced):  # type: ignore[no-untyped-def]  # pragma: no cover
    n, q = forced.shape
    out = np.empty((n, q))
    x = np.zeros(q)
    xn = np.empty(q)
    for k in range(n):
        for i in range(q):
            out[k, i] = x[i]
        for i in range(q):
            s = forced[k, i]
            for j in range(q):
                s += phi[i, j] * x[j]
            xn[i] = s
        for i in range(q):
            x[i] = xn[i]
    return out
