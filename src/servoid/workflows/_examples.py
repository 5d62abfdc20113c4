"""Small records the registered methods run on: each :class:`Method`'s ``example``.

Every registered method names a writer ``example(folder, seed) -> experiment
file`` (:attr:`~servoid.workflows.Method.example`); the conformance suite
(``tests/workflows/test_conformance.py``) runs each method on its own
example from TOML, the command line, the API and as a fleet row.  The
records are short (a few thousand samples) so a run takes seconds, noisy
(the noise drawn from ``seed``, so two seeds give two units of a fleet)
and made by the model family the method fits:

* :func:`open_loop` — a second-order plant driven by white noise
  (``"linear"``), or a static curve on either side of it
  (``"hammerstein"``, ``"wiener"``, ``"hammerstein-wiener"``), or a
  polynomial NARX system (``"narx"``);
* :func:`closed_loop` — the plant under a PI controller, noise in the loop;
* :func:`greybox_tank` — a tank draining through an orifice, with its
  Python model file.

The plants' methods write their own examples from their virtual benches.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

__all__ = ["closed_loop", "greybox_tank", "open_loop"]

Kind = Literal["linear", "hammerstein", "wiener", "hammerstein-wiener", "narx"]

_DT = 0.01
_N = 2000
#: the plant: poles 0.6 ± 0.37j (ω_n ≈ 66 rad/s at 100 Hz sampling, ζ ≈ 0.53), one delay
_A = (1.0, -1.2, 0.5)
_B = (0.0, 0.8, 0.3)


def open_loop(folder: Path, seed: int = 0, *, identify: Mapping[str, Any],
              kind: Kind = "linear", noise: float = 0.02, coloured: bool = False) -> Path:
    """Write an open-loop record and its experiment file (held-back half for validation).

    Parameters
    ----------
    folder : Path
        Where the files go (created).
    seed : int
        Seed of the input and the noise.
    identify : mapping
        The ``[identify]`` table.
    kind : str
        The system that makes the record (see the module notes).
    noise : float
        Standard deviation of the white noise at the output.
    coloured : bool
        Pass the noise through ``(1 + 0.3 q⁻¹)/(1 − 0.6 q⁻¹)`` first (for the
        methods with a noise model).

    Returns
    -------
    Path
        The experiment file.
    """
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    u = rng.standard_normal(_N)
    if kind == "narx":
        y = np.zeros(_N)
        for k in range(1, _N):
            y[k] = 0.5 * y[k - 1] + 0.4 * u[k - 1] + 0.1 * u[k - 1] ** 2
    elif kind == "hammerstein":
        y = lfilter(_B, _A, u + 0.3 * u**2 - 0.1 * u**3)
    elif kind == "wiener":
        x = lfilter(_B, _A, u) / 3.0
        y = x + 0.4 * x**2 - 0.1 * x**3
    elif kind == "hammerstein-wiener":
        u = 2.0 * u
        dead = np.sign(u) * np.maximum(np.abs(u) - 0.5, 0.0)
        x = lfilter(_B, _A, dead) / 3.0
        y = x + 0.4 * x**2
    else:
        y = lfilter(_B, _A, u)
    e = noise * rng.standard_normal(_N)
    y = y + (lfilter([1.0, 0.3], [1.0, -0.6], e) if coloured else e)
    return _write(folder, {"u": u, "y": y}, identify,
                  {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "mm"}})


def closed_loop(folder: Path, seed: int = 0, *, identify: Mapping[str, Any],
                loop: Mapping[str, Any] | None = None) -> Path:
    """Write a closed-loop record (r, u, y) of a continuous plant under a PI controller.

    The plant is 4/(s² + 2·0.4·4π s + (4π)²)·(4π)²/4 sampled at 50 Hz, the
    controller ``(0.5 + 0.06 − 0.5 q⁻¹)/(1 − q⁻¹)``, the reference a random
    binary signal, coloured noise in the loop; ``loop`` is the experiment
    file's ``[loop]`` (the known controller, for the methods that read it).
    """
    from ..bench import simulate_lti_loop
    from ..models import TransferFunction

    dt = 0.02
    wn = 2 * np.pi * 2.0
    plant = TransferFunction([wn**2], [1.0, 2 * 0.4 * wn, wn**2])
    pi = TransferFunction([0.5 + 3.0 * dt, -0.5], [1.0, -1.0], dt)
    rng = np.random.default_rng(seed)
    r = np.repeat(np.sign(rng.standard_normal(1000)), 2)
    exp = simulate_lti_loop(plant, pi, r, dt, noise_std=0.05,
                            noise_model=([1.0, 0.3], [1.0, -0.9]), rng=seed)
    channels = {"r": {"role": "r", "unit": "V"}, "u": {"role": "u", "unit": "V"},
                "y": {"role": "y", "unit": "mm"}}
    extra = {"loop": dict(loop)} if loop else {}
    return _write(folder, {n: exp[n] for n in ("r", "u", "y")}, identify, channels, dt=dt,
                  **extra)


#: The tank's Python model: level h [m], inflow k·u, outflow a·√(2 g h), cross-section 0.01 m².
_TANK = '''"""A tank fed by a pump (k·u) draining through an orifice (a·sqrt(2 g h))."""

import math


def rhs(x, u, p):
    """dh/dt of the level under the pump voltage u[0]."""
    return ((p[0] * u[0] - p[1] * math.sqrt(2.0 * 9.81 * max(x[0], 0.0))) / 0.01,)
'''


def greybox_tank(folder: Path, seed: int = 0) -> Path:
    """Write a tank's record, its Python model file and its experiment file (needs --allow-code)."""
    rng = np.random.default_rng(seed)
    dt, n = 0.5, 600
    u = np.repeat(rng.uniform(2.0, 6.0, n // 40), 40)
    k, a = 2e-4, 3e-5
    h = np.empty(n)
    level = 0.1
    for i in range(n):  # fine Euler steps within each sample: the record, not the fit
        h[i] = level
        for _ in range(50):
            level += dt / 50 * (k * u[i] - a * np.sqrt(2 * 9.81 * max(level, 0.0))) / 0.01
    y = h + 1e-4 * rng.standard_normal(n)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tank.py").write_text(_TANK, encoding="utf-8")
    identify = {"method": "greybox", "model": "tank.py:rhs", "states": ["h"],
                "initial_state": [0.1], "estimate_initial": ["h"],
                "parameters": {"k": [1e-4, 1e-6, 1e-2], "a": [1e-5, 1e-7, 1e-3]},
                "units": {"k": "m³/(s·V)", "a": "m²"}}
    return _write(folder, {"u": u, "y": y}, identify,
                  {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "m"}}, dt=dt)


def _write(folder: Path, signals: Mapping[str, Any], identify: Mapping[str, Any],
           channels: Mapping[str, Any], *, dt: float = _DT, **tables: Any) -> Path:
    from ..data import Experiment, write_csv, write_experiment_spec

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(Experiment.from_arrays(dt, **{k: np.asarray(v, dtype=float)
                                            for k, v in signals.items()}),
              folder / "record.csv", overwrite=True)
    path = folder / "experiment.toml"
    write_experiment_spec({"data": {"file": "record.csv"}, "channels": dict(channels),
                           "split": {"fraction": 0.5}, **tables, "identify": dict(identify)},
                          path, overwrite=True)
    return path
