"""Friction force models shared by the actuator simulators.

All laws return the friction force F_fr [N] that *opposes* motion, so the
equation of motion reads ``m·ẍ = F − F_fr`` with F the applied
(non-friction) force [N]:

* **Coulomb** ``F_c·sgn(v)``;
* **viscous** ``c·v``;
* **Stribeck** ``sgn(v)·(F_c + (F_s − F_c)·exp(−|v/v_s|^δ)) + c·v``;
* **Karnopp** stick–slip: Coulomb + viscous outside a band |v| <= ε;
  inside it the friction balances the applied force up to the breakaway
  force F_s (``F_fr = F`` if |F| <= F_s, else ``F_s·sgn(F)``);
* **three-regime** (models-spec §2 eq. 4.1/4.2, [S2] after Pachnicke):
  sliding ``sgn(v)·(d_k + c_k·|v|)`` for |v| >= ẋ_krit, the constant
  ``F_haft·sgn(v)`` for ε < |v| < ẋ_krit, and Karnopp stick with
  breakaway F_haft for |v| <= ε.  With ``blend=True`` the low-speed
  regime is instead the linear blend from F_haft at ε to
  ``d_k + c_k·ẋ_krit`` at ẋ_krit, which removes the jump at ẋ_krit.

A Karnopp band alone does not stop a body exactly: within it the body
keeps its (small) velocity.  Simulators therefore add a discrete stick
state (see :mod:`._pneumatic_kernel`); these laws are the force part.

Vectorised numpy functions (public) and scalar ``numba.njit`` kernels
(suffix ``_nb``, plain Python in ``.py_func``) give identical values.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import DataError, ModelError, OptionTypeError
from ._common import check_finite

__all__ = [
    "coulomb_friction",
    "coulomb_nb",
    "karnopp_friction",
    "karnopp_nb",
    "stribeck_friction",
    "stribeck_nb",
    "three_regime_friction",
    "three_regime_nb",
    "viscous_friction",
    "viscous_nb",
]


def coulomb_friction(v: ArrayLike, F_c: float) -> NDArray[np.float64]:
    """Return the Coulomb friction ``F_c·sgn(v)`` [N].

    Parameters
    ----------
    v : array_like
        Velocity [m/s].
    F_c : float
        Coulomb (sliding) friction force [N], >= 0.

    Returns
    -------
    ndarray
        Friction force [N]; 0 at v = 0.
    """
    return _nonneg("F_c", F_c) * np.sign(_array("v", v))


def viscous_friction(v: ArrayLike, c: float) -> NDArray[np.float64]:
    """Return the viscous friction ``c·v`` [N].

    Parameters
    ----------
    v : array_like
        Velocity [m/s].
    c : float
        Viscous coefficient [N·s/m], >= 0.

    Returns
    -------
    ndarray
        Friction force [N].
    """
    return _nonneg("c", c) * _array("v", v)


def stribeck_friction(
    v: ArrayLike, F_c: float, F_s: float, v_s: float, *, c: float = 0.0, delta: float = 2.0,
) -> NDArray[np.float64]:
    """Return the Stribeck friction curve [N].

    Parameters
    ----------
    v : array_like
        Velocity [m/s].
    F_c : float
        Coulomb friction [N], >= 0.
    F_s : float
        Static friction [N], >= F_c.
    v_s : float
        Stribeck velocity [m/s], > 0.
    c : float
        Viscous coefficient [N·s/m], >= 0.
    delta : float
        Stribeck exponent [-], > 0 (2 = Gaussian).

    Returns
    -------
    ndarray
        ``sgn(v)·(F_c + (F_s − F_c)·exp(−|v/v_s|^δ)) + c·v`` [N].
    """
    x = _array("v", v)
    fc, fs = _nonneg("F_c", F_c), _nonneg("F_s", F_s)
    if fs < fc:
        raise ModelError(f"F_s must be >= F_c = {fc:g} N, got {fs:g} N")
    vs, d = _pos("v_s", v_s), _pos("delta", delta)
    return np.sign(x) * (fc + (fs - fc) * np.exp(-np.abs(x / vs) ** d)) + _nonneg("c", c) * x


def karnopp_friction(
    v: ArrayLike, F: ArrayLike, F_c: float, F_s: float, eps: float, *, c: float = 0.0,
) -> NDArray[np.float64]:
    """Return the Karnopp stick–slip friction [N].

    Parameters
    ----------
    v : array_like
        Velocity [m/s].
    F : array_like
        Applied (non-friction) force [N], broadcast with `v`.
    F_c : float
        Coulomb friction when sliding [N], >= 0.
    F_s : float
        Breakaway (static) friction [N], >= 0.
    eps : float
        Half-width of the stick band [m/s], > 0.
    c : float
        Viscous coefficient when sliding [N·s/m], >= 0.

    Returns
    -------
    ndarray
        ``sgn(v)·F_c + c·v`` for |v| > ε; inside the band
        ``clip(F, −F_s, F_s)``.
    """
    x, f = _pair(v, F)
    fc, fs, e = _nonneg("F_c", F_c), _nonneg("F_s", F_s), _pos("eps", eps)
    slide = np.sign(x) * fc + _nonneg("c", c) * x
    return np.where(np.abs(x) > e, slide, np.clip(f, -fs, fs))


def three_regime_friction(
    v: ArrayLike,
    F: ArrayLike,
    *,
    F_haft: float,
    d_k: float,
    c_k: float,
    v_krit: float,
    eps: float = 1e-4,
    blend: bool = False,
) -> NDArray[np.float64]:
    """Return the paper's three-regime friction (eq. 4.1/4.2) [N].

    Parameters
    ----------
    v : array_like
        Piston velocity ẋ_k [m/s].
    F : array_like
        Applied force F_p [N], broadcast with `v`.
    F_haft : float
        Static (sticking) friction [N], >= 0.
    d_k : float
        Coulomb part of the sliding friction [N], >= 0.
    c_k : float
        Viscous part of the sliding friction [N·s/m], >= 0.
    v_krit : float
        Speed ẋ_krit above which the sliding law holds [m/s], > eps.
    eps : float
        Half-width of the stick band [m/s], > 0.
    blend : bool
        Blend linearly from F_haft at ε to ``d_k + c_k·ẋ_krit`` at
        ẋ_krit instead of the constant F_haft.

    Returns
    -------
    ndarray
        Friction force [N].

    Examples
    --------
    >>> kw = dict(F_haft=85.0, d_k=55.0, c_k=120.0, v_krit=0.1)
    >>> three_regime_friction([0.2, 0.05, 0.0, 0.0], [0, 0, 40.0, 100.0], **kw).tolist()
    [79.0, 85.0, 40.0, 85.0]
    """
    x, f = _pair(v, F)
    fh, dk, ck = _nonneg("F_haft", F_haft), _nonneg("d_k", d_k), _nonneg("c_k", c_k)
    e, vk = _pos("eps", eps), _pos("v_krit", v_krit)
    if vk <= e:
        raise ModelError(f"v_krit must be > eps = {e:g} m/s, got {vk:g} m/s")
    if not isinstance(blend, (bool, np.bool_)):
        raise OptionTypeError(f"blend must be a bool, got {blend!r}")
    av = np.abs(x)
    sliding = np.sign(x) * (dk + ck * av)
    if blend:
        w = (av - e) / (vk - e)
        low = np.sign(x) * (fh + (dk + ck * vk - fh) * w)
    else:
        low = np.sign(x) * fh
    stick = np.clip(f, -fh, fh)
    return np.where(av >= vk, sliding, np.where(av > e, low, stick))


# -- compiled scalar kernels -------------------------------------------------


@numba.njit(cache=True, inline="always")
def coulomb_nb(v: float, F_c: float) -> float:
    """Coulomb friction of one velocity (kernel)."""
    if v > 0.0:
        return F_c
    if v < 0.0:
        return -F_c
    return 0.0


@numba.njit(cache=True, inline="always")
def viscous_nb(v: float, c: float) -> float:
    """Viscous friction of one velocity (kernel)."""
    return c * v


@numba.njit(cache=True, inline="always")
def stribeck_nb(v: float, F_c: float, F_s: float, v_s: float, c: float, delta: float) -> float:
    """Stribeck friction of one velocity (kernel)."""
    if v == 0.0:
        return 0.0
    mag = F_c + (F_s - F_c) * math.exp(-abs(v / v_s) ** delta)
    return math.copysign(mag, v) + c * v


@numba.njit(cache=True, inline="always")
def karnopp_nb(v: float, F: float, F_c: float, F_s: float, eps: float, c: float) -> float:
    """Karnopp stick–slip friction of one state (kernel)."""
    if abs(v) > eps:
        return math.copysign(F_c, v) + c * v
    return min(max(F, -F_s), F_s)


@numba.njit(cache=True, inline="always")
def three_regime_nb(
    v: float, F: float, F_haft: float, d_k: float, c_k: float, v_krit: float, eps: float,
    blend: bool,
) -> float:
    """Three-regime friction of one state (kernel, spec eq. 4.x)."""
    av = abs(v)
    if av >= v_krit:
        return math.copysign(d_k + c_k * av, v)
    if av > eps:
        if blend:
            w = (av - eps) / (v_krit - eps)
            return math.copysign(F_haft + (d_k + c_k * v_krit - F_haft) * w, v)
        return math.copysign(F_haft, v)
    return min(max(F, -F_haft), F_haft)


# -- private helpers ---------------------------------------------------------


def _pair(v: ArrayLike, F: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x, f = _array("v", v), _array("F", F)
    try:
        return tuple(np.broadcast_arrays(x, f))  # type: ignore[return-value]
    except ValueError:
        raise DataError(f"v and F must have the same shape (or one be a scalar), got "
                        f"{x.shape} and {f.shape}") from None


def _array(name: str, x: ArrayLike) -> NDArray[np.float64]:
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(f"{name} must be an array of real numbers: {exc}") from None
    if not np.all(np.isfinite(a)):
        raise ModelError(f"{name} must be finite")
    return a


def _nonneg(name: str, value: object) -> float:
    v = check_finite(name, value, ModelError)
    if v < 0.0:
        raise ModelError(f"{name} must be >= 0, got {v:g}")
    return v


def _pos(name: str, value: object) -> float:
    v = check_finite(name, value, ModelError)
    if v <= 0.0:
        raise ModelError(f"{name} must be > 0, got {v:g}")
    return v
