"""A virtual rig for any linear plant: analog simulation, anti-alias filter, sampling, noise.

This is the independent generator that servoid's estimators are tested
against.  The plant is continuous; the rig integrates it at a fast analog
rate ``dt / oversample`` (exact discretisation of the cascade realisation
through the matrix exponential, so the fast step adds no integration
error), optionally passes the output through an analog Butterworth
anti-alias filter, samples every ``oversample``-th fast sample, and adds
coloured measurement noise ``v = C(q)/D(q) e`` at the logging rate.

The input reaches the plant as the rig would drive it:

- ``"zoh"``: a staircase held over each logging period (a DAC output);
- ``"foh"``: linear between the logged samples;
- ``"fast"``: the caller gives the analog signal at the fast rate (a
  band-limited signal that the logger only samples).

:func:`simulate_lti_loop` closes a digital controller around the plant
at the logging rate, with the noise inside the loop (the controller sees
the noisy measurement), which is what makes closed-loop records hard.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_int, type_error
from .._errors import DataError, ModelError, check_option
from .._lazy import signal as sps
from ..data import Experiment
from ..models import StateSpace, TransferFunction
from ..signals import MAX_SAMPLES
from ._analog import butterworth, discretise, realise
from ._daq import resolve_rng

__all__ = ["Intersample", "simulate_lti", "simulate_lti_loop"]

#: Largest oversampling factor: the analog path is simulated dt/oversample apart, and
#: beyond this the fast step is far below any plant a rig records at dt.
MAX_OVERSAMPLE = 10_000

Intersample = Literal["zoh", "foh", "fast"]


def simulate_lti(
    plant: TransferFunction,
    u: ArrayLike,
    dt: float,
    *,
    intersample: Intersample = "zoh",
    oversample: int = 20,
    anti_alias: float | None = None,
    noise_std: float = 0.0,
    noise_model: tuple[ArrayLike, ArrayLike] | None = None,
    rng: np.random.Generator | int = 0,
    name: str = "lti",
) -> Experiment:
    """Record a continuous plant driven open loop, as a rig would.

    Parameters
    ----------
    plant : TransferFunction
        Continuous (``dt=None``), proper, SISO.
    u : array_like, shape (N,) or (N·oversample,)
        The input: logged samples for ``"zoh"``/``"foh"``; the analog
        signal at the fast rate for ``"fast"``.
    dt : float
        Logging period [s].
    intersample : {"zoh", "foh", "fast"}
        How the input behaves between logged samples (see the module).
    oversample : int
        Fast analog steps per logging period, >= 1.
    anti_alias : float, optional
        Cut-off [Hz] of a 4th-order analog Butterworth filter on the
        output (and, for ``"fast"``, on the logged input) before sampling.
    noise_std : float
        Standard deviation of the white innovation e, >= 0.
    noise_model : (C, D), optional
        Monic polynomials in q⁻¹ of the noise filter at the logging rate;
        default white noise.
    rng : numpy.random.Generator or int
        Noise source (a seed for reproducibility).
    name : str
        Experiment name.

    Returns
    -------
    Experiment
        Channels ``u`` (role u) and ``y`` (role y), N samples at `dt`; the
        notes record the generator, the intersample behaviour and the seed.
    """
    check_option("intersample", intersample, ("zoh", "foh", "fast"))
    os_ = as_int("oversample", oversample, minimum=1, maximum=MAX_OVERSAMPLE)
    fast_dt = _check_plant(plant, dt) / os_
    uu = as_array("u", u)
    if uu.ndim != 1:
        raise DataError(f"u must be a finite 1-D array, got shape {uu.shape}")
    fast_samples = uu.size if intersample == "fast" else uu.size * os_
    if fast_samples > MAX_SAMPLES:
        raise DataError(
            f"the analog simulation would have {fast_samples:,} fast samples (N·oversample), over "
            f"the budget of {MAX_SAMPLES:,}; shorten u or lower oversample"
        )
    if intersample == "fast":
        if uu.size % os_:
            raise DataError(f"a fast input needs N·oversample samples, got {uu.size}")
        u_fast, hold = uu, "foh"
        n = uu.size // os_
    else:
        n = uu.size
        u_fast = np.repeat(uu, os_) if intersample == "zoh" else _linear(uu, os_)
        hold = "zoh" if intersample == "zoh" else "foh"
    shift = _delay_steps(plant, fast_dt, "dt/oversample")
    u_plant = u_fast  # the input the rig logs is the one it applies, not the plant's delayed one
    if shift:  # the analog input reaches the plant `shift` fast steps late, from rest
        u_plant = np.concatenate([np.zeros(shift), u_fast[:-shift]])
    y_fast = _run(_undelayed(plant), u_plant, fast_dt, hold)
    u_log = uu[::os_] if intersample == "fast" else uu
    if anti_alias is not None:
        aa = realise(butterworth(4, _cutoff(anti_alias, dt)))
        y_fast = _run_ss(aa, y_fast, fast_dt)
        if intersample == "fast":
            u_log = _run_ss(aa, u_fast, fast_dt)[::os_]
    rng_, seed = resolve_rng(rng, "simulate_lti")
    y = y_fast[::os_][:n] + _noise(n, noise_std, noise_model, rng_)
    notes = {"generator": "servoid.bench.simulate_lti", "intersample": intersample,
             "oversample": str(os_), "seed": str(seed)}
    exp = Experiment.from_arrays(dt, u=u_log[:n], y=y, name=name)
    return exp.replace_channels(exp.channels, notes=notes)


def simulate_lti_loop(
    plant: TransferFunction,
    controller: TransferFunction,
    r: ArrayLike,
    dt: float,
    *,
    oversample: int = 20,
    anti_alias: float | None = None,
    noise_std: float = 0.0,
    noise_model: tuple[ArrayLike, ArrayLike] | None = None,
    rng: np.random.Generator | int = 0,
    name: str = "lti-loop",
) -> Experiment:
    """Record a plant under a digital controller, noise in the loop.

    At each logging instant k the controller reads the measurement
    ``y_m(k) = y(k·dt) + v(k)`` and sets ``u(k)`` from ``r(k) − y_m(k)``;
    the DAC holds u over the period while the plant runs at the fast
    rate.  The controller may have direct feed-through.

    Parameters
    ----------
    plant : TransferFunction
        Continuous, proper, SISO.
    controller : TransferFunction
        Discrete at `dt`, proper.
    r : array_like, shape (N,)
        Reference at the logging rate.
    dt, oversample, anti_alias, noise_std, noise_model, rng, name
        As in :func:`simulate_lti`; the anti-alias filter sits in the
        measurement path, inside the loop.

    Returns
    -------
    Experiment
        Channels ``r``, ``u`` and the measured ``y``.
    """
    os_ = as_int("oversample", oversample, minimum=1, maximum=MAX_OVERSAMPLE)
    fast_dt = _check_plant(plant, dt) / os_
    if not isinstance(controller, TransferFunction) or controller.dt is None:
        raise ModelError("controller must be a discrete TransferFunction at the logging dt")
    if not np.isclose(controller.dt, dt, rtol=1e-9):
        raise ModelError(f"controller.dt = {controller.dt} s differs from dt = {dt} s")
    rr = as_array("r", r)
    if rr.ndim != 1:
        raise DataError(f"r must be a finite 1-D array, got shape {rr.shape}")
    n = rr.size
    lag = _delay_steps(plant, dt, "dt")  # a whole number of logging periods: a FIFO of u
    plant = _undelayed(plant)
    path = plant * butterworth(4, _cutoff(anti_alias, dt)) if anti_alias is not None else plant
    # One logging period with u held = os_ fast steps of the exact ZOH map; composing them
    # keeps the analog simulation at the fast rate without a Python loop over fast steps.
    fast = discretise(realise(path), fast_dt, "zoh")
    a_step, b_step = np.linalg.matrix_power(fast.A, os_), _held_input(fast.A, fast.B, os_)
    c_out, d_out = fast.C[0], float(fast.D[0, 0])
    ctl = controller.to_ss()
    rng_, seed = resolve_rng(rng, "simulate_lti_loop")
    v = _noise(n, noise_std, noise_model, rng_)
    x = np.zeros(fast.A.shape[0])
    xc = np.zeros(ctl.A.shape[0])
    u = np.empty(n)
    y = np.empty(n)
    uk = 0.0
    held = np.zeros(lag + 1)  # held[0]: the value that reaches the plant this period
    for k in range(n):
        # y(k·dt) depends on u(k) only through D, which is zero for a strictly proper path
        y[k] = c_out @ x + d_out * (uk if lag == 0 else held[1]) + v[k]
        e = rr[k] - y[k]
        uk = float(ctl.C[0] @ xc + ctl.D[0, 0] * e)
        xc = ctl.A @ xc + ctl.B[:, 0] * e
        u[k] = uk
        held = np.roll(held, -1)
        held[-1] = uk
        x = a_step @ x + b_step * held[0]
    notes = {"generator": "servoid.bench.simulate_lti_loop", "oversample": str(os_),
             "seed": str(seed)}
    exp = Experiment.from_arrays(dt, r=rr, u=u, y=y, name=name)
    return exp.replace_channels(exp.channels, notes=notes)


def _check_plant(plant: object, dt: object) -> float:
    if not isinstance(plant, TransferFunction) or plant.dt is not None:
        raise ModelError("plant must be a continuous TransferFunction (dt=None)")
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not dt > 0:
        raise DataError(f"dt must be > 0 s, got {dt!r}")
    return float(dt)


def _delay_steps(plant: TransferFunction, step: float, what: str) -> int:
    """The plant's input delay as a whole number of ``step``s (else a DataError)."""
    delay = float(getattr(plant, "delay", 0.0))
    k = round(delay / step)
    if abs(k * step - delay) > 1e-9 * max(step, delay):
        raise DataError(f"the rig delays the input in whole steps of {what} = {step:g} s; the "
                        f"plant's delay {delay:g} s is not one: change oversample or the delay")
    return k


def _undelayed(plant: TransferFunction) -> TransferFunction:
    return dataclasses.replace(plant, delay=0.0) if getattr(plant, "delay", 0.0) else plant


def _cutoff(anti_alias: float, dt: float) -> float:
    anti_alias = as_float("anti_alias", anti_alias, finite=False, unit="Hz")
    if not 0 < anti_alias < 0.5 / dt:
        raise DataError(f"anti_alias must lie in (0, {0.5 / dt:g}) Hz (Nyquist), got {anti_alias}")
    return float(anti_alias)


def _linear(u: NDArray[np.float64], os_: int) -> NDArray[np.float64]:
    k = np.arange(u.size * os_) / os_
    return np.interp(k, np.arange(u.size), u)


def _run(plant: TransferFunction, u_fast: NDArray[np.float64], fast_dt: float,
         hold: Literal["zoh", "foh"]) -> NDArray[np.float64]:
    if plant.order == 0:
        return float(plant.num[-1] / plant.den[-1]) * u_fast
    return np.asarray(discretise(realise(plant), fast_dt, hold).simulate(u_fast), dtype=float)


def _run_ss(model: StateSpace, u_fast: NDArray[np.float64], fast_dt: float) -> NDArray[np.float64]:
    return np.asarray(discretise(model, fast_dt, "foh").simulate(u_fast), dtype=float)


def _held_input(a: NDArray[np.float64], b: NDArray[np.float64], os_: int) -> NDArray[np.float64]:
    acc = np.zeros(a.shape[0])
    power = np.eye(a.shape[0])
    for _ in range(os_):
        acc += power @ b[:, 0]
        power = power @ a
    return acc


def _noise(n: int, std: float, model: tuple[ArrayLike, ArrayLike] | None,
           rng: np.random.Generator) -> NDArray[np.float64]:
    if not (isinstance(std, (int, float)) and std >= 0 and np.isfinite(std)):
        raise DataError(f"noise_std must be finite and >= 0, got {std!r}")
    e = rng.standard_normal(n) * float(std)
    if model is None:
        return e
    if isinstance(model, (str, bytes)) or not isinstance(model, (tuple, list)) or len(model) != 2:
        raise type_error("noise_model", model, "a pair (C, D) of polynomials in q⁻¹")
    c, d = (np.atleast_1d(as_array(f"noise_model {label}", p))
            for label, p in zip("CD", model, strict=True))
    for label, p in (("C", c), ("D", d)):
        if p.ndim != 1 or p[0] != 1.0:
            raise ModelError(f"noise_model {label} must be monic in q⁻¹ ({label}[0] == 1)")
    if d.size > 1 and np.any(np.abs(np.roots(d)) >= 1.0):
        raise ModelError("noise_model D must have its roots inside the unit circle")
    return np.asarray(sps.lfilter(c, d, e), dtype=float)
