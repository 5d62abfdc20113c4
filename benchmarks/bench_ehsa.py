"""Nonlinear EHSA simulator: compiled RK4 against pure Python and solve_ivp.

Cases
-----
set B 10 mm step
    ``simulate_ehsa(SET_B, 10 mm step, dt = 1 ms)``: the full-order nonlinear
    model (flapper, spool stage, rate/travel limits, pressure-dependent flow,
    friction, end stops, 1 ms dead time), RK4 at the default dt_int = 2 µs,
    500 steps per output sample.  One core (numba, no parallel loops).
set C PRBS ±1 mm
    Same on the unloaded set with a ±1 mm PRBS-like command (stick-slip).

Methods
-------
numba RK4
    The public call, timed after a warm-up call (JIT compilation and the
    on-disk cache load are excluded).  ``n`` = RK4 steps; steps/s in
    ``extra``.
pure-Python RK4
    The same kernel source (``integrate.py_func``) with the right-hand side
    and its helper swapped for their Python functions, on a short record.
solve_ivp RK45
    ``scipy.integrate.solve_ivp`` (RK45, rtol 1e-6, atol scaled per state)
    on the same Python right-hand side (friction off: solve_ivp has no
    post-step projection for stiction and stops), short record.  ``n`` =
    right-hand-side evaluations / 4 (RK4-step equivalents);
    ``rel_diff`` = |y_ivp − y_numba|/|y_numba| at the end of the record.

Target: >= 2e6 RK4 steps/s for the numba kernel on one core.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import numpy as np
from _harness import Result, time_call
from scipy.integrate import solve_ivp

from servoid.plants.ehsa import SET_B, SET_C, default_dt_int, simulate_ehsa
from servoid.plants.ehsa import _kernel as kernel

SUITE = "ehsa"
DT = 1e-3
TARGET = 2e6


def run(quick: bool) -> list[Result]:
    """Run the suite; ``quick`` uses short records and few repeats."""
    n_samples = 200 if quick else 2000
    repeats = 3 if quick else 7
    rows = []
    rng = np.random.default_rng(20261121)
    prbs = np.repeat(rng.choice([-1e-3, 1e-3], size=n_samples // 20 + 1), 20)[:n_samples]
    for case, params, y_r in (
        ("set B 10 mm step", SET_B, np.full(n_samples, 10e-3)),
        ("set C PRBS ±1 mm", SET_C, prbs),
    ):
        steps = n_samples * round(DT / default_dt_int(params, DT))
        timing = time_call(lambda p=params, u=y_r: simulate_ehsa(p, u, DT), repeats, warmup=1)
        rate = steps / timing.median
        rows.append(Result(
            SUITE, case, steps, "numba RK4", timing.median * 1e3, timing.best * 1e3, repeats,
            note=f"{rate / 1e6:.2f} M steps/s (target {TARGET / 1e6:.0f} M)",
            extra={"steps_per_s": rate, "meets_target": rate >= TARGET},
        ))
    rows += _python_rows(quick)
    return rows


def _python_rows(quick: bool) -> list[Result]:
    n_samples = 2 if quick else 10  # 1 000 / 5 000 RK4 steps
    p = SET_B.with_(T_d=0.0)
    y_r = np.full(n_samples, 10e-3)
    h = default_dt_int(p, DT)
    decimation = round(DT / h)
    packed = kernel.pack(p)
    x0 = np.zeros(8)

    def pure() -> np.ndarray:
        out = np.empty((n_samples, 5))
        with _python_kernel():
            return kernel.integrate.py_func(y_r, 0.0, decimation, 0, h, packed, False, False,
                                            x0, out)

    t0 = time.perf_counter()
    pure()
    t_pure = time.perf_counter() - t0
    steps = n_samples * decimation
    rows = [Result(SUITE, "set B 10 mm step (short)", steps, "pure-Python RK4",
                   t_pure * 1e3, t_pure * 1e3, 1,
                   note=f"{steps / t_pure:.3g} steps/s",
                   extra={"steps_per_s": steps / t_pure})]

    rhs = kernel.rhs.py_func
    scale = np.array([p.x_f_max, p.x_f_max * p.omega_f, 1e-4, 1e-4 * p.omega_sp, p.x_s_max,
                      p.P_s, p.stroke, p.v_max]) * 1e-6

    def fun(_t: float, x: np.ndarray) -> tuple[float, ...]:
        return rhs(*x, 10e-3, packed, False, False)

    t0 = time.perf_counter()
    with _python_kernel():
        sol = solve_ivp(fun, (0.0, n_samples * DT), x0, method="RK45", rtol=1e-6, atol=scale)
    t_ivp = time.perf_counter() - t0
    ref = simulate_ehsa(p, np.full(n_samples + 1, 10e-3), DT, friction=False)
    diff = abs(sol.y[6, -1] - ref.y[-1]) / abs(ref.y[-1])
    equiv = sol.nfev / 4
    rows.append(Result(SUITE, "set B 10 mm step (short)", int(equiv), "solve_ivp RK45",
                       t_ivp * 1e3, t_ivp * 1e3, 1, rel_diff=float(diff),
                       note=f"{sol.nfev} rhs calls, {equiv / t_ivp:.3g} RK4-step equiv/s",
                       extra={"nfev": sol.nfev, "status": sol.status}))
    return rows


@contextlib.contextmanager
def _python_kernel() -> Iterator[None]:
    """Swap the compiled helpers for their Python functions (py_func reads globals)."""
    names = ("rhs", "_stop", "rk4_step", "_rates", "_limits")
    saved = [getattr(kernel, name) for name in names]
    for name, fn in zip(names, saved, strict=True):
        setattr(kernel, name, fn.py_func)
    try:
        yield
    finally:
        for name, fn in zip(names, saved, strict=True):
            setattr(kernel, name, fn)


if __name__ == "__main__":
    for row in run(quick=False):
        print(f"{row.case:28s} {row.method:18s} n={row.n:>9d}  {row.median_ms:10.2f} ms  "
              f"{row.note}" + ("" if row.rel_diff is None else f"  rel.diff {row.rel_diff:.1e}"))
