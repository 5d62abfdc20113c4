"""The one integrator: every simulator's kernel, timed through its public call.

Every simulator in servoid advances its state with ``servoid.integrate.rk4_step``.
This suite times each one through the call a user makes, so that the same script
runs against any commit (``PYTHONPATH=<checkout>/src python benchmarks/bench_integrator.py``)
and the rows of two commits can be set side by side: the speed each kernel had
with its own hand-written RK4 against the speed it has on the shared step.

Cases (CPU time of the call, median over the repeats, after a warm-up call)
-----
ehsa nonlinear
    ``simulate_ehsa(SET_B, ±1 mm PRBS, dt = 1 ms)``, 2000 samples, friction
    and limits on: 1e6 RK4 steps of 8 states.
ehsa linear
    The same with ``linear=True``.
pneumatic closed loop
    ``simulate_pneumatic`` in its PD loop, 1 Hz sine, 4000 samples (4e5 steps).
rigid loop (sign model)
    ``simulate_rigid_loop(..., integration="sign", substeps=10)``, 2e4 samples.
user ODE compiled
    The two-tank grey-box model of ``examples/greybox`` (overflow clamp, pump
    saturation), 1e4 samples, 4 steps per sample, compiled by numba.
user ODE Python
    The same model on the plain-Python integrator, 2000 samples.
fit_greybox Python rhs (FOH)
    The simulator ``fit_greybox`` builds around a Python right-hand side (a
    damped oscillator, first-order hold on the input), 2000 samples, 4 steps
    per sample.

``n`` is the number of RK4 steps; ``extra["output_sha"]`` is a hash of the
outputs rounded to 12 significant digits, so two commits that agree to
1e-12 relative show the same hash.
"""

from __future__ import annotations

import hashlib
import importlib.util
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _harness import Result

SUITE = "integrator"
ROOT = Path(__file__).resolve().parents[1]


def run(quick: bool = False) -> list[Result]:
    """Run the suite; ``quick`` shortens every record tenfold."""
    scale = 10 if quick else 1
    repeats = 3 if quick else 9
    commit = _commit()
    rows = []
    for case, steps, call in _cases(scale):
        call()  # compile or load from the cache
        times = []
        for _ in range(repeats):
            t0 = time.process_time()
            out = call()
            times.append(time.process_time() - t0)
        median = float(np.median(times))
        rows.append(Result(
            SUITE, case, steps, "rk4", median * 1e3, min(times) * 1e3, repeats,
            note=f"{steps / median / 1e6:.3g} M steps/s (CPU time)",
            extra={"steps_per_s": steps / median, "commit": commit,
                   "output_sha": _digest(out)}))
    return rows


def _cases(scale: int) -> list[tuple[str, int, Callable[[], np.ndarray]]]:
    from servoid.plants.ehsa import SET_B, default_dt_int, simulate_ehsa
    from servoid.plants.pneumatic import (
        PNEUMATIC_NOMINAL,
        PositionController,
        pneumatic_dt_int,
        simulate_pneumatic,
    )
    from servoid.plants.rigid import CascadeController, RigidAxis, simulate_rigid_loop

    rng = np.random.default_rng(20261128)
    dt = 1e-3
    n_ehsa = 2000 // scale
    prbs = np.repeat(rng.choice([-1e-3, 1e-3], size=n_ehsa // 20 + 1), 20)[:n_ehsa]
    ehsa_steps = n_ehsa * round(dt / default_dt_int(SET_B, dt))
    n_pn = 4000 // scale
    sine = 0.05 * np.sin(2 * np.pi * 1.0 * dt * np.arange(n_pn))
    pn_steps = n_pn * round(dt / pneumatic_dt_int(PNEUMATIC_NOMINAL, dt))
    n_rigid = 20000 // scale
    reference = 0.05 * np.sin(2 * np.pi * 0.5 * dt * np.arange(n_rigid))
    axis = RigidAxis(95.0, 200.0, 20.0, offset=-3.0)
    controller = CascadeController(kp=160.18, kv=243.45, gtau=35.15 * 0.35)  # the EMPS loop
    tanks, n_ode = _tanks(10000 // scale), 10000 // scale

    return [
        ("ehsa nonlinear", ehsa_steps,
         lambda: simulate_ehsa(SET_B, prbs, dt).y),
        ("ehsa linear", ehsa_steps,
         lambda: simulate_ehsa(SET_B, prbs, dt, linear=True).y),
        ("pneumatic closed loop", pn_steps,
         lambda: simulate_pneumatic(PNEUMATIC_NOMINAL, None, dt, r=sine,
                                    controller=PositionController()).x_k),
        ("rigid loop (sign model)", n_rigid * 10,
         lambda: simulate_rigid_loop(axis, controller, reference, dt, integration="sign",
                                     substeps=10).position),
        ("user ODE compiled", n_ode * 4, tanks(compiled=True)),
        ("user ODE Python", (n_ode // 5) * 4, tanks(compiled=False, n=n_ode // 5)),
        ("fit_greybox Python rhs (FOH)", (2000 // scale) * 4, _greybox(2000 // scale)),
    ]


def _greybox(n: int) -> Callable[[], np.ndarray]:
    """``fit_greybox``'s simulator of a Python rhs: a damped oscillator, FOH input."""
    from servoid.estimate._greybox import _make_simulator

    t = 1e-2 * np.arange(n)
    u = np.sin(2 * np.pi * 0.7 * t)[:, None]

    def rhs(_t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        return np.array([x[1], -p[0] * x[0] - p[1] * x[1] + p[2] * u[0]])

    simulate = _make_simulator(rhs, np.zeros(2), None, t, u, "rk4", 4, "foh", None)
    return lambda: simulate(np.array([40.0, 2.0, 40.0]))


def _tanks(n: int) -> Callable[..., Callable[[], np.ndarray]]:
    """The grey-box example's two tanks as an OdeSystem (compiled or plain)."""
    from servoid.estimate._ode import make_system

    spec = importlib.util.spec_from_file_location(
        "bench_integrator_tanks", ROOT / "examples" / "greybox" / "tanks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    rng = np.random.default_rng(7)
    u = np.repeat(rng.uniform(0.0, 10.0, size=(n // 50 + 1, 1)), 50, axis=0)
    p = np.array([1.5e-5, 2.5e-5, 2.5e-5, 0.0154])
    x0 = np.array([0.1, 0.1])

    def build(compiled: bool, n: int = n) -> Callable[[], np.ndarray]:
        record = np.ascontiguousarray(u[:n])
        system = make_system(module.rhs, module.level, x0=x0, u=record, p=p,
                             state_lower=np.zeros(2), state_upper=np.array([0.3, np.inf]),
                             input_lower=np.zeros(1), input_upper=np.array([8.0]),
                             source="tanks.py:rhs", compile=compiled)
        return lambda: system.simulate(x0, record, p, 1.0, 4)

    return build


def _digest(values: np.ndarray) -> str:
    rounded = np.array([float(f"{v:.12g}") for v in np.ravel(values)])
    return hashlib.sha256(rounded.tobytes()).hexdigest()[:12]


def _commit() -> str:
    try:
        import servoid

        src = Path(servoid.__file__).resolve().parents[2]
        return subprocess.run(["git", "-C", str(src), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


if __name__ == "__main__":
    for row in run(quick=False):
        print(f"{row.case:26s} n={row.n:>9d}  {row.median_ms:9.2f} ms  {row.note:32s} "
              f"{row.extra['output_sha']}  @{row.extra['commit']}")
