"""Study-1 workflow: a closed-loop record → physical plant parameters and a report."""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..._checks import as_float, as_float_list, type_error
from ..._errors import DataError, OptionError, ServoidWarning
from ..._lazy import signal as sps
from ..._progress import stage
from ..._version import __version__
from ...data import Experiment, ExperimentSpec
from ...models import TransferFunction
from ...report import (
    Check,
    Conditions,
    Figure,
    Page,
    Section,
    Table,
    Verdict,
    plot_bode,
    plot_poles,
    plot_residuals,
    plot_validation,
    pvalue_text,
)
from ...validate import ValidationReport, validate
from ...workflows.kit import (
    HORIZON,
    Displayed,
    FigureWriter,
    Method,
    Option,
    ParameterValue,
    RecordSummary,
    TableSchema,
    boolean,
    choice,
    choices,
    count_check,
    integer,
    interval_check,
    keyed,
    number,
    optional,
    parameter_table,
    read_truth,
    report_options,
    spec_conditions,
    spec_inputs,
    summary_of,
    validation_checks,
    validation_section,
)
from ._api import APPROACHES, identify_closed_loop
from ._causes import rejection_note
from ._data_check import nonlinear_wanted, record_notes, saturation_note
from ._dc_gain import Tolerances, check_dc_gain, with_tolerances
from ._first_order import first_order_fit
from ._flow_check import flow_law_of
from ._loop import FeedbackLoop, reduced_plant
from ._nonlinear import NONLINEAR_DEFAULTS
from ._nonlinear_check import refine_after_linear
from ._nonlinear_model import NONLINEAR_PARAMETERS
from ._onestep import DISCRETIZATIONS, fit_one_step
from ._params import SET_B, SET_C
from ._result import ClosedLoopResult
from ._skew import unresolved_skew, with_skew_tolerance
from ._structure_test import compare_structures
from ._structures import STRUCTURES, skew_structure

__all__ = ["LOOP", "METHOD", "METHODS", "ClosedLoopIdentification", "loop_from_table"]

_NAMES = ("K", "omega_hp", "delta_hp")
_F_KEYS = ("num", "den", "dt")
_LABEL = {"indirect": "two-step", "one-step": "one-step", "direct": "direct"}


@dataclass(frozen=True, eq=False, repr=False)
class ClosedLoopIdentification(Displayed):
    """Every closed-loop approach asked for, validated."""

    spec: ExperimentSpec
    loop: FeedbackLoop
    results: Mapping[str, ClosedLoopResult]
    validations: Mapping[str, ValidationReport]
    primary: str
    truth: Mapping[str, float] | None = None
    folder: Path | None = None
    files: tuple[Path, ...] = ()
    notes: tuple[str, ...] = field(default=())
    validation_data: Experiment | None = None
    structure_test: Any = None
    refinement: Any = None
    flow_law: Any = None
    dc_gain: Any = None
    conditions: tuple[Conditions, ...] = ()
    skew: Any = None
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    @property
    def estimate(self) -> Any:
        """Physical estimate of the primary approach."""
        return self.results[self.primary].estimate

    @property
    def validation(self) -> ValidationReport:
        """Validation of the primary approach."""
        return self.validations[self.primary]

    def verdict(self) -> Verdict:
        """The primary approach's checks: validation, structure test, its flags."""
        primary = self.results[self.primary]
        label = _LABEL[self.primary]
        covariance = primary.source.options.get("covariance")
        # what the record cannot fix comes before any interval (servoid.validate.data_limits)
        checks = [Check("data", n.split(": ")[2].split(" (")[0], "caution", n)
                  for n in self.notes if n.startswith(_LIMIT)]
        checks += validation_checks(self.validation, covariance=covariance)
        test = self.structure_test
        if test is not None:
            p = min((t.p_value for t in test.tests), default=math.nan)
            if test.rejected:
                checks.append(Check("structure test", pvalue_text(p), "fail",
                                    f"the data reject the {test.base} model: "
                                    + "; ".join(test.reasons)))
            else:
                checks.append(Check("structure test", pvalue_text(p), "pass",
                                    f"no richer structure explains the data significantly better "
                                    f"than the {test.base} model (level {100 * test.level:.3g} %)"))
        flow = self.flow_law
        if flow is not None:
            outcome = "fail" if flow.biased else "pass"
            meaning = (flow.verdict if flow.seen else
                       "the residual does not follow the valve's flow law (first order in the "
                       f"load pressure, level {100 * flow.level:.3g} %)")
            checks.append(Check("flow law", f"z = {flow.z:+.1f}", outcome, meaning))
        if self.skew is not None:
            # an assumption the record cannot check, stated beside the checks: "info", not a
            # caution, which would make every record with an unresolvable skew inconclusive
            checks.append(Check("channel skew (assumed none)", self.skew.value, "info",
                                self.skew.note))
        dc = self.dc_gain
        if dc is not None:
            checks.append(Check("DC gain", f"z = {dc.z:+.1f}", "fail" if dc.mismatch else "pass",
                                dc.verdict))
        if covariance:
            checks.append(interval_check(covariance))
        flags = [str(n) for n in primary.notes()]
        checks.append(count_check(f"pole flags ({label})", flags,
                                  "see Checks: a pole the model should not have", "caution"))
        if self.refinement is not None:
            checks.append(Check("nonlinear refinement",
                                f"{self.refinement.validation.fit_percent:.1f} %", "info",
                                f"validation fit of the refined nonlinear model (linear "
                                f"{self.validation.fit_percent:.1f} %)"))
        checks.append(count_check("notes", self.notes, "listed under Checks"))
        others = [_LABEL[a] for a in self.results if a != self.primary]
        tested = ("the reduced EHSA plant G0(s) = K / (s (s²/ω_hp² + 2 δ_hp s/ω_hp + 1)) "
                  f"identified by the {label} approach inside its known loop (c = "
                  f"{self.loop.c:g}, F = {_f_text(self.loop)}), simulated in closed loop from "
                  "the reference on the held-back half"
                  + (f"; the {', '.join(others)} approach is shown for comparison."
                     if others else "."))
        return Verdict(tested, tuple(checks), self.conditions)

    def summary(self) -> RecordSummary:
        """The primary approach's K, ω_hp, δ_hp, its validation, structure test and flags."""
        rows = [ParameterValue(row["name"], v["value"], v["std"], *v["ci95"], v["unit"])
                for row in self.table() for v in (row[self.primary],)]
        test = self.structure_test
        return summary_of("closedloop", rows, self.verdict(), validation=self.validation,
                          notes=self.notes, flags=[str(f) for f in self.results[self.primary].flags],
                          structure_rejected=None if test is None else bool(test.rejected))

    def models(self) -> dict[str, Any]:
        """Each approach's continuous plant and discrete closed loop (``<approach>_plant``, …)."""
        out: dict[str, Any] = {}
        for approach, result in self.results.items():
            label = re.sub(r"\W", "_", approach)
            for model, suffix in ((result.plant_continuous, "plant"),
                                  (result.closed_loop, "closed_loop")):
                if model is not None:
                    out[f"{label}_{suffix}"] = model
        return out

    def table(self) -> list[dict[str, Any]]:
        """Per parameter: truth and each approach's value, std and 95 % CI."""
        rows = []
        for name in _NAMES:
            row: dict[str, Any] = {"name": name, "truth": (self.truth or {}).get(name)}
            for approach, result in self.results.items():
                est = result.estimate
                k = est.names.index(name)
                lo, hi = est.confidence_intervals(0.95)[k]
                row[approach] = {"value": float(est.parameters[k]), "std": float(est.std[k]),
                                 "ci95": [float(lo), float(hi)], "unit": est.units[k]}
            rows.append(row)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        return {
            "servoid_version": __version__,
            "method": "closedloop",
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": self.digest(self.spec.data_path),
            "loop": self.loop.to_dict(),
            "primary_approach": self.primary,
            "truth": dict(self.truth) if self.truth else None,
            "parameters": self.table(),
            "approaches": {
                a: {**r.to_dict(), "validation": self.validations[a].summary()}
                for a, r in self.results.items()
            },
            "structure_test": self.structure_test.to_dict() if self.structure_test else None,
            "nonlinear_refinement": self.refinement.to_dict() if self.refinement else None,
            "flow_law": self.flow_law.to_dict() if self.flow_law else None,
            "dc_gain": self.dc_gain.to_dict() if self.dc_gain else None,
            "channel_skew": self.skew.to_dict() if self.skew else None,
            "notes": list(self.notes),
            "verdict": self.verdict().to_dict(),
            "summary": self.summary().to_dict(),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return spec_inputs(self.spec)

    def figures(self) -> dict[str, FigureWriter]:
        """Validation, residuals, Bode of the plant, pole maps."""
        return {"validation.png": partial(_plot_validation, self),
                "residuals.png": partial(_plot_residuals, self),
                "bode.png": partial(_plot_bode, self),
                "poles.png": partial(_plot_poles, self)}

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        return _page(self, files)

    def __str__(self) -> str:
        approaches = list(self.results)
        head = f"  {'param':<9} {'truth':>10}" + "".join(
            f" {_LABEL[a]:>22}" for a in approaches) + "   95 % CI (" + _LABEL[self.primary] + ")"
        lines = [(f"closed-loop identification ({', '.join(_LABEL[a] for a in approaches)}), "
                 f"loop c = {self.loop.c:g}, F = {_f_text(self.loop)}")]
        lines += [f"  {n}" for n in self.notes if n.startswith(_LIMIT)]
        lines.append(head)
        for row in self.table():
            truth = "—" if row["truth"] is None else f"{row['truth']:.5g}"
            cells = "".join(
                f" {row[a]['value']:>11.5g} ± {row[a]['std']:<8.2g}" for a in approaches)
            lo, hi = row[self.primary]["ci95"]
            lines.append(f"  {row['name']:<9} {truth:>10}{cells}   [{lo:.5g}, {hi:.5g}]")
        fits = ", ".join(f"{_LABEL[a]} {v.fit_percent:.2f} %" for a, v in self.validations.items())
        lines.append(f"  validation fit (closed loop, held-back data): {fits}")
        for approach, result in self.results.items():
            if result.intersample_note:
                lines.append(f"  intersample ({_LABEL[approach]}): {result.intersample_note}")
            cov = result.source.options.get("covariance")
            if cov:
                lines.append(f"  intervals ({_LABEL[approach]}): {cov} covariance")
        if self.structure_test is not None:
            mark = "!" if self.structure_test.rejected else " "
            lines.append(f" {mark}structure test: {self.structure_test.verdict}")
        if self.refinement is not None:
            est, val = self.refinement.estimate, self.refinement.validation
            lines.append(f"  nonlinear refinement: validation fit {val.fit_percent:.2f} % "
                         f"({_LABEL[self.primary]} linear {self.validation.fit_percent:.2f} %)")
            lines += [f"    {line}" for line in str(est).splitlines()[1:]]
        lines += [f"  note: {n}" for n in self.notes if not n.startswith(_LIMIT)]
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)


def loop_from_table(table: Mapping[str, Any]) -> FeedbackLoop:
    """Build the known loop from an experiment file's ``[loop]``.

    ``c`` is the forward gain; ``F`` the feedback, a number or a table
    ``{num = [...], den = [...]}`` (continuous, or discrete with ``dt``).
    The keys are :data:`LOOP`'s.
    """
    return _known_loop(LOOP.parse(table, "closedloop"))


def _known_loop(loop: Mapping[str, Any]) -> FeedbackLoop:
    """The loop of a checked ``[loop]`` (:data:`LOOP`)."""
    if loop["c"] is None or loop["F"] is None:
        raise DataError(
            "the closed-loop approaches need the known loop: add [loop] with c = <forward gain> "
            "and F = <feedback gain> to the experiment file"
        )
    with keyed({"c": "[loop] c", "F": "[loop] F"}):
        return FeedbackLoop(loop["c"], loop["F"])


def _feedback(value: Any, where: str = "[loop]", name: str = "F") -> float | TransferFunction:
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(_F_KEYS))
        if unknown:
            raise OptionError(f"unknown key(s) in [loop] F: {', '.join(unknown)}; valid keys "
                              f"are {', '.join(_F_KEYS)}")
        missing = [k for k in ("num", "den") if k not in value]
        if missing:
            raise DataError(f"[loop] F needs {' and '.join(missing)}: write F = {{num = [...], "
                            f"den = [...]}} (continuous) or add dt = <s> (discrete)")
        num = as_float_list("F.num", value["num"], min_length=1, where="[loop]")
        den = as_float_list("F.den", value["den"], min_length=1, where="[loop]")
        dt = value.get("dt")
        if dt is not None:
            dt = as_float("F.dt", dt, positive=True, unit="s", where="[loop]")
        return TransferFunction(np.asarray(num), np.asarray(den), dt=dt)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise type_error("F", value, "a number or a table {num = [...], den = [...]}",
                         where="[loop]")
    return as_float("F", value, where="[loop]")


def _gain(value: Any, where: str, name: str) -> float:
    return as_float(name, value, where=where)


def _tolerance(value: Any, where: str, name: str) -> float:
    return as_float(name, value, nonneg=True, where=where)


def _tolerances(loop: Mapping[str, Any]) -> Tolerances:
    return Tolerances(loop["c_tolerance"], loop["F_tolerance"], loop["gain_tolerance"])


#: ``[loop]`` of the EHSA's closed-loop study: the loop H = c·G0/(1 + F·G0) it runs in.
LOOP = TableSchema("loop", (
    Option("c", None, optional(_gain), "forward gain of the loop (required)"),
    Option("F", None, optional(_feedback),
           "feedback: a gain, or {num = [...], den = [...]} (continuous; discrete with "
           "dt = <s>) (required)"),
    Option("c_tolerance", 0.0, _tolerance,
           "relative tolerance of c (e.g. 0.003); checked against the DC gain the data carry "
           "and propagated into the one-step intervals"),
    Option("F_tolerance", 0.0, _tolerance, "relative tolerance of F, likewise"),
    Option("gain_tolerance", 0.0, _tolerance,
           "relative tolerance of each measured channel's gain (reference and position)"),
    Option("skew_tolerance", 0.0, _tolerance,
           "standard deviation of the skew between the reference and position channels [s] "
           "(e.g. 10e-6 for a multiplexed ADC): the skew is estimated and carried in the "
           "one-step intervals (static F only)"),
), help="the known loop H = c·G0/(1 + F·G0)")


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> ClosedLoopIdentification:
    """Run the closed-loop approaches an experiment file asks for.

    ``[identify]`` keys: ``approach`` (one of ``"indirect"``, ``"one-step"``,
    ``"direct"`` or a list; default both indirect and one-step, the last
    being the primary result), ``na``, ``nb``, ``nk`` (the ARX stage),
    ``prefilter`` [Hz] (zero-phase low-pass for the two-step ARX),
    ``discretization`` of the one-step model (default ``"auto"``: the
    exact sampled model for the reference ``[rig]`` declares, or detects)
    and ``horizon``.
    """
    loop = _known_loop(options["[loop]"])
    estimation, (validation_data, *_) = spec.records()
    if truth is None:
        truth = _truth_from_spec(spec)
    results: dict[str, ClosedLoopResult] = {}
    notes: list[str] = []
    for approach in options["approach"]:
        kwargs: dict[str, Any] = {}
        if approach in ("indirect", "direct"):
            kwargs = {"na": options["na"], "nb": options["nb"], "nk": options["nk"]}
        if approach == "indirect" and options["prefilter"] is not None:
            kwargs["prefilter"] = options["prefilter"]
        if approach == "one-step":
            kwargs.update(_rig_options(spec, options["discretization"]))
        with warnings.catch_warnings(), stage(f"fitting the {_LABEL[approach]} model"):
            # Pole flags become notes of the result and of the report, printed once there.
            warnings.simplefilter("ignore", ServoidWarning)
            result = identify_closed_loop(estimation, loop, approach=approach, **kwargs)
        results[approach] = result
        notes += [f"{_LABEL[approach]}: {n}" for n in result.notes()]
    validations = {a: _validate(r, validation_data, options["horizon"], spec)
                   for a, r in results.items()}
    notes += _disagreement(results)
    primary = options["approach"][-1]
    notes += record_notes(estimation, results.get("one-step"), loop)
    flow_law = dc_gain = None
    first_order = (first_order_fit(results["one-step"], estimation) if "one-step" in results
                   else None)
    if first_order is not None:
        flow_law = flow_law_of(first_order)
        if flow_law.seen:
            notes.append(flow_law.verdict)
        dc_gain = check_dc_gain(first_order, loop.c / float(loop.F),  # type: ignore[arg-type]
                                _tolerances(options["[loop]"]))
        if dc_gain.mismatch:
            notes.append(dc_gain.verdict)
        if saturation_note(flow_law, dc_gain):
            notes.append(saturation_note(flow_law, dc_gain))
    structure_test = skew_caution = None
    if options["structure_test"] and "one-step" in results:
        with stage("testing the model structure (richer models fitted beside it)"):
            structure_test, unresolved = _structure_test(spec, estimation, loop,
                                                         results["one-step"],
                                                         options["discretization"])
        if structure_test.rejected:
            notes.append(rejection_note(structure_test, flow_law, results["one-step"], dc_gain))
        named = structure_test.rejected and structure_test.preferred == "reduced+skew"
        if (unresolved is not None and unresolved.fires and not named
                and options["[loop]"]["skew_tolerance"] == 0):
            skew_caution = unresolved  # a stated tolerance puts the skew in the intervals
            notes.append(unresolved.note)
    if options["[loop]"]["skew_tolerance"] > 0 and "one-step" in results:
        with stage("estimating the channel skew beside the one-step model"):
            skew = with_skew_tolerance(results["one-step"], estimation, loop,
                                       options["[loop]"]["skew_tolerance"],
                                       **_rig_options(spec, options["discretization"]))
        results["one-step"] = skew.result
        notes.append(skew.note)
    if dc_gain is not None and dc_gain.tolerances.any:
        results["one-step"] = with_tolerances(results["one-step"], dc_gain)
        notes.append(f"one-step: the intervals include the loop's stated tolerances (DC gain "
                     f"±{100 * dc_gain.tolerances.dc:.3g} %)")
    refinement = None
    refine = options["refine"]
    if options["structure"] == "auto" and refine is False:  # refine = true/[...] decides alone
        wanted, why = nonlinear_wanted(flow_law, dc_gain, validations.get(primary))
        notes.append(why)
        refine = wanted
    if refine is not False:
        names = NONLINEAR_DEFAULTS if refine is True else tuple(refine)
        with warnings.catch_warnings(), stage("refining with the nonlinear EHSA model"):
            warnings.simplefilter("ignore", ServoidWarning)  # its flags are in its notes
            refinement = refine_after_linear(
                estimation, validation_data, loop, results[primary], parameters=names,
                nominal={"B": SET_B, "C": SET_C}[options["nominal"]],
                **_refine_rig_options(spec))
        notes += [f"nonlinear refinement: {n}" for n in refinement.notes()]
    return ClosedLoopIdentification(spec, loop, results, validations, primary, truth,
                                    notes=tuple(notes), validation_data=validation_data,
                                    structure_test=structure_test, refinement=refinement,
                                    flow_law=flow_law, dc_gain=dc_gain,
                                    conditions=spec_conditions(spec, estimation,
                                                               (validation_data,)),
                                    skew=skew_caution)


#: How the record's limits begin among the notes (``_data_check.record_notes``).
_LIMIT = "data cannot fix: "


def _disagreement(results: Mapping[str, ClosedLoopResult]) -> list[str]:
    """Say in words why the two-step and one-step values differ, when they do."""
    if "indirect" not in results or "one-step" not in results:
        return []
    two, one = results["indirect"].estimate, results["one-step"].estimate
    apart = []
    for name in _NAMES:
        i, k = two.names.index(name), one.names.index(name)
        spread = math.hypot(float(two.std[i]), float(one.std[k]))
        if abs(float(two.parameters[i]) - float(one.parameters[k])) > 4.0 * spread:
            apart.append(name)
    if not apart:
        return []
    return [(
        f"why two-step and one-step disagree on {', '.join(apart)} (by more than 4 combined "
        "standard deviations): the two-step approach fits a low-order ARX model to the closed "
        "loop and divides the known feedback out afterwards. ARX minimises an equation error, "
        "which is unbiased only when the noise enters filtered by 1/A; noise added at the "
        "sensor is not, and the fixed low order cannot absorb the loop's fast dynamics (valve, "
        "filters, sampling). That bias is carried through the division by the loop and the "
        "conversion to continuous time into the physical parameters, and the two-step "
        "intervals cover the noise only, not the bias. The one-step fit simulates the physical "
        "model in its known loop and matches the measured output (output error), which is "
        "consistent when the model's structure is right (`[identify] structure_test = true` "
        "asks the data); trust the one-step values and read the two-step ones as a starting "
        "point."
    )]


def _structure_test(spec: ExperimentSpec, estimation: Any, loop: FeedbackLoop,
                    reduced: ClosedLoopResult, discretization: str) -> tuple[Any, Any]:
    """Fit the richer structures from the reduced estimate and test the reduced one.

    Returns the test and, with a static feedback, how far a skew the record
    cannot resolve moves the reduced estimates (:func:`._skew.unresolved_skew`).
    """
    theta = reduced.estimate.parameters
    fits: dict[str, Any] = {"reduced": reduced}
    extra = {}
    if loop.is_static:  # a channel skew: a delay outside the loop, written as a plant
        extra["reduced+skew"] = skew_structure(float(loop.F))  # type: ignore[arg-type]
    catalogue = {**STRUCTURES, **extra}
    for name in ("reduced+lag", "full-order", *extra):
        structure = catalogue[name]
        start = (*theta[:3], *structure.null)  # the nested point: the reduced fit itself
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            fits[name] = fit_one_step(estimation, loop, start, structure=structure,
                                      **_rig_options(spec, discretization))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # the verdict is the note
        test = compare_structures(fits, estimation, structures=extra)
    skew = unresolved_skew(fits["reduced+skew"], reduced) if "reduced+skew" in fits else None
    return test, skew


def _refine_rig_options(spec: ExperimentSpec) -> dict[str, Any]:
    """The nonlinear refinement's view of the rig: the command and its filter, if declared."""
    rig = spec.rig
    out: dict[str, Any] = {}
    if rig.reference == "command":
        out["intersample"] = "zoh"
        if rig.anti_alias_order is not None:
            num, den = sps.butter(rig.anti_alias_order, 2.0 * np.pi * rig.anti_alias_cutoff,
                                  analog=True)
            out["output_filter"] = TransferFunction(num, den)
    elif rig.reference == "readback":
        out["intersample"] = "foh"
    return out


def _rig_options(spec: ExperimentSpec, discretization: str) -> dict[str, Any]:
    """One-step options from ``[rig]``: a logged command brings the output's chain."""
    rig = spec.rig
    out: dict[str, Any] = {"discretization": discretization}
    if rig.reference == "readback" and discretization == "auto":
        out["discretization"] = "bandlimited"  # declared: the shared chain cancels
    if rig.reference == "command" and discretization in ("auto", "zoh"):
        if rig.anti_alias_order is not None:
            assert rig.anti_alias_cutoff is not None
            num, den = sps.butter(rig.anti_alias_order, 2.0 * np.pi * rig.anti_alias_cutoff,
                                  analog=True)
            out["anti_alias"] = TransferFunction(num, den)
        out["decimation"] = spec.preprocess.decimate
    return out


def _validate(result: ClosedLoopResult, data: Any, horizon: int,
              spec: ExperimentSpec) -> ValidationReport:
    # every model is simulated from an initial state fitted to the record (the held-back half
    # starts with the actuator moving), so the fit judges the dynamics, not a start-up
    # transient; [validation] initial/transient, when given, decide instead
    chosen = spec.validation.initial
    initial = "estimate" if chosen == "auto" else chosen
    transient = spec.validation.transient
    with keyed({"transient": "[validation] transient", "horizon": "[identify] horizon"}):
        if result.closed_loop is not None:
            return validate(result.closed_loop.to_polynomial("oe"), result.align(data),
                            input="r", horizon=horizon, initial=initial, transient=transient)
        # the plant from (u, y): u depends on past residuals through the loop, so only the
        # lags where u leads are tested (closed_loop=True)
        return validate(result.plant.to_polynomial("oe"), data, input="u", horizon=horizon,
                        initial=initial, transient=transient, closed_loop=True)


def _truth_from_spec(spec: ExperimentSpec) -> dict[str, float] | None:
    name = report_options(spec.report).get("truth")
    if name is None:
        return None
    base = spec.source.parent if spec.source else Path.cwd()
    return read_truth(base / name, _NAMES)


def _f_text(loop: FeedbackLoop) -> str:
    return f"{loop.F:g}" if isinstance(loop.F, (int, float)) else "a transfer function"


def _plot_validation(ident: ClosedLoopIdentification, path: Path, overwrite: bool) -> None:
    plot_validation(ident.validation, path, overwrite=overwrite)


def _plot_residuals(ident: ClosedLoopIdentification, path: Path, overwrite: bool) -> None:
    u = None
    if ident.validation_data is not None:  # the input the independence test used
        result = ident.results[ident.primary]
        role = "r" if result.closed_loop is not None else "u"
        u = result.align(ident.validation_data).signal(role)
    plot_residuals(ident.validation, path, overwrite=overwrite, u=u)


def _plot_bode(ident: ClosedLoopIdentification, path: Path, overwrite: bool) -> None:
    plot_bode(_plants(ident), path, f_min=0.1, f_max=0.5 / next(iter(ident.results.values())).dt,
              title="identified plant G0(s)", overwrite=overwrite)


def _plot_poles(ident: ClosedLoopIdentification, path: Path, overwrite: bool) -> None:
    closed = {_LABEL[a]: r.closed_loop for a, r in ident.results.items()
              if r.closed_loop is not None}
    plot_poles(_plants(ident), closed, path, overwrite=overwrite)


def _plants(ident: ClosedLoopIdentification) -> dict[str, TransferFunction]:
    plants: dict[str, TransferFunction] = {}
    if ident.truth and all(k in ident.truth for k in _NAMES):
        plants["truth"] = reduced_plant(tuple(ident.truth[k] for k in _NAMES))
    for approach, result in ident.results.items():
        plants[_LABEL[approach]] = result.plant_continuous
    return plants


def _page(ident: ClosedLoopIdentification, files: Mapping[str, Path]) -> Page:
    spec = ident.spec
    approaches = list(ident.results)
    columns = ("parameter", "truth", *(f"{_LABEL[a]} (± std)" for a in approaches),
               f"95 % CI ({_LABEL[ident.primary]})", "unit")
    rows = []
    for row in ident.table():
        truth = "—" if row["truth"] is None else f"{row['truth']:.6g}"
        cells = [f"{row[a]['value']:.6g} ± {row[a]['std']:.2g}" for a in approaches]
        lo, hi = row[ident.primary]["ci95"]
        rows.append((row["name"], truth, *cells, f"[{lo:.6g}, {hi:.6g}]",
                     row[ident.primary]["unit"]))
    fits = tuple(
        (_LABEL[a], f"{v.fit_percent:.2f} %", pvalue_text(v.residuals.whiteness_pvalue))
        for a, v in ident.validations.items()
    )
    summary = Section(
        "Physical parameters",
        paragraphs=(
            ("Reduced EHSA plant G0(s) = K / (s (s²/ω_hp² + 2 δ_hp s/ω_hp + 1)) identified inside "
            f"its known loop H = c·G0/(1 + F·G0), c = {ident.loop.c:g}, F = {_f_text(ident.loop)}. "
            "Two-step: ARX of the closed loop from (r, y), G0 = B/(c·A − F·B), Tustin d2c; "
            "standard deviations by the delta method from the ARX covariance. One-step: output-"
            "error fit of the parameterised closed loop (Levenberg–Marquardt from several "
            "starts)."),
            *_assumptions(ident),
        ),
        tables=(
            Table(columns, tuple(rows), "Estimates on the estimation half"),
            Table(("approach", "validation fit", "whiteness"), fits,
                  "Closed-loop simulation on the held-back half"),
        ),
    )
    for approach, result in ident.results.items():
        summary = Section(summary.title, summary.paragraphs,
                          (*summary.tables, parameter_table(result.estimate, _LABEL[approach])))
    notes = Section("Checks", paragraphs=ident.notes or (
        "No pole was flagged non-physical, and the data resolve the resonance.",))
    extra = [*_structure_section(ident), *_refinement_section(ident)]
    model_figs = Section(
        "Models",
        figures=(
            Figure.from_file(files["bode.png"], "Bode diagram of the identified plant"
                             + (" against the truth" if ident.truth else "")),
            Figure.from_file(files["poles.png"], "Plant poles (s-plane) and closed-loop poles "
                             "and zeros (z-plane)"),
        ),
    )
    data = Section(
        "Experiment",
        paragraphs=(f"Data file {spec.data_path.name} (sha256 {ident.digest(spec.data_path)[:16]}…).",),
    )
    return Page(
        title=f"Closed-loop identification: {spec.source.name if spec.source else 'experiment'}",
        subtitle="Physical plant parameters with confidence intervals, validated on held-back data",
        sections=(data, summary, *extra, model_figs,
                  validation_section(ident.validation, files["validation.png"],
                                     files["residuals.png"]), notes),
        meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
              ("data file", str(spec.data_path))),
    )




def _structure_section(ident: ClosedLoopIdentification) -> list[Section]:
    test = ident.structure_test
    if test is None:
        return []
    fits = tuple((f.name, str(f.n_parameters), f"{f.cost:.5g}", f"{f.aic:.5g}", f"{f.bic:.5g}",
                  f"{f.whiteness_pvalue:.3g}", f"{f.independence_pvalue:.3g}")
                 for f in test.fits)
    lrs = tuple((f"{t.smaller} vs {t.larger}", str(t.df), f"{t.lr:.4g}", f"{t.scale:.3g}",
                 f"{t.lr_robust:.4g}", f"{t.p_value:.3g}" if t.p_value > 0 else "< 1e-300")
                for t in test.tests)
    banner = ("REJECTED: the reduced model's intervals understate the error; read the "
              f"preferred structure ({test.preferred}) instead." if test.rejected else
              "The data do not reject the reduced model.")
    return [Section(
        "Structure test",
        paragraphs=(banner, test.verdict),
        tables=(
            Table(("structure", "parameters", "cost V", "AIC", "BIC", "whiteness p",
                   "reference–residual p"), fits, "One-step fits on the estimation data"),
            Table(("test", "df", "LR", "colour scale c", "LR/c", "p"), lrs,
                  "Likelihood-ratio tests (boundary null where the larger model's extra "
                  "parameter is one-sided)"),
        ),
    )]


def _refinement_section(ident: ClosedLoopIdentification) -> list[Section]:
    ref = ident.refinement
    if ref is None:
        return []
    return [Section(
        "Nonlinear refinement",
        paragraphs=(f"The nonlinear EHSA simulated in its loop, refined from the linear result: "
                    f"validation fit {ref.validation.fit_percent:.2f} % against "
                    f"{ident.validation.fit_percent:.2f} % for the linear "
                    f"{_LABEL[ident.primary]} model.",
                    *ref.notes()),
        tables=(parameter_table(ref.estimate, "Refined physical parameters"),),
    )]


def _assumptions(ident: ClosedLoopIdentification) -> tuple[str, ...]:
    out = []
    for approach, result in ident.results.items():
        text = f"{_LABEL[approach]}: discretisation {result.discretization!r}"
        if result.intersample_note:
            text += f"; intersample: {result.intersample_note}"
        cov = result.source.options.get("covariance")
        if cov:
            text += f"; intervals from the {cov} covariance"
        out.append(text + ".")
    return tuple(out)


def _warm_up() -> None:
    """Load the one-step fit's compiled kernels (a fleet's workers, before their first record)."""
    from . import _kernels

    _kernels.warm_up()


def _example(folder: Path, seed: int = 0) -> Path:
    """A short closed-loop record of the virtual rig (set B, PRBS) and its experiment file."""
    from ...signals import prbs
    from ._bench import run as run_bench
    from ._bench_config import EhsaBench
    from ._bench_files import write_bench_files

    record = run_bench(EhsaBench(), prbs(9, clock=10, amplitude=1e-3, dt=1e-3), rng=seed)
    return write_bench_files(record, folder, format="csv", overwrite=True)[1]


def _refine(value: Any, where: str, name: str) -> bool | list[str]:
    if isinstance(value, bool):
        return value
    return choices(NONLINEAR_PARAMETERS)(value, where, name)


METHOD = Method(
    name="closedloop",
    summary="physical parameters K, ω_hp, δ_hp of the reduced electro-hydraulic plant inside "
            "its known loop ([loop] c, F): two-step indirect, one-step OE, direct",
    options=(
        Option("approach", ["indirect", "one-step"], choices(APPROACHES),
               "approach or list of approaches; the last is the primary result"),
        Option("na", 3, integer(minimum=0), "poles of the two-step ARX of the closed loop"),
        Option("nb", 4, integer(minimum=1), "B coefficients of the two-step ARX"),
        Option("nk", 0, integer(minimum=0), "delay of the two-step ARX [samples]"),
        Option("prefilter", None, optional(number(positive=True, unit="Hz")),
               "zero-phase low-pass before the two-step ARX [Hz]"),
        Option("discretization", "auto", choice(DISCRETIZATIONS),
               "discretisation of the one-step model: auto = exact for the reference [rig] "
               "declares (or that is detected)"),
        Option("structure_test", True, boolean(),
               "fit the reduced+lag and full-order plants too and test whether the data reject "
               "the reduced one (needs approach one-step)"),
        Option("refine", False, _refine,
               "nonlinear EHSA refinement after the linear fit: true (the default parameters) "
               f"or a list of names from {', '.join(NONLINEAR_PARAMETERS)}"),
        Option("structure", "linear", choice(("linear", "auto")),
               "linear: the linear fits (and the nonlinear refinement only when refine asks); "
               "auto: the nonlinear EHSA refinement runs when a check finds a nonlinearity "
               "(flow law, DC gain, higher-order tests), else the linear model stands"),
        Option("nominal", "B", choice(("B", "C")),
               "nominal parameter set for what the nonlinear refinement does not fit"),
        HORIZON,
    ),
    run=run,
    tables=(LOOP, "validation"),
    warm_up=_warm_up,
    example=_example,
)

#: The plant's methods, as its record names them.
METHODS = (METHOD,)
