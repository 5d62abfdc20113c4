"""Servopneumatic simulator: compiled RK4 against pure Python and solve_ivp.

Cases
-----
closed loop 1 Hz sine
    ``simulate_pneumatic(PNEUMATIC_NOMINAL, None, 1e-4, r=20 mm·sin(2π·1 Hz·t),
    controller=PositionController())``: the spec §2 "Checked" run (spool,
    two chambers with ellipse flow, three-regime friction with stick-slip,
    end stops), RK4 at the default dt_int = 10 µs, 10 steps per sample.
    One core (numba, no parallel loops).

Methods
-------
numba RK4
    The public call, timed after a warm-up call (JIT compilation and the
    on-disk cache load excluded).  ``n`` = RK4 steps; steps/s in ``extra``.
pure-Python RK4
    The same kernel source (``integrate.py_func``) with the right-hand
    side and its helpers swapped for their Python functions, short record.
solve_ivp RK45
    ``scipy.integrate.solve_ivp`` (RK45, rtol 1e-6, atol scaled per state)
    on the same pure-Python right-hand side (stick flag off: solve_ivp has
    no post-step stick/stop handling, so the Karnopp band alone acts),
    short record.  ``n`` = right-hand-side evaluations / 4 (RK4-step
    equivalents).  ``extra["speedup"]`` = numba RK4 steps/s over the
    reference's RK4-step equivalents/s; ``rel_diff`` = |x_k,ivp − x_k,numba|
    at the end of the record relative to the 20 mm amplitude.  The short
    records are a window from t = 0.13 s of the full run (about half stuck), started from its
    state there, so they include slipping and sticking.

Targets: >= 5e6 RK4 steps/s for the numba kernel on one core, and
>= 100× the reference's throughput in RK4-step equivalents per second
(``extra["speedup"]``); the wall-time ratio per simulated second is in
``extra["speedup_per_simulated_second"]`` (RK45 takes longer steps where
the motion is smooth, so it is the smaller of the two).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import numpy as np
from _harness import Result, time_call
from scipy.integrate import solve_ivp

from servoid.plants import _friction as friction_mod
from servoid.plants.pneumatic import (
    PNEUMATIC_NOMINAL,
    PneumaticResponse,
    PositionController,
    simulate_pneumatic,
)
from servoid.plants.pneumatic import _flow as flow_mod
from servoid.plants.pneumatic import _kernel as kernel

SUITE = "pneumatic"
DT = 1e-4
TARGET = 5e6
TARGET_SPEEDUP = 100.0
AMPLITUDE = 0.02


def run(quick: bool) -> list[Result]:
    """Run the suite; ``quick`` uses short records and few repeats."""
    p = PNEUMATIC_NOMINAL
    ctrl = PositionController()
    n_samples = 5000 if quick else 20000  # 0.5 s / 2 s
    repeats = 3 if quick else 7
    r = AMPLITUDE * np.sin(2 * np.pi * np.arange(n_samples) * DT)
    res = simulate_pneumatic(p, None, DT, r=r, controller=ctrl)
    steps = n_samples * round(DT / res.dt_int)
    timing = time_call(lambda: simulate_pneumatic(p, None, DT, r=r, controller=ctrl), repeats,
                       warmup=1)
    rate = steps / timing.median
    numba_s_per_s = timing.median / (n_samples * DT)
    rows = [Result(
        SUITE, "closed loop 1 Hz sine", steps, "numba RK4", timing.median * 1e3,
        timing.best * 1e3, repeats,
        note=f"{rate / 1e6:.2f} M steps/s (target {TARGET / 1e6:.0f} M)",
        extra={"steps_per_s": rate, "meets_target": rate >= TARGET},
    )]
    rows += _python_rows(quick, numba_s_per_s, rate, res)
    return rows


def _python_rows(quick: bool, numba_s_per_s: float, numba_rate: float,
                 full: PneumaticResponse) -> list[Result]:
    p = PNEUMATIC_NOMINAL
    h = full.dt_int
    n_samples = 100 if quick else 400  # 10 / 40 ms
    t_end = n_samples * DT
    # a window in mid-stroke, where the piston slips and sticks (not the quiet start)
    k0 = 1300
    r = np.asarray(full.r)[k0:k0 + n_samples]
    packed = kernel.pack(p)
    x0 = np.array([full.x_v[k0], full.x_v_dot[k0], full.p_I[k0], full.p_II[k0],
                   full.x_k[k0], full.x_k_dot[k0]])
    decimation = round(DT / h)
    zeros = np.zeros(n_samples)

    def pure() -> object:
        out = np.empty((n_samples, kernel.N_OUT))
        with _python_kernel():
            return kernel.integrate.py_func(zeros, r, zeros, True, 300.0, 5.0, decimation, h,
                                            packed, 0, False, x0, bool(x0[5] == 0.0), out)

    t0 = time.perf_counter()
    pure()
    t_pure = time.perf_counter() - t0
    steps = n_samples * decimation
    rows = [Result(SUITE, "closed loop 1 Hz sine (short)", steps, "pure-Python RK4",
                   t_pure * 1e3, t_pure * 1e3, 1,
                   note=f"{steps / t_pure:.3g} steps/s; numba is "
                        f"{t_pure / t_end / numba_s_per_s:.0f}× faster",
                   extra={"steps_per_s": steps / t_pure,
                          "speedup": t_pure / t_end / numba_s_per_s})]

    rhs = kernel.rhs.py_func

    def fun(t: float, x: np.ndarray) -> tuple[float, ...]:
        ri = r[min(int(t / DT), n_samples - 1)]
        return rhs(*x, 0.0, ri, 0.0, 300.0, 5.0, True, False, packed, 0, False)[:6]

    scale = np.array([p.k_v * p.u_max, p.k_v * p.u_max * p.omega_v, p.p_S, p.p_S,
                      p.stroke, 1.0]) * 1e-6
    t0 = time.perf_counter()
    with _python_kernel():
        sol = solve_ivp(fun, (0.0, t_end), x0, method="RK45", rtol=1e-6, atol=scale)
    t_ivp = time.perf_counter() - t0
    diff = abs(sol.y[4, -1] - full.x_k[k0 + n_samples]) / AMPLITUDE
    equiv = sol.nfev / 4
    ratio = numba_rate / (equiv / t_ivp)
    per_second = t_ivp / t_end / numba_s_per_s
    rows.append(Result(
        SUITE, "closed loop 1 Hz sine (short)", int(equiv), "solve_ivp RK45",
        t_ivp * 1e3, t_ivp * 1e3, 1, rel_diff=float(diff),
        note=f"{sol.nfev} rhs calls, {equiv / t_ivp:.3g} RK4-step equiv/s: numba RK4 is "
             f"{ratio:.0f}× the throughput (target {TARGET_SPEEDUP:.0f}×) and "
             f"{per_second:.0f}× faster per simulated second",
        extra={"nfev": sol.nfev, "status": sol.status, "speedup": ratio,
               "speedup_per_simulated_second": per_second,
               "meets_target": ratio >= TARGET_SPEEDUP},
    ))
    return rows


@contextlib.contextmanager
def _python_kernel() -> Iterator[None]:
    """Swap the compiled helpers for their Python functions (py_func reads globals)."""
    swaps = [
        (kernel, "rhs"), (kernel, "flows"), (kernel, "piston_force"),
        (kernel, "rk4_step"), (kernel, "_rates"), (kernel, "_limits"),
        (kernel, "orifice_mass_flow_nb"), (kernel, "three_regime_nb"),
        (flow_mod, "psi_ellipse_nb"), (flow_mod, "psi_saint_venant_nb"),
        (friction_mod, "three_regime_nb"),
    ]
    saved = [(mod, name, getattr(mod, name)) for mod, name in swaps]
    for mod, name, fn in saved:
        setattr(mod, name, fn.py_func)
    try:
        yield
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)


if __name__ == "__main__":
    for row in run(quick=False):
        print(f"{row.case:32s} {row.method:18s} n={row.n:>9d}  {row.median_ms:10.2f} ms  "
              f"{row.note}" + ("" if row.rel_diff is None else f"  rel.diff {row.rel_diff:.1e}"))
