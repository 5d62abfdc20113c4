"""Compiled RK4 kernel of the nonlinear EHSA simulator (numba).

Inner helpers trust their inputs: :func:`servoid.plants.ehsa.simulate_ehsa`
validates everything and packs the parameters with :func:`pack`.

States, in order: flapper x_f, ẋ_f; spool-stage z, ż; spool x_s; load
pressure P_L; piston y, ẏ.  Limits (flapper and spool travel, end stops)
are handled twice: inside the right-hand side a state at its limit cannot
move further out, and after each step the state is projected back onto
its range with the outward velocity zeroed (an inelastic stop).  Stiction
is handled after each step too: a piston whose velocity fell into the
Karnopp band, or changed sign during the step, is stopped exactly
(``ẏ = 0``) when the applied force is within the breakaway force; inside
the right-hand side the Karnopp law then holds it (``ÿ = 0``), so it
neither drifts nor chatters.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ...integrate import rk4_step
from ._params import EhsaParameters

__all__ = ["N_PARAMS", "integrate", "pack", "rhs"]

# indices into the packed parameter vector (compile-time constants for numba)
_CREF, _KFB, _WF2, _ZF, _XFMAX, _WSP2, _ZSP, _KS2, _WS1, _VSMAX = range(10)
_XSMAX, _U0, _CDW, _DP, _INVRHO, _KQS, _KP, _AP, _KCE, _BP = range(10, 20)
_INVM, _KL, _FEXT, _FC, _FS, _EPS, _STROKE = range(20, 27)
N_PARAMS = 27


def pack(p: EhsaParameters) -> NDArray[np.float64]:
    """Return the parameter vector the kernel reads."""
    v = np.empty(N_PARAMS)
    v[_CREF] = p.reference_gain
    v[_KFB] = p.K_fb
    v[_WF2] = p.omega_f**2
    v[_ZF] = 2.0 * p.delta_f * p.omega_f
    v[_XFMAX] = p.x_f_max
    v[_WSP2] = p.omega_sp**2
    v[_ZSP] = 2.0 * p.delta_sp * p.omega_sp
    v[_KS2] = p.K_s2
    v[_WS1] = p.omega_s1
    v[_VSMAX] = p.v_s_max
    v[_XSMAX] = p.x_s_max
    v[_U0] = p.u_0
    v[_CDW] = p.C_d * p.w
    v[_DP] = p.P_s - p.P_T
    v[_INVRHO] = 1.0 / p.rho
    v[_KQS] = p.K_qs
    v[_KP] = 4.0 * p.beta_e / p.V_t
    v[_AP] = p.A_p
    v[_KCE] = p.K_ce
    v[_BP] = p.B_p
    v[_INVM] = 1.0 / p.M_t
    v[_KL] = p.K_l
    v[_FEXT] = p.F_ext
    v[_FC] = p.F_c
    v[_FS] = p.F_s
    v[_EPS] = p.eps_v
    v[_STROKE] = p.stroke
    return v


@numba.njit(cache=True, inline="always")
def _stop(x: float, v: float, a: float, lim: float) -> tuple[float, float]:
    """Rates (ẋ, v̇) of a mass at a travel limit: no outward motion."""
    if x >= lim:
        if v >= 0.0:
            return 0.0, min(a, 0.0)
        return v, a
    if x <= -lim:
        if v <= 0.0:
            return 0.0, max(a, 0.0)
        return v, a
    return v, a


@numba.njit(cache=True, inline="always")
def rhs(
    xf: float, vf: float, z: float, vz: float, xs: float, pl: float, y: float, vy: float,
    r: float, p: NDArray[np.float64], linear: bool, friction: bool,
) -> tuple[float, float, float, float, float, float, float, float]:
    """Return the time derivatives of the eight states (spec §1.4)."""
    ef = p[_CREF] * r - p[_KFB] * y
    dxf = vf
    af = p[_WF2] * (ef - xf) - p[_ZF] * vf
    az = p[_WSP2] * (p[_KS2] * xf - z) - p[_ZSP] * vz
    dxs = p[_WS1] * (z - xs)
    if linear:
        q = p[_KQS] * xs
    else:
        dxf, af = _stop(xf, vf, af, p[_XFMAX])
        vmax = p[_VSMAX]
        dxs = min(max(dxs, -vmax), vmax)
        if (xs >= p[_XSMAX] and dxs > 0.0) or (xs <= -p[_XSMAX] and dxs < 0.0):
            dxs = 0.0
        mag = abs(xs) - p[_U0]
        q = 0.0
        if mag > 0.0:
            # Merritt's matched, critically lapped valve: the metering edge
            # sees P_s − P_L (x_e > 0) or P_s + P_L (x_e < 0)
            drop = p[_DP] - pl if xs > 0.0 else p[_DP] + pl
            if drop > 0.0:
                q = math.copysign(mag, xs) * p[_CDW] * math.sqrt(drop * p[_INVRHO])
    dpl = p[_KP] * (q - p[_AP] * vy - p[_KCE] * pl)
    fnet = p[_AP] * pl - p[_BP] * vy - p[_KL] * y - p[_FEXT]
    ffr = 0.0
    if friction and not linear:
        if abs(vy) > p[_EPS]:
            ffr = math.copysign(p[_FC], vy)
        elif abs(fnet) <= p[_FS]:
            ffr = fnet  # Karnopp stick: friction balances the applied force
        else:
            ffr = math.copysign(p[_FS], fnet)
    ay = (fnet - ffr) * p[_INVM]
    dy = vy
    if not linear:
        dy, ay = _stop(y, vy, ay, p[_STROKE])
    return dxf, af, vz, az, dxs, dpl, dy, ay


@numba.njit(cache=True, inline="always")
def _rates(t, x, r, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    p, linear, friction = ctx
    return rhs(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], r, p, linear, friction)


@numba.njit(cache=True, inline="always")
def _limits(t, x, before, r, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Post-step hook: inelastic travel limits, then stiction of a piston at rest."""
    p, linear, friction = ctx
    if linear:
        return x
    xf, vf, z, vz, xs, pl, y, vy = x
    xfmax = p[_XFMAX]
    if xf > xfmax:
        xf = xfmax
        vf = min(vf, 0.0)
    elif xf < -xfmax:
        xf = -xfmax
        vf = max(vf, 0.0)
    xs = min(max(xs, -p[_XSMAX]), p[_XSMAX])
    stroke = p[_STROKE]
    if y > stroke:
        y = stroke
        vy = min(vy, 0.0)
    elif y < -stroke:
        y = -stroke
        vy = max(vy, 0.0)
    # stop exactly if the piston came to rest (or reversed) and the force at rest
    # cannot break away
    if (
        friction
        and (abs(vy) <= p[_EPS] or vy * before[7] < 0.0)
        and abs(p[_AP] * pl - p[_KL] * y - p[_FEXT]) <= p[_FS]
    ):
        vy = 0.0
    return xf, vf, z, vz, xs, pl, y, vy


@numba.njit(cache=True)
def integrate(
    y_r: NDArray[np.float64], y_r_past: float, decimation: int, delay: int, h: float,
    p: NDArray[np.float64], linear: bool, friction: bool, x0: NDArray[np.float64],
    out: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Integrate with fixed-step RK4; fill ``out`` and return the final state.

    ``out[i]`` holds (y, ẏ, P_L, x_s, x_f) at t = i·decimation·h, before
    the step that starts there.  The reference of step k is
    ``y_r[(k − delay) // decimation]`` (``y_r_past`` for k < delay):
    zero-order hold on the sample grid, delayed by ``delay`` steps.
    """
    x = (x0[0], x0[1], x0[2], x0[3], x0[4], x0[5], x0[6], x0[7])
    ctx = (p, linear, friction)
    for i in range(y_r.size):
        out[i, 0] = x[6]
        out[i, 1] = x[7]
        out[i, 2] = x[5]
        out[i, 3] = x[4]
        out[i, 4] = x[0]
        for m in range(decimation):
            j = i * decimation + m - delay
            r = y_r_past if j < 0 else y_r[j // decimation]
            x, _ = rk4_step(_rates, _limits, 0.0, x, r, ctx, h)
    final = np.empty(8)
    for k in range(8):
        final[k] = x[k]
    return final
