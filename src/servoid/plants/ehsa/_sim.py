"""Nonlinear EHSA simulator (models-spec §1.4), compiled RK4.

Equations (states x_f, ẋ_f, z, ż, x_s, P_L, y, ẏ)::

    e_f  = K_TM·K_driver·y_r(t − T_d) − K_fb·y
    ẍ_f  = ω_f²(e_f − x_f) − 2δ_f ω_f ẋ_f          |x_f| ≤ x_f,max
    z̈    = ω_sp²(K_s2·x_f − z) − 2δ_sp ω_sp ż
    ẋ_s  = sat(ω_s1(z − x_s), ±v_s,max)            |x_s| ≤ x_s,max
    x_e  = sgn(x_s)·max(|x_s| − u_0, 0)
    Q_L  = C_d w x_e √(max(P_s − P_T − sgn(x_e)·P_L, 0)/ρ)
    (V_t/4β_e)·Ṗ_L = Q_L − A_p ẏ − K_ce P_L
    M_t ÿ = A_p P_L − B_p ẏ − K_l y − F_ext − F_fr      |y| ≤ stroke

Friction ``F_fr``: Coulomb ``F_c·sgn(ẏ)`` for |ẏ| > ε, Karnopp stick
with breakaway ``F_s`` inside the band; a piston that comes to rest is
stopped exactly (ẏ = 0), see :mod:`._ehsa_kernel`.  Travel limits are
inelastic stops.

Time discretisation.  The reference ``y_r`` is given as samples at the
output period ``dt`` and held (ZOH); the integrator takes
``decimation = dt/dt_int`` fixed RK4 steps per sample, and the dead time
is rounded to a whole number of steps.  RK4 is stable for ``|λ|·dt_int``
up to about 2.8, far above the default: ``dt_int`` is the largest
``dt/n`` not above ``min(2 µs, 0.05/ω_max)``, ω_max being the fastest
linear mode (ω_f, ω_sp, ω_s1, ω_hp, B_p/M_t).  2 µs follows the spec
(Set C has ω_hp ≈ 9·10³ rad/s: ω·dt_int = 0.018, a relative RK4 error
per period of order 1e-9); the small step also resolves the switching
events (stick/slip, limits, dead zone), which the fixed-step scheme
locates only to within one step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

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
from ._kernel import integrate, pack
from ._params import EhsaParameters

__all__ = ["STATE_NAMES", "EhsaResponse", "default_dt_int", "simulate_ehsa"]

#: Names of the simulator's states, in the order of ``x0``.
STATE_NAMES = ("x_f", "x_f_dot", "z", "z_dot", "x_s", "P_L", "y", "y_dot")

_DT_INT_MAX = 2e-6  # [s] models-spec §1.4
_OMEGA_DT = 0.05  # ω_max·dt_int at most: RK4 phase error ~ (ω dt)^4/120 per radian


@dataclass(frozen=True, eq=False)
class EhsaResponse:
    """Sampled response of the nonlinear EHSA simulator.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s], ``k·dt``.
    y_r : ndarray, shape (N,)
        Reference (command) samples [m].
    y : ndarray, shape (N,)
        Piston position [m].
    y_dot : ndarray, shape (N,)
        Piston velocity [m/s].
    P_L : ndarray, shape (N,)
        Load pressure [Pa].
    x_s : ndarray, shape (N,)
        Spool position [m].
    x_f : ndarray, shape (N,)
        Flapper position (equivalent displacement) [m].
    P_s : ndarray, shape (N,)
        Supply pressure [Pa] (constant: an ideal supply).
    P_T : ndarray, shape (N,)
        Return pressure [Pa] (constant).
    dt : float
        Sample period [s].
    dt_int : float
        Integration step [s].
    dead_time : float
        Dead time applied, a whole number of steps [s].
    linear : bool
        The linearised simulator was used.
    friction : bool
        Friction was on (always False when `linear`).
    final_state : ndarray, shape (8,)
        State at ``t = N·dt``, in :data:`STATE_NAMES` order; pass it as
        ``x0`` to continue.
    """

    t: NDArray[np.float64]
    y_r: NDArray[np.float64]
    y: NDArray[np.float64]
    y_dot: NDArray[np.float64]
    P_L: NDArray[np.float64]
    x_s: NDArray[np.float64]
    x_f: NDArray[np.float64]
    P_s: NDArray[np.float64]
    P_T: NDArray[np.float64]
    dt: float
    dt_int: float
    dead_time: float
    linear: bool
    friction: bool
    final_state: NDArray[np.float64]

    def __post_init__(self) -> None:
        freeze_arrays(self, ("t", "y_r", "y", "y_dot", "P_L", "x_s", "x_f", "P_s", "P_T",
                             "final_state"))


def default_dt_int(params: EhsaParameters, dt: float) -> float:
    """Return the default integration step for sample period dt [s].

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters (set the fastest mode ω_max).
    dt : float
        Sample period [s], > 0.

    Returns
    -------
    float
        The largest ``dt/n`` (n integer) not above
        ``min(2 µs, 0.05/ω_max)`` [s].
    """
    check_instance("params", params, EhsaParameters)
    dt = check_period("dt", dt)
    return largest_step(dt, min(_DT_INT_MAX, _OMEGA_DT / _omega_max(params)))


def simulate_ehsa(
    params: EhsaParameters,
    y_r: ArrayLike,
    dt: float,
    *,
    dt_int: float | None = None,
    linear: bool = False,
    friction: bool = True,
    x0: ArrayLike | None = None,
    y_r_past: float = 0.0,
) -> EhsaResponse:
    """Simulate the nonlinear EHSA for a sampled reference.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters, including the simulator's T_d, u_0, F_c,
        F_s, eps_v, K_l and F_ext.
    y_r : array_like, shape (N,)
        Reference samples [m] at period `dt`, held between samples.
    dt : float
        Sample period of `y_r` and of the output [s], > 0.
    dt_int : float, optional
        Integration step [s], ``dt/dt_int`` a whole number; default
        :func:`default_dt_int`.
    linear : bool
        Linearised simulator: flow ``K_qs·x_s``, no travel or rate
        limits, no dead zone, no friction, no end stops (dead time,
        ``K_l`` and ``F_ext`` stay).  Its y_r → y response is that of
        ``full_order_closed_loop(params, exact=True)`` delayed by T_d.
    friction : bool
        Coulomb/Karnopp friction on (ignored when `linear`).
    x0 : array_like, shape (8,), optional
        Initial state in :data:`STATE_NAMES` order [SI]; default rest
        at zero.
    y_r_past : float
        Reference before t = 0 [m], seen during the dead time.

    Returns
    -------
    EhsaResponse
        Sampled outputs, the steps used and the final state.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.plants.ehsa import SET_B
    >>> res = simulate_ehsa(SET_B, np.full(400, 1e-3), 1e-3)  # 1 mm step
    >>> bool(abs(res.y[-1] - 1e-3) < 2.5e-5)  # stiction leaves < 23 µm
    True
    """
    check_instance("params", params, EhsaParameters)
    dt = check_period("dt", dt)
    ref = check_signal("y_r", y_r, "m")
    h = default_dt_int(params, dt) if dt_int is None else integration_step(dt, dt_int)
    decimation = check_steps(ref.size, dt, h, "simulate_ehsa")
    linear = check_bool("linear", linear)
    friction = check_bool("friction", friction) and not linear
    state = np.zeros(len(STATE_NAMES)) if x0 is None else check_state(x0, STATE_NAMES)
    past = check_finite("y_r_past", y_r_past)
    delay = round(params.T_d / h)
    out = np.empty((ref.size, 5))
    final = integrate(ref, past, decimation, delay, h, pack(params), linear, friction, state,
                      out)
    n = ref.size
    return EhsaResponse(
        t=np.arange(n, dtype=np.float64) * dt,
        y_r=ref,
        y=out[:, 0],
        y_dot=out[:, 1],
        P_L=out[:, 2],
        x_s=out[:, 3],
        x_f=out[:, 4],
        P_s=np.full(n, params.P_s),
        P_T=np.full(n, params.P_T),
        dt=dt,
        dt_int=h,
        dead_time=delay * h,
        linear=linear,
        friction=friction,
        final_state=final,
    )


# -- private helpers ---------------------------------------------------------


def _omega_max(p: EhsaParameters) -> float:
    return max(p.omega_f, p.omega_sp, p.omega_s1, p.omega_hp, p.B_p / p.M_t)
