"""PNLSS: the fit and the compiled simulation against plain scipy and numpy.

Target (issue 27): 1e4 samples, 2 states, degree 3 (full monomials): the fit
≤ 10 s on one core; the compiled simulation ≥ 10 M state updates/s; side by
side with a plain scipy ``least_squares`` implementation of the same model
and the same model's plain-numpy simulation.

Case
----
fit-1e4
    A Duffing-type hardening spring (x'' + 2ζω x' + ω²(x + 0.5 x³) = ω² u,
    5 Hz, ζ = 0.1) simulated by RK4 at 20 steps a sample (a plain Python
    loop, not servoid's kernels), sampled at 50 Hz, 1e4 samples of a
    random-phase multisine over (0, 15 Hz] at 0.3 RMS, output noise
    σ = 0.005; fixed seed. The model: 2 states, degree 3, full monomials
    (the constant and 16 monomials of x1, x2, u: 57 coefficients).
simulate
    The fitted model's free run on 1e6 samples (1e5 under ``--quick``).

Methods
-------
servoid fit_pnlss
    ``fit_pnlss(exp, 2, 3)``: the n4sid start, Levenberg–Marquardt on the
    linear part, then on all, with the compiled exact Jacobian.
scipy least_squares (numpy sim, 2-point Jacobian)
    The same model and the same start (servoid's linear start with E = F = 0
    and the initial state as parameters), ``scipy.optimize.least_squares``
    (``method="lm"``, ``jac="2-point"``, ``x_scale="jac"``) on the residual of a
    plain-numpy simulation loop, ``max_nfev`` = 4·(p + 1) (scipy's count
    leaves out the differencing calls, so it runs to its own convergence
    here): what a user writes without a compiled model. Its ``extra`` gives
    the RMS it reached, scipy's status and its time over servoid's.
servoid simulate / numpy simulate
    ``PnlssModel.simulate`` (numba) against a plain numpy loop over the same
    equations (monomials by ``np.prod(z ** P, axis=1)``); ``extra`` gives the
    state updates per second (samples × 1: one state update a sample).

``rel_diff`` of the numpy simulation: max |y_numpy − y_servoid| / max |y|.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from _harness import Result, time_call

from servoid import ServoidWarning
from servoid.data import Experiment
from servoid.nonlinear import fit_pnlss

SUITE = "pnlss"
SEED = 20261129
FS = 50.0


def _record(n: int) -> Experiment:
    rng = np.random.default_rng(SEED)
    k = np.arange(1, int(0.3 * n))
    t = np.arange(n) / FS
    # the multisine by blocks of lines (an n × 0.3 n matrix would not fit in memory)
    u = np.zeros(n)
    for block in np.array_split(k, max(1, k.size // 200)):
        u += np.cos(2 * np.pi * np.outer(t, block * FS / n)
                    + rng.uniform(0, 2 * np.pi, block.size)).sum(1)
    u = 0.3 * u / u.std()
    w, z, over = 2 * np.pi * 5, 0.1, 20
    h = 1 / (FS * over)

    def f(s0: float, s1: float, v: float) -> tuple[float, float]:
        return s1, w * w * (v - s0 - 0.5 * s0**3) - 2 * z * w * s1

    x, v, y = 0.0, 0.0, np.empty(n)
    for i in range(n):  # a plain RK4 loop: not the estimator's kernels
        y[i] = x
        for _ in range(over):
            a = f(x, v, u[i])
            b = f(x + h / 2 * a[0], v + h / 2 * a[1], u[i])
            c = f(x + h / 2 * b[0], v + h / 2 * b[1], u[i])
            d = f(x + h * c[0], v + h * c[1], u[i])
            x += h / 6 * (a[0] + 2 * b[0] + 2 * c[0] + d[0])
            v += h / 6 * (a[1] + 2 * b[1] + 2 * c[1] + d[1])
    return Experiment.from_arrays(u=u, y=y + 0.005 * rng.standard_normal(n), dt=1 / FS)


def _numpy_simulate(theta: np.ndarray, shapes: tuple[int, int, int], P: np.ndarray,
                    un: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """The model's free run by a plain numpy loop."""
    nx, nu, nm = shapes
    sizes = np.cumsum([nx * nx, nx * nu, nx, nu, nx * nm])
    A, B, C, D, E, F = np.split(theta, sizes)
    A, B, E = A.reshape(nx, nx), B.reshape(nx, nu), E.reshape(nx, nm)
    x = x0.copy()
    y = np.empty(un.shape[0])
    for t in range(un.shape[0]):
        zt = np.concatenate([x, un[t]])
        m = np.prod(zt ** P, axis=1)
        y[t] = C @ x + D @ un[t] + F @ m
        x = A @ x + B @ un[t] + E @ m
        if not np.all(np.abs(x) < 1e12):
            y[t:] = np.nan
            break
    return y


def run(quick: bool) -> list[Result]:
    n = 10_000
    exp = _record(n)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        timing = time_call(lambda: fit_pnlss(exp, 2, 3), repeats=2 if quick else 5)
        est = fit_pnlss(exp, 2, 3)
        start = fit_pnlss(exp, 2, 3, max_iter=0)  # the linear start, E = F = 0
    model = est.model
    o = est.options
    rms = float(np.sqrt(o["cost"]))
    rows.append(Result(SUITE, "fit-1e4", n, "servoid fit_pnlss", timing.median * 1e3,
                       timing.best * 1e3, len(timing.times),
                       note=f"{o['iterations']} LM iterations, free-run RMS {rms:.4g}",
                       extra={"iterations": o["iterations"], "rms": rms,
                              "parameters": est.parameters.size}))
    # the same problem by scipy least_squares on a plain numpy simulation
    from scipy.optimize import least_squares

    m0 = start.model
    un = (exp["u"][:, None] - m0.u_mean) / m0.u_scale
    yn = (exp["y"] - m0.y_mean) / m0.y_scale
    shapes = (m0.n_states, m0.n_inputs, m0.n_monomials)
    p0 = np.concatenate([m0.parameters, np.zeros(m0.n_states)])
    n_model = m0.n_parameters

    def residual(p: np.ndarray) -> np.ndarray:
        r = _numpy_simulate(p[:n_model], shapes, m0.powers, un, p[n_model:]) - yn
        return np.where(np.isfinite(r), r, 1e6)

    # MINPACK's lm counts the Jacobian's differencing calls in nfev (trf does not)
    n_jac = 2 if quick else 4
    nfev = n_jac * (p0.size + 1)
    t0 = time.perf_counter()
    sol = least_squares(residual, p0, method="lm", jac="2-point", x_scale="jac",
                        max_nfev=nfev)
    took = time.perf_counter() - t0
    reached = float(np.sqrt(np.mean(sol.fun**2))) * m0.y_scale
    rows.append(Result(
        SUITE, "fit-1e4", n, "scipy least_squares (numpy sim, 2-point)", took * 1e3, took * 1e3,
        1, note=f"{sol.message} RMS {reached:.4g} (servoid {rms:.4g})",
        extra={"nfev": int(sol.nfev), "status": int(sol.status), "rms": reached,
               "speedup_servoid": took / timing.median}))
    # simulation speed
    n_sim = 100_000 if quick else 1_000_000
    rng = np.random.default_rng(SEED + 1)
    u_long = 0.3 * rng.standard_normal(n_sim)
    sim = time_call(lambda: model.simulate(u_long), repeats=3 if quick else 7)
    rate = n_sim / sim.median
    rows.append(Result(SUITE, "simulate", n_sim, "servoid PnlssModel.simulate (numba)",
                       sim.median * 1e3, sim.best * 1e3, len(sim.times),
                       note=f"{rate / 1e6:.3g} M state updates/s",
                       extra={"updates_per_s": rate}))
    n_np = 10_000
    un_s = (u_long[:n_np, None] - model.u_mean) / model.u_scale
    np_t = time_call(lambda: _numpy_simulate(model.parameters, shapes, model.powers, un_s,
                                             np.zeros(model.n_states)), repeats=3)
    y_np = _numpy_simulate(model.parameters, shapes, model.powers, un_s, np.zeros(2))
    y_sv = (model.simulate(u_long[:n_np]) - model.y_mean) / model.y_scale
    diff = float(np.max(np.abs(y_np - y_sv)) / np.max(np.abs(y_sv)))
    rate_np = n_np / np_t.median
    rows.append(Result(SUITE, "simulate", n_np, "numpy loop (same model)", np_t.median * 1e3,
                       np_t.best * 1e3, len(np_t.times), rel_diff=diff,
                       note=f"{rate_np / 1e6:.3g} M state updates/s "
                            f"({rate / rate_np:.0f}× slower than servoid)",
                       extra={"updates_per_s": rate_np, "speedup": rate / rate_np}))
    return rows
