"""Grey-box refinement of the nonlinear EHSA from closed-loop records.

The source study ([S1]) identifies the reduced linear loop and ends by
asking for the nonlinear effects; models-spec §1.4 gives them: the valve's
pressure-dependent flow law, flapper and spool travel limits (flow
saturation), the spool rate limit, Coulomb/Karnopp friction and a dead
time.  :func:`refine_nonlinear_ehsa` fits a chosen subset of those
parameters, together with the reduced K, ω_hp, δ_hp, by output error of
the *closed loop* driven by the recorded reference: every trial θ runs
the compiled simulator (:class:`NonlinearEhsa`) on every record, as the
pneumatic refinement does (:func:`servoid.plants.pneumatic.refine_parameters`)::

    θ̂ = argmin Σ_t (y(t) − ŷ(t, θ))²,   ŷ = NonlinearEhsa(θ).simulate(r)

The pieces: the model and its parameter map in :mod:`._nonlinear_model`
(K, ω_hp, δ_hp realised through w, M_t and K_ce/B_p; the Karnopp
breakaway F_s moves with F_c), the supply/return pressure and oil
temperature side channels in :mod:`._nonlinear_side`, the search in
:mod:`._nonlinear_search`, validation and the workflow step in
:mod:`._nonlinear_check`.

Coordinates.  The optimiser (bounded trust-region reflective
least squares, :func:`scipy.optimize.least_squares`) works in
``z = log(θ/θ₀)`` for positive parameters (relative steps, positivity)
and ``z = (θ − θ₀)/s`` for T_d and u₀ (which may be 0), s a typical
size.  Finite differences use a step of 1 % in z: the fixed-step
simulator locates stick–slip and limit events to within one RK4 step, so
its output is piecewise smooth in θ with jumps far below the noise; a
1 % step differentiates the trend, a √ε step the jumps (on a Set B bench
record: derivative norms scattered by up to 40 % for steps of 1e-5 and
1e-4, steady to 1 % for 1e-2).  The Jacobian behind the covariance is
the central one at the optimum.

Identifiability.  A limit the record never reaches does not move the
output at all, so nothing bounds it, and a covariance built with it is
singular or meaningless.  Before the fit each parameter is moved by ±5 %
(in z) at the start; if the output moves by less than 0.05·σ (σ the
noise level, the norm over the whole record), the data alone cannot fix
it to better than 100 %
(``σ·0.05/‖Δy‖ > 1``): it is flagged, held at its start value, reported
with an infinite standard deviation and a reason, and a
:class:`~servoid.ServoidWarning` says so.  The same test runs on the
final Jacobian (a parameter may have moved out of reach), and a
remaining rank loss flags the parameters of the null direction.  The
rest goes through the shared checks of
:func:`servoid.estimate.check_identifiability`
(correlation, near-null directions, std against value and against the
Hammersley–Chapman–Robbins floor, the cost's curvature over ±1σ — a
saturation that switches on at the optimum shows there — and several
starts).

Covariance.  As :func:`~servoid.estimate.fit_greybox`: ``"white"``
σ̂²(JᵀJ)⁻¹; ``"robust"`` (the ``"auto"`` choice, output error without a
noise model) the sandwich with the residual autocovariance extended by an
AIC-chosen AR model — bench residuals are coloured by the rig's
decimation filter and by what the model leaves out; ``"bootstrap"``
refits on sieve-resampled residuals, each refit tens of simulations
(:mod:`servoid.estimate._covariance`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_generator, as_instance, as_int, as_mapping, type_error
from ..._errors import (
    ConvergenceError,
    DataError,
    ModelError,
    OptionError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from ..._warn import warn
from ...closedloop import output_name, reference_name
from ...data import Experiment, ExperimentSet, as_segments, detect_intersample
from ...estimate import GREYBOX_COVARIANCES, Estimate, check_identifiability, weakest_parameters
from ...estimate import resolve_covariance as resolve
from ...models import TransferFunction
from ._loop import FeedbackLoop
from ._nonlinear_model import (
    INTERSAMPLES,
    NONLINEAR_PARAMETERS,
    UNITS,
    Intersample,
    NonlinearEhsa,
    check_output_filter,
    fastest_mode,
    physical_parameters,
    reduced_parameters,
)
from ._nonlinear_search import (
    Coordinate,
    add_peaks,
    bootstrap,
    bound_notes,
    covariance_of,
    final_jacobian,
    probe,
    search,
    summary_in_theta,
    values_of,
)
from ._nonlinear_side import operating_point
from ._params import SET_B, EhsaParameters
from ._result import ClosedLoopResult

__all__ = ["NONLINEAR_DEFAULTS", "refine_nonlinear_ehsa"]

Covariance = Literal["auto", "white", "robust", "bootstrap"]

#: What :func:`refine_nonlinear_ehsa` fits unless told: the reduced loop, the effects
#: a small PRBS reaches (friction, spool rate limit) and the dead time.
NONLINEAR_DEFAULTS: tuple[str, ...] = ("K", "omega_hp", "delta_hp", "F_c", "v_s_max", "T_d")

_LINEAR = ("K", "omega_hp", "delta_hp")
_ADDITIVE = ("T_d", "u_0")  # may be 0: optimised as (θ − θ₀)/s, not log θ


def refine_nonlinear_ehsa(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop,
    start: ClosedLoopResult | Estimate | Mapping[str, float] | Sequence[float] | None = None,
    parameters: Sequence[str] = NONLINEAR_DEFAULTS,
    *,
    nominal: EhsaParameters = SET_B,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    reference: str | None = None,
    output: str | None = None,
    supply_pressure: str | float | None = "p_supply",
    return_pressure: str | float | None = "p_return",
    oil_temperature: str | None = "t_oil",
    intersample: Literal["auto", "zoh", "foh"] = "auto",
    output_filter: TransferFunction | None = None,
    covariance: Covariance = "auto",
    multistart: int = 0,
    n_bootstrap: int = 200,
    rng: np.random.Generator | int | None = None,
    max_nfev: int | None = None,
) -> Estimate:
    """Refine the nonlinear EHSA by closed-loop output error.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Estimation record(s), positions in metres: the reference r, the
        position y and the side channels named below.  Each record starts
        at rest at its first measured position.
    loop : FeedbackLoop
        Known gains: ``c = K_TM·K_driver`` and the feedback spring
        ``F = K_fb`` (a gain; the loop is mechanical).
    start : ClosedLoopResult, Estimate, mapping or sequence, optional
        Start values: a linear result (its K, ω_hp, δ_hp, e.g. the
        one-step fit), an estimate or mapping with names of
        :data:`NONLINEAR_PARAMETERS`, or (K [1/s], ω_hp [rad/s], δ_hp
        [-]).  Values not given come from `nominal` at the measured
        pressures.
    parameters : sequence of str
        Parameters to fit, among :data:`NONLINEAR_PARAMETERS`; the others
        are held at their start values.
    nominal : EhsaParameters
        Physical parameters of everything not fitted (valve stages,
        areas, volumes, β_e, ...); its loop gains are replaced by `loop`.
    bounds : mapping, optional
        ``{name: (lower, upper)}`` for fitted parameters; defaults are
        a factor 3 about the start (10 for F_c and v_s_max),
        [0, max(5·T_d, 10·dt)] for T_d and [0, x_s_max/2] for u_0.
    reference : str, optional
        Channel that drives the model, in metres of commanded position;
        default the record's reference (role ``"r"``).  The loop is closed
        mechanically by the feedback spring, so the only plant input a
        rig can log is the command itself — the DAC codes, or the coil
        current as ``i_c/K_driver`` — and either may be named here.
    output : str, optional
        Position channel when there are several outputs.
    supply_pressure : str, float or None
        Channel (Pa, kPa, MPa, bar), value [Pa] or None (nominal) of the
        valve's supply pressure; the median over the records sets the
        flow law (see :mod:`._nonlinear_side`).
    return_pressure : str, float or None
        The same for the return (tank) pressure.
    oil_temperature : str or None
        Oil-temperature channel (°C or K), reported only: the simulator
        has no temperature dependence.
    intersample : {"auto", "zoh", "foh"}
        The reference between samples: ``"zoh"`` for the staircase the
        DAC played, ``"foh"`` for a command logged through the rig's
        analog chain (band-limited; see the notes); ``"auto"`` asks
        :func:`~servoid.data.detect_intersample` of the first record.
    output_filter : TransferFunction, optional
        Continuous unit-gain filter of the position chain (the rig's
        anti-alias filter), applied to the simulated position.  Use it
        with ``intersample="zoh"`` on the DAC command; with a reference
        logged through the same filter, leave it out (both channels
        then share its lag).
    covariance : {"auto", "white", "robust", "bootstrap"}
        ``"auto"`` is ``"robust"`` (module notes).
    multistart : int
        Extra random starts, >= 0 (within the bounds); the lowest cost
        wins and the diagnostics compare the minima.
    n_bootstrap : int
        Refits for ``covariance="bootstrap"``, >= 2.
    rng : numpy.random.Generator or int, optional
        Source of the random starts and resamples.
    max_nfev : int, optional
        Limit on the solver's residual evaluations per start (default
        30·(n + 1)).

    Returns
    -------
    Estimate
        ``method = "nonlinear-ehsa"``; `names` are `parameters` in order,
        a flagged one with its start value and an infinite variance;
        `model` is the refined :class:`NonlinearEhsa`; `options` hold the
        physical set, the operating point, the start and bounds, the
        flags with reasons, the identifiability diagnostics, the
        covariance used and the solver report.

    Notes
    -----
    A reference logged through the rig's anti-alias filter is the DAC
    staircase with its edges smoothed; driven by it, the model's spool
    meets its rate limit less hard than the real one did, and v_s_max and
    T_d absorb the difference.  On 20 Set B bench records (30 dB, PRBS of
    255 bits of 10 ms at ±1 mm, 2550 samples) the logged reference gave
    v_s_max −18…+4 % and T_d +7…+25 % of the truth (|z| up to 4.8) while
    K, ω_hp, δ_hp (within 1 %) and F_c kept |z| < 2.6; with the DAC
    command (``"zoh"``) and the chain's filter (`output_filter`) every
    |z| stayed below 2.8 and the 95 % intervals covered 113 of 120.
    Give both when they are known (the experiment file's ``[rig]``
    declares them).

    Raises
    ------
    OptionError
        A parameter that cannot be refined, an unknown option value, or
        bounds for a parameter that is not fitted.
    DataError
        Bounds that exclude the start, records without a reference or in
        other units, pressures that are not physical.
    ChannelError
        A named side channel is missing.
    ModelError
        A dynamic feedback F, or start values that give no physical set.
    ConvergenceError
        The simulation fails at the start or every start's search fails.

    Warns
    -----
    ServoidWarning
        A parameter is not identifiable from the record, or an
        identifiability check fails (correlation, std, curvature, local
        minima); a parameter ends on a bound; the supply or the
        temperature varies over the record.

    Examples
    --------
    >>> from servoid.plants.ehsa import EhsaBench, run
    >>> from servoid.signals import prbs
    >>> rec = run(EhsaBench(fidelity="nonlinear"), prbs(7, clock=10, amplitude=1e-3,
    ...                                                  dt=1e-3), rng=1)
    >>> exp = rec.raw.calibrate(rec.calibration(), {"yr_cmd": "m", "y_pos": "m",
    ...     "p_supply": "Pa", "p_return": "Pa", "t_oil": "°C"}).decimate(5)
    >>> est = refine_nonlinear_ehsa(exp, FeedbackLoop(0.01, 0.01),
    ...                             parameters=("K", "omega_hp", "delta_hp"))
    >>> round(est["omega_hp"] / 163.3, 1)
    1.0
    """
    check_option("intersample", intersample, ("auto", *INTERSAMPLES))
    check_option("covariance", covariance, GREYBOX_COVARIANCES)
    check_output_filter(output_filter)
    multistart = as_int("multistart", multistart, minimum=0)
    n_bootstrap = as_int("n_bootstrap", n_bootstrap, minimum=2)
    kind = resolve(covariance, noise_model=False)
    generator = as_generator(rng) if multistart or kind == "bootstrap" else None
    free = _check_names(parameters)
    bounds = {} if bounds is None else dict(as_mapping("bounds", bounds))
    if max_nfev is not None:
        max_nfev = as_int("max_nfev", max_nfev, minimum=1)
    as_instance("nominal", nominal, EhsaParameters,
                "an EhsaParameters (e.g. servoid.plants.ehsa.SET_B)")
    c, f = _loop_gains(loop)
    segments = as_segments(data)
    dt = segments[0].dt
    if reference is None:
        ref_name = reference_name(data, "refine_nonlinear_ehsa")
    else:
        for seg in segments:
            seg.channel(reference)  # a ChannelError listing the channels
        ref_name = reference
    out_name = output_name(segments[0], output)
    records = [_record(seg, ref_name, out_name) for seg in segments]
    lengths = [y.size for _, y in records]
    hold, hold_reason = _hold(intersample, records[0][0])

    op = operating_point(segments, supply_pressure, return_pressure, oil_temperature,
                         nominal.P_s, nominal.P_T)
    base = nominal.with_(P_s=op.P_s, P_T=op.P_T, K_fb=f, K_TM=c / nominal.K_driver)
    try:
        start_params = physical_parameters(base, _start_values(start))
    except ModelError as exc:
        raise ModelError(f"the start values give no physical EHSA: {exc}") from None
    coords = _coordinates(free, start_params, bounds, dt)
    template = NonlinearEhsa.for_parameters(start_params, dt, intersample=hold,
                                            output_filter=output_filter,
                                            omega_max=_omega_max(start_params, coords))
    y_all = np.concatenate([y for _, y in records])
    sigma_data = _noise_level(records)
    counter = [0]

    def simulate(values: Mapping[str, float]) -> NDArray[np.float64] | None:
        counter[0] += 1
        try:
            model = template.with_params(physical_parameters(start_params, values))
            return np.concatenate([model.simulate(r, y0=float(y[0])) for r, y in records])
        except (ModelError, DataError):
            return None

    tic = time.perf_counter()
    y_start = simulate({})
    if y_start is None:
        raise ConvergenceError(
            "the nonlinear EHSA simulation fails at the start values "
            f"{ {cd.name: cd.start for cd in coords} }; start from a stable, physical set")
    flags = probe(coords, simulate, y_start, sigma_data)
    if {"x_s_max", "x_f_max"} & set(flags):
        add_peaks(flags, template.with_params(start_params), records)
    for name, reason in flags.items():
        _warn(f"{name}: not identifiable from this record — {reason}; held at its start "
              f"value {_value_of(start_params, name):.6g} {UNITS[name]}, reported with an "
              "infinite standard deviation")
    fit = [cd for cd in coords if cd.name not in flags]
    z_opt = np.zeros(len(fit))
    report: dict[str, Any] = {"nfev": 0, "status": 0, "message": "nothing fitted"}
    summary = None
    if fit:
        z_opt, report, summary = search(fit, simulate, y_all, max_nfev, multistart, generator,
                                         sigma_data)
    values = values_of(fit, z_opt)
    y_hat = simulate(values)
    if y_hat is None:
        raise ConvergenceError(f"the simulation fails at the solver's final point {values}")
    resid = y_all - y_hat
    jac, late = final_jacobian(fit, z_opt, simulate, y_hat, sigma_data)
    keep = [k for k, cd in enumerate(fit) if cd.name not in late]
    cov_z, ar_order = covariance_of(kind, jac[:, keep], resid, lengths)
    if cov_z is None:  # rank loss among the rest: flag its direction, keep the others
        weak = weakest_parameters(jac[:, keep], [fit[k].name for k in keep])
        for name in weak:
            late[name] = ("not separately identifiable: the output depends on a combination "
                          f"of {', '.join(weak)} only")
        keep = [k for k in keep if fit[k].name not in weak]
        cov_z, ar_order = covariance_of(kind, jac[:, keep], resid, lengths)
        assert cov_z is not None
    for name, reason in late.items():
        flags[name] = reason
        _warn(f"{name}: not identifiable at the fitted values — {reason}; reported with an "
              "infinite standard deviation")
    fitted = [fit[k] for k in keep]
    d = np.array([cd.derivative(float(z_opt[k])) for k, cd in zip(keep, fitted, strict=True)])
    cov_fit = cov_z * np.outer(d, d)
    extra: dict[str, Any] = {}
    if kind == "bootstrap" and fitted:
        assert generator is not None
        cov_fit, extra["bootstrap"] = bootstrap(fitted, z_opt[keep], values, simulate,
                                                 y_hat, resid, lengths, max_nfev, n_bootstrap,
                                                 generator)

    names = tuple(free)
    theta = np.array([values.get(n, _value_of(start_params, n)) for n in names])
    idx = [names.index(cd.name) for cd in fitted]
    cov = np.zeros((len(names), len(names)))
    cov[np.ix_(idx, idx)] = cov_fit
    for n in flags:
        cov[names.index(n), names.index(n)] = np.inf
    notes = bound_notes(fitted, theta[idx])
    ident = None
    if fitted:
        theta_fit = theta[idx]

        def residual_theta(th: NDArray[np.float64]) -> NDArray[np.float64]:
            vals = dict(values)
            vals.update({cd.name: float(v) for cd, v in zip(fitted, th, strict=True)})
            yh = simulate(vals)
            return np.full(y_all.size, np.nan) if yh is None else y_all - yh

        ident = check_identifiability(
            residual_theta, theta_fit, cov_fit, [cd.name for cd in fitted],
            jacobian=-jac[:, keep] / d, groups=[lengths],
            multistart=summary_in_theta(summary, fit, keep), warn=False)
        notes += [flag.message for flag in ident.flags]
    for note in notes:
        _warn(note)
    refined = physical_parameters(start_params, values)
    options = {
        "parameters": list(names),
        "start": {cd.name: cd.start for cd in coords},
        "bounds": {cd.name: [cd.lower, cd.upper] for cd in coords},
        "not_identifiable": dict(flags),
        "identifiability": None if ident is None else ident.to_dict(),
        "warnings": notes,
        "covariance": kind,
        "covariance_ar_order": ar_order,
        **extra,
        "physical": {k: float(v) for k, v in vars(refined).items()},
        "reduced": dict(zip(_LINEAR, reduced_parameters(refined), strict=True)),
        "operating_point": op.to_dict(),
        "loop": {"c": c, "F": f},
        "reference": ref_name,
        "output": out_name,
        "intersample": hold,
        "intersample_reason": hold_reason,
        "output_filter": None if output_filter is None else
        {"num": output_filter.num.tolist(), "den": output_filter.den.tolist(),
         "delay": output_filter.delay},
        "dt_int": template.dt_int,
        "noise_std_data": sigma_data,
        "residual_rms": math.sqrt(float(resid @ resid) / resid.size),
        "simulations": counter[0],
        "seconds": time.perf_counter() - tic,
        **report,
    }
    sigma2 = float(resid @ resid) / max(resid.size - len(fitted), 1)

    def model_at(th: NDArray[np.float64]) -> NonlinearEhsa:
        vals = {n: float(v) for n, v in zip(names, th, strict=True)}
        return template.with_params(physical_parameters(start_params, vals))

    return Estimate(
        model=template.with_params(refined),
        parameters=theta,
        names=names,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=resid.size,
        method="nonlinear-ehsa",
        status="ok",
        options=options,
        units=tuple(UNITS[n] for n in names),
        residual_function=lambda: resid.copy(),
        model_function=model_at,
    )


# -- input checks ------------------------------------------------------------


def _check_names(parameters: Sequence[str]) -> list[str]:
    if isinstance(parameters, str) or not isinstance(parameters, Sequence):
        raise OptionTypeError(f"parameters must be a sequence of names, got {parameters!r}")
    names = list(parameters)
    unknown = [n for n in names if n not in NONLINEAR_PARAMETERS]
    if unknown or not names:
        raise OptionError(
            f"parameters must name parameters of the nonlinear EHSA among "
            f"{', '.join(NONLINEAR_PARAMETERS)}; got "
            f"{', '.join(map(repr, unknown)) or 'none'}")
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise OptionError(f"parameters must be unique, repeated: {', '.join(dupes)}")
    return names


def _loop_gains(loop: object) -> tuple[float, float]:
    as_instance("loop", loop, FeedbackLoop, "a FeedbackLoop(c, F), e.g. FeedbackLoop(c=0.01, "
                "F=0.01)")
    if not loop.is_static:
        raise ModelError("the nonlinear EHSA closes its loop with the feedback spring: F must be "
                         "a gain (K_fb [m/m]), not a transfer function")
    c, f = float(loop.c), float(loop.F)  # type: ignore[arg-type]
    if c <= 0:
        raise ModelError(f"c = K_TM·K_driver must be > 0 for the EHSA, got {c:g}")
    return c, f


def _record(seg: Experiment, ref: str, out: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    for name in (ref, out):
        unit = seg.unit(name)
        if unit not in ("m", ""):
            raise DataError(f"channel {name!r} is in {unit!r}; the simulator works in metres "
                            "(its limits and forces are absolute): calibrate it to m")
    seg.require_samples(10, "the nonlinear EHSA refinement")
    return np.asarray(seg[ref], dtype=float), np.asarray(seg[out], dtype=float)


def _start_values(start: object) -> dict[str, float]:
    if start is None:
        return {}
    if isinstance(start, ClosedLoopResult):
        start = start.estimate
    if isinstance(start, Estimate):
        return {n: float(v) for n, v in zip(start.names, start.parameters, strict=True)
                if n in NONLINEAR_PARAMETERS}
    if isinstance(start, Mapping):
        unknown = sorted(set(start) - set(NONLINEAR_PARAMETERS))
        if unknown:
            raise OptionError(f"start names {', '.join(unknown)}, not among "
                              f"{', '.join(NONLINEAR_PARAMETERS)}")
        return {str(k): _finite(f"start[{k!r}]", v) for k, v in start.items()}
    if isinstance(start, (Sequence, np.ndarray)) and not isinstance(start, str):
        vals = [_finite("start", v) for v in start]
        if len(vals) != 3:
            raise DataError(f"start as a sequence must be (K, omega_hp, delta_hp), got "
                            f"{len(vals)} values")
        return dict(zip(_LINEAR, vals, strict=True))
    raise type_error("start", start, "a ClosedLoopResult, an Estimate, a mapping {name: value} "
                     "or (K, omega_hp, delta_hp)")


def _hold(intersample: str, r: NDArray[np.float64]) -> tuple[Intersample, str]:
    """The reference's hold, detected for ``"auto"``, and why."""
    if intersample != "auto":
        return intersample, "given"  # type: ignore[return-value]
    check = detect_intersample(r)
    hold: Intersample = "zoh" if check.kind == "zoh" else "foh"
    return hold, f"detected: {check.reason}"


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise type_error(name, value, "a number")
    v = float(value)
    if not math.isfinite(v):
        raise DataError(f"{name} must be finite, got {v}")
    return v


def _value_of(params: EhsaParameters, name: str) -> float:
    """Value of a refinable parameter in a physical set."""
    if name in _LINEAR:
        return reduced_parameters(params)[_LINEAR.index(name)]
    return float(getattr(params, name))


def _coordinates(free: Sequence[str], params: EhsaParameters,
                 bounds: dict[str, tuple[float, float]], dt: float) -> list[Coordinate]:
    extra = sorted(set(bounds) - set(free))
    if extra:
        raise OptionError(f"bounds given for parameters that are not fitted: {', '.join(extra)}")
    coords = []
    for name in free:
        v = _value_of(params, name)
        log = name not in _ADDITIVE and v > 0
        if name == "T_d":
            default = (0.0, max(5.0 * v, 10.0 * dt))
            scale = v if v > 0 else dt
        elif name == "u_0":
            default = (0.0, 0.5 * params.x_s_max)
            scale = v if v > 0 else 0.01 * params.x_s_max
        elif not log:  # F_c started at 0: additive, up to 5 % of the stall force
            default = (0.0, 0.05 * params.stall_force)
            scale = 0.01 * params.stall_force
        else:
            wide = 10.0 if name in ("F_c", "v_s_max") else 3.0
            default = (v / wide, v * wide)
            scale = v
        pair = bounds.get(name, default)
        if not (isinstance(pair, Sequence) and len(pair) == 2):
            raise OptionTypeError(f"bounds[{name!r}] must be a pair (lower, upper), got {pair!r}")
        lo, hi = (_finite(f"bounds[{name!r}]", b) for b in pair)
        if not lo < hi:
            raise DataError(f"bounds of {name} need lower < upper, got ({lo:g}, {hi:g})")
        if not lo <= v <= hi:
            raise DataError(f"the start value of {name} = {v:.6g} {UNITS[name]} lies outside its "
                            f"bounds [{lo:.6g}, {hi:.6g}]; widen the bounds or change the start")
        if log and lo < 0:
            raise DataError(f"{name} is positive: its lower bound must be >= 0, got {lo:g}")
        coords.append(Coordinate(name, v, lo, hi, log, scale))
    return coords


def _omega_max(params: EhsaParameters, coords: Sequence[Coordinate]) -> float:
    """Fastest mode the RK4 step must resolve anywhere inside the bounds."""
    ratio = {cd.name: cd.upper / cd.start for cd in coords
             if cd.name in ("omega_hp", "delta_hp") and cd.start > 0}
    # B_p/M_t grows at most as δ·ω (∝ δ·ω where the viscous share dominates, slower else)
    viscous = params.B_p / params.M_t * ratio.get("omega_hp", 1.0) * ratio.get("delta_hp", 1.0)
    high = params.omega_hp * ratio.get("omega_hp", 1.0)
    return max(fastest_mode(params), high, viscous)


def _noise_level(records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]]) -> float:
    """Noise std of the positions from their second differences (MAD).

    The servo moves little between samples at the identification rate, so
    the second difference is noise, ``√6·σ`` for white noise; the median
    of absolute deviations ignores the PRBS edges.  Only the probes use
    it (a threshold), never the covariance.
    """
    d2 = np.concatenate([np.diff(y, 2) for _, y in records])
    sigma = float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))
    spread = float(np.std(np.concatenate([y for _, y in records])))
    return max(sigma, 1e-6 * spread, 1e-15)


def _warn(message: str) -> None:
    warn(message, ServoidWarning)
