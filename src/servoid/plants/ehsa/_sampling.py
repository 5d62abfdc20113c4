"""Exact sampled models of a continuous closed loop for a stated input course.

The one-step fit compares samples of the measured output with samples of
the continuous loop's response.  What those samples are depends on how
the reference ran between its samples and on what the rig did to the
output before servoid saw it:

- ``"zoh"``: the reference is a staircase held over each period (a DAC
  command).  Exact: the zero-order-hold equivalent.  When the output went
  through an analog anti-alias filter ``A(s)`` before an ADC at
  ``q``·f_s and servoid's FIR decimation by q (:func:`servoid.data.decimate`)
  while the reference did not (it is the command itself, subsampled), the
  model is that chain: ``A(s)·H(s)`` driven by the staircase, sampled at
  ``q``·f_s, filtered by the same zero-phase FIR and kept every q-th sample.
- ``"foh"``: straight lines between the samples.
- ``"bandlimited"``: a smooth reference read back through the same filter
  and decimation as the output, so both share them and only ``H(s)``
  relates the two band-limited signals.  Its course between samples is
  taken as the 7th-degree polynomial through the eight nearest samples
  (Lagrange interpolation, error O((ω·dt)⁸) for a component at ω, which
  approaches the band-limited sinc interpolation; the cubic of
  :mod:`servoid.estimate._hybrid` left a 0.3 % bias on δ_hp for the
  unloaded actuator at ω_hp·dt = 0.9).

Each period's state transition for a polynomial input course is exact
(Van Loan's block exponential, :func:`servoid.estimate._hybrid.piece_transition`).
The sampled model is LTI; it is returned as a causal transfer function
``G'(z)`` at the data rate with an *advance* L >= 0: ``y(k) = G'(q)·r(k + L)``
(the band-limited course and the zero-phase FIR look ahead).  Its
denominator is the characteristic polynomial of the one-period transition
(padded with poles at z = 0), its numerator the first coefficients of
``D(q⁻¹)·g(q⁻¹)`` with g the impulse response, exact once the look-ahead
has passed: the tail of g obeys D's recursion.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..._errors import ModelError
from ..._lazy import signal as sps
from ...estimate import piece_transition
from ...models import TransferFunction
from . import _kernels

__all__: list[str] = []

Hold = Literal["zoh", "foh", "bandlimited"]
HOLDS: tuple[Hold, ...] = ("zoh", "foh", "bandlimited")

#: Degree of the band-limited course (8 nodes, 3 samples behind and 4 ahead).
BANDLIMITED_DEGREE = 7
_FIR_SPAN = 20  # servoid.data.decimate: firwin(20·q + 1, 1/q, hamming)
_STATUS = {
    _kernels.BAD_COEFFICIENTS: "the closed-loop model has non-finite or vanishing coefficients: "
                               "the parameters left the range where the plant structure is "
                               "defined",
    _kernels.STATIC: "the closed loop has no dynamics (a static gain): nothing to sample",
    _kernels.IMPROPER: "the closed loop is improper (more zeros than poles): it cannot be "
                       "sampled; check the plant structure's lag parameters",
    _kernels.OVERFLOW: "the sampled closed loop is not finite over one sample period: the "
                       "parameters left the range where the plant structure can be sampled "
                       "(an anti_alias filter that does not match the data, or a poor theta0, "
                       "can drive them there)",
}


@lru_cache(maxsize=8)
def decimation_taps(q: int) -> NDArray[np.float64]:
    """Return the FIR that :func:`servoid.data.decimate` applies (its ``"fir"`` type)."""
    taps = np.asarray(sps.firwin(_FIR_SPAN * q + 1, 1.0 / q, window="hamming"), dtype=float)
    taps.setflags(write=False)
    return taps


def sampled_loop(
    closed: TransferFunction,
    dt: float,
    hold: Hold,
    *,
    anti_alias: TransferFunction | None = None,
    decimation: int = 1,
) -> tuple[TransferFunction, int]:
    """Return the sampled model ``G'`` and its advance L of a continuous loop.

    ``y(k) = G'(q)·r(k + L)``; see the module docstring for the holds and
    the rig chain (`anti_alias`, `decimation`), which only ``"zoh"`` takes.
    """
    return sampled_arrays(np.asarray(closed.num, float), np.asarray(closed.den, float), dt,
                          hold, anti_alias=anti_alias, decimation=decimation)


def sampled_arrays(
    num: NDArray[np.float64],
    den: NDArray[np.float64],
    dt: float,
    hold: Hold,
    *,
    anti_alias: TransferFunction | None = None,
    decimation: int = 1,
) -> tuple[TransferFunction, int]:
    """:func:`sampled_loop` of ``num(s)/den(s)`` given as arrays (descending powers)."""
    if hold != "zoh" and (anti_alias is not None or decimation > 1):
        raise ModelError(
            f"the anti-alias filter and decimation of the output enter the model only for a "
            f"staircase reference (hold 'zoh'); with hold {hold!r} the reference was read back "
            "through the same chain as the output and the chain cancels"
        )
    if anti_alias is not None:
        num, den = np.polymul(num, anti_alias.num), np.polymul(den, anti_alias.den)
    if hold == "zoh":
        return _chain(num, den, dt, decimation)
    return _polynomial_hold(num, den, dt, 1 if hold == "foh" else BANDLIMITED_DEGREE)


def sampled_coefficients(
    num: NDArray[np.float64],
    den: NDArray[np.float64],
    dt: float,
    hold: Hold,
    *,
    anti_alias: TransferFunction | None = None,
    decimation: int = 1,
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """:func:`sampled_arrays` as ``(b, a, advance)`` for lfilter, without a TransferFunction.

    ``a`` is monic and ``b`` as long as ``a``: ``lfilter(b, a, r)`` simulates
    the model.  The fits' inner loops call this at every step.
    """
    if hold == "zoh" or anti_alias is not None or decimation > 1:
        model, advance = sampled_arrays(num, den, dt, hold, anti_alias=anti_alias,
                                        decimation=decimation)
        b = np.concatenate([np.zeros(model.den.size - model.num.size), model.num])
        return b, np.asarray(model.den, dtype=float), advance
    return polynomial_hold_arrays(num, den, dt, 1 if hold == "foh" else BANDLIMITED_DEGREE)


def _realise(num: NDArray[np.float64], den: NDArray[np.float64],
             unit: float) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                   NDArray[np.float64], float]:
    """Companion form of num/den in time measured in `unit` seconds: (A, b, c, d)."""
    den, num = _leading(_finite(den)), _leading(_finite(num))
    n = den.size - 1
    if n < 1:
        raise ModelError(_STATUS[_kernels.STATIC])
    if num.size > den.size:
        raise ModelError(_STATUS[_kernels.IMPROPER])
    scale = unit ** np.arange(n + 1)  # s = s'/unit: the s^(n−i) coefficient gains unit^i
    dd = den * scale
    nn = np.concatenate([np.zeros(n + 1 - num.size), num]) * scale
    nn, dd = nn / dd[0], dd / dd[0]
    d = float(nn[0])
    a = np.zeros((n, n))
    a[np.arange(n - 1), np.arange(1, n)] = 1.0
    a[-1, :] = -dd[::-1][:n]
    b = np.zeros(n)
    b[-1] = 1.0
    c = (nn - d * dd)[::-1][:n]  # strictly proper part, ascending powers
    return a, b, c, d


def _check_transition(phi: NDArray[np.float64], g: NDArray[np.float64]) -> None:
    """A ModelError when one sample period of the model overflows (a fast unstable pole)."""
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(g))):
        raise ModelError(_STATUS[_kernels.OVERFLOW])


def _finite(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """`poly` as floats, or a ModelError when a coefficient is not finite or all vanish."""
    poly = np.asarray(poly, dtype=float)
    if not np.all(np.isfinite(poly)) or not np.any(poly):
        raise ModelError(_STATUS[_kernels.BAD_COEFFICIENTS])
    return poly


def _leading(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """`poly` without its leading zeros (numpy's trim_zeros is slow on small arrays)."""
    return poly[np.flatnonzero(poly)[0]:]


def _polynomial_hold(num: NDArray[np.float64], den: NDArray[np.float64], dt: float,
                     degree: int) -> tuple[TransferFunction, int]:
    """Exact model for an input that is the degree-`degree` polynomial through nearby samples."""
    b, a, advance = polynomial_hold_arrays(num, den, dt, degree)
    return TransferFunction(b, a, dt), advance


def polynomial_hold_arrays(num: NDArray[np.float64], den: NDArray[np.float64], dt: float,
                           degree: int) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """:func:`_polynomial_hold` as ``(b, a, advance)``, b padded to a's length, a monic.

    The period [k, k+1] interpolates the samples ``r(k + m)``, m = −behind …
    degree − behind; its state transition and input weights come from Van
    Loan's block exponential (:func:`servoid.estimate._hybrid.piece_transition`,
    compiled in :func:`._kernels.polynomial_hold`), and
    ``y(k) = c·x(k) + d·r(k)``, ``x(k+1) = Φx(k) + Σ_m Γ_m r(k+m)`` gives the
    impulse response ``g(j) = Σ_m c·Φ^(j−1+m)·Γ_m`` and the transfer function
    (:func:`_rational`).
    """
    behind = (degree - 1) // 2 if degree > 1 else 0
    m_min, m_max = -behind, degree - behind
    b, a, status = _kernels.polynomial_hold(
        np.ascontiguousarray(num, dtype=float), np.ascontiguousarray(den, dtype=float),
        float(dt), _hold_weights(m_min, m_max), m_min, m_max)
    if status != _kernels.OK:
        raise ModelError(_STATUS[status])
    return b, a, max(m_max - 1, 0)


@lru_cache(maxsize=8)
def _hold_weights(m_min: int, m_max: int) -> NDArray[np.float64]:
    weights = _kernels.hold_weights(m_min, m_max)
    weights.setflags(write=False)
    return weights


def _chain(num: NDArray[np.float64], den: NDArray[np.float64], dt: float,
           q: int) -> tuple[TransferFunction, int]:
    """Staircase at dt → continuous model → samples at dt/q → servoid's FIR decimation."""
    tau = dt / q
    a, b, c, d = _realise(num, den, tau)
    n = a.shape[0]
    phi, g = piece_transition(a, b, 1.0, 1.0, 0)
    _check_transition(phi, g)
    gamma = g[:, 0]
    taps = decimation_taps(q) if q > 1 else np.ones(1)
    half = (taps.size - 1) // 2
    advance = -(-half // q)  # ceil: y(k) reads the fast samples up to kq + half
    # from k_tail on every fast sample in the FIR window lies after the pulse (index >= q)
    k_tail = -(-(taps.size - 1 - half + q) // q)
    length = k_tail + advance + n + 1
    n_fast = (length + 2) * q + taps.size
    # w(i): fast-rate response to a unit pulse held over fast samples 0..q−1 (from rest), by
    # the recursion of the fast-rate model c(zI − Φ)⁻¹γ + d written as num/den
    markov = np.empty(n + 1)
    markov[0] = d
    row = c.copy()
    for i in range(1, n + 1):
        markov[i] = row @ gamma  # c·Φ^(i−1)·γ
        row = row @ phi
    eig = np.linalg.eigvals(phi)
    den_fast = np.real(np.poly(eig))
    num_fast = np.convolve(den_fast, markov)[: n + 1]
    pulse = np.zeros(n_fast)
    pulse[:q] = 1.0
    w = sps.lfilter(num_fast, den_fast, pulse)
    # h(jp) = Σ_l taps(l)·w((jp − L)·q + half − l), w = 0 before the pulse
    idx = (np.arange(length + 1)[:, None] - advance) * q + half - np.arange(taps.size)[None, :]
    padded = np.concatenate([[0.0], w])
    h = padded[np.where((idx >= 0) & (idx < n_fast), idx + 1, 0)] @ taps
    return _rational(eig**q, h, length, dt), advance


def _rational(phi: NDArray[np.float64], h: NDArray[np.float64], length: int,
              dt: float) -> TransferFunction:
    """``N(q⁻¹)/D(q⁻¹)`` with D = det(zI − Φ) and N the first `length` terms of D·h.

    `phi` is the one-period transition Φ or its eigenvalues.
    """
    den = np.real(np.poly(phi))
    num = np.convolve(den, h)[:length]
    den_padded = np.concatenate([den, np.zeros(max(length - den.size, 0))])
    num_padded = np.concatenate([num, np.zeros(max(den_padded.size - num.size, 0))])
    return TransferFunction(num_padded, den_padded, dt)
