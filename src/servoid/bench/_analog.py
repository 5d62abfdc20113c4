"""Analog parts of the bench: well-scaled realisations and filters.

A continuous transfer function of high order (the 8th-order EHSA loop,
a Butterworth anti-alias filter) simulated at a fast analog rate through
its polynomial coefficients loses digits: at 20 kHz the discrete poles
cluster near z = 1 and a ``lfilter`` on the 8th-order closed loop is off
by 1e-3 relative.  Here the model is factored into first- and
second-order sections, each realised on its own and cascaded into a
block-triangular state space, balanced, and discretised through the
matrix exponential; the result is simulated mode by mode
(:meth:`servoid.models.StateSpace.simulate`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._lazy import linalg as la
from .._lazy import signal as sps
from ..models import StateSpace, TransferFunction

__all__ = ["Hold", "butterworth", "discrete_sos", "discretise", "realise"]

Hold = Literal["zoh", "foh"]


def butterworth(order: int, cutoff: float) -> TransferFunction:
    """Return an analog Butterworth low-pass filter.

    Parameters
    ----------
    order : int
        Filter order, >= 1.
    cutoff : float
        -3 dB frequency [Hz], > 0.

    Returns
    -------
    TransferFunction
        Continuous, unit DC gain.
    """
    num, den = sps.butter(order, 2.0 * np.pi * cutoff, analog=True)
    return TransferFunction(num, den)


def realise(model: TransferFunction) -> StateSpace:
    """Return a balanced cascade realisation of a continuous model.

    Parameters
    ----------
    model : TransferFunction
        Continuous (``dt=None``), proper.

    Returns
    -------
    StateSpace
        Continuous; the same transfer function, block-triangular and
        diagonally balanced.
    """
    z, p, k = sps.tf2zpk(model.num, model.den)
    sections = sps.zpk2sos(z, p, k, analog=True)
    n = p.size
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    cu = np.zeros((1, n))  # input of the current section as cu·x + du·u
    du = np.ones((1, 1))
    at = 0
    for sec in sections:
        num = np.trim_zeros(sec[:3], "f")
        den = np.trim_zeros(sec[3:], "f")
        if num.size == 0:
            num = np.zeros(1)
        ai, bi, ci, di = sps.tf2ss(num, den)
        m = ai.shape[0]
        blk = slice(at, at + m)
        a[blk, :] += bi @ cu
        a[blk, blk] += ai
        b[blk] = bi @ du
        cu = di @ cu
        cu[:, blk] += ci
        du = di @ du
        at += m
    if n:
        # Powers-of-two diagonal scaling: exact, and it evens out the rows of the
        # sections (Butterworth coefficients reach ω_c⁴ ≈ 1e15).
        a, scale = la.matrix_balance(a, permute=False, separate=True)
        s = scale[0]
        b = b / s[:, None]
        cu = cu * s[None, :]
    return StateSpace(a, b, cu, du)


def discretise(model: StateSpace, dt: float, hold: Hold) -> StateSpace:
    """Return the exact discrete equivalent for a ZOH or FOH input.

    Parameters
    ----------
    model : StateSpace
        Continuous, one input.
    dt : float
        Sample period [s].
    hold : {"zoh", "foh"}
        ``"zoh"``: the input is a staircase (a DAC output); ``"foh"``:
        the input is linear between samples (a smooth signal sampled).

    Returns
    -------
    StateSpace
        Discrete at `dt`.
    """
    ad, bd, cd, dd, _ = sps.cont2discrete((model.A, model.B, model.C, model.D), dt,
                                          method=hold)
    return StateSpace(ad, bd, cd, dd, dt=dt)


def discrete_sos(model: StateSpace, dt: float) -> NDArray[np.float64]:
    """Return the first-order-hold equivalent of a filter as sections.

    Only for a first-order hold: its equivalent is biproper, so the zeros
    from the polynomial route are well defined.  The zero-order-hold
    equivalent of a strictly proper filter has a numerator whose leading
    coefficient is zero up to rounding, and the polynomial route turns
    that into a spurious huge zero (checked: 20 % error); simulate it with
    :func:`discretise` instead.

    Parameters
    ----------
    model : StateSpace
        Continuous, one input and output, of low order.
    dt : float
        Sample period [s].

    Returns
    -------
    ndarray, shape (n_sections, 6)
        For :func:`scipy.signal.sosfilt`, which filters many channels at
        once along axis 0.
    """
    d = discretise(model, dt, "foh")
    z, p, k = sps.ss2zpk(d.A, d.B, d.C, d.D)
    return np.asarray(sps.zpk2sos(z, p, k), dtype=np.float64)
