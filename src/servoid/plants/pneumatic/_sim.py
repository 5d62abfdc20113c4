"""Servopneumatic actuator simulator (models-spec §2), compiled RK4.

Equations (states x_v, ẋ_v, p_I, p_II, x_k, ẋ_k; edges i = 1..4 with
area ``π·(a_i d_i)·|x_v|``)::

    (1)   ẍ_v + 2ξ_v ω_v ẋ_v + ω_v² x_v = k_v ω_v² sat(u, ±u_max)
    (2.1) ṗ_I  = κ(R T_S ṁ_I  − A_I ẋ_k p_I)/(V_0I + A_I x_k)
    (2.2) ṗ_II = κ(R T_S ṁ_II + A_II ẋ_k p_II)/(V_0II − A_II x_k)
    (3.1) ṁ_I  = x_v > 0: orifice 2, supply → I;  x_v < 0: −orifice 1, I → exhaust
    (3.2) ṁ_II = x_v < 0: orifice 3, supply → II; x_v > 0: −orifice 4, II → exhaust
    F_p   = p_I A_I − p_II A_II − p_amb(A_I − A_II) − m_k g + F_ext
    (4.x) m_k ẍ_k = F_p − F_fr(ẋ_k, F_p)     three-regime friction, |x_k| <= stroke/2

Each orifice passes ``A·ψ(p_down/p_up)·p_up·√(2/(R T_S))`` with ψ the
ellipse(p_krit) or Saint-Venant flow function (:mod:`._flow`).  The chamber
temperature is not a state: the model takes T = T_S in both the flow and
the chamber equations, so the response reports T_I = T_II = T_S.  The
stick–slip and end-stop treatment is documented in :mod:`._pneumatic_kernel`.

Because the model is adiabatic (κ > 1) with a fixed temperature T_S, the
"mass" p·V/(R·T_S) is not conserved against ∫ṁ dt; what holds exactly is
the energy balance ``d(p·V)/dt = κ·R·T_S·ṁ − (κ − 1)·p·V̇`` (spec §3.6),
and with the valve closed ``p·V^κ`` is constant.

Closed loop.  With a :class:`PositionController` the valve input is the
analog law ``u = sat(u_ff + K_p(r − x_k) − K_d ẋ_k, ±u_max)`` evaluated at
every RK4 stage, with the reference r and the feed-forward u_ff held
(ZOH) over each sample.

Time discretisation.  Inputs are samples at the output period ``dt``
(ZOH); the integrator takes ``dt/dt_int`` fixed RK4 steps per sample.
The default ``dt_int`` is the largest ``dt/n`` not above
``min(10 µs, 0.02/ω_max)``, ω_max the fastest linear mode (spool ω_v,
the pneumatic spring at supply pressure and end of stroke, c_k/m_k); for
the nominal set ω_v·dt_int = 0.01, so RK4's relative error per period is
of order 1e-10, and the switching events (valve null, stick, stops) are
located to within 10 µs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._errors import DataError, ModelError, OptionTypeError, check_option
from ..._lazy import optimize
from .._common import (
    check_bool,
    check_finite,
    check_instance,
    check_period,
    check_signal,
    check_state,
    check_steps,
    freeze_arrays,
    integration_step,
    largest_step,
)
from ._flow import FLOW_KINDS, FlowKind, orifice_mass_flow
from ._kernel import BAD_PRESSURE, integrate, pack
from ._params import PneumaticParameters

__all__ = [
    "PNEUMATIC_STATE_NAMES",
    "PneumaticResponse",
    "PositionController",
    "pneumatic_dt_int",
    "pneumatic_rest_state",
    "simulate_pneumatic",
]

#: Names of the simulator's states, in the order of ``x0``.
PNEUMATIC_STATE_NAMES = ("x_v", "x_v_dot", "p_I", "p_II", "x_k", "x_k_dot")

_DT_INT_MAX = 1e-5  # [s]
_OMEGA_DT = 0.02  # ω_max·dt_int at most


@dataclass(frozen=True)
class PositionController:
    """Analog PD position controller of the valve input.

    ``u = sat(u_ff + K_p·(r − x_k) − K_d·ẋ_k, ±u_max)``, u_max from the
    actuator parameters.  Defaults are the spec's §2 "Checked" loop [A].

    Parameters
    ----------
    K_p : float
        Position gain [V/m], >= 0. [A] 300.
    K_d : float
        Velocity gain [V·s/m], >= 0. [A] 5.
    """

    K_p: float = 300.0
    K_d: float = 5.0

    def __post_init__(self) -> None:
        for name in ("K_p", "K_d"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise OptionTypeError(f"PositionController.{name} must be a real number, "
                                      f"got {value!r}")
            if not (math.isfinite(value) and value >= 0.0):
                raise ModelError(f"PositionController.{name} must be finite and >= 0, "
                                 f"got {value}")
            object.__setattr__(self, name, float(value))


@dataclass(frozen=True, eq=False)
class PneumaticResponse:
    """Sampled response of the servopneumatic simulator.

    Every sensor of [S2] is here, sampled at ``t = k·dt`` (the state at
    the start of sample k; flows, acceleration and forces evaluated
    there).  Arrays are read-only.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s].
    u : ndarray, shape (N,)
        Valve amplifier input actually applied, after saturation [V].
    r : ndarray or None, shape (N,)
        Position reference [m] (closed loop), else None.
    f_ext : ndarray, shape (N,)
        External force on the piston, positive upwards (along x_k) [N].
    x_v : ndarray, shape (N,)
        Spool position [m].
    x_v_dot : ndarray, shape (N,)
        Spool velocity [m/s].
    p_I : ndarray, shape (N,)
        Pressure in chamber I (under the piston) [Pa] (absolute).
    p_II : ndarray, shape (N,)
        Pressure in chamber II (rod side) [Pa] (absolute).
    T_I : ndarray, shape (N,)
        Temperature in chamber I [K]: T_S, not a state of this model.
    T_II : ndarray, shape (N,)
        Temperature in chamber II [K]: T_S, not a state of this model.
    m_dot_I : ndarray, shape (N,)
        Mass flow into chamber I [kg/s].
    m_dot_II : ndarray, shape (N,)
        Mass flow into chamber II [kg/s].
    x_k : ndarray, shape (N,)
        Piston position, positive upwards [m].
    x_k_dot : ndarray, shape (N,)
        Piston velocity [m/s].
    x_k_ddot : ndarray, shape (N,)
        Piston acceleration [m/s²].
    F_p : ndarray, shape (N,)
        Applied (pressure, weight and external) force on the piston [N].
    F_fr : ndarray, shape (N,)
        Friction force opposing motion [N] (equal to F_p while stuck).
    stuck : ndarray of bool, shape (N,)
        The piston is held by static friction.
    dt : float
        Sample period [s].
    dt_int : float
        Integration step [s].
    flow : str
        Flow function used ("ellipse" or "saint-venant").
    blend : bool
        The blended low-speed friction was used.
    final_state : ndarray, shape (6,)
        State at ``t = N·dt`` in :data:`PNEUMATIC_STATE_NAMES` order; pass
        it as ``x0`` to continue.
    """

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    r: NDArray[np.float64] | None
    f_ext: NDArray[np.float64]
    x_v: NDArray[np.float64]
    x_v_dot: NDArray[np.float64]
    p_I: NDArray[np.float64]
    p_II: NDArray[np.float64]
    T_I: NDArray[np.float64]
    T_II: NDArray[np.float64]
    m_dot_I: NDArray[np.float64]
    m_dot_II: NDArray[np.float64]
    x_k: NDArray[np.float64]
    x_k_dot: NDArray[np.float64]
    x_k_ddot: NDArray[np.float64]
    F_p: NDArray[np.float64]
    F_fr: NDArray[np.float64]
    stuck: NDArray[np.bool_]
    dt: float
    dt_int: float
    flow: str
    blend: bool
    final_state: NDArray[np.float64]

    def __post_init__(self) -> None:
        freeze_arrays(self, ("t", "u", "r", "f_ext", "x_v", "x_v_dot", "p_I", "p_II", "T_I",
                             "T_II", "m_dot_I", "m_dot_II", "x_k", "x_k_dot", "x_k_ddot", "F_p",
                             "F_fr", "stuck", "final_state"), flags=("stuck",), optional=("r",))


def pneumatic_dt_int(params: PneumaticParameters, dt: float) -> float:
    """Return the default integration step for sample period dt [s].

    Parameters
    ----------
    params : PneumaticParameters
        Physical parameters (set the fastest mode ω_max).
    dt : float
        Sample period [s], > 0.

    Returns
    -------
    float
        The largest ``dt/n`` (n integer) not above
        ``min(10 µs, 0.02/ω_max)`` [s].
    """
    check_instance("params", params, PneumaticParameters)
    dt = check_period("dt", dt)
    return largest_step(dt, min(_DT_INT_MAX, _OMEGA_DT / _omega_max(params)))


def pneumatic_rest_state(
    params: PneumaticParameters, x_k: float = 0.0, f_ext: float = 0.0,
) -> NDArray[np.float64]:
    """Return a force-free rest state near valve-null pressure.

    Each chamber's valve-null pressure p_n is where its supply and
    exhaust edges pass equal flow at equal small openings (the level a
    leaky, critically lapped valve settles to; 4.48 bar for the nominal
    set).  The pressures are then moved by the least change that makes
    F_p = 0, so the piston is at rest and force-free.

    Parameters
    ----------
    params : PneumaticParameters
        Physical parameters.
    x_k : float
        Piston position [m], within ±stroke/2.
    f_ext : float
        External force at rest [N] (positive upwards).

    Returns
    -------
    ndarray, shape (6,)
        State in :data:`PNEUMATIC_STATE_NAMES` order.
    """
    check_instance("params", params, PneumaticParameters)
    xk = check_finite("x_k", x_k)
    fe = check_finite("f_ext", f_ext)
    if abs(xk) > params.stroke / 2.0:
        raise DataError(f"x_k must be within ±{params.stroke / 2:g} m, got {xk:g}")
    pn1 = _null_pressure(params, params.ad_2, params.ad_1)
    pn2 = _null_pressure(params, params.ad_3, params.ad_4)
    a1, a2 = params.A_I, params.A_II
    excess = pn1 * a1 - pn2 * a2 - params.static_force + fe
    p1 = pn1 - excess * a1 / (a1 * a1 + a2 * a2)
    p2 = pn2 + excess * a2 / (a1 * a1 + a2 * a2)
    if p1 <= 0.0 or p2 <= 0.0:
        raise ModelError(f"no rest state with positive pressures for f_ext = {fe:g} N "
                         f"(p_I = {p1:g} Pa, p_II = {p2:g} Pa)")
    return np.array([0.0, 0.0, p1, p2, xk, 0.0])


def simulate_pneumatic(
    params: PneumaticParameters,
    u: ArrayLike | None,
    dt: float,
    *,
    r: ArrayLike | None = None,
    f_ext: ArrayLike | None = None,
    controller: PositionController | None = None,
    x0: ArrayLike | None = None,
    dt_int: float | None = None,
    flow: FlowKind = "ellipse",
    blend: bool = False,
) -> PneumaticResponse:
    """Simulate the servopneumatic actuator (spec §2).

    Parameters
    ----------
    params : PneumaticParameters
        Physical parameters.
    u : array_like or None, shape (N,)
        Valve amplifier input samples [V] (ZOH), saturated at ±u_max.
        With a `controller` it is a feed-forward added to the control
        law, and may be None (zero).
    dt : float
        Sample period of the inputs and outputs [s], > 0.
    r : array_like, shape (N,), optional
        Position reference samples [m] (ZOH); required with a
        `controller`, not allowed without one.
    f_ext : array_like, shape (N,), optional
        External force samples on the piston [N], positive upwards
        (ZOH); default 0.
    controller : PositionController, optional
        Close the loop with the analog PD law (evaluated at every RK4
        stage).
    x0 : array_like, shape (6,), optional
        Initial state in :data:`PNEUMATIC_STATE_NAMES` order [SI];
        pressures > 0, |x_k| <= stroke/2.  Default
        :func:`pneumatic_rest_state` at x_k = 0.  A piston starting
        with ẋ_k = 0 starts stuck unless |F_p| > F_haft.
    dt_int : float, optional
        Integration step [s], ``dt/dt_int`` a whole number; default
        :func:`pneumatic_dt_int`.
    flow : {"ellipse", "saint-venant"}
        Flow function: ellipse with b = p_krit, or Saint-Venant.
    blend : bool
        Use the blended low-speed friction (see
        :func:`three_regime_friction`) instead of the constant F_haft.

    Returns
    -------
    PneumaticResponse
        Every sensor of the paper at the sample times, and the final state.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.plants.pneumatic import PNEUMATIC_NOMINAL, PositionController
    >>> t = np.arange(2000) * 1e-3
    >>> res = simulate_pneumatic(PNEUMATIC_NOMINAL, None, 1e-3,
    ...                          r=0.02 * np.sin(2 * np.pi * t),
    ...                          controller=PositionController())
    >>> bool(np.max(np.abs(res.x_k - res.r)) < 8e-3)  # stick-slip: within 8 mm
    True
    """
    check_instance("params", params, PneumaticParameters)
    dt = check_period("dt", dt)
    check_option("flow", flow, FLOW_KINDS)
    blend = check_bool("blend", blend)
    if controller is not None and not isinstance(controller, PositionController):
        raise OptionTypeError(f"controller must be a PositionController or None, "
                              f"got {type(controller).__name__}")
    closed = controller is not None
    if closed:
        if r is None:
            raise DataError("r (position reference [m]) is required with a controller")
        ref = check_signal("r", r, "m")
        n = ref.size
        uff = np.zeros(n) if u is None else check_signal("u", u, "V", n)
    else:
        if r is not None:
            raise DataError("r (position reference) needs a controller; pass controller=...")
        if u is None:
            raise DataError("u (valve input [V]) is required without a controller")
        uff = check_signal("u", u, "V")
        n = uff.size
        ref = np.zeros(n)
    fe = np.zeros(n) if f_ext is None else check_signal("f_ext", f_ext, "N", n)
    h = pneumatic_dt_int(params, dt) if dt_int is None else integration_step(dt, dt_int)
    decimation = check_steps(n, dt, h, "simulate_pneumatic")
    state = pneumatic_rest_state(params, 0.0, float(fe[0])) if x0 is None else _check_x0(
        params, x0)
    kp = controller.K_p if closed else 0.0
    kd = controller.K_d if closed else 0.0
    out = np.empty((n, 13))
    final, _, status, bad = integrate(
        uff, ref, fe, closed, kp, kd, decimation, h, pack(params),
        FLOW_KINDS.index(flow), blend, state, bool(state[5] == 0.0), out)
    if status == BAD_PRESSURE:
        raise ModelError(
            f"a chamber pressure left (0, ∞) at t = {bad * h:.6g} s; the inputs drive the "
            f"model outside its range (try a smaller dt_int than {h:g} s or milder inputs)"
        )
    temp = np.full(n, params.T_S)
    return PneumaticResponse(
        t=np.arange(n, dtype=np.float64) * dt,
        u=out[:, 8],
        r=ref if closed else None,
        f_ext=fe,
        x_v=out[:, 0],
        x_v_dot=out[:, 12],
        p_I=out[:, 1],
        p_II=out[:, 2],
        T_I=temp,
        T_II=temp.copy(),
        m_dot_I=out[:, 3],
        m_dot_II=out[:, 4],
        x_k=out[:, 5],
        x_k_dot=out[:, 6],
        x_k_ddot=out[:, 7],
        F_p=out[:, 9],
        F_fr=out[:, 10],
        stuck=out[:, 11] > 0.5,
        dt=dt,
        dt_int=h,
        flow=flow,
        blend=blend,
        final_state=final,
    )


# -- private helpers ---------------------------------------------------------


def _omega_max(p: PneumaticParameters) -> float:
    lim = p.stroke / 2.0
    k_end = max(p.stiffness(p.p_S, p.p_S, lim), p.stiffness(p.p_S, p.p_S, -lim))
    return max(p.omega_v, math.sqrt(k_end / p.m_k), p.c_k / p.m_k)


def _null_pressure(p: PneumaticParameters, ad_in: float, ad_out: float) -> float:
    def imbalance(pc: float) -> float:
        kw = {"R": p.R, "T_up": p.T_S, "kappa": p.kappa, "b": p.p_krit}
        q_in = orifice_mass_flow(ad_in, p.p_S, pc, **kw)
        q_out = orifice_mass_flow(ad_out, pc, p.p_R, **kw)
        return float(q_in - q_out)

    return float(optimize.brentq(imbalance, p.p_R, p.p_S, xtol=1e-6))


def _check_x0(params: PneumaticParameters, x0: ArrayLike) -> NDArray[np.float64]:
    state = check_state(x0, PNEUMATIC_STATE_NAMES)
    if state[2] <= 0.0 or state[3] <= 0.0:
        raise DataError(f"x0 pressures p_I, p_II must be > 0 Pa (absolute), "
                        f"got {state[2]:g}, {state[3]:g}")
    if abs(state[4]) > params.stroke / 2.0:
        raise DataError(f"x0 piston position x_k must be within ±{params.stroke / 2:g} m, "
                        f"got {state[4]:g}")
    return state
