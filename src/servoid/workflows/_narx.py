"""``method = "narx"``: polynomial NARX, terms chosen by forward OLS, validated by free run."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from .. import __version__
from .._errors import ServoidWarning
from ..data import ExperimentSpec
from ..estimate import Estimate
from ..report import Page, Section, Table, plot_residuals, plot_validation
from ..validate import ValidationReport, validate
from ._arx import HORIZON, OUTPUT, ROLE
from ._common import keyed, parameter_table, sha256, spec_inputs, validation_section
from ._lti import _truth_from_spec
from ._options import choice, integer, number, optional, orders
from ._registry import FigureWriter, Method, Option
from ._summary import Displayed

__all__ = ["METHOD", "NarxResult"]

#: Library parameter → the experiment-file key, for errors raised below the workflow.
_KEYS = {name: f"[identify] {name}" for name in
         ("na", "nb", "nk", "degree", "max_terms", "tolerance", "criterion", "horizon")}


@dataclass(frozen=True, eq=False, repr=False)
class NarxResult(Displayed):
    """A polynomial NARX model from an experiment file, validated.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    estimate : Estimate
        The model (:class:`~servoid.nonlinear.NarxModel`) with covariance;
        ``options["selection"]`` lists the terms in the order they entered.
    validations : tuple of ValidationReport
        Free run and k-step prediction on each validation record.
    title : str
        The structure in words.
    truth : mapping or None
        Known coefficients by term name (``[report] truth``).
    notes : tuple of str
        Verdicts and warnings in words.
    folder, files
        Where the results were written.
    """

    spec: ExperimentSpec
    estimate: Estimate
    validations: tuple[ValidationReport, ...]
    title: str
    truth: Mapping[str, float] | None = None
    notes: tuple[str, ...] = ()
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())

    method = "narx"

    @property
    def validation(self) -> ValidationReport:
        """Validation on the first validation record."""
        return self.validations[0]

    def __str__(self) -> str:
        est = self.estimate
        o = est.options
        lines = [(f"{self.title}: output {o['output']} from {', '.join(o['inputs'])} "
                  f"({o['input']}); {est.parameters.size} of {o['n_candidates']} candidate "
                  f"terms on {est.n_samples} samples, σ̂² = {est.noise_variance:.4g}")]
        lines += str(est).splitlines()[1:]
        lines.append(f"  term selection (forward OLS, {_criterion_words(o)}), in order of entry:")
        lines += ["    " + line for line in _selection_lines(o["selection"])]
        for v in self.validations:
            lines.append(f"  {v}")
        for note in self.notes:
            lines.append(f"  note: {note}")
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        spec = self.spec
        return {
            "servoid_version": __version__,
            "method": "narx",
            "experiment_file": str(spec.source) if spec.source else None,
            "data_file": str(spec.data_path),
            "data_sha256": sha256(spec.data_path),
            "data_files": [{"path": str(p), "sha256": sha256(p)} for p in spec.data_paths],
            "validation_files": [{"path": str(p), "sha256": sha256(p)}
                                 for p in spec.validation_paths],
            "structure": self.title,
            "estimate": self.estimate.to_dict(),
            "model": self.estimate.model.to_dict(),
            "selection": list(self.estimate.options["selection"]),
            "truth": dict(self.truth) if self.truth else None,
            "validation": self.validation.summary(),
            "validations": [v.summary() for v in self.validations],
            "notes": list(self.notes),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return spec_inputs(self.spec)

    def figures(self) -> dict[str, FigureWriter]:
        """Validation and residual plots per record."""
        out: dict[str, FigureWriter] = {}
        for k, v in enumerate(self.validations):
            suffix = "" if k == 0 else f"-{k + 1}"
            out[f"validation{suffix}.png"] = partial(_plot_validation, v)
            out[f"residuals{suffix}.png"] = partial(_plot_residuals, v)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page: model, ERR table, a validation per record."""
        spec, est = self.spec, self.estimate
        o = est.options
        data_files = ", ".join(f"{p.name} (sha256 {sha256(p)[:16]}…)" for p in spec.data_paths)
        val_files = ", ".join(p.name for p in spec.validation_paths)
        experiment = Section("Experiment", paragraphs=(
            (f"Estimation data: {data_files}; input {', '.join(o['inputs'])} ({o['input']}), "
             f"output {o['output']}."),
            (f"Validation records: {val_files}." if val_files else
             "Validation: the held-back part of the record ([split])."),
        ))
        tables = [parameter_table(est, "Coefficients refitted by least squares on the selected "
                                       "terms; std from σ̂²(ΦᵀΦ)⁻¹")]
        if self.truth:
            tables.append(_truth_table(est, self.truth))
        model = Section("Model", paragraphs=(_model_text(est), str(est.model)),
                        tables=tuple(tables))
        selection = Section(
            "Term selection",
            paragraphs=(
                (f"Forward orthogonal least squares over {o['n_candidates']} candidate terms "
                 f"({_criterion_words(o)}). ERR is the share of Σy² a term explains beyond the "
                 "terms above it (Chen, Billings & Luo 1989); 1 − ΣERR is what is still "
                 "unexplained after it. Terms tried after the last kept one show why the "
                 "criterion stopped."),),
            tables=(_selection_table(o["selection"]),))
        sections = [experiment, model, selection]
        for k, v in enumerate(self.validations):
            suffix = "" if k == 0 else f"-{k + 1}"
            section = validation_section(v, files[f"validation{suffix}.png"],
                                         files[f"residuals{suffix}.png"])
            title = section.title + (f": {v.experiment}" if v.experiment else "")
            sections.append(Section(title, section.paragraphs, section.tables, section.figures))
        sections.append(Section("Notes", paragraphs=self.notes or
                                ("The validation data do not reject the model.",)))
        name = spec.source.name if spec.source else "experiment"
        return Page(
            title=f"Identification report: {name}",
            subtitle=f"{self.title}, validated by free-run simulation on data not used for "
                     "fitting",
            sections=tuple(sections),
            meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
                  ("data file", ", ".join(str(p) for p in spec.data_paths))),
        )


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> NarxResult:
    """Fit a polynomial NARX model and validate it on each validation record."""
    from ..nonlinear import fit_narx

    estimation, validations = spec.records()
    notes: list[str] = []
    with keyed(_KEYS), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        estimate = fit_narx(estimation, na=options["na"], nb=options["nb"], nk=options["nk"],
                            degree=options["degree"], max_terms=options["max_terms"],
                            criterion=options["criterion"], tolerance=options["tolerance"],
                            input=options["input"], output=options["output"])
    notes += _notes(caught)
    output = estimate.options["output"]
    reports = []
    for v in validations:
        with keyed({**_KEYS, "transient": "[validation] transient",
                    "initial": "[validation] initial"}), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ServoidWarning)
            reports.append(validate(estimate, v, input=options["input"], output=output,
                                    horizon=options["horizon"], initial=spec.validation.initial,
                                    transient=spec.validation.transient,
                                    limits=spec.limits(output)))
        notes += [f"{v.name or 'validation'}: {n}" for n in _notes(caught)]  # a diverging run
    for report in reports:
        notes += [f"{report.experiment or 'validation'}: {n}" for n in report.notes()]
    for note in notes:
        warnings.warn(note, ServoidWarning, stacklevel=3)  # run ← identify ← user
    if truth is None:
        truth = _truth_from_spec(spec, list(estimate.names))
    o = estimate.options
    title = (f"NARX (na = {o['na']}, nb = {_short(o['nb'])}, nk = {_short(o['nk'])}, degree = "
             f"{o['degree']}, {estimate.parameters.size} terms)")
    return NarxResult(spec, estimate, tuple(reports), title, truth,
                      tuple(dict.fromkeys(notes)))


# -- private ------------------------------------------------------------------------------


def _notes(caught: Sequence[warnings.WarningMessage]) -> list[str]:
    """ServoidWarnings as notes; any other warning is passed on as it came."""
    out = []
    for w in caught:
        if issubclass(w.category, ServoidWarning):
            out.append(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return out


def _criterion_words(o: Mapping[str, Any]) -> str:
    if o["criterion"] == "err":
        return f"stopped when 1 − ΣERR fell below {o['tolerance']:g}"
    return f"number of terms by {o['criterion'].upper()} on the one-step residual variance"


def _selection_table(rows: Sequence[Mapping[str, Any]]) -> Table:
    body = []
    for k, r in enumerate(rows, start=1):
        crit = r.get("criterion")
        body.append((str(k), r["term"], f"{r['err']:.4g}", f"{r['unexplained']:.4g}",
                     "—" if crit is None else f"{crit:.6g}", str(r["kept"])))
    return Table(("step", "term", "ERR", "1 − ΣERR", "criterion", "kept"), tuple(body),
                 "Terms in the order they entered the forward selection; \"pruned\": entered, "
                 "then dropped because the criterion is lower without it")


def _selection_lines(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    table = _selection_table(rows)
    last = max((k for k, r in enumerate(rows) if r["kept"] != "no"), default=0)
    widths = [max(len(c), *(len(r[i]) for r in table.rows)) if table.rows else len(c)
              for i, c in enumerate(table.columns)]
    head = "  ".join(c.rjust(w) for c, w in zip(table.columns, widths, strict=True))
    return [head, *("  ".join(cell.rjust(w) for cell, w in zip(r, widths, strict=True))
                    for r in table.rows[: last + 4])]


def _truth_table(est: Estimate, truth: Mapping[str, float]) -> Table:
    rows = []
    for r in est.table():
        known = truth.get(r.name)
        z = "—" if known is None or not r.std > 0 else f"{(r.value - known) / r.std:+.2f}"
        rows.append((r.name, f"{r.value:.6g}", "—" if known is None else f"{known:.6g}", z))
    missed = [name for name in truth if name not in est.names]
    caption = "Estimate against the known value; z = (estimate − truth)/std"
    if missed:
        caption += f". Known terms not selected: {', '.join(missed)}"
    return Table(("term", "estimate", "truth", "z"), tuple(rows), caption)


def _model_text(est: Estimate) -> str:
    o = est.options
    return (f"Polynomial NARX of degree {o['degree']}: {est.parameters.size} terms kept of "
            f"{o['n_candidates']} candidates, fitted by least squares on the one-step "
            f"equations ({est.n_samples} samples); one-step residual variance "
            f"{est.noise_variance:.4g}; scaled condition number {o['condition']:.3g}. The "
            "coefficients' intervals assume white equation errors; the free-run validation "
            "below is how the model is judged.")


def _short(values: Sequence[int]) -> str:
    return str(values[0]) if len(values) == 1 else str(list(values))


def _plot_validation(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_validation(report, path, overwrite=overwrite)


def _plot_residuals(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_residuals(report, path, overwrite=overwrite)


METHOD = Method(
    name="narx",
    summary="polynomial NARX y(t) = Σ θ·(products of lagged y and u) + e: terms chosen by "
            "forward orthogonal least squares (ERR) and BIC/AIC, validated by free run",
    options=(
        ROLE,
        OUTPUT,
        Option("na", 2, integer(minimum=0, maximum=100),
               "output lags y(t-1) … y(t-na) among the candidates"),
        Option("nb", 2, orders(1), "input lags per input (a list: one value per input)"),
        Option("nk", 1, orders(0), "input delay per input [samples] (a list as for nb)"),
        Option("degree", 2, integer(minimum=1, maximum=10),
               "highest degree of the candidate monomials (1: linear ARX terms)"),
        Option("max_terms", None, optional(integer(minimum=1)),
               "most terms to keep (default: as many as the criterion wants)"),
        Option("criterion", "bic", choice(("bic", "aic", "err")),
               "how many terms: bic, aic (on the one-step residual variance) or err (stop "
               "when 1 − ΣERR < tolerance)"),
        Option("tolerance", 0.01, number(positive=True),
               "ERR threshold ρ in (0, 1) for criterion = \"err\" (above the noise share of "
               "Σy²)"),
        HORIZON,
    ),
    run=run,
)
