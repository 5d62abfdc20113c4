"""An independent implementation of the EMA and its drive, for the tests.

Written from the equations of ``docs/ema.md``, not from the kernel: the
continuous actuator as a linear state space (exact zero-order-hold
discretisation by the matrix exponential) or as a nonlinear ODE solved by
SciPy's ``solve_ivp`` to a tight tolerance, and the drive as plain Python.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm


def linear_matrices(p):
    """A, B_u, B_f of the actuator without Coulomb friction and backlash."""
    n = p.transmission
    a = np.zeros((5, 5))
    a[0, 0], a[0, 2] = -p.R / p.L, -p.K_m / p.L
    a[1, 2] = 1.0
    # J ω̇ = K i − (k (θ/n − x) + c (ω/n − v))/n − b_m ω
    a[2, 0] = p.K_m / p.J_m
    a[2, 1] = -p.k_s / n**2 / p.J_m
    a[2, 2] = (-p.c_s / n**2 - p.b_m) / p.J_m
    a[2, 3] = p.k_s / n / p.J_m
    a[2, 4] = p.c_s / n / p.J_m
    a[3, 4] = 1.0
    # m v̇ = k (θ/n − x) + c (ω/n − v) − b_L v − f
    a[4, 1] = p.k_s / n / p.m_L
    a[4, 2] = p.c_s / n / p.m_L
    a[4, 3] = -p.k_s / p.m_L
    a[4, 4] = (-p.c_s - p.b_L) / p.m_L
    b = np.zeros((5, 2))
    b[0, 0] = 1.0 / p.L
    b[4, 1] = -1.0 / p.m_L
    return a, b


def zoh(a, b, dt):
    """Exact discretisation of ẋ = Ax + Bw with w held over dt."""
    m = np.zeros((a.shape[0] + b.shape[1],) * 2)
    m[:5, :5] = a * dt
    m[:5, 5:] = b * dt
    e = expm(m)
    return e[:5, :5], e[:5, 5:]


def sign(x):
    return 1.0 if x > 0 else -1.0 if x < 0 else 0.0


def rhs(p, u, f):
    """The nonlinear ODE (Coulomb by sign, no sticking) as a solve_ivp function."""
    n = p.transmission

    def f_rhs(t, s):
        i, th, om, x, v = s
        fs = p.k_s * (th / n - x) + p.c_s * (om / n - v)
        return [(u - p.R * i - p.K_m * om) / p.L, om,
                (p.K_m * i - fs / n - p.b_m * om - p.T_cm * sign(om)) / p.J_m,
                v, (fs - p.b_L * v - p.F_cL * sign(v) - f) / p.m_L]
    return f_rhs


class Drive:
    """The cascade of the drive, sample by sample."""

    def __init__(self, c, dt, theta0, omega0):
        self.c, self.dt = c, dt
        self.z = [0.0, 0.0, 0.0]
        self.q = 2 * math.pi / c.encoder_counts if c.encoder_counts else 0.0
        self.prev = self.enc(theta0 - omega0 * dt * c.outer_every)
        self.i_ref = 0.0
        self.w_ref = 0.0
        self.k = 0

    def enc(self, th):
        return math.floor(th / self.q) * self.q if self.q else th

    @staticmethod
    def pi(kp, ki, z, e, lim, period):
        out = kp * e + z
        sat = abs(out) > lim
        out = max(-lim, min(lim, out))
        if not (sat and e * out > 0):
            z = z + ki * e * period
        return out, z

    def step(self, r, state, transmission):
        c = self.c
        i, th, _, x, _ = state
        th_m = self.enc(th)
        x_m = x if c.feedback == "load" else th_m / transmission
        if self.k % c.outer_every == 0:
            t_o = c.outer_every * self.dt
            w_hat = (th_m - self.prev) / t_o
            self.prev = th_m
            self.w_ref, self.z[2] = self.pi(c.kp_x, c.ki_x, self.z[2], r - x_m, c.w_max, t_o)
            self.i_ref, self.z[1] = self.pi(c.kp_w, c.ki_w, self.z[1], self.w_ref - w_hat,
                                            c.i_max, t_o)
        u, self.z[0] = self.pi(c.kp_i, c.ki_i, self.z[0], self.i_ref - i, c.u_max, self.dt)
        self.k += 1
        return u


def simulate_linear(p, c, r, dt, f_ext, x0):
    """The drive around the exact sampled linear actuator."""
    a, b = linear_matrices(p)
    phi, gam = zoh(a, b, dt)
    state = np.array(x0, dtype=float)
    drive = Drive(c, dt, state[1], state[2])
    out = np.empty((r.size, 6))
    for k in range(r.size):
        u = drive.step(r[k], state, p.transmission)
        out[k, :5], out[k, 5] = state, u
        state = phi @ state + gam @ np.array([u, f_ext[k]])
    return out


def simulate_ode(p, c, r, dt, f_ext, x0, rtol=1e-11):
    """The drive around solve_ivp (DOP853) of the nonlinear ODE, sample by sample."""
    state = np.array(x0, dtype=float)
    drive = Drive(c, dt, state[1], state[2])
    out = np.empty((r.size, 6))
    for k in range(r.size):
        u = drive.step(r[k], state, p.transmission)
        out[k, :5], out[k, 5] = state, u
        sol = solve_ivp(rhs(p, u, f_ext[k]), (0.0, dt), state, method="DOP853", rtol=rtol,
                        atol=1e-12 * np.maximum(np.abs(state), 1e-3))
        state = sol.y[:, -1]
    return out
