"""Rigid axis with viscous and Coulomb friction, in its position loop.

The inverse dynamic model of a rigid prismatic (or rotary) axis is

    τ = M·q̈ + Fv·q̇ + Fc·sign(q̇) + offset,

with ``Fv``, ``Fc`` replaced by ``Fv+``, ``Fc+`` for q̇ > 0 and ``Fv−``,
``Fc−`` for q̇ < 0 in the asymmetric variant (the friction force is then
``Fv−·q̇ − Fc−`` for q̇ < 0). The direct model, ``q = 1/(s(M s + Fv))·(τ − d)``,
is a pure integrator, so such axes run in closed loop: here the cascaded
position / velocity loop of the EMPS benchmark (Janot, Gautier, Brunot,
*Data Set and Reference Models of EMPS*, Workshop on Nonlinear System
Identification Benchmarks, 2019):

    v(k)  = kv·(kp·(r(k) − q(k)) − q̇f(k)),  saturated to ±``saturation`` [V],
    q̇f(k) = (qf(k) − qf(k−1))/dt,  qf(k) = (q(k) + q(k−1))/2,
    τ     = gtau·v, held over one sample (zero-order hold).

Between samples the force is constant, so the plant has a closed-form
solution on each side of q̇ = 0. The ``"exact"`` simulator integrates it
exactly and treats q̇ = 0 as an event: the axis sticks while the net force
lies within the Coulomb band (−Fc− ≤ τ − offset ≤ Fc+) and breaks away
otherwise. That is the Filippov solution of the sign-function model: no
chattering, no step-size choice, and a simulated output that is smooth in
the parameters (which an output-error fit needs). The ``"sign"`` simulator
integrates the same equation with the sign function literally, by a
fixed-step RK4 with ``substeps`` steps per sample, as a fixed-step
block-diagram solver would; it chatters around q̇ = 0 with an amplitude of
order Fc·h/M.

Disturbances. A measured force ``d(k)`` [N], held over each sample like
the drive force, enters the loop in one of two places
(``disturbance_at``): ``"drive"`` adds it to the drive force after the
voltage limit, ``τ = gtau·v + d``, as the force pulses of the EMPS
validation record (a voltage added to the controller output, so the
recorded drive force contains them); ``"load"`` applies it to the axis
as an external force that the drive force does not contain,
``M·q̈ = gtau·v + d − friction − offset``. A ``reference_offset`` [m] is
added to the reference before the controller sees it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float
from ..._errors import DataError, ModelError, OptionTypeError, check_option
from ...integrate import keep, rk4_step

__all__ = ["PARAMETER_SETS", "CascadeController", "RigidAxis", "RigidLoopResponse",
           "simulate_rigid_loop"]

Integration = Literal["exact", "sign"]
INTEGRATIONS: tuple[Integration, ...] = ("exact", "sign")
DisturbanceAt = Literal["drive", "load"]
DISTURBANCE_AT: tuple[DisturbanceAt, ...] = ("drive", "load")

# indices of the packed axis vector read by the kernels
_M, _FVP, _FCP, _FVN, _FCN, _OFF = range(6)
_MAX_EVENTS = 8  # velocity reversals and stops handled within one sample


@dataclass(frozen=True)
class RigidAxis:
    """Rigid axis: mass and (possibly asymmetric) friction.

    Parameters
    ----------
    mass : float
        Moving mass (or inertia) M [kg], > 0.
    viscous : float
        Viscous friction Fv [N·s/m] (for q̇ > 0 when asymmetric), >= 0.
    coulomb : float
        Coulomb friction Fc [N] (for q̇ > 0 when asymmetric), >= 0.
    offset : float
        Constant force offset [N] (drive or sensor offset, gravity).
    viscous_negative : float or None
        Viscous friction Fv− [N·s/m] for q̇ < 0; None: symmetric (= ``viscous``).
    coulomb_negative : float or None
        Coulomb friction Fc− [N] for q̇ < 0; None: symmetric (= ``coulomb``).
    """

    mass: float
    viscous: float
    coulomb: float
    offset: float = 0.0
    viscous_negative: float | None = None
    coulomb_negative: float | None = None

    def __post_init__(self) -> None:
        for name in ("mass", "viscous", "coulomb", "offset", "viscous_negative",
                     "coulomb_negative"):
            value = getattr(self, name)
            if value is None and name in ("viscous_negative", "coulomb_negative"):
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise OptionTypeError(f"{name} must be a number, got {type(value).__name__}")
            if not math.isfinite(value):
                raise ModelError(f"{name} must be finite, got {value}")
            object.__setattr__(self, name, float(value))
        if self.mass <= 0:
            raise ModelError(f"mass must be > 0 kg, got {self.mass}")
        for name in ("viscous", "coulomb", "viscous_negative", "coulomb_negative"):
            value = getattr(self, name)
            if value is not None and value < 0:
                raise ModelError(f"{name} must be >= 0 (friction dissipates), got {value}")

    @property
    def is_symmetric(self) -> bool:
        """True when both directions share Fv and Fc."""
        return self.viscous_negative is None and self.coulomb_negative is None

    def friction(self, velocity: ArrayLike) -> NDArray[np.float64]:
        """Friction force plus offset at a velocity [N].

        Parameters
        ----------
        velocity : array_like
            Velocity q̇ [m/s]; at exactly 0 the Coulomb term is 0 (sign(0) = 0).
        """
        v = np.asarray(velocity, dtype=float)
        p = self.packed()
        pos = p[_FVP] * v + p[_FCP]
        neg = p[_FVN] * v - p[_FCN]
        return np.where(v > 0, pos, np.where(v < 0, neg, 0.0)) + p[_OFF]

    def force(self, velocity: ArrayLike, acceleration: ArrayLike) -> NDArray[np.float64]:
        """Inverse model τ = M·q̈ + friction(q̇) + offset [N].

        Parameters
        ----------
        velocity : array_like
            Velocity q̇ [m/s].
        acceleration : array_like
            Acceleration q̈ [m/s²].
        """
        return self.mass * np.asarray(acceleration, dtype=float) + self.friction(velocity)

    def packed(self) -> NDArray[np.float64]:
        """Parameters as the simulator kernels read them."""
        fvn = self.viscous if self.viscous_negative is None else self.viscous_negative
        fcn = self.coulomb if self.coulomb_negative is None else self.coulomb_negative
        return np.array([self.mass, self.viscous, self.coulomb, fvn, fcn, self.offset])


@dataclass(frozen=True)
class CascadeController:
    """Cascaded position / velocity P controller with a voltage limit.

    The EMPS control law: ``v = kv·(kp·(r − q) − q̇f)`` [V], with q̇f the
    backward difference of the two-sample mean of q, saturated to
    ±``saturation``; the drive applies ``τ = gtau·v`` [N].

    Parameters
    ----------
    kp : float
        Position-loop gain [1/s], > 0.
    kv : float
        Velocity-loop gain [V/(m/s)], > 0.
    gtau : float
        Drive gain [N/V], > 0.
    saturation : float
        Voltage limit [V], > 0 (``inf``: none).
    """

    kp: float
    kv: float
    gtau: float
    saturation: float = 10.0

    def __post_init__(self) -> None:
        for name in ("kp", "kv", "gtau", "saturation"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise OptionTypeError(f"{name} must be a number, got {type(value).__name__}")
            if not value > 0 or math.isnan(value) or (name != "saturation"
                                                      and not math.isfinite(value)):
                raise ModelError(f"{name} must be finite and > 0, got {value}")
            object.__setattr__(self, name, float(value))


@dataclass(frozen=True, eq=False)
class RigidLoopResponse:
    """Simulated closed loop, one value per controller sample.

    Attributes
    ----------
    time : ndarray
        Sample times [s].
    position : ndarray
        Position q(k) at the sample instants [m].
    velocity : ndarray
        Velocity q̇(k) at the sample instants [m/s].
    voltage : ndarray
        Controller output after saturation v(k) [V].
    force : ndarray
        Drive force gtau·v(k) [N], plus the disturbance when it enters at
        the drive.
    saturated : float
        Fraction of samples at the voltage limit.
    integration : str
        ``"exact"`` or ``"sign"``.
    """

    time: NDArray[np.float64]
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    voltage: NDArray[np.float64]
    force: NDArray[np.float64]
    saturated: float
    integration: str


#: The published EMPS axis (Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*,
#: 2019: the symmetric model's M, Fv, Fc and offset by IDIM-LS), the one set with a source.
PARAMETER_SETS = {"EMPS": RigidAxis(mass=95.1089, viscous=203.5034, coulomb=20.3935,
                                    offset=-3.1648)}


def simulate_rigid_loop(
    axis: RigidAxis,
    controller: CascadeController,
    r: ArrayLike,
    dt: float,
    *,
    q0: float | None = None,
    v0: float = 0.0,
    integration: Integration = "exact",
    substeps: int = 10,
    disturbance: ArrayLike | None = None,
    disturbance_at: DisturbanceAt = "drive",
    reference_offset: float = 0.0,
) -> RigidLoopResponse:
    """Simulate a rigid axis in its cascaded position loop.

    Parameters
    ----------
    axis : RigidAxis
        Mass and friction.
    controller : CascadeController
        Gains, drive gain and voltage limit.
    r : array_like, shape (N,)
        Reference position [m] at the controller samples.
    dt : float
        Controller sample period [s], > 0.
    q0 : float, optional
        Initial position [m]; default ``r[0]``. The controller's memory
        (q at the two previous samples) is filled as if the axis had been
        moving at ``v0`` before.
    v0 : float
        Initial velocity [m/s].
    integration : {"exact", "sign"}
        Closed-form integration with stick/slip events (the Filippov
        solution), or fixed-step RK4 of the sign-function model.
    substeps : int
        RK4 steps per sample for ``"sign"`` (ignored by ``"exact"``).
    disturbance : array_like, shape (N,), optional
        Measured force on the axis [N] per sample, held over the sample,
        positive in the direction of positive q (e.g. the EMPS force
        pulses, gtau times the pulse voltage); default none.
    disturbance_at : {"drive", "load"}
        Where it enters: added to the drive force after the voltage limit
        (and so part of the returned force), or an external load on the
        axis that the drive force does not contain.
    reference_offset : float
        Constant added to the reference [m] (e.g. a zero that differs
        between the reference and the encoder).

    Returns
    -------
    RigidLoopResponse
        Position, velocity, voltage and force per sample.

    Examples
    --------
    >>> import numpy as np
    >>> axis = RigidAxis(95.0, 203.0, 20.0, -3.0)
    >>> ctrl = CascadeController(kp=160.18, kv=243.45, gtau=35.15)
    >>> out = simulate_rigid_loop(axis, ctrl, np.full(500, 1e-3), 1e-3, q0=0.0)
    >>> bool(abs(out.position[-1] - 1e-3) < 2e-5)  # stuck within Fc/(kp·kv·gtau)
    True
    """
    if not isinstance(axis, RigidAxis):
        raise OptionTypeError(f"axis must be a RigidAxis, got {type(axis).__name__}")
    if not isinstance(controller, CascadeController):
        raise OptionTypeError(f"controller must be a CascadeController, "
                              f"got {type(controller).__name__}")
    check_option("integration", integration, INTEGRATIONS)
    ref = np.ascontiguousarray(as_array("r", r, finite=False))
    if ref.ndim != 1 or ref.size < 2:
        raise DataError(f"r must be 1-D with at least 2 samples, got shape {ref.shape}")
    if not np.all(np.isfinite(ref)):
        raise DataError("r must be finite")
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.number)) or not dt > 0:
        raise DataError(f"dt must be > 0 s, got {dt!r}")
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise DataError(f"substeps must be an integer >= 1, got {substeps!r}")
    check_option("disturbance_at", disturbance_at, DISTURBANCE_AT)
    offset = as_float("reference_offset", reference_offset, unit="m")
    if disturbance is None:
        dist = np.zeros(ref.size)
    else:
        dist = np.ascontiguousarray(as_array("disturbance", disturbance, ndim=1))
        if dist.size != ref.size:
            raise DataError(f"disturbance must have one value per reference sample ({ref.size}),"
                            f" got {dist.size}")
    if offset != 0.0:
        ref = ref + offset
    q_start = float(ref[0]) if q0 is None else as_float("q0", q0, finite=False)
    v0 = as_float("v0", v0, finite=False)
    if not (math.isfinite(q_start) and math.isfinite(v0)):
        raise DataError(f"q0 and v0 must be finite, got {q0!r} and {v0!r}")
    gains = np.array([controller.kp, controller.kv, controller.gtau, controller.saturation,
                      float(dt)])
    at_drive = disturbance_at == "drive"
    out = _run_loop(axis.packed(), gains, ref, dist, q_start, float(v0), integration == "exact",
                    int(substeps))
    q, v, volt = out[0], out[1], out[2]
    for arr in (q, v, volt):
        arr.setflags(write=False)
    force = controller.gtau * volt + (dist if at_drive else 0.0)
    force.setflags(write=False)
    sat = float(np.mean(np.abs(volt) >= controller.saturation * (1 - 1e-12)))
    time = dt * np.arange(ref.size)
    return RigidLoopResponse(time, q, v, volt, force, sat, integration)


# -- compiled kernels -------------------------------------------------------------------------


def _run_loop(p: NDArray[np.float64], gains: NDArray[np.float64], r: NDArray[np.float64],
              d: NDArray[np.float64], q0: float, v0: float, exact: bool, substeps: int
              ) -> NDArray[np.float64]:
    return _loop_kernel(p, gains, r, d, q0, v0, exact, substeps)


@numba.njit(cache=True)
def _loop_kernel(p, gains, r, d, q0, v0, exact, substeps):  # type: ignore[no-untyped-def]  # pragma: no cover
    kp, kv, gtau, vmax, dt = gains[0], gains[1], gains[2], gains[3], gains[4]
    n = r.size
    out = np.empty((3, n))
    q, v = q0, v0
    # q(k−1), q(k−2): the controller's memory, as if the axis had been moving at v0
    q1, q2 = q0 - v0 * dt, q0 - 2.0 * v0 * dt
    state = np.empty(2)
    for k in range(n):
        # q̇f(k) = (qf(k) − qf(k−1))/dt with qf(k) = (q(k) + q(k−1))/2 = (q(k) − q(k−2))/(2 dt)
        qdf = (q - q2) / (2.0 * dt)
        volt = kv * (kp * (r[k] - q) - qdf)
        if volt > vmax:
            volt = vmax
        elif volt < -vmax:
            volt = -vmax
        out[0, k] = q
        out[1, k] = v
        out[2, k] = volt
        q2, q1 = q1, q
        state[0], state[1] = q, v
        # a disturbance adds to the force on the axis wherever it enters (drive or load)
        if exact:
            _exact_step(p, gtau * volt + d[k], dt, state)
        else:
            _rk4_steps(p, gtau * volt + d[k], dt, substeps, state)
        q, v = state[0], state[1]
    return out


@numba.njit(cache=True)
def _phi(a, t):  # type: ignore[no-untyped-def]  # pragma: no cover
    # φ1 = (1 − e^{−at})/a and φ2 = (t − φ1)/a, by series when a·t is small (a = 0 allowed)
    x = a * t
    if x < 1e-4:
        phi1 = t * (1.0 - x / 2.0 + x * x / 6.0)
        phi2 = t * t * (0.5 - x / 6.0 + x * x / 24.0)
    else:
        phi1 = -math.expm1(-x) / a
        phi2 = (t - phi1) / a
    return phi1, phi2


@numba.njit(cache=True)
def _exact_step(p, force, h, state):  # type: ignore[no-untyped-def]  # pragma: no cover
    m = p[0]
    net = force - p[5]
    q, v = state[0], state[1]
    remaining = h
    for _ in range(_MAX_EVENTS):
        if remaining <= 0.0:
            break
        if v > 0.0:
            s = 1.0
        elif v < 0.0:
            s = -1.0
        elif net > p[2]:
            s = 1.0
        elif net < -p[4]:
            s = -1.0
        else:
            break  # stuck: the net force lies within the Coulomb band until the next sample
        if s > 0:
            fv, c = p[1], net - p[2]
        else:
            fv, c = p[3], net + p[4]
        a = fv / m
        acc = c / m  # acceleration at zero velocity
        phi1, phi2 = _phi(a, remaining)
        v_end = v * (1.0 - a * phi1) + acc * phi1
        if s * v_end >= 0.0 or s * acc >= 0.0:
            q += v * phi1 + acc * phi2
            v = v_end
            if s * v < 0.0:
                v = 0.0
            break
        # velocity reaches zero inside the step: solve v(t*) = 0, stop there, re-decide
        if a * remaining < 1e-12:
            t_stop = -v / acc
        else:
            v_inf = acc / a
            t_stop = math.log((v - v_inf) / (-v_inf)) / a
        t_stop = min(max(t_stop, 0.0), remaining)
        phi1, phi2 = _phi(a, t_stop)
        q += v * phi1 + acc * phi2
        v = 0.0
        remaining -= t_stop
    state[0], state[1] = q, v


@numba.njit(cache=True, inline="always")
def _accel(p, net, v):  # type: ignore[no-untyped-def]  # pragma: no cover
    if v > 0.0:
        return (net - p[1] * v - p[2]) / p[0]
    if v < 0.0:
        return (net - p[3] * v + p[4]) / p[0]
    return net / p[0]


@numba.njit(cache=True, inline="always")
def _rates(t, x, net, p):  # type: ignore[no-untyped-def]  # pragma: no cover
    return x[1], _accel(p, net, x[1])


@numba.njit(cache=True)
def _rk4_steps(p, force, h, substeps, state):  # type: ignore[no-untyped-def]  # pragma: no cover
    net = force - p[5]
    x = (state[0], state[1])
    dh = h / substeps
    for _ in range(substeps):
        x, _ = rk4_step(_rates, keep, 0.0, x, net, p, dh)
    state[0], state[1] = x[0], x[1]
