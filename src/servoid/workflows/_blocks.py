"""``method = "hammerstein" | "wiener" | "hammerstein-wiener"``: block-oriented models.

A static curve before (Hammerstein), after (Wiener) or on both sides of
(Hammerstein–Wiener) a linear block, fitted jointly by output error
(:func:`servoid.nonlinear.fit_block`), validated on each validation
record by free-run simulation with the initial state fitted, and drawn
with its ±2σ band.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._checks import as_float_list
from .._errors import DataError, ServoidError, ServoidWarning
from ..data import Experiment, ExperimentSpec
from ..estimate import Estimate
from ..nonlinear import (
    SHAPES,
    AbsoluteValue,
    DeadZone,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    SignedPower,
    StaticNonlinearity,
    fit_block,
)
from ..report import Figure, Page, Section, new_figure, plot_residuals, plot_validation, save_figure
from ..validate import ValidationReport, validate
from ._arx import HORIZON, OUTPUT, ROLE
from ._common import (
    keyed,
    parameter_table,
    read_truth,
    report_options,
    sha256,
    spec_inputs,
    validation_section,
)
from ._lti import model_dict
from ._options import boolean, choice, integer, number, optional
from ._registry import FigureWriter, Method, Option
from ._summary import Displayed

__all__ = ["HAMMERSTEIN", "HAMMERSTEIN_WIENER", "WIENER", "BlockResult"]

_TITLES = {"hammerstein": "Hammerstein", "wiener": "Wiener",
           "hammerstein-wiener": "Hammerstein–Wiener"}
#: Parameters each shape takes from ``*_parameters``, in order.
_PARAMETERS = {"deadzone": ("lower", "upper"), "saturation": ("lower", "upper"),
               "abs": ("center",), "power": ("exponent",),
               "polynomial": ("c1", "c2", "…"), "piecewise-linear": ("s0", "s1", "…")}


@dataclass(frozen=True)
class StaticCurve:
    """A fitted static block drawn over its input's range, with a ±2σ band."""

    block: str
    kind: str
    x: np.ndarray
    value: np.ndarray
    std: np.ndarray


@dataclass(frozen=True, eq=False, repr=False)
class BlockResult(Displayed):
    """A block-oriented model identified from an experiment file, validated.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    method : str
        ``"hammerstein"``, ``"wiener"`` or ``"hammerstein-wiener"``.
    estimate : Estimate
        The model (a :class:`~servoid.nonlinear.BlockModel`) with covariance.
    validations : tuple of ValidationReport
        One per validation record.
    title : str
        The structure in words.
    curves : tuple of StaticCurve
        The static blocks with their bands.
    notes : tuple of str
        Verdicts and warnings in words.
    truth : mapping or None
        Known parameter values by name (``[report] truth``).
    folder, files
        Where the results were written.
    """

    spec: ExperimentSpec
    method: str
    estimate: Estimate
    validations: tuple[ValidationReport, ...]
    title: str
    curves: tuple[StaticCurve, ...] = ()
    notes: tuple[str, ...] = ()
    truth: Mapping[str, float] | None = None
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())

    @property
    def validation(self) -> ValidationReport:
        """Validation on the first validation record."""
        return self.validations[0]

    def __str__(self) -> str:
        est = self.estimate
        o = est.options
        lines = [(f"{self.title}: output {o['output']} from {', '.join(o['inputs'])} "
                 f"({o['input']}); {est.parameters.size} parameters on {est.n_samples} samples, "
                 f"σ̂² = {est.noise_variance:.4g}")]
        truth = self.truth or {}
        lines += [line + (f"   truth {truth[name]:.6g}" if name in truth else "")
                  for name, line in zip(est.names, str(est).splitlines()[1:], strict=True)]
        lines += [f"  {v}" for v in self.validations]
        lines += [f"  note: {n}" for n in self.notes]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        model = self.estimate.model
        return {
            "servoid_version": __version__,
            "method": self.method,
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": sha256(self.spec.data_path),
            "data_files": [{"path": str(p), "sha256": sha256(p)} for p in self.spec.data_paths],
            "validation_files": [{"path": str(p), "sha256": sha256(p)}
                                 for p in self.spec.validation_paths],
            "structure": self.title,
            "estimate": self.estimate.to_dict(),
            "model": {
                "type": "block", "structure": model.structure, "dt": model.dt,
                "offset": model.offset,
                "input_nonlinearity": _shape_dict(model.input_nonlinearity),
                "output_nonlinearity": _shape_dict(model.output_nonlinearity),
                "linear": model_dict(model.linear),
                # for servoid export --to json: the model file keeps the covariance
                "parameter_names": list(self.estimate.names),
                "covariance": np.asarray(self.estimate.covariance).tolist(),
            },
            "validation": self.validation.summary(),
            "validations": [v.summary() for v in self.validations],
            "truth": dict(self.truth) if self.truth else None,
            "notes": list(self.notes),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return spec_inputs(self.spec)

    def figures(self) -> dict[str, FigureWriter]:
        """Validation and residual plots per record, the static curves."""
        out: dict[str, FigureWriter] = {}
        for k, v in enumerate(self.validations):
            suffix = "" if k == 0 else f"-{k + 1}"
            out[f"validation{suffix}.png"] = partial(_plot_validation, v)
            out[f"residuals{suffix}.png"] = partial(_plot_residuals, v)
        if self.curves:
            out["static.png"] = partial(_plot_curves, self.curves, self.title)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
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
        figures = (Figure.from_file(files["static.png"], "Fitted static curve(s) over the range "
                                    "their input covers, with ±2σ bands from the covariance"),) \
            if "static.png" in files else ()
        model = Section("Model", paragraphs=(_model_text(self),),
                        tables=(parameter_table(est),), figures=figures)
        sections = [experiment, model]
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
            subtitle=f"{self.title} with parameter uncertainty, validated on data not used for "
                     "fitting",
            sections=tuple(sections),
            meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
                  ("data file", ", ".join(str(p) for p in spec.data_paths))),
        )


def run(structure: str, spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> BlockResult:
    """Fit the block model and validate it on each validation record."""
    estimation, validations = spec.records()
    first = estimation if isinstance(estimation, Experiment) else estimation[0]
    role = options["input"]
    settings: dict[str, Any] = {}
    for side in ("input", "output"):
        key = f"{side}_nonlinearity"
        if key in options:
            settings[key] = _shape(options, side)
            # one shape per side can be free-scale (two are refused), so the side whose shape
            # uses them hands its breakpoints or degree on
            if settings[key] == "piecewise-linear" and options[f"{side}_breakpoints"] is not None:
                settings["breakpoints"] = options[f"{side}_breakpoints"]
            if settings[key] == "polynomial":
                settings["degree"] = options[f"{side}_degree"]
    with keyed({"nb": "[identify] nb", "nf": "[identify] nf", "nk": "[identify] nk",
                "n_poles": "[identify] n_poles", "n_zeros": "[identify] n_zeros",
                "max_iter": "[identify] max_iter", "tol": "[identify] tol"}):
        estimate = fit_block(
            estimation, structure, linear=options["linear"], nb=options["nb"], nf=options["nf"],
            nk=options["nk"], n_poles=options["n_poles"], n_zeros=options["n_zeros"],
            offset=options["offset"], input=role, output=options["output"],
            initial=options["initial"], max_iter=options["max_iter"], tol=options["tol"],
            **settings)
    output = estimate.options["output"]
    with keyed({"transient": "[validation] transient", "horizon": "[identify] horizon",
                "initial": "[validation] initial"}):
        reports = tuple(
            validate(estimate, v, input=role, output=output, horizon=options["horizon"],
                     initial=spec.validation.initial, transient=spec.validation.transient,
                     limits=spec.limits(output))
            for v in validations)
    notes: list[str] = []
    if estimate.status != "ok":
        notes.append(f"the search ended with status: {estimate.status}")
    for report in reports:
        notes += [f"{report.experiment or 'validation'}: {n}" for n in report.notes()]
    for note in notes:
        warnings.warn(note, ServoidWarning, stacklevel=4)
    o = estimate.options
    orders = (f"nb = {o['nb']}, nf = {o['nf']}, nk = {o['nk']}" if o["linear"] == "oe" else
              f"continuous, {o['n_poles']} poles, {o['n_zeros']} zeros")
    shapes = " / ".join(s for s in (o["input_nonlinearity"], o["output_nonlinearity"]) if s)
    title = f"{_TITLES[structure]} ({shapes}; {orders})"
    if truth is None:
        truth = _truth_from_spec(spec, estimate.names)
    return BlockResult(spec, structure, estimate, reports, title,
                       _curves(estimate, first.signal(role)[:, 0]), tuple(notes),
                       {k: v for k, v in (truth or {}).items() if k in estimate.names} or None)


# -- options -------------------------------------------------------------------------------------


def _shape(options: Mapping[str, Any], side: str) -> StaticNonlinearity | str:
    """The shape of one side from its name and optional start parameters."""
    kind = options[f"{side}_nonlinearity"]
    values = options[f"{side}_parameters"]
    if values is None:
        return kind
    key = f"[identify] {side}_parameters"
    expected = _PARAMETERS[kind]
    try:
        if kind in ("deadzone", "saturation", "abs", "power") and len(values) != len(expected):
            raise DataError(f"{key} for \"{kind}\" must hold {len(expected)} value(s) "
                            f"({', '.join(expected)}), got {len(values)}: {values}")
        if kind == "deadzone":
            return DeadZone(*values)
        if kind == "saturation":
            return Saturation(*values)
        if kind == "abs":
            return AbsoluteValue(values[0])
        if kind == "power":
            return SignedPower(values[0])
        if kind == "polynomial":
            return Polynomial(tuple(values))
        breakpoints = options[f"{side}_breakpoints"]
        if breakpoints is None:
            raise DataError(f"{key} for \"piecewise-linear\" are its slopes: give "
                            f"[identify] {side}_breakpoints too")
        return PiecewiseLinear(tuple(breakpoints), tuple(values))
    except ServoidError as exc:
        text = str(exc)
        if text.startswith(key):
            raise
        raise type(exc)(f"{key}: {text}") from None


def _numbers() -> Any:
    def check(value: Any, where: str, name: str) -> list[float]:
        return as_float_list(name, value, min_length=1, where=where)
    return check


def _side_options(side: str, default: str) -> tuple[Option, ...]:
    return (
        Option(f"{side}_nonlinearity", default, choice(SHAPES),
               f"shape of the {side} static block: " + ", ".join(SHAPES)),
        Option(f"{side}_parameters", None, optional(_numbers()),
               "start values of its parameters (deadzone, saturation: [lower, upper]; abs: "
               "[center]; power: [exponent]; polynomial: [c1, c2, …]; piecewise-linear: "
               "slopes); none: from the data"),
        Option(f"{side}_breakpoints", None, optional(_numbers()),
               "breakpoints of a piecewise-linear shape (increasing; none: quantiles of its "
               "input)"),
        Option(f"{side}_degree", 3, integer(minimum=1, maximum=12),
               "degree of a polynomial shape"),
    )


def _method(structure: str, summary: str) -> Method:
    sides = {"hammerstein": _side_options("input", "polynomial"),
             "wiener": _side_options("output", "polynomial"),
             "hammerstein-wiener": (*_side_options("input", "deadzone"),
                                    *_side_options("output", "polynomial"))}[structure]
    return Method(
        name=structure,
        summary=summary,
        options=(
            ROLE, OUTPUT, *sides,
            Option("linear", "oe", choice(("oe", "tf")),
                   'linear block: "oe" (discrete B/F: nb, nf, nk) or "tf" (continuous: '
                   "n_poles, n_zeros)"),
            Option("nb", 2, integer(minimum=1, maximum=50), "B coefficients of the linear block"),
            Option("nf", 2, integer(minimum=0, maximum=50), "F order (poles) of the linear block"),
            Option("nk", 1, integer(minimum=0), "delay of the linear block [samples]"),
            Option("n_poles", 2, integer(minimum=1, maximum=20), "poles of a continuous block"),
            Option("n_zeros", None, optional(integer(minimum=0, maximum=20)),
                   "zeros of a continuous block (none: n_poles − 1)"),
            Option("offset", False, boolean(), "fit a constant output offset"),
            Option("initial", "estimate", choice(("estimate", "zero")),
                   "initial state of the linear block in the fit: estimated or rest"),
            Option("max_iter", 200, integer(minimum=1), "most iterations of the joint search"),
            Option("tol", 1e-10, number(positive=True), "relative tolerance of the search"),
            HORIZON,
        ),
        run=partial(run, structure),
    )


HAMMERSTEIN = _method("hammerstein", "Hammerstein model y = G(q)·f(u) + e: a static curve "
                      "(dead zone, saturation, …) before a linear block, jointly by output error")
WIENER = _method("wiener", "Wiener model y = g(G(q)·u) + e: a linear block before a static "
                 "curve (|x|, saturation, …), jointly by output error")
HAMMERSTEIN_WIENER = _method("hammerstein-wiener", "Hammerstein–Wiener model y = g(G(q)·f(u)) "
                             "+ e: static curves on both sides of a linear block")


# -- private ---------------------------------------------------------------------------------


def _truth_from_spec(spec: ExperimentSpec, names: Sequence[str]) -> dict[str, float] | None:
    name = report_options(spec.report).get("truth")
    if name is None:
        return None
    base = spec.source.parent if spec.source else Path.cwd()
    return read_truth(base / name, list(names)) or None


def _shape_dict(shape: StaticNonlinearity | None) -> dict[str, Any] | None:
    if shape is None:
        return None
    out: dict[str, Any] = {"kind": shape.kind,
                           "parameters": dict(zip(shape.names, shape.parameters.tolist(),
                                                  strict=True))}
    if isinstance(shape, PiecewiseLinear):
        out["breakpoints"] = list(shape.breakpoints)
    return out


def _curves(estimate: Estimate, u: np.ndarray) -> tuple[StaticCurve, ...]:
    """Each static block over its input's range, ±σ by the delta method."""
    model = estimate.model
    try:
        _v, x, _ = model.signals(u)
    except ServoidError:
        return ()
    out = []
    prefixes = ("input.", "output.") if model.structure == "hammerstein-wiener" else ("", "")
    blocks = (("input", model.input_nonlinearity, u, prefixes[0]),
              ("output", model.output_nonlinearity, x, prefixes[1]))
    for block, shape, signal, prefix in blocks:
        if shape is None:
            continue
        index = [estimate.names.index(prefix + name) for name in shape.names]
        grid = np.linspace(float(np.min(signal)), float(np.max(signal)), 400)
        jac = shape.jacobian(grid)
        cov = estimate.covariance[np.ix_(index, index)]
        std = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", jac, cov, jac), 0.0, None))
        out.append(StaticCurve(block, shape.kind, grid, shape(grid), std))
    return tuple(out)


def _model_text(result: BlockResult) -> str:
    est = result.estimate
    o = est.options
    scale = ("the linear block's static gain is fixed to 1 (the static curve carries the gain)"
             if o.get("unit_gain") else "the static curve has unit slope (the linear block "
             "carries the gain)")
    return (f"{result.title} by output error (joint least squares over every parameter, the "
            f"linear block's initial state estimated) on {est.n_samples} samples; residual "
            f"variance {est.noise_variance:.4g}; status {est.status}; {o.get('nfev')} "
            f"evaluations. Scale convention: {scale}. Covariance σ̂²(JᵀJ)⁻¹ at the minimum, "
            "right for white output noise.")


def _plot_validation(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_validation(report, path, overwrite=overwrite)


def _plot_residuals(report: ValidationReport, path: Path, overwrite: bool) -> None:
    plot_residuals(report, path, overwrite=overwrite)


def _plot_curves(curves: Sequence[StaticCurve], title: str, path: Path,
                 overwrite: bool) -> None:
    fig = new_figure((5.0 * len(curves), 3.6))
    for k, curve in enumerate(curves):
        ax = fig.add_subplot(1, len(curves), k + 1)
        ax.plot(curve.x, curve.value, color="C0", lw=1.5, label=f"{curve.kind}")
        ax.fill_between(curve.x, curve.value - 2 * curve.std, curve.value + 2 * curve.std,
                        color="C0", alpha=0.2, lw=0, label="±2σ")
        ax.set_xlabel(f"{curve.block} block input")
        ax.set_ylabel(f"{curve.block} block output")
        ax.set_title(f"{curve.block}: {curve.kind}")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, overwrite)
