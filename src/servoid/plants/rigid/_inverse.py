"""Rigid actuators with friction: inverse-model LS and closed-loop OE.

Inverse dynamic identification model with least squares (IDIM-LS), the
recipe of Janot, Gautier and Brunot, *Data Set and Reference Models of
EMPS* (Workshop on Nonlinear System Identification Benchmarks, 2019):

1. the measured position is low-passed forward and backward (zero phase,
   Butterworth, :func:`servoid.data.lowpass`);
2. velocity and acceleration come from central differences of it;
3. the force and every regressor column pass through the same anti-alias
   filter and are down-sampled together (*parallel decimation*,
   :func:`servoid.data.decimate`), which removes the high-frequency force
   ripple the rigid model does not describe while keeping force and
   regressors consistent;
4. ``τ = Φ θ`` is solved by QR with covariance σ̂²(ΦᵀΦ)⁻¹
   (:func:`servoid.estimate.lstsq`).

The decimation filter. MATLAB's ``decimate`` (used by the reference)
applies an order-8 Chebyshev I at 0.8 times the new Nyquist frequency
forward and backward and keeps samples ``r − (r·⌈N/r⌉ − N)``, ``+r``, …;
SciPy's keeps samples 0, r, … and pads the record differently. The
parameters hardly depend on that choice (within 0.5 % on EMPS), but the
relative error does: the record starts with the axis already moving, so
the first and last decimated samples carry the zero-phase filters'
end transients (a 26 N residual at sample 0 against a 2.3 N RMS), and
these two samples alone move the relative error by 0.1 to 0.4 percentage
points. ``pipeline = "servoid"`` uses servoid's linear-phase FIR decimator
by default (``"fir"``, no forward-backward padding transient) and drops
``trim = 1`` decimated sample at each end; with these, EMPS gives the
published parameters within 0.25 %, their standard deviations within
0.1 %, and the relative error within 0.003 percentage points. The IIR
(``"iir"``, MATLAB's filter design) with the same trim is within 0.25 %
and 0.04 percentage points.

The published pipeline. ``pipeline = "published"`` is a faithful port of
the reference's MATLAB script ``Script_IDIM_LS.m`` (Janot, Gautier,
Brunot 2019, distributed with the data): ``[b, a] = butter(4, 100/500)``
applied by MATLAB's ``filtfilt`` (odd reflection of ``3·(nfilt − 1)``
samples at each end, steady-state initial conditions — SciPy's
``filtfilt`` pads ``3·nfilt`` by default); velocity and acceleration
by the script's ``diffcent`` (a central difference with one-sided ends,
applied to q and then to q̇, so q̈(k) = (q(k+2) − 2q(k) + q(k−2))/(4 dt²));
the first 49 samples dropped (``n_border = 50`` in MATLAB's 1-based
indexing; nothing at the end); every column and the force through
MATLAB's ``decimate`` (order-8 Chebyshev I, 0.05 dB ripple, cut at
0.8/r, the same ``filtfilt``, samples ``r − (r·⌈N/r⌉ − N)``, ``+r``, …
in 1-based indexing); ``X \\ y`` and the script's standard deviations
``std(e)·√diag((ΦᵀΦ)⁻¹)`` (σ̂ with N − 1, mean removed). On EMPS it gives
the published 4.0834 % and every published digit of the parameters.
It is the default: fitted on either EMPS record and scored on the other,
it predicts the other record better on average (inverse model and
closed-loop simulation alike); ``docs/emps.md`` gives the numbers.

Closed-loop output error. :func:`fit_closed_loop_oe` adjusts the same
physical parameters so that the simulated closed loop (the axis in its
known cascaded controller, :func:`servoid.plants.rigid.simulate_rigid_loop`)
reproduces the measured position and/or drive force, by nonlinear least
squares from the IDIM-LS estimate.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float
from ..._errors import (
    ChannelError,
    ConvergenceError,
    DataError,
    OptionError,
    OptionTypeError,
    check_option,
)
from ..._lazy import optimize
from ...data import Channel, Experiment, decimate, lowpass
from ...estimate import Estimate, lstsq
from ._axis import CascadeController, RigidAxis, RigidLoopResponse, simulate_rigid_loop

Integration = Literal["exact", "sign"]  # as simulate_rigid_loop takes them
DisturbanceAt = Literal["drive", "load"]

__all__ = [
    "FRICTION_MODELS",
    "InverseDynamicsRegression",
    "fit_closed_loop_oe",
    "fit_inverse_dynamics",
    "inverse_dynamics_regression",
]

FrictionModel = Literal["symmetric", "asymmetric"]
FRICTION_MODELS: tuple[FrictionModel, ...] = ("symmetric", "asymmetric")
Differentiation = Literal["central", "backward"]
DecimationFilter = Literal["fir", "iir"]
OeOutput = Literal["position", "force", "both"]
Pipeline = Literal["servoid", "published"]
INVERSE_PIPELINES: tuple[Pipeline, ...] = ("servoid", "published")
_SERVOID_DEFAULTS: dict[str, Any] = {"decimation_filter": "fir", "differentiation": "central",
                                     "trim": 1}
# Script_IDIM_LS.m keeps q_f(n_border:N_pts) with n_border = 50 (1-based): 49 samples go
_PUBLISHED_BORDER = 49
# MATLAB decimate's IIR filter: cheby1(8, 0.05, 0.8/r)
_MATLAB_DECIMATE_ORDER = 8
_MATLAB_DECIMATE_RIPPLE = 0.05
_MAX_BA_ORDER = 8

_NAMES: dict[str, tuple[str, ...]] = {
    "symmetric": ("M", "Fv", "Fc", "offset"),
    "asymmetric": ("M", "Fv+", "Fc+", "Fv-", "Fc-"),
}
_UNITS: dict[str, tuple[str, ...]] = {
    "symmetric": ("kg", "N·s/m", "N", "N"),
    "asymmetric": ("kg", "N·s/m", "N", "N·s/m", "N"),
}


@dataclass(frozen=True, eq=False)
class InverseDynamicsRegression:
    """Decimated force and regressors of the inverse dynamic model.

    Attributes
    ----------
    force : ndarray, shape (N,)
        Decimated drive force τ [N].
    regressors : ndarray, shape (N, n)
        Decimated columns Φ, one per parameter.
    names : tuple of str
        Parameter names, one per column.
    units : tuple of str
        Parameter units.
    dt : float
        Sample period after decimation [s].
    t0 : float
        Time of the first row [s].
    options : mapping
        The settings that built it (channels, filters, trim), JSON-friendly.
    """

    force: NDArray[np.float64]
    regressors: NDArray[np.float64]
    names: tuple[str, ...]
    units: tuple[str, ...]
    dt: float
    t0: float
    options: Mapping[str, Any]

    @property
    def time(self) -> NDArray[np.float64]:
        """Times of the rows [s]."""
        return self.t0 + self.dt * np.arange(self.force.size)


def inverse_dynamics_regression(
    data: Experiment,
    *,
    position: str | None = None,
    force: str | None = None,
    model: FrictionModel = "symmetric",
    pipeline: Pipeline = "published",
    cutoff: float = 100.0,
    order: int = 4,
    decimation: int = 10,
    decimation_filter: DecimationFilter | None = None,
    differentiation: Differentiation | None = None,
    trim: int | None = None,
) -> InverseDynamicsRegression:
    """Build the filtered, decimated IDIM regression τ = Φ θ.

    Parameters are those of :func:`fit_inverse_dynamics`.

    Returns
    -------
    InverseDynamicsRegression
        Force, regressors and their time base after parallel decimation.
    """
    if not isinstance(data, Experiment):
        raise OptionTypeError(f"data must be an Experiment, got {type(data).__name__}")
    check_option("model", model, FRICTION_MODELS)
    check_option("pipeline", pipeline, INVERSE_PIPELINES)
    _check_int("order", order, 1)
    _check_int("decimation", decimation, 1)
    given = {"decimation_filter": decimation_filter, "differentiation": differentiation,
             "trim": trim}
    pos_name = _single(data, position, "y", "position")
    force_name = _force_name(data, force)
    if pipeline == "published":
        fixed = [k for k, v in given.items() if v is not None]
        if fixed:
            raise OptionError(
                f"{' and '.join(fixed)} {'is a setting' if len(fixed) == 1 else 'are settings'} "
                "of pipeline='servoid'; pipeline='published' (the default) is the reference's "
                "MATLAB recipe and fixes them: pass pipeline='servoid' as well, or leave "
                f"{'it' if len(fixed) == 1 else 'them'} unset")
        cutoff = as_float("cutoff", cutoff)
        return _published_regression(data, pos_name, force_name, model, cutoff, int(order),
                                     int(decimation))
    decimation_filter, differentiation, trim = (
        _SERVOID_DEFAULTS[k] if v is None else v for k, v in given.items())
    check_option("decimation_filter", decimation_filter, ("fir", "iir"))
    check_option("differentiation", differentiation, ("central", "backward"))
    _check_int("trim", trim, 0)
    filtered = lowpass(data.select(pos_name), cutoff, order, zero_phase=True)[pos_name]
    qd, qdd, tau, first = _derivatives(filtered, data[force_name], data.dt, differentiation)
    columns = _columns(qd, qdd, model)
    names = _NAMES[model]
    # Parallel decimation: one Experiment holds τ and every column, so they see one filter.
    stack = Experiment(
        (Channel("tau", "side", tau),
         *(Channel(f"phi{k}", "side", col) for k, col in enumerate(columns))),
        data.dt,
        t0=data.t0 + first * data.dt,
    )
    reduced = decimate(stack, decimation, ftype=decimation_filter)
    if reduced.n_samples - 2 * trim <= len(names):
        raise DataError(
            f"{reduced.n_samples} decimated samples less 2·trim = {2 * trim} leave too few "
            f"equations for {len(names)} parameters; use a longer record, a smaller trim or "
            "less decimation"
        )
    keep = slice(trim, reduced.n_samples - trim)
    y = np.array(reduced["tau"][keep])
    phi = np.column_stack([reduced[f"phi{k}"][keep] for k in range(len(names))])
    for arr in (y, phi):
        arr.setflags(write=False)
    return InverseDynamicsRegression(
        force=y,
        regressors=phi,
        names=names,
        units=_UNITS[model],
        dt=reduced.dt,
        t0=reduced.t0 + trim * reduced.dt,
        options={
            "model": model,
            "pipeline": "servoid",
            "position": pos_name,
            "force": force_name,
            "cutoff": float(cutoff),
            "order": int(order),
            "decimation": int(decimation),
            "decimation_filter": decimation_filter,
            "differentiation": differentiation,
            "trim": int(trim),
            "dt": reduced.dt,
        },
    )


def fit_inverse_dynamics(
    data: Experiment,
    *,
    position: str | None = None,
    force: str | None = None,
    model: FrictionModel = "symmetric",
    pipeline: Pipeline = "published",
    cutoff: float = 100.0,
    order: int = 4,
    decimation: int = 10,
    decimation_filter: DecimationFilter | None = None,
    differentiation: Differentiation | None = None,
    trim: int | None = None,
) -> Estimate:
    """Fit mass and friction by inverse-model least squares (IDIM-LS).

    Parameters
    ----------
    data : Experiment
        A record with the position [m] and the drive force [N].
    position : str, optional
        Position channel; default the experiment's only output (``y``) channel.
    force : str, optional
        Force channel; default a channel called ``"force"``, else the only
        plant-input (``u``) channel.
    model : {"symmetric", "asymmetric"}
        ``τ = M q̈ + Fv q̇ + Fc sign(q̇) + offset``, or separate ``Fv±``,
        ``Fc±`` per direction (the offset is then absorbed by Fc±:
        ``1 = 1(q̇>0) + 1(q̇<0)``, so it has no column).
    pipeline : {"published", "servoid"}
        ``"published"`` (the default): the reference's MATLAB script
        exactly (see the module notes); it fixes the filters, the
        differences and the border, so ``decimation_filter``,
        ``differentiation`` and ``trim`` must be left unset, and its
        standard deviations use the script's σ̂. It is the default because
        it predicts the other EMPS record better (``docs/emps.md``).
        ``"servoid"``: servoid's filters, each adjustable.
    cutoff : float
        Cutoff of the zero-phase Butterworth on the position [Hz]; the
        reference uses 100 Hz (about 5× the position-loop bandwidth).
    order : int
        Butterworth order (applied twice, forward and backward).
    decimation : int
        Parallel decimation factor of force and regressors (1: none).
    decimation_filter : {"fir", "iir"}, optional
        Anti-alias filter of :func:`servoid.data.decimate` (default
        ``"fir"``); see the module notes.
    differentiation : {"central", "backward"}, optional
        Central differences (no delay, the reference; the default), or
        backward ones (half a sample of delay per derivative, for comparison).
    trim : int, optional
        Decimated samples dropped at each end (filter end transients), >= 0;
        default 1.

    Returns
    -------
    Estimate
        ``model`` is a :class:`~servoid.plants.rigid.RigidAxis`; ``options`` hold
        the settings, ``condition`` (of the column-scaled Φ) and
        ``condition_unscaled`` (of Φ as is, the reference's), ``relative_error``
        100·‖τ − Φθ̂‖/‖τ‖ [%] and the decimated ``dt``. Residuals are the
        decimated force errors [N].

    Raises
    ------
    DataError
        Bad settings, or too few samples for the filters.
    IdentifiabilityError
        The motion does not excite every column (e.g. never moves backwards
        for the asymmetric model).

    Examples
    --------
    >>> from servoid.datasets import load_emps
    >>> est = fit_inverse_dynamics(load_emps())
    >>> round(est["M"], 4), round(float(est.options["relative_error"]), 4)
    (95.1089, 4.0834)
    """
    reg = inverse_dynamics_regression(
        data, position=position, force=force, model=model, pipeline=pipeline, cutoff=cutoff,
        order=order, decimation=decimation, decimation_filter=decimation_filter,
        differentiation=differentiation, trim=trim,
    )
    y, phi = reg.force, reg.regressors
    result = lstsq(phi, y, reg.names)
    theta = result.theta
    rel = 100.0 * np.sqrt(result.rss) / float(np.linalg.norm(y))
    covariance, noise_variance = result.covariance, result.noise_variance
    if pipeline == "published":
        # the script's σ̂ is std(error_LS): divided by N − 1, the mean removed
        published_var = float(np.var(y - phi @ theta, ddof=1))
        covariance = covariance * (published_var / max(noise_variance, 1e-300))
        noise_variance = published_var

    def residuals() -> NDArray[np.float64]:
        return y - phi @ theta

    return Estimate(
        model=_axis(theta, model),
        parameters=theta,
        names=reg.names,
        covariance=covariance,
        noise_variance=noise_variance,
        n_samples=result.n_rows,
        method="idim-ls",
        options={
            **reg.options,
            "condition": result.condition,
            # the reference quotes cond(Φ) of the unscaled columns (25.99 on EMPS)
            "condition_unscaled": float(np.linalg.cond(phi)),
            "relative_error": rel,
            "solver": result.method,
        },
        units=reg.units,
        residual_function=residuals,
    )


def fit_closed_loop_oe(
    data: Experiment,
    controller: CascadeController,
    start: RigidAxis | Estimate,
    *,
    output: OeOutput = "both",
    model: FrictionModel | None = None,
    reference: str | None = None,
    position: str | None = None,
    force: str | None = None,
    q0: float | None = None,
    v0: float = 0.0,
    integration: Integration = "exact",
    max_nfev: int | None = None,
    tol: float = 1e-10,
    disturbance: str | None = None,
    disturbance_at: DisturbanceAt = "drive",
    reference_offset: float = 0.0,
) -> Estimate:
    """Refine mass and friction by closed-loop output error.

    The axis is simulated in its known loop from the reference
    (:func:`~servoid.plants.rigid.simulate_rigid_loop`) and θ minimises
    ``Σ (y − ŷ(θ))²`` over the chosen outputs by Levenberg–Marquardt. With
    ``output = "both"`` position and force errors are each divided by their
    RMS at the start, so both count; the covariance is σ̂²(JᵀJ)⁻¹ of that
    weighted problem. It assumes white output errors, which closed-loop
    simulation errors are not, so read it as a lower bound.

    Parameters
    ----------
    data : Experiment
        Record with the reference, the position and the drive force.
    controller : CascadeController
        The known controller (gains, drive gain, voltage limit).
    start : RigidAxis or Estimate
        Starting point, e.g. the :func:`fit_inverse_dynamics` estimate.
    output : {"position", "force", "both"}
        Measured signal(s) the simulation must reproduce.
    model : {"symmetric", "asymmetric"}, optional
        Friction model; default that of ``start``.
    reference : str, optional
        Reference channel; default the only ``r`` channel.
    position : str, optional
        Position channel; default the only ``y`` channel.
    force : str, optional
        Force channel; default ``"force"``, else the only ``u`` channel.
    q0 : float, optional
        Initial position [m]; default the first measured position.
    v0 : float
        Initial velocity [m/s].
    integration : {"exact", "sign"}
        Simulator; ``"exact"`` is smooth in θ, which finite-difference
        Jacobians need.
    max_nfev : int, optional
        Limit on simulations (default 100·(n + 1)).
    tol : float
        Relative tolerance on cost, step and gradient.
    disturbance : str, optional
        Channel of a measured disturbance force [N] on the axis (e.g. the
        EMPS force pulses); default none.
    disturbance_at : {"drive", "load"}
        Where it enters the loop (see
        :func:`~servoid.plants.rigid.simulate_rigid_loop`).
    reference_offset : float
        Constant added to the reference [m].

    Returns
    -------
    Estimate
        ``model`` is the refined :class:`~servoid.plants.rigid.RigidAxis`;
        ``options`` hold the relative errors of position and force [%]
        at the start and at the optimum, and the solver report.

    Raises
    ------
    ConvergenceError
        The solver stopped without meeting its tolerances.
    """
    if not isinstance(data, Experiment):
        raise OptionTypeError(f"data must be an Experiment, got {type(data).__name__}")
    if not isinstance(controller, CascadeController):
        raise OptionTypeError(f"controller must be a CascadeController, "
                              f"got {type(controller).__name__}")
    check_option("output", output, ("position", "force", "both"))
    axis0 = start.model if isinstance(start, Estimate) else start
    if not isinstance(axis0, RigidAxis):
        raise OptionTypeError(f"start must be a RigidAxis or its Estimate, "
                              f"got {type(start).__name__}")
    if model is None:
        model = "symmetric" if axis0.is_symmetric else "asymmetric"
    check_option("model", model, FRICTION_MODELS)
    r = data[_single(data, reference, "r", "reference")]
    q_meas = data[_single(data, position, "y", "position")]
    f_meas = data[_force_name(data, force)]
    dist = None if disturbance is None else data.channel(disturbance).values
    q_start = float(q_meas[0]) if q0 is None else float(q0)
    theta0 = _theta(axis0, model)
    names = _NAMES[model]
    scale = np.abs(theta0) + 1e-3 * np.max(np.abs(theta0))

    def simulate(theta: NDArray[np.float64]) -> RigidLoopResponse:
        return simulate_rigid_loop(_axis(theta, model, clip=True), controller, r, data.dt,
                                   q0=q_start, v0=v0, integration=integration,
                                   disturbance=dist, disturbance_at=disturbance_at,
                                   reference_offset=reference_offset)

    sim0 = simulate(theta0)
    weights = {
        "position": 1.0 / max(_rms(q_meas - sim0.position), 1e-300),
        "force": 1.0 / max(_rms(f_meas - sim0.force), 1e-300),
    }
    use = ("position", "force") if output == "both" else (output,)

    def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
        sim = simulate(z * scale)
        parts = []
        if "position" in use:
            parts.append(weights["position"] * (q_meas - sim.position))
        if "force" in use:
            parts.append(weights["force"] * (f_meas - sim.force))
        return np.concatenate(parts)

    res = optimize.least_squares(
        residuals, theta0 / scale, method="lm", xtol=tol, ftol=tol, gtol=tol,
        max_nfev=max_nfev if max_nfev is not None else 100 * (theta0.size + 1),
    )
    if res.status <= 0 or not np.all(np.isfinite(res.x)):
        raise ConvergenceError(
            f"closed-loop OE did not converge ({res.message.strip()}; {res.nfev} simulations "
            f"from {dict(zip(names, theta0.tolist(), strict=True))}); start from the IDIM-LS "
            "estimate or raise max_nfev"
        )
    theta = res.x * scale
    r_opt = np.asarray(res.fun)
    n_res = r_opt.size
    sigma2 = float(r_opt @ r_opt) / max(n_res - theta.size, 1)
    jac = np.asarray(res.jac) / scale  # d r / d θ
    cov = sigma2 * np.linalg.pinv(jac.T @ jac)
    sim = simulate(theta)

    def residual_function() -> NDArray[np.float64]:
        return residuals(res.x)

    return Estimate(
        model=_axis(theta, model),
        parameters=theta,
        names=names,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_res,
        method="closed-loop-oe",
        options={
            "model": model,
            "output": output,
            "integration": integration,
            "disturbance": disturbance,
            "disturbance_at": disturbance_at,
            "reference_offset": float(reference_offset),
            "q0": q_start,
            "v0": float(v0),
            "theta0": theta0.tolist(),
            "weights": {k: weights[k] for k in use},
            "start_relative_error": _errors(q_meas, f_meas, sim0),
            "relative_error": _errors(q_meas, f_meas, sim),
            "nfev": int(res.nfev),
            "cost": float(res.cost),
            "message": str(res.message),
            "solver_status": int(res.status),
        },
        units=_UNITS[model],
        residual_function=residual_function,
    )


# -- helpers -----------------------------------------------------------------------------------


def _check_int(name: str, value: object, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise DataError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _published_regression(data: Experiment, pos_name: str, force_name: str, model: str,
                          cutoff: float, order: int, r: int) -> InverseDynamicsRegression:
    from scipy import signal as sps  # deferred: importing scipy.signal costs ~1 s
    dt = data.dt
    nyquist = 0.5 / dt
    if not 0 < cutoff < nyquist:
        raise DataError(
            f"cutoff must lie in (0, {nyquist:g}) Hz (the Nyquist frequency), got {cutoff}")
    if order > _MAX_BA_ORDER:
        raise DataError(
            f"order must be <= {_MAX_BA_ORDER} with pipeline = 'published' (the script filters "
            f"with a transfer function, which loses accuracy at high orders), got {order}")
    n_rows = data.n_samples - _PUBLISHED_BORDER
    names = _NAMES[model]
    # MATLAB's filtfilt needs more samples than its padding (3·8 for the order-8 decimator)
    needed = max(3 * _MATLAB_DECIMATE_ORDER, 3 * order) + 1
    if n_rows < needed or -(-n_rows // r) <= len(names):
        raise DataError(
            f"the published pipeline drops {_PUBLISHED_BORDER} samples and then needs more than "
            f"{max(needed, r * len(names))} samples ({len(names)} parameters after decimation "
            f"by {r}); the record has {data.n_samples}: use a longer record or less decimation")
    b, a = sps.butter(order, cutoff / nyquist)
    q = _matlab_filtfilt(b, a, np.asarray(data[pos_name], dtype=float))
    qd = _diffcent(q, dt)
    qdd = _diffcent(qd, dt)
    keep = slice(_PUBLISHED_BORDER, None)
    qd, qdd = qd[keep], qdd[keep]
    tau = np.asarray(data[force_name], dtype=float)[keep]
    if r > 1:
        cb, ca = _matlab_decimation_filter(r)
    first = r - (r * -(-tau.size // r) - tau.size) - 1  # MATLAB's nbeg, 0-based

    def dec(x: NDArray[np.float64]) -> NDArray[np.float64]:
        if r == 1:
            return np.array(x, dtype=float)
        return np.ascontiguousarray(_matlab_filtfilt(cb, ca, x)[first::r])

    y = dec(tau)
    phi = np.column_stack([dec(col) for col in _columns(qd, qdd, model)])
    for arr in (y, phi):
        arr.setflags(write=False)
    return InverseDynamicsRegression(
        force=y,
        regressors=phi,
        names=names,
        units=_UNITS[model],
        dt=r * dt,
        t0=data.t0 + (_PUBLISHED_BORDER + (first if r > 1 else 0)) * dt,
        options={
            "model": model,
            "pipeline": "published",
            "position": pos_name,
            "force": force_name,
            "cutoff": float(cutoff),
            "order": int(order),
            "decimation": int(r),
            "decimation_filter": "matlab-decimate",
            "differentiation": "diffcent",
            "border": _PUBLISHED_BORDER,
            "dt": r * dt,
        },
    )


def _matlab_decimation_filter(r: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """MATLAB decimate's Chebyshev I, its order lowered until the design is accurate."""
    from scipy import signal as sps
    edge = 0.8 / r
    for n in range(_MATLAB_DECIMATE_ORDER, 0, -1):
        b, a = sps.cheby1(n, _MATLAB_DECIMATE_RIPPLE, edge)
        # decimate's own test: the gain at the band edge must be −ripple dB within 1e-6
        z = np.exp(-1j * np.pi * edge * np.arange(max(b.size, a.size)))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            gain_db = 20.0 * np.log10(abs((z[:b.size] @ b) / (z[:a.size] @ a)))
        if np.any(b != 0) and abs(gain_db + _MATLAB_DECIMATE_RIPPLE) <= 1e-6:
            return b, a
    raise DataError(f"decimation = {r} is too large for MATLAB's decimation filter (no accurate "
                    "Chebyshev design); decimate in stages or choose a smaller factor")


def _matlab_filtfilt(b: NDArray[np.float64], a: NDArray[np.float64], x: NDArray[np.float64]
                     ) -> NDArray[np.float64]:
    """MATLAB's filtfilt: odd reflection of 3·(nfilt − 1) samples, steady-state start."""
    from scipy import signal as sps
    nfilt = max(len(a), len(b))
    # SciPy's own default pads 3·nfilt; with 3·(nfilt − 1) and its lfilter_zi start (the same
    # steady state MATLAB solves for) the two agree to rounding
    return np.asarray(sps.filtfilt(b, a, x, padtype="odd", padlen=3 * (nfilt - 1)))


def _diffcent(y: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """The reference's central difference, one-sided at both ends."""
    out = np.empty_like(y)
    out[1:-1] = 0.5 * (y[2:] - y[:-2])
    out[0] = y[1] - y[0]
    out[-1] = y[-1] - y[-2]
    return out / dt


def _single(data: Experiment, name: str | None, role: Any, what: str) -> str:
    if name is not None:
        data.channel(name)
        return name
    names = data.names_of(role)
    if len(names) != 1:
        data.signal(role)  # raises naming what exists when there is none
        raise ChannelError(
            f"the experiment has {len(names)} {role!r} channels ({', '.join(names)}); "
            f"name the {what} channel"
        )
    return names[0]


def _force_name(data: Experiment, force: str | None) -> str:
    if force is not None:
        data.channel(force)
        return force
    if "force" in data.names:
        return "force"
    return _single(data, None, "u", "force")


def _derivatives(
    q: NDArray[np.float64], tau: NDArray[np.float64], dt: float, how: Differentiation
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]:
    if how == "central":
        qd = (q[2:] - q[:-2]) / (2.0 * dt)
        qdd = (q[2:] - 2.0 * q[1:-1] + q[:-2]) / dt**2
        return qd, qdd, np.asarray(tau[1:-1]), 1
    qd = (q[2:] - q[1:-1]) / dt
    qdd = (q[2:] - 2.0 * q[1:-1] + q[:-2]) / dt**2
    return qd, qdd, np.asarray(tau[2:]), 2


def _columns(
    qd: NDArray[np.float64], qdd: NDArray[np.float64], model: str
) -> tuple[NDArray[np.float64], ...]:
    if model == "symmetric":
        return qdd, qd, np.sign(qd), np.ones_like(qd)
    pos = (qd > 0).astype(float)
    neg = (qd < 0).astype(float)
    return qdd, qd * pos, pos, qd * neg, -neg


def _axis(theta: Sequence[float] | NDArray[np.float64], model: str, clip: bool = False) -> RigidAxis:
    t = np.asarray(theta, dtype=float)
    if clip:
        # an optimiser may try a non-physical point; simulate its nearest physical neighbour
        t = t.copy()
        t[0] = max(t[0], 1e-9 * max(abs(t[0]), 1.0))
        idx = [1, 2] if model == "symmetric" else [1, 2, 3, 4]
        t[idx] = np.maximum(t[idx], 0.0)
    if model == "symmetric":
        return _rigid(t[0], t[1], t[2], t[3])
    return _rigid(t[0], t[1], t[2], 0.0, t[3], t[4])


def _rigid(*values: float) -> RigidAxis:
    # An estimate may come out non-physical (negative friction on bad data): keep it as
    # fitted in the parameter vector, and give the model the nearest valid axis.
    m, fv, fc, off, *neg = (float(v) for v in values)
    neg_fixed = [max(v, 0.0) for v in neg]
    return RigidAxis(max(m, np.finfo(float).tiny), max(fv, 0.0), max(fc, 0.0), off, *neg_fixed)


def _theta(axis: RigidAxis, model: str) -> NDArray[np.float64]:
    p = axis.packed()
    if model == "symmetric":
        if not axis.is_symmetric:
            return np.array([p[0], 0.5 * (p[1] + p[3]), 0.5 * (p[2] + p[4]), p[5]])
        return np.array([p[0], p[1], p[2], p[5]])
    # asymmetric has no offset: fold it into the Coulomb levels (Fc+ + off, Fc− − off)
    return np.array([p[0], p[1], p[2] + p[5], p[3], p[4] - p[5]])


def _rms(x: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _errors(q: NDArray[np.float64], f: NDArray[np.float64], sim: RigidLoopResponse
            ) -> dict[str, float]:
    return {
        "position": 100.0 * float(np.linalg.norm(q - sim.position) / np.linalg.norm(q)),
        "force": 100.0 * float(np.linalg.norm(f - sim.force) / np.linalg.norm(f)),
    }
