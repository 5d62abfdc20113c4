"""Compressible orifice flow and pneumatic chamber equations.

Flow functions ψ(π) of the pressure ratio π = p_down/p_up (models-spec §2):

* **ellipse(b)**: ``ψ_max`` for π ≤ b and ``ψ_max·√(1 − ((π − b)/(1 − b))²)``
  for b < π ≤ 1, with b the critical ratio (the paper's ``p_krit``);
* **Saint-Venant**: ``√(κ/(κ − 1)·(π^{2/κ} − π^{(κ+1)/κ}))`` for
  π_c < π ≤ 1, clamped to its maximum ``ψ_max`` for π ≤ π_c =
  ``(2/(κ + 1))^{κ/(κ−1)}`` (choked flow);

both with ``ψ_max = (2/(κ + 1))^{1/(κ−1)}·√(κ/(κ + 1))`` (0.4842 for
κ = 1.4) and ψ = 0 for π ≥ 1.  The orifice mass flow is
``ṁ = A_eff·ψ(p_down/p_up)·p_up·√(2/(R·T_up))``; :func:`orifice_mass_flow`
extends it to reversed pressure drops (flow from "down" to "up", negative),
which the paper's equations leave out but a simulator needs once an
external force pushes a chamber above supply pressure.

The chamber equation (spec eq. 2.x) is the energy balance of an adiabatic
chamber of volume ``V = V₀ ± A·x`` fed at temperature T::

    ṗ = κ·(R·T·ṁ − p·V̇)/V

Every law comes twice: a vectorised numpy function for analysis and
identification (public), and a scalar ``numba.njit`` kernel (suffix
``_nb``) for compiled simulators; the plain Python function behind each
kernel is its ``.py_func``.  Kernels trust their inputs.
"""

from __future__ import annotations

import math
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array
from ..._errors import ModelError, OptionTypeError, check_option
from .._common import check_finite

__all__ = [
    "FLOW_KINDS",
    "FlowKind",
    "chamber_pressure_rate",
    "chamber_pressure_rate_nb",
    "critical_pressure_ratio",
    "orifice_mass_flow",
    "orifice_mass_flow_nb",
    "psi_ellipse",
    "psi_ellipse_nb",
    "psi_max",
    "psi_saint_venant",
    "psi_saint_venant_nb",
]

#: Flow-function names accepted by :func:`orifice_mass_flow` and the simulator.
FlowKind = Literal["ellipse", "saint-venant"]
FLOW_KINDS: tuple[str, ...] = ("ellipse", "saint-venant")

# integer codes of the flow kinds inside compiled kernels
ELLIPSE, SAINT_VENANT = 0, 1


def psi_max(kappa: float = 1.4) -> float:
    """Return the maximum (choked) value of the flow function.

    Parameters
    ----------
    kappa : float
        Isentropic exponent κ [-], > 1.

    Returns
    -------
    float
        ``(2/(κ + 1))^{1/(κ−1)}·√(κ/(κ + 1))`` [-] (0.4842 for κ = 1.4).
    """
    k = _check_kappa(kappa)
    return (2.0 / (k + 1.0)) ** (1.0 / (k - 1.0)) * math.sqrt(k / (k + 1.0))


def critical_pressure_ratio(kappa: float = 1.4) -> float:
    """Return the Saint-Venant critical pressure ratio π_c.

    Parameters
    ----------
    kappa : float
        Isentropic exponent κ [-], > 1.

    Returns
    -------
    float
        ``(2/(κ + 1))^{κ/(κ−1)}`` [-] (0.5283 for κ = 1.4).
    """
    k = _check_kappa(kappa)
    return (2.0 / (k + 1.0)) ** (k / (k - 1.0))


def psi_ellipse(pi: ArrayLike, b: float, kappa: float = 1.4) -> NDArray[np.float64]:
    """Evaluate the ellipse flow function with critical ratio b.

    Parameters
    ----------
    pi : array_like
        Pressure ratio p_down/p_up [-], >= 0.
    b : float
        Critical pressure ratio [-], 0 <= b < 1 (the paper's p_krit).
    kappa : float
        Isentropic exponent κ [-], > 1 (sets ψ_max).

    Returns
    -------
    ndarray
        ψ(π) [-]: ψ_max for π <= b, the quarter ellipse down to 0 at
        π = 1, and 0 for π >= 1.

    Examples
    --------
    >>> round(float(psi_ellipse(0.1, 0.25)), 4), float(psi_ellipse(1.0, 0.25))
    (0.4842, 0.0)
    """
    x = _check_ratio(pi)
    b = _check_b(b)
    pm = psi_max(kappa)
    s = np.clip((x - b) / (1.0 - b), 0.0, 1.0)
    return pm * np.sqrt(1.0 - s * s)


def psi_saint_venant(pi: ArrayLike, kappa: float = 1.4) -> NDArray[np.float64]:
    """Evaluate the Saint-Venant flow function, clamped when choked.

    Parameters
    ----------
    pi : array_like
        Pressure ratio p_down/p_up [-], >= 0.
    kappa : float
        Isentropic exponent κ [-], > 1.

    Returns
    -------
    ndarray
        ψ(π) [-]: ``√(κ/(κ−1)·(π^{2/κ} − π^{(κ+1)/κ}))`` for π_c < π < 1,
        ψ_max for π <= π_c and 0 for π >= 1.
    """
    x = _check_ratio(pi)
    k = _check_kappa(kappa)
    pc = critical_pressure_ratio(k)
    y = np.clip(x, pc, 1.0)
    inner = np.maximum(y ** (2.0 / k) - y ** ((k + 1.0) / k), 0.0)
    out = np.sqrt(k / (k - 1.0) * inner)
    return np.where(x <= pc, psi_max(k), out)


def orifice_mass_flow(
    area: ArrayLike,
    p_up: ArrayLike,
    p_down: ArrayLike,
    *,
    R: float = 290.0,
    T_up: float = 293.15,
    kappa: float = 1.4,
    flow: FlowKind = "ellipse",
    b: float = 0.528,
) -> NDArray[np.float64]:
    """Return the mass flow through an orifice [kg/s].

    Parameters
    ----------
    area : array_like
        Effective area A_eff = flow coefficient × geometric area [m²], >= 0.
    p_up : array_like
        Nominal upstream pressure [Pa] (absolute), > 0.
    p_down : array_like
        Nominal downstream pressure [Pa] (absolute), > 0.
    R : float
        Gas constant [J/(kg·K)], > 0.
    T_up : float
        Temperature of the gas entering the orifice [K], > 0.
    kappa : float
        Isentropic exponent κ [-], > 1.
    flow : {"ellipse", "saint-venant"}
        Flow function.
    b : float
        Critical ratio of the ellipse [-] (ignored for Saint-Venant).

    Returns
    -------
    ndarray
        ``A·ψ(p_down/p_up)·p_up·√(2/(R·T_up))`` [kg/s] when
        p_up >= p_down; otherwise the reversed flow
        ``−A·ψ(p_up/p_down)·p_down·√(2/(R·T_up))`` (same temperature).

    Examples
    --------
    >>> a = 3.1416 * 6e-3 * 1e-3  # π·(a d)·x_v at x_v = 1 mm
    >>> round(float(orifice_mass_flow(a, 6e5, 1.013e5, b=0.25)) * 1e3, 1)  # choked [g/s]
    26.6
    """
    check_option("flow", flow, FLOW_KINDS)
    a = as_array("area", area, finite=False)
    pu = as_array("p_up", p_up, finite=False)
    pd = as_array("p_down", p_down, finite=False)
    if np.any(a < 0.0) or not np.all(np.isfinite(a)):
        raise ModelError("area must be finite and >= 0 m²")
    for name, v in (("p_up", pu), ("p_down", pd)):
        if np.any(~np.isfinite(v)) or np.any(v <= 0.0):
            raise ModelError(f"{name} must be finite and > 0 Pa (absolute), got min {v.min():g}")
    _check_positive_float("R", R)
    _check_positive_float("T_up", T_up)
    forward = pu >= pd
    hi = np.where(forward, pu, pd)
    lo = np.where(forward, pd, pu)
    ratio = lo / hi
    psi = psi_ellipse(ratio, b, kappa) if flow == "ellipse" else psi_saint_venant(ratio, kappa)
    mag = a * psi * hi * math.sqrt(2.0 / (R * T_up))
    return np.where(forward, mag, -mag)


def chamber_pressure_rate(
    p: ArrayLike,
    m_dot: ArrayLike,
    V: ArrayLike,
    V_dot: ArrayLike,
    *,
    R: float = 290.0,
    T: float = 293.15,
    kappa: float = 1.4,
) -> NDArray[np.float64]:
    """Return ṗ of an adiabatic chamber (spec eq. 2.x) [Pa/s].

    Parameters
    ----------
    p : array_like
        Chamber pressure [Pa] (absolute).
    m_dot : array_like
        Mass flow into the chamber [kg/s].
    V : array_like
        Chamber volume [m³], > 0: ``V₀ + A·x`` (chamber I) or
        ``V₀ − A·x`` (chamber II).
    V_dot : array_like
        Rate of the volume [m³/s]: ``±A·ẋ``.
    R : float
        Gas constant [J/(kg·K)].
    T : float
        Temperature of the inflowing gas [K] (the spec takes T_S).
    kappa : float
        Isentropic exponent κ [-].

    Returns
    -------
    ndarray
        ``κ·(R·T·ṁ − p·V̇)/V`` [Pa/s].
    """
    vol = as_array("V", V, finite=False)
    if vol.size and np.any(vol <= 0.0):
        raise ModelError(f"V must be > 0 m³, got min {vol.min():g}")
    R, T, kappa = (check_finite(n, v) for n, v in (("R", R), ("T", T), ("kappa", kappa)))
    return kappa * (R * T * as_array("m_dot", m_dot, finite=False)
                    - as_array("p", p, finite=False) * as_array("V_dot", V_dot, finite=False)) / vol


# -- compiled scalar kernels -------------------------------------------------


@numba.njit(cache=True, inline="always")
def psi_ellipse_nb(pi: float, b: float, psi_max: float) -> float:
    """Ellipse flow function of one ratio (kernel; 0 <= b < 1)."""
    if pi <= b:
        return psi_max
    if pi >= 1.0:
        return 0.0
    s = (pi - b) / (1.0 - b)
    return psi_max * math.sqrt(1.0 - s * s)


@numba.njit(cache=True, inline="always")
def psi_saint_venant_nb(pi: float, kappa: float, pi_c: float, psi_max: float) -> float:
    """Saint-Venant flow function of one ratio (kernel)."""
    if pi <= pi_c:
        return psi_max
    if pi >= 1.0:
        return 0.0
    inner = pi ** (2.0 / kappa) - pi ** ((kappa + 1.0) / kappa)
    if inner <= 0.0:
        return 0.0
    return math.sqrt(kappa / (kappa - 1.0) * inner)


@numba.njit(cache=True, inline="always")
def orifice_mass_flow_nb(
    area: float, p_up: float, p_down: float, c_flow: float, kind: int,
    b: float, kappa: float, pi_c: float, psi_max: float,
) -> float:
    """Signed orifice mass flow [kg/s] (kernel).

    ``c_flow = √(2/(R·T_up))``; ``kind`` 0 = ellipse(b), 1 = Saint-Venant.
    """
    if area == 0.0:
        return 0.0
    if p_up >= p_down:
        hi, lo, sign = p_up, p_down, 1.0
    else:
        hi, lo, sign = p_down, p_up, -1.0
    ratio = lo / hi
    if kind == 0:
        psi = psi_ellipse_nb(ratio, b, psi_max)
    else:
        psi = psi_saint_venant_nb(ratio, kappa, pi_c, psi_max)
    return sign * area * psi * hi * c_flow


@numba.njit(cache=True, inline="always")
def chamber_pressure_rate_nb(
    p: float, m_dot: float, V: float, V_dot: float, kappa_RT: float, kappa: float,
) -> float:
    """Chamber ṗ = (κRT·ṁ − κ·p·V̇)/V [Pa/s] (kernel)."""
    return (kappa_RT * m_dot - kappa * p * V_dot) / V


# -- private helpers ---------------------------------------------------------


def _check_positive_float(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"{name} must be a real number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ModelError(f"{name} must be finite and > 0, got {v}")
    return v


def _check_kappa(kappa: object) -> float:
    k = _check_positive_float("kappa", kappa)
    if k <= 1.0:
        raise ModelError(f"kappa must be > 1, got {k:g}")
    return k


def _check_b(b: object) -> float:
    if isinstance(b, bool) or not isinstance(b, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"b must be a real number, got {b!r}")
    v = float(b)
    if not (0.0 <= v < 1.0):
        raise ModelError(f"b (critical pressure ratio) must be in [0, 1), got {v:g}")
    return v


def _check_ratio(pi: ArrayLike) -> NDArray[np.float64]:
    x = as_array("pi", pi, finite=False)
    if np.any(~np.isfinite(x)) or np.any(x < 0.0):
        raise ModelError("pressure ratio pi must be finite and >= 0")
    return x
