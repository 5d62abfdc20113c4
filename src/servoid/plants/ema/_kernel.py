"""Compiled right-hand side and loop kernel of the EMA (numba).

Inner helpers trust their inputs: :func:`servoid.plants.ema.simulate_ema`
checks everything and packs the parameters with :func:`pack`.

States, in order: motor current i [A], motor angle θ [rad], motor speed
ω [rad/s], load position x [m], load velocity v [m/s]; plus a *stuck* flag
per side.  With ``n = 2πN/lead`` the nut position is θ/n and the screw
force ``F_s = k_s·dz(θ/n − x) + c_s·(ω/n − v)`` (``dz`` the backlash dead
zone of half-width ``backlash/2``; the damper acts only in contact)::

    L·di/dt = u − R·i − K_m·ω
    J_m·dω/dt = K_m·i − F_s/n − b_m·ω − T_cm·sgn(ω)
    m_L·dv/dt = F_s − b_L·v − F_cL·sgn(v) − F_ext

Stick–slip (Karnopp, no chatter).  After each RK4 step a side whose
velocity changed sign, or lies within the band its Coulomb friction alone
removes in two steps (an RK4 step across the sign change may land on the
same side), sticks — velocity set to
exactly 0 — if the force driving it (everything but its Coulomb
friction) is within its (non-zero) Coulomb level; while stuck, its acceleration is
0.  At the start of every step a stuck side breaks away when that force
exceeds the Coulomb level, and then accelerates against friction in the
force's direction.  The switching instants are located within one
integration step.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ...integrate import rk4_step
from ._params import EmaParameters

__all__ = ["N_OUT", "N_STATES", "pack", "rates", "run_loop"]

_KM, _R, _L, _J, _BM, _TCM, _NT, _KS, _CS, _HB, _ML, _BL, _FCL = range(13)
_KPI, _KII, _KPW, _KIW, _KPX, _KIX, _UMAX, _IMAX, _WMAX, _CPR, _LOADFB = range(11)
N_STATES = 5

#: Per-sample output columns: i, θ, ω, x, v, u, i_ref, ω_ref, î, θ̂, x̂, F_s, stuck motor,
#: stuck load, saturated (bit 1 voltage, 2 current, 4 speed).
N_OUT = 15


def pack(p: EmaParameters) -> NDArray[np.float64]:
    """Return the parameter vector the kernel reads."""
    return np.array([p.K_m, p.R, p.L, p.J_m, p.b_m, p.T_cm, p.transmission, p.k_s, p.c_s,
                     0.5 * p.backlash, p.m_L, p.b_L, p.F_cL])


@numba.njit(cache=True, inline="always")
def screw_force(theta, omega, x, v, p):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Force of the screw on the load [N] (positive pushes the load to +x)."""
    nt = p[_NT]
    d = theta / nt - x
    hb = p[_HB]
    if hb > 0.0:
        if d > hb:
            d -= hb
        elif d < -hb:
            d += hb
        else:
            return 0.0
    return p[_KS] * d + p[_CS] * (omega / nt - v)


@numba.njit(cache=True, inline="always")
def driving(x, fext, p):  # type: ignore[no-untyped-def]  # pragma: no cover
    """(motor torque, load force, screw force) driving each side, Coulomb friction aside."""
    fs = screw_force(x[1], x[2], x[3], x[4], p)
    tm = p[_KM] * x[0] - fs / p[_NT] - p[_BM] * x[2]
    fl = fs - p[_BL] * x[4] - fext
    return tm, fl, fs


@numba.njit(cache=True, inline="always")
def _accel(drive, speed, coulomb, mass, stuck):  # type: ignore[no-untyped-def]  # pragma: no cover
    if stuck:
        return 0.0
    if speed > 0.0:
        return (drive - coulomb) / mass
    if speed < 0.0:
        return (drive + coulomb) / mass
    if drive > coulomb:  # at rest and breaking away: friction opposes the driving force
        return (drive - coulomb) / mass
    if drive < -coulomb:
        return (drive + coulomb) / mass
    return 0.0


@numba.njit(cache=True, inline="always")
def rates(t, x, w, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The right-hand side: five rates, then the screw force.

    ``w = (u, F_ext, motor stuck, load stuck)`` is held over the step;
    ``ctx = (p, ε_motor, ε_load)`` with ``p`` :func:`pack`'s vector and
    ε the stick bands of the post-step hook.
    """
    p = ctx[0]
    u, fext, stuck_m, stuck_l = w
    tm, fl, fs = driving(x, fext, p)
    di = (u - p[_R] * x[0] - p[_KM] * x[2]) / p[_L]
    dw = _accel(tm, x[2], p[_TCM], p[_J], stuck_m)
    dv = _accel(fl, x[4], p[_FCL], p[_ML], stuck_l)
    return di, x[2], dw, x[4], dv, fs


@numba.njit(cache=True, inline="always")
def _stick(t, x, before, w, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Post-step hook: (state, motor stuck, load stuck) with the Karnopp stick test."""
    p, eps_m, eps_l = ctx
    _, fext, stuck_m, stuck_l = w
    i, th, om, xl, vl = x
    if not stuck_m or not stuck_l:
        tm, fl, _ = driving(x, fext, p)
        if not stuck_m and (abs(om) <= eps_m or om * before[2] < 0.0) and abs(tm) <= p[_TCM] \
                and p[_TCM] > 0.0:
            stuck_m = True
            om = 0.0
        if not stuck_l and (abs(vl) <= eps_l or vl * before[4] < 0.0) and abs(fl) <= p[_FCL] \
                and p[_FCL] > 0.0:
            stuck_l = True
            vl = 0.0
    return (i, th, om, xl, vl), stuck_m, stuck_l


@numba.njit(cache=True, inline="always")
def _sat(value, limit):  # type: ignore[no-untyped-def]  # pragma: no cover
    if value > limit:
        return limit, True
    if value < -limit:
        return -limit, True
    return value, False


@numba.njit(cache=True, inline="always")
def _integrate(z, gain, error, period, saturated, output):  # type: ignore[no-untyped-def]  # pragma: no cover
    # conditional integration: hold the integrator when saturated and the error pushes outward
    if saturated and error * output > 0.0:
        return z
    return z + gain * error * period


@numba.njit(cache=True)
def run_loop(p, g, r, fext, noise_i, noise_x, x0, dt, substeps, outer_every,
             out, analog):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Simulate the drive and the actuator; fill ``out`` (N, N_OUT) and ``analog``.

    ``analog`` is (N·substeps, 5) for the state at every integration step,
    or (0, 5) for none.  Returns the final state.
    """
    h = dt / substeps
    n = r.size
    x = (x0[0], x0[1], x0[2], x0[3], x0[4])
    cpr = g[_CPR]
    q = 2.0 * math.pi / cpr if cpr > 0.0 else 0.0
    nt = p[_NT]
    t_outer = outer_every * dt

    def angle(theta):  # type: ignore[no-untyped-def]
        return math.floor(theta / q) * q if q > 0.0 else theta

    tm0, fl0, _ = driving(x, fext[0], p)
    stuck_m = x[2] == 0.0 and abs(tm0) <= p[_TCM] and p[_TCM] > 0.0
    stuck_l = x[4] == 0.0 and abs(fl0) <= p[_FCL] and p[_FCL] > 0.0
    th_prev = angle(x[1] - x[2] * t_outer)
    z_i = 0.0
    z_w = 0.0
    z_x = 0.0
    w_ref = 0.0
    i_ref = 0.0
    sat_w = False
    sat_i = False
    keep_analog = analog.shape[0] > 0
    # stick bands: the speed friction alone takes away in two steps (an RK4 step across the
    # sign change can land on the same side, so a sign test alone misses the stop)
    ctx = (p, 2.0 * h * p[_TCM] / p[_J], 2.0 * h * p[_FCL] / p[_ML])
    for k in range(n):
        th_meas = angle(x[1])
        i_meas = x[0] + noise_i[k]
        x_meas = x[3] + noise_x[k] if g[_LOADFB] > 0.0 else th_meas / nt
        flags = 0.0
        if k % outer_every == 0:
            w_hat = (th_meas - th_prev) / t_outer
            th_prev = th_meas
            e_x = r[k] - x_meas
            w_ref, sat_w = _sat(g[_KPX] * e_x + z_x, g[_WMAX])
            z_x = _integrate(z_x, g[_KIX], e_x, t_outer, sat_w, w_ref)
            e_w = w_ref - w_hat
            i_ref, sat_i = _sat(g[_KPW] * e_w + z_w, g[_IMAX])
            z_w = _integrate(z_w, g[_KIW], e_w, t_outer, sat_i, i_ref)
        e_i = i_ref - i_meas
        u, sat_u = _sat(g[_KPI] * e_i + z_i, g[_UMAX])
        z_i = _integrate(z_i, g[_KII], e_i, dt, sat_u, u)
        if sat_u:
            flags += 1.0
        if sat_i:
            flags += 2.0
        if sat_w:
            flags += 4.0
        fe = fext[k]
        out[k, 0] = x[0]
        out[k, 1] = x[1]
        out[k, 2] = x[2]
        out[k, 3] = x[3]
        out[k, 4] = x[4]
        out[k, 5] = u
        out[k, 6] = i_ref
        out[k, 7] = w_ref
        out[k, 8] = i_meas
        out[k, 9] = th_meas
        out[k, 10] = x_meas
        out[k, 11] = screw_force(x[1], x[2], x[3], x[4], p)
        out[k, 12] = 1.0 if stuck_m else 0.0
        out[k, 13] = 1.0 if stuck_l else 0.0
        out[k, 14] = flags
        for m in range(substeps):
            if keep_analog:
                row = k * substeps + m
                for c in range(5):
                    analog[row, c] = x[c]
            if stuck_m or stuck_l:  # breakaway at the start of a step
                tm, fl, _ = driving(x, fe, p)
                if stuck_m and abs(tm) > p[_TCM]:
                    stuck_m = False
                if stuck_l and abs(fl) > p[_FCL]:
                    stuck_l = False
            (x, stuck_m, stuck_l), _ = rk4_step(rates, _stick, 0.0, x, (u, fe, stuck_m, stuck_l),
                                               ctx, h)
    final = np.empty(5)
    for c in range(5):
        final[c] = x[c]
    return final
