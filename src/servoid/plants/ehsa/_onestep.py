"""One-step parameterised closed loop: OE on Gcl(q, θ), θ = (K, ω_hp, δ_hp) (spec §1.5).

The continuous closed loop ``c·G0(s, θ)/(1 + F·G0(s, θ))`` becomes a
discrete model in one of two ways:

- a *map* of the source study, Tustin (plain or prewarped at ω_hp): an
  approximation with no statement about the reference between samples;
- an *exact sampled model* for a stated course of the reference between
  samples (:mod:`._sampling`): a staircase (``"zoh"``, with the rig's
  anti-alias filter and servoid's FIR decimation of the output when they
  are declared), straight lines (``"foh"``) or a band-limited signal read
  back like the output (``"bandlimited"``).  ``"auto"`` detects the
  staircase or band-limited reference (:func:`servoid.data.detect_intersample`).

The fit does not depend on any other estimator: it starts from a grid
(:mod:`._start`) at several points and keeps the best optimum.  After
the fit the resonance is checked against the sample rate and the
parameter intervals; what the data cannot resolve is flagged with the
rate that would resolve it.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float, as_instance, as_int, type_error
from ..._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    OptionError,
    ServoidWarning,
    check_option,
)
from ..._lazy import optimize
from ..._warn import warn
from ...closedloop import check_name
from ...data import Experiment, ExperimentSet, as_segments, detect_intersample
from ...estimate import Estimate, fit_tf_greybox
from ...models import TransferFunction, c2d
from ._descent import descend
from ._kernels import level_residuals
from ._loop import FeedbackLoop
from ._onestep_model import Coefficients, model_function
from ._physical import anchors_of, delta_method, pole_report, warn_flagged
from ._result import ClosedLoopResult
from ._sampling import BANDLIMITED_DEGREE, Hold
from ._start import grid_starts
from ._structures import STRUCTURES, PlantStructure

__all__ = ["DISCRETIZATIONS", "fit_one_step"]

Discretization = Literal["auto", "tustin", "prewarp", "zoh", "foh", "bandlimited"]
Initial = Literal["level", "rest"]
#: How :func:`fit_one_step` can turn the continuous closed loop into a discrete model.
DISCRETIZATIONS: tuple[Discretization, ...] = (
    "auto", "tustin", "prewarp", "zoh", "foh", "bandlimited")

#: 95 % interval half-width (1.96σ) beyond which the resonance counts as not determined.
_UNDETERMINED = 0.5
#: Nyquist frequency over ω_hp below which the resonance counts as not resolved.
_NYQUIST_MARGIN = 2.0


def fit_one_step(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop,
    theta0: Sequence[float] | NDArray[np.float64] | None = None,
    *,
    structure: PlantStructure | str = "reduced",
    output: str | None = None,
    start: int = 0,
    max_nfev: int | None = None,
    integrator_tol: float = 0.1,
    discretization: Discretization = "auto",
    anti_alias: TransferFunction | None = None,
    decimation: int = 1,
    n_starts: int = 3,
    initial: Initial = "level",
) -> ClosedLoopResult:
    """Fit K, ω_hp, δ_hp by output error on the closed loop from r.

    The model is ``Gcl(q, θ) = c·G/(1 + F·G)`` with ``G`` the plant of
    `structure` (the reduced ``K/(s(s²/ω² + 2δs/ω + 1))`` by default),
    discretised as `discretization` says; the criterion
    ``Σ (y − Gcl(q, θ) r)²`` is minimised by Levenberg–Marquardt in the
    structure's coordinates (log K, log ω, δ). It keeps the integrator
    exact and, unlike ARX, is consistent under white measurement noise.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the reference r and the output y.
    loop : FeedbackLoop
        Known forward gain c and feedback F.
    theta0 : sequence of float, optional
        Start in the structure's parameters (reduced: K [1/s], ω_hp
        [rad/s], δ_hp [-]); one fit from there. Default: `n_starts` fits
        from a grid scored on the data (first-order bandwidth for K, then
        ω_hp and δ_hp), the best optimum kept.
    structure : PlantStructure or str
        The plant structure, or its name in
        ``servoid.plants.ehsa._structures.STRUCTURES``.
    output : str, optional
        Output channel name when there are several.
    start : int
        First sample in the criterion (the model starts from rest).
    max_nfev : int, optional
        Limit on model simulations per start.
    integrator_tol : float
        Not used for the fit (the integrator is exact); kept for a uniform
        pole report [rad/s].
    discretization : {"auto", "tustin", "prewarp", "zoh", "foh", "bandlimited"}
        ``"tustin"``: the source study's map (on data from a continuous
        loop it overestimates ω_hp by about (ω_hp·dt)²/12, 0.22 % for Set
        B at 1 kHz); ``"prewarp"``: Tustin prewarped at the current ω_hp
        (ω_hp is then bounded below π/dt, where the map exists);
        ``"zoh"``: exact for a staircase reference (a DAC command), with
        `anti_alias` and `decimation` of the output when given;
        ``"foh"``: exact for straight lines between samples;
        ``"bandlimited"``: a smooth reference read back through the same
        filter and decimation as y (7th-degree interpolation between
        samples); ``"auto"``: ``"zoh"`` when a rig chain is given, else
        the reference's course as :func:`servoid.data.detect_intersample`
        finds it. The result states the assumption used.
    anti_alias : TransferFunction, optional
        Continuous filter the output passed through before the ADC while
        the reference did not (it is the logged command); staircase
        references only.
    decimation : int
        Factor of servoid's FIR decimation (:func:`servoid.data.decimate`)
        applied to y after the ADC, the reference being subsampled;
        staircase references only. 1: none.
    n_starts : int
        Number of grid starts when `theta0` is not given, >= 1.
    initial : {"level", "rest"}
        State of the loop before each record: ``"level"``: at rest at a
        level, with an offset on the output, both estimated with θ (two
        numbers per record: removing the means, as spec §3.2 does, moves a
        record that starts at rest off zero by exactly these, and the
        start-up transient would bias K otherwise); ``"rest"``: at rest at
        zero, no offset. They enter the final fit as known (their own
        uncertainty is not in the covariance).

    Returns
    -------
    ClosedLoopResult
        ``approach = "one-step"``; the covariance of
        :func:`~servoid.estimate.fit_tf_greybox` (``source.options["covariance"]``
        says which) mapped to (K, ω, δ); ``intersample`` and
        ``intersample_note`` state the assumption, ``flags`` what the data
        cannot resolve.

    Raises
    ------
    ConvergenceError
        Levenberg–Marquardt did not converge from any start.
    DataError
        No reference channel, or a start value that is not positive.
    IdentifiabilityError
        The parameters cannot be separated from the data (the message
        names the sample rate or excitation that would separate them).
    OptionError
        An unknown discretization or structure, or a rig chain with a
        hold other than ``"zoh"``.

    Warns
    -----
    ServoidWarning
        A flagged pole, a resonance not resolved at this rate or not
        determined by the data, or a stated hold the reference contradicts.

    Examples
    --------
    >>> from servoid.signals import prbs
    >>> from servoid.plants.ehsa import simulate_closed_loop
    >>> loop = FeedbackLoop(0.01, 0.01)
    >>> r = prbs(9, clock=10, amplitude=1e-3, dt=1e-3).values
    >>> y = simulate_closed_loop((3451.7, 163.3, 0.249), r, 1e-3, loop)
    >>> fit = fit_one_step(Experiment.from_arrays(1e-3, r=r, y=y), loop, discretization="tustin")
    >>> [round(float(v), 3) for v in fit.estimate.parameters]
    [3451.7, 163.3, 0.249]
    """
    check_option("discretization", discretization, DISCRETIZATIONS)
    check_option("initial", initial, ("level", "rest"))
    _check_loop(loop)
    _require_reference(data, "one-step")
    plant_structure = _structure(structure)
    n_starts = as_int("n_starts", n_starts, minimum=1)
    integrator_tol = as_float("integrator_tol", integrator_tol, nonneg=True)
    output = check_name("output", output)
    if max_nfev is not None:
        max_nfev = as_int("max_nfev", max_nfev, minimum=1)
    decimation = as_int("decimation", decimation, minimum=1)
    if anti_alias is not None and (not isinstance(anti_alias, TransferFunction)
                                   or anti_alias.dt is not None):
        raise type_error("anti_alias", anti_alias, "a continuous TransferFunction (the analog "
                         "anti-alias filter) or None")
    segments = as_segments(data)
    dt = segments[0].dt
    start = as_int("start", start, minimum=0)
    if any(seg.n_samples <= start + 4 for seg in segments):
        raise DataError(f"start = {start} leaves too few samples in a record of "
                        f"{min(seg.n_samples for seg in segments)}")
    chain = anti_alias is not None or decimation > 1
    hold, note = _intersample(segments[0], discretization, chain, anti_alias, decimation)
    model_fn, coefficients, advance = model_function(plant_structure, loop, dt, discretization,
                                                      hold, anti_alias, decimation)
    records = [(seg.signal("r")[:, 0], seg[_output(seg, output)]) for seg in segments]
    problem = _Problem(_aligned(segments, output, advance),
                       (segments[0].names_of("r")[0], _output(segments[0], output)), dt,
                       start + advance, initial, isinstance(data, ExperimentSet))
    omega_n = math.pi / dt
    bounds = _bounds(plant_structure, discretization, omega_n)
    if theta0 is None:
        top = 0.999 * omega_n if discretization == "prewarp" else 1.5 * omega_n
        starts = [plant_structure.start(t) for t in grid_starts(records, loop, dt, top,
                                                                  n_starts)]
    else:
        starts = [_check_theta0(theta0, plant_structure)]
    est = _best_fit(problem, model_fn, coefficients, starts, plant_structure, max_nfev, bounds)
    return greybox_result(
        "one-step", est, loop, dt, est.model, integrator_tol, discretization=discretization,
        structure=plant_structure, hold=hold, note=note, advance=advance, reference=records,
    )


def greybox_result(
    approach: str,
    est: Estimate,
    loop: FeedbackLoop | None,
    dt: float,
    closed_loop: TransferFunction | None,
    integrator_tol: float,
    discretization: str = "tustin",
    *,
    structure: PlantStructure | None = None,
    hold: Hold | None = None,
    note: str = "",
    advance: int = 0,
    reference: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]] | None = None,
) -> ClosedLoopResult:
    """Wrap an OE fit as a closed-loop result in (K, ω, δ), with its checks."""
    plant_structure = structure if structure is not None else STRUCTURES["reduced"]
    theta = np.asarray(est.parameters, dtype=float)
    plant_c = plant_structure.plant(theta)
    physical = _reduced_estimate(est, plant_structure, plant_c)
    w = float(physical.parameters[1])
    if discretization == "prewarp":
        plant = c2d(plant_c, dt, "tustin", prewarp=min(w, 0.999 * math.pi / dt))
    elif discretization == "tustin":
        plant = c2d(plant_c, dt, "tustin")
    else:
        plant = c2d(plant_c, dt, "zoh" if hold == "zoh" else "foh")
    physical = dataclasses.replace(physical, options={
        **dict(physical.options), "discretization": discretization,
        "intersample": hold or "none", "advance": advance, "structure": plant_structure.name})
    anchors = anchors_of(plant_c, None)
    report_loop = closed_loop
    if hold is not None and loop is not None:
        # the loop's own poles, not those of the rig's anti-alias filter or FIR
        report_loop = c2d(loop.close(plant_c), dt, "zoh" if hold == "zoh" else "foh")
    poles = pole_report(report_loop, plant, plant_c, anchors, 0.0, 0.0, integrator_tol)
    warn_flagged(poles)
    flags = _resolution_flags(physical, dt, reference)
    for flag in flags:
        warn(flag, ServoidWarning)
    return ClosedLoopResult(
        approach, physical, closed_loop, plant, plant_c, poles, loop, 0.0, 0.0, est,
        discretization=discretization, intersample=hold or "none", intersample_note=note,
        advance=advance, flags=flags, structure=plant_structure.name,
    )


# -- discretisation and intersample --------------------------------------------------------


def _intersample(
    segment: Experiment, discretization: str, chain: bool,
    anti_alias: TransferFunction | None, decimation: int,
) -> tuple[Hold | None, str]:
    """The hold used (None for a Tustin map) and the sentence that states it."""
    if chain and discretization not in ("auto", "zoh"):
        raise OptionError(
            f"anti_alias and decimation describe the output's chain for a staircase reference "
            f"(a logged DAC command); discretization={discretization!r} does not take them: use "
            "'zoh' or 'auto'. A reference read back through the same chain as the output needs "
            "neither (the chain cancels): use 'bandlimited'"
        )
    check = detect_intersample(segment.signal("r")[:, 0])
    seen = f"detected {check.reason}"
    if discretization in ("tustin", "prewarp"):
        what = ("Tustin's map prewarped at ω_hp" if discretization == "prewarp" else
                "Tustin's map (it overestimates ω_hp by ≈ (ω_hp·dt)²/12)")
        hint = repr(check.kind)
        return None, (f"no intersample model: {what} approximates the continuous loop; "
                      f"reference {seen}; discretization={hint} (or 'auto') models it exactly")
    if discretization == "auto":
        hold: Hold = "zoh" if chain else check.kind
        if chain and check.kind != "zoh":
            warn(
                "the rig chain (anti-alias filter / decimation of y) is declared for a logged "
                f"command, but the reference looks band-limited ({check.reason}); the staircase "
                "model is used as declared. If r was read back through the same chain, declare "
                "it so (it cancels) and use discretization='bandlimited'",
                ServoidWarning)
    else:
        hold = discretization  # type: ignore[assignment]
        if hold in ("zoh", "bandlimited") and check.kind != hold:
            warn(
                f"discretization={hold!r} assumes a {_KIND[hold]} reference, but it looks "
                f"{_KIND[check.kind]} ({check.reason}); the estimate is biased if the "
                "assumption is wrong: use 'auto' or declare how r was logged",
                ServoidWarning)
    if hold == "zoh":
        text = "reference taken as a staircase held over each sample (zero-order hold, exact)"
        if chain:
            parts = []
            if anti_alias is not None:
                parts.append(f"the order-{anti_alias.order} analog anti-alias filter")
            if decimation > 1:
                parts.append(f"servoid's FIR decimation by {decimation}")
            text += (f"; {' and '.join(parts)} of the output are in the model (declared; the "
                     "reference is the logged command, subsampled)")
    elif hold == "foh":
        text = "reference taken as straight lines between samples (first-order hold, exact)"
    else:
        text = (f"reference taken as band-limited, read back through the same filter and "
                f"decimation as the output, which then cancel (continuous-time criterion; "
                f"degree-{BANDLIMITED_DEGREE} interpolation between samples)")
    source = "declared" if discretization != "auto" or chain else "auto"
    return hold, f"{text}; {source}; reference {seen}"


_KIND = {"zoh": "staircase (DAC command)", "bandlimited": "band-limited (read back)"}


def _aligned(segments: Sequence[Experiment], output: str | None,
             advance: int) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """(r, y) with y delayed by `advance` samples: ``y(k − L) = G'(q)·r(k)`` is causal.

    The first `advance` outputs are unknown (zero here) and left out of the criterion.
    """
    out = []
    for seg in segments:
        r = np.ascontiguousarray(seg.signal("r")[:, 0], dtype=float)
        y = np.ascontiguousarray(seg[_output(seg, output)], dtype=float)
        if advance:
            y = np.concatenate([np.zeros(advance), y[: y.size - advance]])
        out.append((r, y))
    return out


def _bounds(plant_structure: PlantStructure, discretization: str,
            omega_n: float) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The structure's bounds, and ω_hp < π/dt for the prewarped map (None: unbounded).

    Beyond π/dt, tan(ω·dt/2) changes sign and the prewarped map does not exist.
    Infinite bounds become finite ones far enough never to bind (fit_tf_greybox moves a start
    inside the bounds by a relative margin, which an infinite bound turns into NaN) and
    moderate enough for the trust-region scaling, which works with distances to the bounds.
    """
    given = plant_structure.bounds
    prewarp = discretization == "prewarp" and "omega_hp" in plant_structure.names
    if given is None and not prewarp:
        return None
    n = plant_structure.n_parameters
    is_log = np.array([t == "log" for t in plant_structure.transforms])
    lo = np.full(n, -np.inf) if given is None else np.asarray(given[0], dtype=float).copy()
    hi = np.full(n, np.inf) if given is None else np.asarray(given[1], dtype=float).copy()
    lo = np.where(is_log, np.maximum(lo, 1e-30), np.where(np.isfinite(lo), lo, -1e3))
    hi = np.where(np.isfinite(hi), hi, np.where(is_log, 1e30, 1e3))
    if prewarp:
        k = plant_structure.names.index("omega_hp")
        hi[k] = min(hi[k], 0.999 * omega_n)
    return lo, hi


@dataclass(frozen=True)
class _Problem:
    """The aligned records and what the criterion uses of them."""

    records: list[tuple[NDArray[np.float64], NDArray[np.float64]]]
    names: tuple[str, str]  # reference and output channel names
    dt: float
    start: int  # first sample of the criterion in each record (user's start + advance)
    initial: str  # "level" or "rest"
    as_set: bool


def _best_fit(
    problem: _Problem,
    model_fn: Callable[[NDArray[np.float64]], TransferFunction],
    coefficients: Coefficients,
    starts: Sequence[NDArray[np.float64]],
    plant_structure: PlantStructure,
    max_nfev: int | None,
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
) -> Estimate:
    """Descend from every start, then fit (with covariance) from the best optimum.

    The descents use a loose tolerance (1e-6 on cost and step), estimate
    the rest level before each record with θ (variable projection) and rank
    the basins; :func:`~servoid.estimate.fit_tf_greybox` then converges from
    the best one, on records preceded by that level held long enough for
    the loop to settle, and supplies the covariance and its diagnostics
    once.  Should it fail there, the next basin is tried.
    """
    if bounds is not None:
        starts = [np.clip(t, bounds[0], 0.99 * bounds[1]) for t in starts]
    ranked = _rank_starts(problem, coefficients, starts, plant_structure, bounds, max_nfev)
    failures: list[Exception] = []
    dt = problem.dt
    for theta0, nuisance in ranked:
        data, prefix = _with_levels(problem, model_fn, theta0, nuisance)
        try:
            est = fit_tf_greybox(
                data, model_fn, theta0, plant_structure.names, plant_structure.units,
                input="r", output=problem.names[1], transform=plant_structure.transforms,
                bounds=bounds, start=problem.start + prefix, max_nfev=max_nfev,
                method_name="one-step")
        except (ConvergenceError, IdentifiabilityError) as exc:
            failures.append(exc)
            continue
        # the criterion's samples in the caller's records: the held level is not data
        return dataclasses.replace(est, options={
            **dict(est.options), "start": problem.start, "prefix": prefix,
            "initial": problem.initial,
            "initial_level": [lv for lv, _ in nuisance],
            "output_offset": [off for _, off in nuisance],
            "structure": plant_structure.name, "n_starts": len(starts),
            "starts": [np.asarray(t, float).tolist() for t in starts]})
    first = failures[0]
    if all(isinstance(f, IdentifiabilityError) for f in failures):
        raise IdentifiabilityError(
            f"{first} — at dt = {dt:g} s (f_s = {1 / dt:g} Hz, Nyquist "
            f"{math.pi / dt:.4g} rad/s) the closed loop does not show omega_hp and "
            "delta_hp separately: the resonance lies beyond what this rate resolves or "
            "the reference does not excite it. Record at f_s >= 4·f_hp (f_hp from the "
            "design or a step test) with a reference that reaches the resonance"
        ) from None
    raise first


def _level_fit(
    problem: _Problem, model: tuple[NDArray[np.float64], NDArray[np.float64]],
) -> tuple[list[NDArray[np.float64]], list[tuple[float, float]]]:
    """Residuals with the rest level and output offset of each record projected out.

    `model` is ``(b, a)`` as lfilter takes it.  A loop held at level ℓ
    before the record adds ``ℓ·(G(1) − s(k))`` to the response from rest
    (s the step response, G(1) the static gain); an offset o of the output
    adds o.  Removing the means (spec §3.2) leaves exactly these two for a
    record that starts at rest: ``ℓ = −mean(r)`` and
    ``o = G(1)·mean(r) − mean(y)``, which differ from zero by the loop's lag
    over a short record.  Both are linear: least squares per record, on the
    criterion's samples.  G(1) is the settled step response (it equals the
    static gain once the loop has settled within the record, which a record
    that resolves it always allows); a start after the transient has died
    out (decay energy below 1e-6 of the whole) leaves the level without
    effect and undetermined, so the offset is fitted alone.  The simulation
    and the regression are one compiled pass (:func:`._kernels.level_residuals`).
    """
    b, a = model
    out, nuisance = [], []
    with np.errstate(all="ignore"):
        for r, y in problem.records:
            e, level, offset = level_residuals(b, a, r, y, problem.start,
                                               problem.initial == "level")
            if not (math.isfinite(level) and math.isfinite(offset)):
                # what the least-squares solver does on a non-finite column: the start fails
                raise np.linalg.LinAlgError("the level regression is not finite")
            out.append(e)
            nuisance.append((level, offset))
    return out, nuisance


def _with_levels(
    problem: _Problem, model_fn: Callable[[NDArray[np.float64]], TransferFunction],
    theta: NDArray[np.float64], nuisance: Sequence[tuple[float, float]],
) -> tuple[Experiment | ExperimentSet, int]:
    """The records preceded by their rest levels (held until the loop settles), offset off y."""
    prefix = 0
    if problem.initial == "level" and any(lv for lv, _ in nuisance):
        model = model_fn(theta)
        radius = float(np.max(np.abs(model.poles()))) if model.order else 0.0
        n = max(r.size for r, _ in problem.records)
        # settle to 1e-9 of the level; a loop too slow for that over the record gets 4 records
        prefix = n * 4 if radius >= 1.0 else int(min(
            max(math.ceil(math.log(1e-9) / math.log(max(radius, 1e-300))), 1), 4 * n))
    out = []
    r_name, y_name = problem.names
    for (r, y), (level, offset) in zip(problem.records, nuisance, strict=True):
        y = y - offset
        if prefix:
            r = np.concatenate([np.full(prefix, level), r])
            y = np.concatenate([np.zeros(prefix), y])  # outside the criterion
        out.append(Experiment.from_arrays(problem.dt, r=r, y=y, names={"r": r_name, "y": y_name}))
    return (ExperimentSet(tuple(out)) if problem.as_set else out[0]), prefix


def _rank_starts(
    problem: _Problem,
    coefficients: Coefficients,
    starts: Sequence[NDArray[np.float64]],
    plant_structure: PlantStructure,
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    max_nfev: int | None,
) -> list[tuple[NDArray[np.float64], list[tuple[float, float]]]]:
    """The optima of loose descents from each start with their levels, best first.

    A descent that comes within :data:`_JOIN` (relative) of an optimum an
    earlier descent found has joined that basin: it would end there, so it
    stops and counts as that optimum (the usual case: every start of a
    well-excited record leads to the one minimum, and the last third of
    each later descent is spent converging onto it again).
    """
    is_log = np.array([t == "log" for t in plant_structure.transforms])

    def to_theta(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(is_log, np.exp(np.where(is_log, z, 0.0)), z)

    found: list[tuple[float, NDArray[np.float64], NDArray[np.float64]]] = []  # cost, z, scale

    def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
        for k, (_, z_opt, scale) in enumerate(found):
            if np.all(np.abs(z - z_opt) <= scale):
                raise _Joined(k)
        parts, _ = _level_fit(problem, coefficients(to_theta(z)))
        out = parts[0] if len(parts) == 1 else np.concatenate(parts)  # (no copy of one record)
        # a diverging simulation: finite, so the step is refused (in place, no N-float mask)
        return np.nan_to_num(out, copy=False, nan=1e30, posinf=1e30, neginf=1e30)

    lo = hi = None
    if bounds is not None:
        lo = np.where(is_log, np.log(np.where(is_log, bounds[0], 1.0)), bounds[0])
        hi = np.where(is_log, np.log(np.where(is_log, bounds[1], 1.0)), bounds[1])
    ranked: list[tuple[float, NDArray[np.float64]]] = []
    limit = max_nfev if max_nfev is not None else 100 * (len(plant_structure.names) + 1)
    for theta0 in starts:
        z0 = np.where(is_log, np.log(np.where(is_log, theta0, 1.0)), theta0)
        try:
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                if lo is None:
                    x, cost = _loose(residuals, z0, limit)
                else:
                    res = optimize.least_squares(
                        residuals, z0, method="trf", bounds=(lo, hi), xtol=1e-6, ftol=1e-6,
                        gtol=1e-8, max_nfev=limit)
                    x, cost = res.x, float(res.cost)
        except _Joined as joined:
            cost, z_opt, _ = found[joined.basin]
            ranked.append((cost, to_theta(z_opt)))
            continue
        except (ValueError, np.linalg.LinAlgError):
            ranked.append((math.inf, np.asarray(theta0, dtype=float)))
            continue
        ok = np.all(np.isfinite(x)) and np.isfinite(cost) and cost < 1e50
        ranked.append((float(cost) if ok else math.inf, to_theta(x) if ok else theta0))
        if ok:
            # log coordinates are relative already; the others relative to the optimum
            scale = _JOIN * np.where(is_log, 1.0, np.abs(x))
            found.append((float(cost), np.array(x, dtype=float), scale))
    ranked.sort(key=lambda item: item[0])
    out = []
    for _, theta in ranked:
        _, nuisance = _level_fit(problem, coefficients(theta))
        out.append((theta, nuisance))
    return out


def _loose(residuals: Callable[[NDArray[np.float64]], NDArray[np.float64]],
           z0: NDArray[np.float64], max_nfev: int) -> tuple[NDArray[np.float64], float]:
    """A loose unbounded descent (:func:`._descent.descend`, MINPACK's tolerances 1e-6)."""
    out = descend(residuals, z0, ftol=1e-6, xtol=1e-6, gtol=1e-8, max_nfev=max_nfev)
    return out.x, out.cost


#: Relative distance to a found optimum within which a later descent has joined its basin.
#: The loose descents stop at 1e-6; a basin of the criterion is far wider than 1e-3 of a
#: parameter (distinct minima lie a factor 1.5 or more apart in ω_hp).
_JOIN = 1e-3


class _Joined(Exception):
    """A descent reached the neighbourhood of an optimum found before."""

    def __init__(self, basin: int) -> None:
        super().__init__(basin)
        self.basin = basin


# -- the physical estimate and its checks ------------------------------------------------------


def _reduced_estimate(est: Estimate, plant_structure: PlantStructure,
                      plant_c: TransferFunction) -> Estimate:
    """(K, ω, δ) of the structure's θ with the covariance by the delta method."""
    from ._loop import PARAMETER_NAMES, PARAMETER_UNITS

    theta = np.asarray(est.parameters, dtype=float)
    if plant_structure.name == "reduced":
        return dataclasses.replace(est, model=plant_c)
    values = np.asarray(plant_structure.reduced(theta), dtype=float)

    def fun(t: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(plant_structure.reduced(t), dtype=float)

    cov = delta_method(fun, theta, np.asarray(est.covariance), 0.01)
    return dataclasses.replace(
        est, model=plant_c, parameters=values, names=PARAMETER_NAMES, covariance=cov,
        units=PARAMETER_UNITS)


def _resolution_flags(
    physical: Estimate, dt: float,
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]] | None,
) -> tuple[str, ...]:
    """Say when the resonance is beyond the rate or not determined by the data."""
    w, d = (float(v) for v in physical.parameters[1:3])
    std = np.asarray(physical.std, dtype=float)
    omega_n = math.pi / dt
    fs = 1.0 / dt
    f_hp = w / (2.0 * math.pi)
    needed = _round_up(4.0 * f_hp)
    flags = []
    if w * _NYQUIST_MARGIN > omega_n:
        flags.append(
            f"omega_hp = {w:.4g} rad/s ({f_hp:.4g} Hz) is not resolved at f_s = {fs:g} Hz: "
            f"the Nyquist frequency {omega_n:.4g} rad/s is less than twice the resonance, so the "
            "sampled record hardly shows it and the estimate rests on a small phase lag; "
            f"record at f_s >= {needed:g} Hz (4·f_hp) to resolve it"
            + ("" if w < omega_n else
               " (the estimate lies beyond the Nyquist frequency itself: take f_hp from the "
               "design values if this one looks implausible)")
        )
    rel = np.abs(std[1:3] / np.array([w, d]))
    if not np.all(np.isfinite(rel)) or np.any(1.96 * rel > _UNDETERMINED):
        band = ""
        if records:
            band = (f" (the reference carries {100 * _power_above(records, dt, w / 2):.2g} % of "
                    "its power above omega_hp/2)")
        rate = (f", and sample at f_s >= {needed:g} Hz (4·f_hp)" if needed > fs else "")
        flags.append(
            f"the data do not determine the resonance: the 95 % intervals of omega_hp "
            f"(± {196 * rel[0]:.3g} %) and delta_hp (± {196 * rel[1]:.3g} %) are not both "
            f"within ± {100 * _UNDETERMINED:.0f} %{band}; excite up to the resonance (e.g. a "
            f"PRBS whose band 0.44/T_bit reaches f_hp){rate}. Intervals this wide are "
            "linearised and not reliable"
        )
    return tuple(flags)


def _power_above(records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 dt: float, omega: float) -> float:
    total = above = 0.0
    for r, _ in records:
        spec = np.abs(np.fft.rfft(r - r.mean())) ** 2
        freq = 2.0 * math.pi * np.fft.rfftfreq(r.size, dt)
        total += float(spec.sum())
        above += float(spec[freq >= omega].sum())
    return above / total if total > 0 else 0.0


def _round_up(value: float) -> float:
    """Round up to two significant digits (a rate to ask for)."""
    if value <= 0 or not math.isfinite(value):
        return value
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.ceil(value / scale) * scale


# -- checks ------------------------------------------------------------------------------------


def _structure(structure: PlantStructure | str) -> PlantStructure:
    if isinstance(structure, PlantStructure):
        return structure
    if not isinstance(structure, str):
        raise type_error("structure", structure, "a PlantStructure or its name (one of "
                         f"{', '.join(repr(s) for s in STRUCTURES)})")
    check_option("structure", structure, tuple(STRUCTURES))
    return STRUCTURES[structure]


def _output(seg: Experiment, output: str | None) -> str:
    outputs = seg.names_of("y")
    if not outputs:
        seg.signal("y")
    return output or outputs[0]


def _check_theta0(theta0: ArrayLike,
                  plant_structure: PlantStructure | None = None) -> NDArray[np.float64]:
    ps = plant_structure if plant_structure is not None else STRUCTURES["reduced"]
    theta = as_array("theta0", theta0, finite=False).ravel()
    names = ", ".join(ps.names)
    if theta.size != ps.n_parameters or not np.all(np.isfinite(theta)):
        raise DataError(f"theta0 must be {ps.n_parameters} finite numbers ({names}), "
                        f"got {theta0!r}")
    logs = [n for n, t, v in zip(ps.names, ps.transforms, theta, strict=True)
            if t == "log" and v <= 0]
    if logs:
        raise DataError(f"theta0 needs {' > 0 and '.join(logs)} > 0 (log parameters), "
                        f"got {theta0!r}")
    return theta


def _check_loop(loop: object) -> None:
    as_instance("loop", loop, FeedbackLoop, "a FeedbackLoop(c, F), e.g. FeedbackLoop(c=0.01, "
                "F=0.01)")


def _require_reference(data: Experiment | ExperimentSet, approach: str) -> None:
    first = as_segments(data)[0]
    if not first.names_of("r"):
        names = ", ".join(f"{c.name} ({c.role})" for c in first.channels)
        raise DataError(
            f"the {approach} approach fits the closed loop from the reference r to y, but the "
            f"experiment has no reference ('r') channel; it has: {names}. Map the command "
            "channel to role 'r', or use approach='direct' with the measured plant input u"
        )
