"""Compiled RK4 kernel of the servopneumatic actuator (numba).

Inner helpers trust their inputs: :func:`servoid.plants.pneumatic.simulate_pneumatic`
validates everything and packs the parameters with :func:`pack`.

States, in order: spool x_v, ẋ_v; chamber pressures p_I, p_II; piston
x_k, ẋ_k; plus a discrete *stuck* flag.

Stick–slip scheme (no chatter).  The friction force of a moving piston is
the three-regime law of :func:`._friction.three_regime_nb`.  After each
RK4 step, a moving piston whose speed fell into the stick band
(|ẋ_k| <= ε) or whose velocity changed sign during the step is *stuck*
(ẋ_k set to exactly 0) if the applied force F_p at the end of the step is
within the static friction F_haft.  While stuck, the right-hand side keeps
ẋ_k = ẍ_k = 0 exactly (friction balances F_p) and the pressures evolve
alone.  At the start of every step a stuck piston breaks away if
|F_p| > F_haft; it then accelerates with ``(F_p − F_haft·sgn F_p)/m_k``.
Sticking needs |F_p| <= F_haft and breaking away needs |F_p| > F_haft,
so a piston cannot flip between the two states within one step, and the
switching instants are located to within one integration step.

End stops at ±stroke/2 are inelastic: inside the right-hand side a
piston at a stop cannot move further out, and after each step the
position is projected onto the range with the outward velocity zeroed.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ...integrate import rk4_step
from .._friction import three_regime_nb
from ._flow import orifice_mass_flow_nb
from ._params import PneumaticParameters

__all__ = ["N_OUT", "N_PARAMS", "integrate", "pack", "rhs"]

# indices into the packed parameter vector (compile-time constants for numba)
_KV, _WV2, _ZV, _A1, _A2, _A3, _A4, _CFLOW, _KRT, _KAPPA = range(10)
_B, _PIC, _PSIMAX, _PS, _PR, _AI, _AII, _V0I, _V0II, _FSTAT = range(10, 20)
_INVM, _FHAFT, _VKRIT, _CK, _DK, _EPS, _XLIM, _UMAX = range(20, 28)
N_PARAMS = 28

#: Output columns: x_v, p_I, p_II, ṁ_I, ṁ_II, x_k, ẋ_k, ẍ_k, u, F_p, F_fr, stuck, ẋ_v.
N_OUT = 13

# status codes returned by integrate
OK, BAD_PRESSURE = 0, 1


def pack(p: PneumaticParameters) -> NDArray[np.float64]:
    """Return the parameter vector the kernel reads."""
    v = np.empty(N_PARAMS)
    v[_KV] = p.k_v
    v[_WV2] = p.omega_v**2
    v[_ZV] = 2.0 * p.xi_v * p.omega_v
    v[_A1] = math.pi * p.ad_1
    v[_A2] = math.pi * p.ad_2
    v[_A3] = math.pi * p.ad_3
    v[_A4] = math.pi * p.ad_4
    v[_CFLOW] = math.sqrt(2.0 / (p.R * p.T_S))
    v[_KRT] = p.kappa * p.R * p.T_S
    v[_KAPPA] = p.kappa
    v[_B] = p.p_krit
    v[_PIC] = p.pi_crit
    v[_PSIMAX] = p.psi_max
    v[_PS] = p.p_S
    v[_PR] = p.p_R
    v[_AI] = p.A_I
    v[_AII] = p.A_II
    v[_V0I] = p.V_0I
    v[_V0II] = p.V_0II
    v[_FSTAT] = p.static_force
    v[_INVM] = 1.0 / p.m_k
    v[_FHAFT] = p.F_haft
    v[_VKRIT] = p.v_krit
    v[_CK] = p.c_k
    v[_DK] = p.d_k
    v[_EPS] = p.eps_v
    v[_XLIM] = p.stroke / 2.0
    v[_UMAX] = p.u_max
    return v


@numba.njit(cache=True, inline="always")
def flows(
    xv: float, p_i: float, p_ii: float, p: NDArray[np.float64], kind: int,
) -> tuple[float, float]:
    """Return the mass flows (ṁ_I, ṁ_II) into the chambers (eq. 3.x)."""
    if xv > 0.0:
        m1 = orifice_mass_flow_nb(p[_A2] * xv, p[_PS], p_i, p[_CFLOW], kind,
                                  p[_B], p[_KAPPA], p[_PIC], p[_PSIMAX])
        m2 = -orifice_mass_flow_nb(p[_A4] * xv, p_ii, p[_PR], p[_CFLOW], kind,
                                   p[_B], p[_KAPPA], p[_PIC], p[_PSIMAX])
    elif xv < 0.0:
        m1 = -orifice_mass_flow_nb(-p[_A1] * xv, p_i, p[_PR], p[_CFLOW], kind,
                                   p[_B], p[_KAPPA], p[_PIC], p[_PSIMAX])
        m2 = orifice_mass_flow_nb(-p[_A3] * xv, p[_PS], p_ii, p[_CFLOW], kind,
                                  p[_B], p[_KAPPA], p[_PIC], p[_PSIMAX])
    else:
        m1 = 0.0
        m2 = 0.0
    return m1, m2


@numba.njit(cache=True, inline="always")
def piston_force(p_i: float, p_ii: float, fext: float, p: NDArray[np.float64]) -> float:
    """Return F_p = p_I A_I − p_II A_II − p_amb(A_I − A_II) − m g + F_ext."""
    return p_i * p[_AI] - p_ii * p[_AII] - p[_FSTAT] + fext


@numba.njit(cache=True, inline="always")
def rhs(
    xv: float, vv: float, p_i: float, p_ii: float, xk: float, vk: float,
    uff: float, r: float, fext: float, kp: float, kd: float, closed: bool, stuck: bool,
    p: NDArray[np.float64], kind: int, blend: bool,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float]:
    """Return the six state rates and (ṁ_I, ṁ_II, u, F_p, F_fr)."""
    u = uff
    if closed:
        u += kp * (r - xk) - kd * vk
    umax = p[_UMAX]
    u = min(max(u, -umax), umax)
    av = p[_WV2] * (p[_KV] * u - xv) - p[_ZV] * vv
    m1, m2 = flows(xv, p_i, p_ii, p, kind)
    vol1 = p[_V0I] + p[_AI] * xk
    vol2 = p[_V0II] - p[_AII] * xk
    kap = p[_KAPPA]
    dp1 = (p[_KRT] * m1 - kap * p_i * p[_AI] * vk) / vol1
    dp2 = (p[_KRT] * m2 + kap * p_ii * p[_AII] * vk) / vol2
    fp = piston_force(p_i, p_ii, fext, p)
    if stuck:
        return vv, av, dp1, dp2, 0.0, 0.0, m1, m2, u, fp, fp
    ffr = three_regime_nb(vk, fp, p[_FHAFT], p[_DK], p[_CK], p[_VKRIT], p[_EPS], blend)
    ak = (fp - ffr) * p[_INVM]
    dx = vk
    lim = p[_XLIM]
    if xk >= lim and vk >= 0.0:
        dx = 0.0
        ak = min(ak, 0.0)
    elif xk <= -lim and vk <= 0.0:
        dx = 0.0
        ak = max(ak, 0.0)
    return vv, av, dp1, dp2, dx, ak, m1, m2, u, fp, ffr


@numba.njit(cache=True, inline="always")
def _rates(t, x, w, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    uff, r, fext, stuck = w
    kp, kd, closed, p, kind, blend = ctx
    return rhs(x[0], x[1], x[2], x[3], x[4], x[5], uff, r, fext, kp, kd, closed, stuck, p,
               kind, blend)


@numba.njit(cache=True, inline="always")
def _limits(t, x, before, w, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Post-step hook: (state, stuck, ok): pressure check, end stops, sticking."""
    _, _, fext, stuck = w
    p = ctx[3]
    xv, vv, p1, p2, xk, vk = x
    if not (p1 > 0.0 and p2 > 0.0 and math.isfinite(p1) and math.isfinite(p2)):
        return x, stuck, False
    lim = p[_XLIM]
    if xk > lim:
        xk = lim
        vk = min(vk, 0.0)
    elif xk < -lim:
        xk = -lim
        vk = max(vk, 0.0)
    if (
        not stuck
        and (abs(vk) <= p[_EPS] or vk * before[5] < 0.0)
        and abs(piston_force(p1, p2, fext, p)) <= p[_FHAFT]
    ):
        stuck = True
        vk = 0.0
    return (xv, vv, p1, p2, xk, vk), stuck, True


@numba.njit(cache=True)
def integrate(
    u: NDArray[np.float64], r: NDArray[np.float64], fext: NDArray[np.float64],
    closed: bool, kp: float, kd: float, decimation: int, h: float,
    p: NDArray[np.float64], kind: int, blend: bool, x0: NDArray[np.float64], stuck0: bool,
    out: NDArray[np.float64],
) -> tuple[NDArray[np.float64], bool, int, int]:
    """Integrate with fixed-step RK4; fill ``out``.

    ``out[i]`` holds the :data:`N_OUT` outputs at t = i·decimation·h,
    before the step that starts there.  Inputs are held (ZOH) over each
    sample.  Returns (final state, final stuck flag, status, step index);
    status :data:`BAD_PRESSURE` stops at the first step that leaves a
    non-positive or non-finite pressure.
    """
    x = (x0[0], x0[1], x0[2], x0[3], x0[4], x0[5])
    stuck = stuck0
    ctx = (kp, kd, closed, p, kind, blend)
    fh = p[_FHAFT]
    status = OK
    bad_step = -1
    for i in range(u.size):
        uf = u[i]
        ri = r[i]
        fe = fext[i]
        for m in range(decimation):
            if stuck and abs(piston_force(x[2], x[3], fe, p)) > fh:
                stuck = False  # breakaway
            (x_new, stuck_new, ok), k1 = rk4_step(_rates, _limits, 0.0, x, (uf, ri, fe, stuck),
                                                  ctx, h)
            if m == 0:
                out[i, 0] = x[0]
                out[i, 1] = x[2]
                out[i, 2] = x[3]
                out[i, 3] = k1[6]
                out[i, 4] = k1[7]
                out[i, 5] = x[4]
                out[i, 6] = x[5]
                out[i, 7] = k1[5]
                out[i, 8] = k1[8]
                out[i, 9] = k1[9]
                out[i, 10] = k1[10]
                out[i, 11] = 1.0 if stuck else 0.0
                out[i, 12] = x[1]
            if not ok:
                status = BAD_PRESSURE
                bad_step = i * decimation + m
                x = x_new
                break
            x, stuck = x_new, stuck_new
        if status != OK:
            for j in range(i, u.size):
                for c in range(out.shape[1]):
                    out[j, c] = np.nan
            break
    final = np.empty(6)
    for k in range(6):
        final[k] = x[k]
    return final, stuck, status, bad_step
