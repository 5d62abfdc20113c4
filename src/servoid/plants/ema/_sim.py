"""Simulate the EMA in its sampled cascade: :func:`simulate_ema`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float, as_instance
from ..._errors import DataError, OptionError
from ._control import TVC_CONTROLLER, EmaController
from ._kernel import N_OUT, N_STATES, pack, run_loop
from ._params import EmaParameters

__all__ = ["EmaResponse", "simulate_ema"]

#: Integration steps per sample when ``dt_int`` is not given.
DEFAULT_SUBSTEPS = 10
_NOISE_KEYS = ("current", "position")
_STATE_NAMES = ("current", "angle", "speed", "position", "velocity")


@dataclass(frozen=True, eq=False)
class EmaResponse:
    """The simulated actuator and drive, per controller sample.

    Every array has one value per sample ``k`` at ``t_k = k·dt``, before
    the step that starts there (the drive's output ``voltage[k]`` is held
    over ``[t_k, t_k + dt)``).

    Attributes
    ----------
    time : ndarray
        Sample instants [s].
    reference : ndarray
        Position reference [m].
    current, angle, speed : ndarray
        Motor current [A], angle [rad] and speed [rad/s].
    position, velocity : ndarray
        Load position [m] and velocity [m/s].
    voltage : ndarray
        Motor voltage the drive applies [V].
    current_ref, speed_ref : ndarray
        The speed loop's current reference [A] and the position loop's
        speed reference [rad/s].
    measured_current, measured_angle, measured_position : ndarray
        What the drive read: current [A], encoder angle [rad], position
        fed back [m] (noise and encoder counts included).
    screw_force : ndarray
        Force of the screw on the load [N].
    stuck_motor, stuck_load : ndarray of bool
        Side held by its static friction.
    saturated : ndarray of int
        Limits active at the sample: bit 0 voltage, 1 current, 2 speed.
    dt, dt_int : float
        Sample period and integration step [s].
    analog : ndarray or None
        With ``analog=True``: the state (i, θ, ω, x, v) at every
        integration step, shape (N·dt/dt_int, 5).
    final : ndarray
        The state after the last sample.
    """

    time: NDArray[np.float64]
    reference: NDArray[np.float64]
    current: NDArray[np.float64]
    angle: NDArray[np.float64]
    speed: NDArray[np.float64]
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    voltage: NDArray[np.float64]
    current_ref: NDArray[np.float64]
    speed_ref: NDArray[np.float64]
    measured_current: NDArray[np.float64]
    measured_angle: NDArray[np.float64]
    measured_position: NDArray[np.float64]
    screw_force: NDArray[np.float64]
    stuck_motor: NDArray[np.bool_]
    stuck_load: NDArray[np.bool_]
    saturated: NDArray[np.int64]
    dt: float
    dt_int: float
    analog: NDArray[np.float64] | None
    final: NDArray[np.float64]

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.time.size)

    def saturation_fraction(self) -> dict[str, float]:
        """Fraction of samples at each limit (voltage, current, speed)."""
        return {name: float(np.mean((self.saturated & bit) > 0))
                for name, bit in (("voltage", 1), ("current", 2), ("speed", 4))}


def simulate_ema(
    params: EmaParameters,
    reference: ArrayLike,
    dt: float,
    *,
    controller: EmaController = TVC_CONTROLLER,
    f_ext: ArrayLike | float | None = None,
    x0: ArrayLike | None = None,
    dt_int: float | None = None,
    measurement_noise: Mapping[str, ArrayLike] | None = None,
    analog: bool = False,
) -> EmaResponse:
    """Simulate the EMA in its sampled current, speed, position loops.

    Between samples the actuator's ODE (:mod:`._kernel`) is stepped by
    :func:`servoid.integrate.rk4_step` with the drive's voltage held; the
    drive runs once per sample (:class:`EmaController`).

    Parameters
    ----------
    params : EmaParameters
        The actuator.
    reference : array_like, shape (N,)
        Position reference per sample [m].
    dt : float
        The drive's sample period [s], > 0.
    controller : EmaController
        Gains, limits and sensors of the drive.
    f_ext : array_like or float, optional
        External force on the load per sample, held over the sample [N],
        positive against positive motion; default none.
    x0 : array_like, shape (5,), optional
        Initial (i [A], θ [rad], ω [rad/s], x [m], v [m/s]); default at
        rest at ``reference[0]`` with the screw unloaded.
    dt_int : float, optional
        Integration step [s]; ``dt`` must be a whole multiple of it.
        Default ``dt/10``.
    measurement_noise : mapping, optional
        Sensor noise the drive reads, one value per sample:
        ``"current"`` [A] and ``"position"`` [m] (the LVDT); the encoder
        counts are the controller's ``encoder_counts``.
    analog : bool
        Also return the state at every integration step.

    Returns
    -------
    EmaResponse
        States, drive signals and flags per sample.

    Raises
    ------
    DataError
        A reference that is not 1-D with two samples or not finite,
        ``dt`` or ``dt_int`` not positive, ``dt`` not a multiple of
        ``dt_int``, arrays of the wrong length.
    OptionError
        An unknown ``measurement_noise`` key.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.plants.ema import TVC_EMA
    >>> r = np.r_[0.0, np.full(2999, 1e-3)]  # a 1 mm step at a 10 kHz drive: at 50 ms, 0.3 s
    >>> out = simulate_ema(TVC_EMA, r, 1e-4)
    >>> round(1e3 * float(out.position[500]), 2), round(1e3 * float(out.position[-1]), 3)
    (0.86, 1.0)
    """
    as_instance("params", params, EmaParameters, "EmaParameters (e.g. TVC_EMA)")
    as_instance("controller", controller, EmaController, "an EmaController")
    ref = np.ascontiguousarray(as_array("reference", reference, ndim=1, min_size=2), dtype=float)
    dt = as_float("dt", dt, positive=True, unit="s")
    substeps = _substeps(dt, dt_int)
    n = ref.size
    fe = _per_sample("f_ext", f_ext, n)
    noise = {key: np.zeros(n) for key in _NOISE_KEYS}
    if measurement_noise is not None:
        unknown = sorted(set(measurement_noise) - set(_NOISE_KEYS))
        if unknown:
            raise OptionError(f"measurement_noise has unknown key(s) {', '.join(unknown)}; "
                              f"valid: {', '.join(_NOISE_KEYS)}")
        for key, values in measurement_noise.items():
            noise[key] = _per_sample(f"measurement_noise[{key!r}]", values, n)
    if x0 is None:
        start = np.array([0.0, ref[0] * params.transmission, 0.0, ref[0], 0.0])
    else:
        start = np.array(as_array("x0", x0, ndim=1), dtype=float)
        if start.size != N_STATES:
            raise DataError(f"x0 must hold {N_STATES} values ({', '.join(_STATE_NAMES)}), got "
                            f"{start.size}")
    out = np.empty((n, N_OUT))
    fine = np.empty((n * substeps if analog else 0, N_STATES))
    final = run_loop(pack(params), controller.packed(), ref, fe, noise["current"],
                     noise["position"], start, dt, substeps, controller.outer_every, out, fine)
    cols = [np.ascontiguousarray(out[:, c]) for c in range(N_OUT)]
    for arr in (*cols, fine, final, ref):
        arr.setflags(write=False)
    flags = cols[14].astype(np.int64)
    stuck_m, stuck_l = cols[12] > 0, cols[13] > 0
    for arr in (flags, stuck_m, stuck_l):
        arr.setflags(write=False)
    time = dt * np.arange(n)
    time.setflags(write=False)
    return EmaResponse(
        time=time, reference=ref, current=cols[0], angle=cols[1], speed=cols[2],
        position=cols[3], velocity=cols[4], voltage=cols[5], current_ref=cols[6],
        speed_ref=cols[7], measured_current=cols[8], measured_angle=cols[9],
        measured_position=cols[10], screw_force=cols[11], stuck_motor=stuck_m,
        stuck_load=stuck_l, saturated=flags, dt=dt, dt_int=dt / substeps,
        analog=fine if analog else None, final=final)


def _substeps(dt: float, dt_int: float | None) -> int:
    if dt_int is None:
        return DEFAULT_SUBSTEPS
    dt_int = as_float("dt_int", dt_int, positive=True, unit="s")
    ratio = dt / dt_int
    m = round(ratio)
    if m < 1 or not math.isclose(ratio, m, rel_tol=1e-9):
        raise DataError(f"dt = {dt:g} s must be a whole multiple of dt_int = {dt_int:g} s (the "
                        f"drive's voltage is held over whole integration steps); got "
                        f"{ratio:.6g} steps per sample")
    return int(m)


def _per_sample(name: str, value: ArrayLike | float | None, n: int) -> NDArray[np.float64]:
    if value is None:
        return np.zeros(n)
    arr = as_array(name, value)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.ndim != 1 or arr.size != n:
        raise DataError(f"{name} must be a number or hold one value per reference sample "
                        f"({n}), got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=float)
