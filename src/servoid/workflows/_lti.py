"""The black-box result every linear method shares, and its run flow.

ARX, OE, ARMAX, BJ, continuous transfer functions and subspace models all
end the same way: an :class:`~servoid.estimate.Estimate` validated on each
validation record, an optional order-search table, a measured frequency
response to compare with, and notes in plain words.  This module turns
that into the console text, ``results.json`` and the report page.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .._checks import as_bool
from .._errors import ServoidError, ServoidWarning, SimulationDivergedError
from .._version import __version__
from .._warn import warn
from ..data import Experiment, ExperimentSet, ExperimentSpec
from ..estimate import Estimate, frequency_band
from ..report import (
    Check,
    Conditions,
    Figure,
    Page,
    Section,
    Table,
    Verdict,
    plot_bode_bands,
    plot_pole_zero,
    plot_residuals,
    plot_singular_values,
    plot_validation,
)
from ..validate import ValidationReport, validate
from ._common import (
    DivergedRun,
    data_limit_notes,
    keyed,
    parameter_table,
    spec_inputs,
    truth_from_spec,
    validation_section,
    warnings_as_notes,
)
from ._registry import FigureWriter
from ._structure import record_dt, structure_checks, structure_notes
from ._summary import Displayed, ParameterValue, RecordSummary, summary_of
from ._verdict import (
    count_check,
    diverged_check,
    interval_check,
    spec_conditions,
    spec_text,
    validation_checks,
)

__all__ = ["IdentificationResult", "OrderRow", "fit_or_search", "gain_unit", "lti_result",
           "model_dict", "n_inputs", "on_edge", "order_grid", "outputs_of", "spec_value"]


@dataclass(frozen=True)
class OrderRow:
    """One candidate of an order search, scored."""

    orders: Mapping[str, Any]
    n_parameters: int
    loss: float
    scores: Mapping[str, float]
    fit: float
    status: str = "ok"


@dataclass(frozen=True, eq=False, repr=False)
class IdentificationResult(Displayed):
    """A linear model identified from an experiment file, validated.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    method : str
        The registered method (``"arx"``, ``"oe"``, ``"tf"``, …).
    estimate : Estimate
        The model with its covariance.
    validations : tuple of ValidationReport or DivergedRun
        One per validation record (the held-back part, or each
        ``[validation] file``); a :class:`DivergedRun` where the model's
        free run diverged on the record (the model failed there).
    title : str
        The structure in words, e.g. ``"OE (nb = 2, nf = 2, nk = 1)"``.
    orders : tuple of OrderRow
        Every candidate of an order search, best first (empty without one).
    criterion : str
        The criterion that ranked them.
    characteristics : tuple
        Derived rows (gain, ω_n, ζ, time constants) with their std.
    measured : FrequencyResponseData or None
        A measured FRF of the same data, drawn under the model's Bode.
    truth : mapping or None
        Known values by name (``[report] truth``).
    notes : tuple of str
        Verdicts and warnings in words.
    gain_unit : str
        Output unit per input unit (for gains and Bode magnitudes).
    feedback : FeedbackTest or None
        Whether the estimation record looks closed loop (open-loop methods).
    folder, files
        Where the results were written.
    conditions : tuple of Conditions
        Rate, length, excitation and band of each record.
    edge : tuple of str
        Orders whose chosen value sits on the edge of the searched grid.
    spec_numbers : mapping
        Spec number → (measured, fitted model) for a model fitted to an FRF.
    how : str
        How the method fits, for the report (``"linear least squares"``).
    direct : bool
        The method is the direct approach on closed-loop data (a noise
        model of its own makes it consistent there): a record that looks
        closed loop is then information, not a caution.
    digests : dict
        SHA-256 of the input files by real path, each hashed once (filled
        by ``write_results``; see :meth:`digest`).
    """

    spec: ExperimentSpec
    method: str
    estimate: Estimate
    validations: tuple[ValidationReport | DivergedRun, ...]
    title: str
    orders: tuple[OrderRow, ...] = ()
    criterion: str = ""
    characteristics: tuple[Any, ...] = ()
    measured: Any = None
    singular_values: tuple[float, ...] = ()
    truth: Mapping[str, float] | None = None
    notes: tuple[str, ...] = ()
    gain_unit: str = ""
    feedback: Any = None
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())
    conditions: tuple[Conditions, ...] = ()
    edge: tuple[str, ...] = ()
    spec_numbers: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    how: str = ""
    direct: bool = False
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    @property
    def validation(self) -> ValidationReport | DivergedRun:
        """Validation on the first validation record."""
        return self.validations[0]

    @property
    def diverged(self) -> tuple[DivergedRun, ...]:
        """The validation records on which the free run diverged."""
        return tuple(v for v in self.validations if isinstance(v, DivergedRun))

    # -- console and JSON ---------------------------------------------------------------
    def __str__(self) -> str:
        est = self.estimate
        lines = [self._headline()]
        lines += [f"  data cannot fix: {d['channel']!r} {d['name']} ({d['value']}): "
                  f"{d['meaning']}" for d in self.estimate.options.get("data_limits", ())]
        truth = self.truth or {}
        body = str(est).splitlines()[1:]
        if len(body) == len(est.names):  # one line per parameter: show the known value
            body = [line + (f"   truth {truth[name]:.6g}" if name in truth else "")
                    for name, line in zip(est.names, body, strict=True)]
        lines += body
        if self.characteristics:
            lines.append("  characteristics (± std):")
            for row in self.characteristics:
                truth = self._truth(row.name)
                lines.append(f"    {row.name:<10} {row.value: .6g} ± {row.std:.2g} {row.unit}"
                             + (f"   truth {truth:.6g}" if truth is not None else ""))
        if self.orders:
            lines.append(f"  order search by {self.criterion} ({len(self.orders)} candidates, "
                         "best first):")
            lines += ["    " + line for line in _order_lines(self.orders, self.criterion)[:11]]
        lines += self._extra_lines()
        for v in self.validations:
            lines.append(f"  {v}")
        measured = {k: m for k, (m, _) in self.spec_numbers.items()}
        fitted = {k: f for k, (_, f) in self.spec_numbers.items()}
        for name in self.spec_numbers:
            lines.append(f"  {name}: measured {spec_text(name, measured[name], measured)}, "
                         f"fitted model {spec_text(name, fitted[name], fitted)}")
        for note in self.notes:
            lines.append(f"  note: {note}")
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        return {
            "servoid_version": __version__,
            "method": self.method,
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": self.digest(self.spec.data_path),
            "data_files": [{"path": str(p), "sha256": self.digest(p)}
                           for p in self.spec.data_paths],
            "validation_files": [{"path": str(p), "sha256": self.digest(p)}
                                 for p in self.spec.validation_paths],
            "structure": self.title,
            "estimate": self.estimate.to_dict(),
            "model": model_dict(self.estimate.model),
            "characteristics": [row.__dict__ for row in self.characteristics],
            "order_search": {"criterion": self.criterion,
                             "candidates": [_row_dict(r) for r in self.orders]}
            if self.orders else None,
            "singular_values": list(self.singular_values) or None,
            "measured_frf": self.measured.to_dict() if self.measured is not None else None,
            "truth": dict(self.truth) if self.truth else None,
            "feedback_test": self.feedback.to_dict() if self.feedback is not None else None,
            "validation": self.validation.summary(),
            "validations": [v.summary() for v in self.validations],
            "notes": list(self.notes),
            "spec_numbers": {k: {"measured": _finite(m), "fitted": _finite(f)}
                             for k, (m, f) in self.spec_numbers.items()} or None,
            "verdict": self.verdict().to_dict(),
            "summary": self.summary().to_dict(),
        }

    def summary(self) -> RecordSummary:
        """Parameters with σ and intervals, the first validation's fit and tests, the decision."""
        first = self.validations[0]
        return summary_of(
            self.method, self.estimate.table(0.95), self.verdict(),
            validation=first if isinstance(first, ValidationReport) else None, notes=self.notes,
            diverged=[f"{v.experiment or 'the held-back part'} (sample {v.sample}, t = "
                      f"{v.time:.6g} s)" for v in self.diverged],
            extra=self._summary_extra())

    def models(self) -> dict[str, Any]:
        """The identified model as ``"G"`` (what :func:`load_results` rebuilds)."""
        return {"G": self.estimate.model}

    def _summary_extra(self) -> list[ParameterValue]:
        """Scalars beside the parameters: the measured spec numbers of an FRF fit."""
        return [spec_value(k, m) for k, (m, _) in self.spec_numbers.items()]

    # -- files ------------------------------------------------------------------------------
    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return spec_inputs(self.spec)

    def figures(self) -> dict[str, FigureWriter]:
        """Validation and residual plots per record, Bode, pole–zero map."""
        out: dict[str, FigureWriter] = {}
        for k, v in enumerate(self.validations):
            if isinstance(v, DivergedRun):
                continue  # nothing finite to draw; the page says where it diverged
            suffix = "" if k == 0 else f"-{k + 1}"
            out[f"validation{suffix}.png"] = partial(_plot_validation, v)
            out[f"residuals{suffix}.png"] = partial(_plot_residuals, v)
        if _has_frequency_response(self.estimate) and self._reports():
            out["bode.png"] = partial(_plot_bode, self)
            out["poles.png"] = partial(_plot_poles, self)
        if self.singular_values:
            order = int(self.estimate.options.get("order", 0))
            out["singular_values.png"] = partial(_plot_sv, self.singular_values, order)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        spec, est = self.spec, self.estimate
        o = est.options
        data_files = ", ".join(f"{p.name} (sha256 {self.digest(p)[:16]}…)"
                               for p in spec.data_paths)
        val_files = ", ".join(p.name for p in spec.validation_paths)
        experiment = Section("Experiment", paragraphs=(
            f"Estimation data: {data_files}; input {', '.join(o.get('inputs', []))} "
            f"({o.get('input', 'u')}), output {', '.join(outputs_of(est))}.",
            (f"Validation records: {val_files}." if val_files else
             "Validation: the held-back part of the record ([split])."),
        ))
        sections = [experiment, self._model_section(files), *self._extra_sections(files)]
        if self.orders:
            sections.append(Section(
                "Order search",
                paragraphs=(f"{len(self.orders)} candidates ranked by {self.criterion} "
                            "(lower is better; fit: higher is better).",),
                tables=(_order_table(self.orders, self.criterion),),
                figures=tuple(Figure.from_file(files[n], "Subspace singular values and the "
                                               "chosen order") for n in files
                              if n == "singular_values.png")))
        elif "singular_values.png" in files:
            sections.append(Section("Order", figures=(Figure.from_file(
                files["singular_values.png"], "Subspace singular values and the chosen order"),)))
        for k, v in enumerate(self.validations):
            suffix = "" if k == 0 else f"-{k + 1}"
            if isinstance(v, DivergedRun):
                section = Section("Validation: FAILED", paragraphs=(v.note,))
            else:
                section = validation_section(v, files[f"validation{suffix}.png"],
                                             files[f"residuals{suffix}.png"])
            title = section.title + (f": {v.experiment}" if v.experiment else "")
            if len(outputs_of(est)) > 1:
                title += f" ({v.output})"
            sections.append(Section(title, section.paragraphs, section.tables, section.figures))
        sections.append(Section("Notes", paragraphs=self.notes or
                                ("None: no step of the run warned.",)))
        name = spec.source.name if spec.source else "experiment"
        return Page(
            title=f"Identification report: {name}",
            subtitle=self._subtitle(),
            sections=tuple(sections),
            meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
                  ("data file", ", ".join(str(p) for p in spec.data_paths))),
        )

    # -- what a method family words its own way (narx, block models override these) --------
    def _headline(self) -> str:
        """The first console line: structure, channels, size of the fit."""
        est = self.estimate
        o = est.options
        return (f"{self.title}: output {', '.join(outputs_of(est))} from "
                f"{', '.join(o.get('inputs', []))} ({o.get('input', 'u')}); "
                f"{est.parameters.size} parameters on {est.n_samples} samples, "
                f"σ̂² = {est.noise_variance:.4g}")

    def _extra_lines(self) -> list[str]:
        """Console lines of a method's own section (after the parameters)."""
        return []

    def _model_section(self, files: Mapping[str, Path]) -> Section:
        """The report's Model section."""
        tables = [parameter_table(self.estimate)]
        if self.characteristics:
            tables.append(_characteristics_table(self.characteristics, self.truth))
        return Section("Model", paragraphs=(_model_text(self),), tables=tuple(tables),
                       figures=tuple(_model_figures(files, self.measured is not None)))

    def _extra_sections(self, files: Mapping[str, Path]) -> list[Section]:
        """A method's own report sections, after the Model section."""
        return []

    def _subtitle(self) -> str:
        return (f"{self.title} with parameter uncertainty, validated on data not used for "
                "fitting")

    def _reports(self) -> list[ValidationReport]:
        """The validations that ran to the end (not diverged)."""
        return [v for v in self.validations if isinstance(v, ValidationReport)]

    def _truth(self, name: str) -> float | None:
        return None if not self.truth else self.truth.get(name)

    # -- the verdict --------------------------------------------------------------------------
    def verdict(self) -> Verdict:
        """What the report decides: the checks on each validation record, one decision."""
        est = self.estimate
        # what the data cannot fix and the assumptions they break come before any interval
        checks: list[Check] = [Check(f"data: {d['name']}", f"{d['channel']}: {d['value']}",
                                     "caution", d["meaning"])
                               for d in est.options.get("data_limits", ())]
        checks += [Check("consistency", "not consistent", "caution", why)
                   for why in est.options.get("broken_assumptions", ())]
        several = len(self.validations) > 1
        multi = len(outputs_of(est)) > 1
        covariance = est.options.get("covariance")
        for v in self.validations:
            if isinstance(v, DivergedRun):
                checks.append(diverged_check(v))
                continue
            record = " ".join(x for x in ((v.experiment or "held-back part") if several else "",
                                          v.output if multi else "") if x)
            checks += validation_checks(v, covariance=covariance, record=record)
        checks += structure_checks(est.model, record_dt(self.validations, est.model), est,
                                   in_loop=bool(est.options.get("validated_in_loop")))
        checks += self._verdict_checks()
        if self.feedback is not None and self.feedback.has_feedback:
            p = f"p = {self.feedback.pvalue:.2g}"
            if self.direct:
                checks.append(Check("feedback test", p, "info",
                                    f"the record looks closed loop; {self.method.upper()} on "
                                    "(u, y) is the direct "
                                    "approach, consistent when its noise model is right (see "
                                    "the residual whiteness)"))
            else:
                checks.append(Check("feedback test", p, "caution",
                                    f"the record looks closed loop: {self.method} on (u, y) is "
                                    "biased under feedback"))
        if self.edge:
            checks.append(Check("order search", ", ".join(self.edge), "caution",
                                "the chosen order sits on the edge of the searched grid"))
        if not str(est.status).startswith("ok"):
            checks.append(Check("solver", str(est.status), "caution",
                                "the estimate did not converge cleanly"))
        if covariance:
            checks.append(interval_check(covariance))
        checks.append(count_check("notes", self.notes, "listed under Notes"))
        tables: tuple[Table, ...] = ()
        if self.spec_numbers:
            measured = {k: m for k, (m, _) in self.spec_numbers.items()}
            fitted = {k: f for k, (_, f) in self.spec_numbers.items()}
            tables = (Table(("spec number", "measured FRF", "fitted model"),
                            tuple((k, spec_text(k, m, measured), spec_text(k, f, fitted))
                                  for k, (m, f) in self.spec_numbers.items()),
                            "Spec numbers"),)
        return Verdict(self._tested(), tuple(checks), self.conditions, tables)

    def _tested(self) -> str:
        """What was tested, in one sentence."""
        est = self.estimate
        o = est.options
        records = len(self.validations)
        run = "in its loop from the reference" if o.get("validated_in_loop") else \
            "from the input"
        return (f"{self.title}, output {', '.join(outputs_of(est))} from "
                f"{', '.join(o.get('inputs', []))} ({o.get('input', 'u')}), fitted on "
                f"{est.n_samples} samples and simulated {run} on "
                f"{'a record' if records == 1 else f'{records} records'} not used for fitting.")

    def _verdict_checks(self) -> list[Check]:
        """A method's own checks (block and NARX models add theirs)."""
        return []


# -- the run flow shared by the black-box methods --------------------------------------------


def order_grid(options: Mapping[str, Any], keys: Sequence[str],
               n_inputs: int) -> tuple[dict[str, Any], dict[str, list[int]]]:
    """Split order options into fixed values and a grid to search.

    A list is a grid for single-input data and one value per input for
    several inputs.
    """
    fixed: dict[str, Any] = {}
    grid: dict[str, list[int]] = {}
    for key in keys:
        value = options[key]
        if isinstance(value, list) and n_inputs == 1 and len(value) > 1:
            grid[key] = value
        elif isinstance(value, list) and n_inputs == 1:
            fixed[key] = value[0]
        else:
            fixed[key] = value
    return fixed, grid


def fit_or_search(
    fit: Any, estimation: Experiment | ExperimentSet, validation: Experiment,
    fixed: Mapping[str, Any], grid: Mapping[str, Sequence[int]], criterion: str,
    **settings: Any,
) -> tuple[Estimate, tuple[OrderRow, ...], list[str]]:
    """Fit once, or search a grid (then the ranking rows and the orders on its edge)."""
    from ..estimate import select_order

    if not grid:
        return fit(estimation, **fixed, **settings), (), []
    selection = select_order(fit, estimation, grid, validation=validation,
                             criterion="bic" if criterion == "mdl" else criterion,
                             **fixed, **settings)
    rows = tuple(
        OrderRow(dict(c.orders), c.n_parameters, c.loss, {"aic": c.aic, "bic": c.bic,
                                                            "fpe": c.fpe}, c.fit, c.status)
        for c in selection.ranked())
    return selection.estimate, rows, list(selection.edge)


def on_edge(chosen: Mapping[str, int], grid: Mapping[str, Sequence[int]],
            lowest: Mapping[str, int]) -> list[str]:
    """Orders whose chosen value is the largest of its grid, or the smallest above its floor."""
    return [k for k, values in grid.items()
            if chosen[k] == max(values) or (chosen[k] == min(values) and chosen[k] > lowest[k])]


def lti_result(
    spec: ExperimentSpec,
    method: str,
    estimate: Estimate,
    title: str,
    validations: Sequence[Experiment],
    options: Mapping[str, Any],
    *,
    orders: Sequence[OrderRow] = (),
    criterion: str = "",
    edge: Sequence[str] = (),
    characteristics: Sequence[Any] = (),
    measured: Any = None,
    singular_values: Sequence[float] = (),
    truth: Mapping[str, float] | None = None,
    notes: Sequence[str] = (),
    estimation: Experiment | ExperimentSet | None = None,
    closed_loop: bool = False,
    modal: bool = True,
    result_type: type[IdentificationResult] | None = None,
    extra: Mapping[str, Any] | None = None,
    records: Experiment | ExperimentSet | None = None,
    spec_numbers: Mapping[str, tuple[float, float]] | None = None,
    how: str = "",
    direct: bool = False,
    loop_model: Any = None,
) -> IdentificationResult:
    """Validate an estimate on each record and assemble the result.

    Verdicts (a negative fit, a structure the residual tests reject, an
    order on the edge of its grid, a closed-loop record under an
    open-loop method) become notes and are also warned, so a script sees
    them as :class:`~servoid.ServoidWarning`.  With ``estimation`` given
    and the input ``u``, the feedback test runs on it; ``closed_loop``
    says the method is made for closed-loop data (then the residuals are
    tested against past inputs only).

    A free run that diverges on a record
    (:class:`~servoid.SimulationDivergedError`) does not end the run: the
    record gets a :class:`DivergedRun` (no metrics) and a note, and the
    result is written as usual, its verdict saying the model failed.

    ``modal = False`` skips the static gain, ω_n and ζ (a nonlinear
    model has none); ``result_type`` is the class to build (a subclass of
    :class:`IdentificationResult`) with its own fields in ``extra``.
    The test conditions (rate, length, excitation, band) are read from
    ``estimation`` (or ``records``, the estimation data of a method that
    does not want the feedback test) and the validation records.  ``how``
    says how the method fits (the report's Model section); ``direct``
    marks the direct approach on closed-loop data (a noise model of its
    own), for which a record that looks closed loop is no caution.
    ``loop_model`` (the closed loop r → y of a plant that cannot run free)
    is validated in place of the estimate, driven by the reference.
    """
    input_role = estimate.options.get("input", "u")
    feedback = None
    all_notes = list(notes)
    # [loop] open = true: the record was taken in open loop, so no feedback test
    declared_open = as_bool("[loop] open", spec.loop.get("open", False))
    if estimation is not None and input_role == "u" and not closed_loop and not declared_open:
        # feedback is a property of the test run: the whole record is the best evidence
        whole = estimation if spec.validation.files else spec.load()
        feedback = _feedback(whole, estimate)
        if feedback is not None and feedback.has_feedback:
            closed_loop = True
            all_notes.append(_feedback_note(method, feedback, direct))
    estimate, limits = data_limit_notes(estimate, estimation if estimation is not None
                                        else records, closed_loop, outputs_of(estimate))
    all_notes += limits
    if measured is None and estimation is not None:
        measured = _measured_frf(estimation, estimate, closed_loop)
    if not characteristics and modal:
        characteristics = _characteristics(estimate, validations[0])
    reports: list[ValidationReport | DivergedRun] = []
    with keyed({"transient": "[validation] transient", "horizon": "[identify] horizon",
                "initial": "[validation] initial"}):
        for v in validations:
            for output in outputs_of(estimate):
                try:
                    with warnings_as_notes() as said:
                        reports.append(validate(
                            estimate if loop_model is None else loop_model, v,
                            input=input_role if loop_model is None else "r", output=output,
                            horizon=options.get("horizon", 5), initial=spec.validation.initial,
                            transient=spec.validation.transient, limits=spec.limits(output),
                            closed_loop=closed_loop))
                    all_notes += [f"{v.name or 'validation'}: {n}" for n in said]
                except SimulationDivergedError as exc:
                    # the model fails on this record, the run goes on; its note supersedes
                    # what the simulation warned on the way
                    reports.append(DivergedRun.from_error(exc, v.name, output, v.dt))
    all_notes += structure_notes(estimate.model, validations[0].dt, estimate,
                                 in_loop=loop_model is not None)
    if edge:
        all_notes.append(f"the chosen {', '.join(edge)} sits on the edge of the searched grid; "
                         "widen the grid to be sure the best order is inside it")
    for report in reports:
        if isinstance(report, DivergedRun):
            all_notes.append(report.note)  # names its record
        else:
            all_notes += [f"{report.experiment or 'validation'}: {n}" for n in report.notes()]
    all_notes = list(dict.fromkeys(all_notes))
    for note in all_notes:
        warn(note, ServoidWarning)  # lti_result ← run ← identify ← user
    if truth is None:
        truth = truth_from_spec(spec, [*estimate.names, *(r.name for r in characteristics)])
    data = estimation if estimation is not None else records
    # the excitation: the model's input in open loop, the reference in closed loop
    channel = None if closed_loop else next(iter(estimate.options.get("inputs") or []), None)
    conditions = () if data is None else spec_conditions(spec, data, validations, channel)
    return (result_type or IdentificationResult)(
        spec, method, estimate, tuple(reports), title, tuple(orders), criterion,
        tuple(characteristics), measured, tuple(float(s) for s in singular_values), truth,
        tuple(all_notes), gain_unit(validations[0], estimate), feedback, conditions=conditions,
        edge=tuple(edge), spec_numbers=dict(spec_numbers or {}), how=how, direct=direct,
        **(extra or {}))


def _feedback(data: Experiment | ExperimentSet, estimate: Estimate) -> Any:
    """The feedback test on the estimation record, or None when it cannot run."""
    from ..closedloop import feedback_test

    inputs = estimate.options.get("inputs") or []
    outputs = outputs_of(estimate)
    if len(inputs) != 1 or len(outputs) != 1:
        return None  # the test is single-input single-output
    first = data if isinstance(data, Experiment) else data[0]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            return feedback_test(first, input=inputs[0], output=outputs[0])
    except ServoidError:  # too short or not exciting enough for the test's own ARX
        return None


def _characteristics(estimate: Estimate, exp: Experiment) -> list[Any]:
    """Static gain, time constants, ω_n and ζ with their std, or none for MIMO models."""
    from ..estimate import modal_parameters

    inputs = estimate.options.get("inputs") or []
    outputs = outputs_of(estimate)
    if len(inputs) != 1 or len(outputs) != 1 or estimate.model_function is None:
        return []
    units = {"output_unit": exp.unit(outputs[0]) if outputs[0] in exp.names else "",
             "input_unit": exp.unit(inputs[0]) if inputs[0] in exp.names else ""}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            return modal_parameters(estimate, **units)
    except ServoidError:  # e.g. an integrator has no static gain to report
        return []


def _measured_frf(data: Experiment | ExperimentSet, estimate: Estimate,
                  closed_loop: bool) -> Any:
    """A Welch FRF of the estimation record to draw under the model, or None."""
    from ..estimate import estimate_frf

    inputs = estimate.options.get("inputs") or []
    outputs = outputs_of(estimate)
    if len(inputs) != 1 or len(outputs) != 1:
        return None
    first = data if isinstance(data, Experiment) else data[0]
    reference = "r" if closed_loop and first.names_of("r") else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            return estimate_frf(first, input=inputs[0], output=outputs[0], reference=reference,
                                method="welch")
    except ServoidError:  # too short for a spectral estimate: the Bode shows the model alone
        return None


def _feedback_note(method: str, test: Any, direct: bool) -> str:
    if direct:
        return (f"the record looks closed loop (feedback test p = {test.pvalue:.2g}); "
                f"{method.upper()} on (u, y) is the direct approach, consistent when its noise "
                "model is right — "
                "check that the residuals are white")
    return (f"the record looks closed loop (feedback test p = {test.pvalue:.2g}): {method} on "
            "(u, y) is biased under feedback; use method = \"bj\" (direct, with a noise "
            "model), \"two-stage\" or \"cliv\" (the reference as instrument), or "
            "\"indirect\" with the controller in [loop]")


def outputs_of(estimate: Estimate) -> list[str]:
    """The output channel(s) an estimate models."""
    o = estimate.options
    return list(o["outputs"]) if o.get("outputs") else [o["output"]]


def gain_unit(exp: Experiment, estimate: Estimate) -> str:
    """``output unit/input unit`` of an estimate's first path, or ''."""
    out = outputs_of(estimate)[0]
    inputs = estimate.options.get("inputs") or []
    y = exp.unit(out) if out in exp.names else ""
    u = exp.unit(inputs[0]) if inputs and inputs[0] in exp.names else ""
    if not y and not u:
        return ""
    return f"{y or '1'}/{u or '1'}"


def n_inputs(data: Experiment | ExperimentSet, role: str) -> int:
    """Number of channels of ``role`` in the estimation data."""
    first = data if isinstance(data, Experiment) else data[0]
    return max(len(first.names_of(role)), 1)  # type: ignore[arg-type]


def model_dict(model: Any) -> dict[str, Any]:
    """A model's structure and coefficients as plain data."""
    if hasattr(model, "transfer_function"):  # PolynomialModel
        tf = model.transfer_function(0)
        return {
            "type": "polynomial", "structure": model.structure, "dt": model.dt,
            "a": model.a, "b": [list(b) for b in model.b], "c": model.c, "d": model.d,
            "f": [list(f) for f in model.f], "nk": list(model.nk),
            "poles": _complex_list(tf.poles()), "zeros": _complex_list(tf.zeros()),
        }
    if hasattr(model, "num"):  # TransferFunction
        return {"type": "transfer_function", "dt": model.dt, "num": model.num,
                "den": model.den, "delay": float(getattr(model, "delay", 0.0)),
                "poles": _complex_list(model.poles()), "zeros": _complex_list(model.zeros())}
    if hasattr(model, "A"):  # StateSpace
        return {"type": "state_space", "dt": model.dt, "A": model.A, "B": model.B,
                "C": model.C, "D": model.D, "poles": _complex_list(model.poles())}
    return {"type": type(model).__name__}


#: An FRF's spec numbers as summary scalars: (name, unit) by the start of their key.
_SPEC_SCALARS = (("bandwidth", "bandwidth", "Hz"), ("phase lag", "phase_lag", "deg"),
                 ("resonance peak", "resonance_peak", "dB"),
                 ("resonance frequency", "resonance_frequency", "Hz"))


def spec_value(key: str, value: float) -> ParameterValue:
    """A spec number (``"bandwidth (-3 dB) [Hz]"``) as a summary scalar without an interval.

    Its name is a plain word a fleet file can use as a ``[limits.<name>]``
    table and a column (``bandwidth``, ``phase_lag``, ``resonance_peak``,
    ``resonance_frequency``); a number undefined in the measured band is NaN.
    """
    name, unit = next(((n, u) for start, n, u in _SPEC_SCALARS if key.startswith(start)),
                      (re.sub(r"\W+", "_", key).strip("_"), ""))
    return ParameterValue(name, float(value), math.nan, math.nan, math.nan, unit)


# -- private ------------------------------------------------------------------------------


def _finite(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _complex_list(values: Any) -> list[dict[str, float]]:
    return [{"re": float(v.real), "im": float(v.imag)} for v in np.asarray(values)]


def _row_dict(row: OrderRow) -> dict[str, Any]:
    return {"orders": dict(row.orders), "n_parameters": row.n_parameters, "loss": row.loss,
            **dict(row.scores), "fit_percent": None if math.isnan(row.fit) else row.fit,
            "status": row.status}


def _order_lines(rows: Sequence[OrderRow], criterion: str) -> list[str]:
    table = _order_table(rows, criterion, status_width=48)
    widths = [max(len(c), *(len(r[i]) for r in table.rows)) for i, c in enumerate(table.columns)]
    head = "  ".join(c.rjust(w) for c, w in zip(table.columns, widths, strict=True))
    body = ["  ".join(cell.rjust(w) for cell, w in zip(r, widths, strict=True))
            for r in table.rows]
    return [head, *body]


def _order_table(rows: Sequence[OrderRow], criterion: str, status_width: int = 0) -> Table:
    keys = list(rows[0].orders)
    score_names = list(rows[0].scores)
    columns = (*keys, "parameters", "loss", *score_names, "validation fit %", "status")
    body = []
    for r in rows:
        body.append((*(_order_text(r.orders[k]) for k in keys), str(r.n_parameters),
                     _num(r.loss), *(_num(r.scores[s]) for s in score_names),
                     "—" if math.isnan(r.fit) else f"{r.fit:.2f}",
                     _clip(r.status, status_width)))
    return Table(columns, tuple(body), f"Ranked by {criterion}; the first row was chosen")


def _clip(text: str, width: int) -> str:
    return text if not width or len(text) <= width else text[: width - 1] + "…"


def _order_text(value: Any) -> str:
    return ", ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def _num(x: float) -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.5g}"


def _characteristics_table(rows: Sequence[Any], truth: Mapping[str, float] | None) -> Table:
    body = tuple(
        (r.name, f"{r.value:.6g}", f"{r.std:.3g}", f"[{r.ci_low:.6g}, {r.ci_high:.6g}]", r.unit,
         "—" if not truth or r.name not in truth else f"{truth[r.name]:.6g}")
        for r in rows)
    return Table(("quantity", "estimate", "std", "95 % CI", "unit", "truth"), body,
                 "Continuous-time characteristics, std by the delta method")


def _model_text(result: IdentificationResult) -> str:
    est = result.estimate
    o = est.options
    parts = [f"{result.title} by {result.how or result.method} on {est.n_samples} "
             f"samples; residual variance {est.noise_variance:.4g}; status {est.status}."]
    if "condition" in o:
        parts.append(f"Scaled condition number {o['condition']:.3g} ({o.get('solver')} route).")
    if "iterations" in o:
        parts.append(f"{o['iterations']} iterations.")
    if str(o.get("covariance", "")).startswith(("robust", "sandwich")):
        parts.append("The covariance allows for coloured residuals (sandwich with an AR model of "
                     "the residuals).")
    parts.append("Bode bands are ±2σ from the parameter covariance (delta method).")
    return " ".join(parts)


def _model_figures(files: Mapping[str, Path], measured: bool) -> list[Figure]:
    out = []
    if "bode.png" in files:
        over = ", over the measured frequency response and its coherence" if measured else ""
        out.append(Figure.from_file(files["bode.png"], "Bode diagram of the identified model "
                                    f"with ±2σ bands from its covariance{over}"))
    if "poles.png" in files:
        out.append(Figure.from_file(files["poles.png"], "Poles (×) and zeros (○)"))
    return out


def _has_frequency_response(est: Estimate) -> bool:
    model = est.model
    return hasattr(model, "freqresp") or hasattr(model, "transfer_function")


def _frequency_grid(result: IdentificationResult) -> np.ndarray:
    first = result._reports()[0]  # figures() draws a Bode only when one validation ran
    dt = first.time[1] - first.time[0]
    nyquist = 0.5 / dt
    lowest = nyquist / max(first.measured.size, 1000)
    return np.logspace(np.log10(lowest), np.log10(nyquist * 0.999), 400)


def _plot_validation(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_validation(report, path, overwrite=overwrite)


def _plot_residuals(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_residuals(report, path, overwrite=overwrite)


def _plot_bode(result: IdentificationResult, path: Path, overwrite: bool) -> None:
    est = result.estimate
    f = _frequency_grid(result)
    bands = {}
    inputs = est.options.get("inputs", ["u"])
    outputs = outputs_of(est)
    for k, y_name in enumerate(outputs):
        for i, u_name in enumerate(inputs):
            label = result.method if len(inputs) * len(outputs) == 1 else \
                f"{result.method}: {u_name} → {y_name}"
            bands[label] = frequency_band(est, f, input=i, output=k)
    plot_bode_bands(bands, path, measured=result.measured, unit=result.gain_unit,
                    title=f"{result.title}", overwrite=overwrite)


def _plot_poles(result: IdentificationResult, path: Path, overwrite: bool) -> None:
    plot_pole_zero({result.method: result.estimate.model}, path, overwrite=overwrite)


def _plot_sv(values: Sequence[float], order: int, path: Path, overwrite: bool) -> None:
    plot_singular_values(values, order, path, overwrite=overwrite)
