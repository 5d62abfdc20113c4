"""The known part of the loop: forward gain c and feedback F (spec §1.1, §1.5)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, type_error
from ..._errors import DataError, ModelError
from ..._lazy import signal as sps
from ...models import TransferFunction, c2d

__all__ = ["FeedbackLoop", "reduced_plant"]

PARAMETER_NAMES: tuple[str, str, str] = ("K", "omega_hp", "delta_hp")
PARAMETER_UNITS: tuple[str, str, str] = ("1/s", "rad/s", "-")
_ONE = np.ones(1)
_ONE.setflags(write=False)


@dataclass(frozen=True, eq=False)
class FeedbackLoop:
    """Known forward gain and feedback around the plant G0.

    The convention is negative feedback: the closed loop from the
    reference r to the output y is ``H = c·G0/(1 + F·G0)``, the plant
    input is ``u = c·r − F·y`` and therefore ``G0 = H/(c − F·H)``.
    For the EHSA of spec §1.1, ``c = K_TM·K_driver`` and ``F = K_fb``.

    Parameters
    ----------
    c : float
        Forward gain from r to the loop summing point, finite and ≠ 0.
    F : float or TransferFunction
        Feedback from y to the summing point: a gain > 0, or a continuous
        or discrete transfer function with a positive static gain.

    Examples
    --------
    >>> loop = FeedbackLoop(c=0.01, F=0.01)
    >>> loop.is_static
    True
    """

    c: float
    F: float | TransferFunction

    def __post_init__(self) -> None:
        c = self.c
        if isinstance(c, bool) or not isinstance(c, (int, float, np.integer, np.floating)):
            raise type_error("c", c, "a number (the forward gain), e.g. FeedbackLoop(c=0.01, "
                             "F=0.01)")
        if not math.isfinite(float(c)) or float(c) == 0.0:
            raise ModelError(
                f"c must be a finite, non-zero forward gain, got c = {c!r}; with c = 0 the "
                "reference does not reach the plant and the closed loop carries no information"
            )
        object.__setattr__(self, "c", float(c))
        f = self.F
        if isinstance(f, TransferFunction):
            gain = f.dc_gain()
            label = f"F with static gain {gain:.6g}"
        elif isinstance(f, bool) or not isinstance(f, (int, float, np.integer, np.floating)):
            raise type_error("F", f, "a number or a TransferFunction (the feedback), e.g. "
                             "FeedbackLoop(c=0.01, F=0.01)")
        else:
            gain = float(f)
            object.__setattr__(self, "F", gain)
            label = f"F = {gain!r}"
        if not math.isfinite(gain) or gain == 0.0:
            raise ModelError(
                f"the feedback must be non-zero and finite, got {label}: with F = 0 the loop is "
                "open (G0 = H/c) and the plant's integrator makes the record drift; pass the known "
                "feedback gain, e.g. FeedbackLoop(c=0.01, F=0.01) (F = K_fb [m/m])"
            )
        if gain < 0.0:
            raise ModelError(
                f"the feedback has the wrong sign: {label}. FeedbackLoop uses the negative-"
                "feedback convention H = c·G0/(1 + F·G0) with u = c·r − F·y, so a stabilising "
                f"feedback is positive: pass F = {-gain:.6g} (the sign is already in the "
                "convention)"
            )

    @property
    def is_static(self) -> bool:
        """True when F is a plain gain."""
        return not isinstance(self.F, TransferFunction)

    def feedback_at(self, dt: float | None) -> TransferFunction:
        """Return F as a transfer function at sample period ``dt``.

        Parameters
        ----------
        dt : float or None
            Sample period [s], or None for continuous time. A continuous
            F is discretised by Tustin at ``dt``; a discrete F must
            already have this ``dt``.

        Returns
        -------
        TransferFunction
            The feedback path, continuous or discrete as asked.
        """
        f = self.F
        if not isinstance(f, TransferFunction):
            method = None if dt is None else "tustin"
            return TransferFunction([float(f)], [1.0], dt, method)
        if f.dt is None:
            return f if dt is None else c2d(f, dt, "tustin")
        if dt is None:
            raise ModelError(
                f"F is discrete (dt = {f.dt} s) but a continuous feedback was asked for; "
                "give F as a continuous TransferFunction or a gain"
            )
        if not math.isclose(f.dt, dt, rel_tol=1e-9):
            raise ModelError(
                f"F is discrete with dt = {f.dt} s but the data have dt = {dt} s; "
                "give F at the data rate or as a continuous TransferFunction"
            )
        return f

    def close(self, plant: TransferFunction) -> TransferFunction:
        """Return the closed loop ``c·G0/(1 + F·G0)``.

        Parameters
        ----------
        plant : TransferFunction
            The plant G0, continuous or discrete.

        Returns
        -------
        TransferFunction
            The closed loop from r to y, same time base as `plant`.
        """
        f_num, f_den = self._feedback_arrays(plant.dt)
        num = self.c * np.convolve(plant.num, f_den)
        den = poly_add(np.convolve(plant.den, f_den), np.convolve(f_num, plant.num))
        return TransferFunction(num, den, plant.dt, plant.method, plant.prewarp)

    def plant_from(self, closed_loop: TransferFunction) -> TransferFunction:
        """Return the plant ``G0 = H/(c − F·H)`` from a closed loop H.

        Parameters
        ----------
        closed_loop : TransferFunction
            The closed loop H from r to y, continuous or discrete.

        Returns
        -------
        TransferFunction
            The plant G0; for a dynamic F its order grows by deg F (spec
            §1.5) until near pole-zero pairs are cancelled.
        """
        h = closed_loop
        f_num, f_den = self._feedback_arrays(h.dt)
        num = np.convolve(h.num, f_den)
        den = poly_add(self.c * np.convolve(h.den, f_den), -np.convolve(f_num, h.num))
        if not np.any(den):
            raise ModelError("c·A − F·B vanishes identically: the closed loop equals c/F")
        return TransferFunction(num, den, h.dt, h.method, h.prewarp)

    def _feedback_arrays(self, dt: float | None) -> tuple[NDArray[np.float64],
                                                          NDArray[np.float64]]:
        # a static F needs no TransferFunction (the fits close the loop at every step)
        if self.is_static:
            return np.array([float(self.F)]), _ONE  # type: ignore[arg-type]
        f = self.feedback_at(dt)
        return np.asarray(f.num, dtype=float), np.asarray(f.den, dtype=float)

    def plant_input(self, r: ArrayLike, y: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Return the plant input ``u = c·r − F·y`` the loop forms.

        Parameters
        ----------
        r : array_like, shape (N,)
            Reference samples.
        y : array_like, shape (N,)
            Output samples.
        dt : float
            Sample period [s] (a dynamic F is applied at this rate).

        Returns
        -------
        ndarray, shape (N,)
            The plant input.
        """
        rr = np.asarray(r, dtype=float).ravel()
        yy = np.asarray(y, dtype=float).ravel()
        if rr.shape != yy.shape:
            raise DataError(f"r and y must have the same length, got {rr.size} and {yy.size}")
        if self.is_static:
            return self.c * rr - float(self.F) * yy  # type: ignore[arg-type]
        f = self.feedback_at(dt)
        numq = np.concatenate([np.zeros(f.den.size - f.num.size), f.num])
        return self.c * rr - sps.lfilter(numq, f.den, yy)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data description for JSON."""
        if self.is_static:
            return {"c": self.c, "F": float(self.F)}  # type: ignore[arg-type]
        f = self.F
        assert isinstance(f, TransferFunction)
        return {"c": self.c, "F": {"num": f.num.tolist(), "den": f.den.tolist(), "dt": f.dt}}


def poly_add(p: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
    """``numpy.polyadd`` of coefficient arrays (descending powers), without poly1d."""
    a, b = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    if a.size < b.size:
        a, b = b, a
    out = a.copy()
    out[a.size - b.size:] += b
    return out


def reduced_plant(theta: Sequence[float] | NDArray[np.float64]) -> TransferFunction:
    """Return the reduced EHSA plant G_simple(s) for θ = (K, ω, δ).

    ``G_simple = K/(s·(s²/ω_hp² + 2δ_hp·s/ω_hp + 1))`` (spec §1.1, Eq. 6).

    Parameters
    ----------
    theta : sequence of float
        Velocity gain K [1/s], hydraulic natural frequency ω_hp [rad/s]
        and damping ratio δ_hp [-].

    Returns
    -------
    TransferFunction
        Continuous ``K·ω²/(s³ + 2δω·s² + ω²·s)``.

    Examples
    --------
    >>> g = reduced_plant((3451.7, 163.3, 0.249))
    >>> round(float(g.num[-1] / g.den[-2]), 1)
    3451.7
    """
    arr = as_array("theta", theta, ndim=1)
    if arr.size != 3:
        raise DataError(f"theta must hold 3 values (K [1/s], omega_hp [rad/s], delta_hp [-]), "
                        f"got {arr.size}: {arr.tolist()!r}")
    return plant_of_theta(arr)


def plant_of_theta(theta: Sequence[float] | NDArray[np.float64]) -> TransferFunction:
    """:func:`reduced_plant` without the argument checks, for the fits' inner loops."""
    k, w, d = (float(x) for x in theta)
    return TransferFunction([k * w * w], [1.0, 2.0 * d * w, w * w, 0.0])


def tustin(model: TransferFunction, dt: float) -> TransferFunction:
    """Return the Tustin image of a continuous model, fast.

    Same map as ``c2d(model, dt, "tustin")`` (``s = k(z − 1)/(z + 1)``,
    k = 2/dt) as one matrix product with cached basis polynomials, so the
    one-step fit can rebuild its model at every iteration for microseconds.
    """
    return tustin_arrays(model.num, model.den, dt)


def tustin_arrays(num: ArrayLike, den: ArrayLike, dt: float) -> TransferFunction:
    """Return the Tustin image of ``num(s)/den(s)`` (descending powers)."""
    numz, denz = tustin_coefficients(num, den, dt)
    return TransferFunction(numz, denz, dt, "tustin")


def tustin_coefficients(num: ArrayLike, den: ArrayLike,
                        dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`tustin_arrays` as its (numerator, denominator) in z, not normalised."""
    d = np.asarray(den, dtype=float)
    n = d.size - 1
    basis = _tustin_basis(n, float(dt))
    b = np.asarray(num, dtype=float)
    numz = np.concatenate([np.zeros(n + 1 - b.size), b]) @ basis
    return numz, d @ basis


@lru_cache(maxsize=32)
def _tustin_basis(n: int, dt: float) -> NDArray[np.float64]:
    # row j: s^(n−j) -> k^(n−j)·(z − 1)^(n−j)·(z + 1)^j, descending powers of z
    k = 2.0 / dt
    rows = []
    for j in range(n + 1):
        m = n - j
        p = np.ones(1)
        for _ in range(m):
            p = np.polymul(p, [k, -k])
        for _ in range(j):
            p = np.polymul(p, [1.0, 1.0])
        rows.append(p)
    basis = np.array(rows)
    basis.setflags(write=False)
    return basis


def tustin_inverse(model: TransferFunction) -> TransferFunction:
    """Return the Tustin d2c of a discrete model, fast.

    The same substitution as ``d2c(model, "tustin")`` (``z = (k + s)/(k − s)``)
    as one matrix product; unlike :func:`~servoid.models.d2c` it does not
    zero coefficients at rounding level, which the delta method does not need.
    """
    assert model.dt is not None
    n = model.order
    basis = _tustin_inverse_basis(n, float(model.dt))
    num = np.concatenate([np.zeros(n + 1 - model.num.size), model.num]) @ basis
    return TransferFunction(num, model.den @ basis, None)


@lru_cache(maxsize=32)
def _tustin_inverse_basis(n: int, dt: float) -> NDArray[np.float64]:
    # row j: z^(n−j) -> (s + k)^(n−j)·(k − s)^j, descending powers of s
    k = 2.0 / dt
    rows = []
    for j in range(n + 1):
        p = np.ones(1)
        for _ in range(n - j):
            p = np.polymul(p, [1.0, k])
        for _ in range(j):
            p = np.polymul(p, [-1.0, k])
        rows.append(p)
    basis = np.array(rows)
    basis.setflags(write=False)
    return basis
