"""Identify from a TOML experiment file and write a results folder."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._errors import DataError, OptionError, OutputExistsError, check_option
from ..data import ExperimentSpec, load_experiment_spec
from ..estimate import Estimate, fit_arx, select_arx_order
from ..report import (
    Figure,
    Page,
    Section,
    Table,
    plot_residuals,
    plot_validation,
    write_html,
    write_json,
)
from ..validate import ValidationReport, validate

__all__ = ["IdentificationResult", "identify"]

METHODS = ("arx",)
_IDENTIFY_KEYS = ("method", "input", "output", "na", "nb", "nk", "criterion", "horizon")
_REPORT_KEYS = ("folder",)


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """What :func:`identify` produced: estimate, validation and files."""

    spec: ExperimentSpec
    estimate: Estimate
    validation: ValidationReport
    folder: Path | None
    files: tuple[Path, ...]

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        model = self.estimate.model
        poles = np.roots(model.a) if model.a.size > 1 else np.empty(0)
        return {
            "servoid_version": __version__,
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": _sha256(self.spec.data_path),
            "estimate": self.estimate.to_dict(),
            "model": {
                "structure": "arx",
                "dt": model.dt,
                "a": model.a,
                "b": [list(b) for b in model.b],
                "nk": list(model.nk),
                "poles": [{"re": p.real, "im": p.imag} for p in poles],
            },
            "validation": self.validation.summary(),
        }


def identify(
    spec: ExperimentSpec | str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    overwrite: bool = False,
    write: bool = True,
) -> IdentificationResult:
    """Run the identification an experiment file describes.

    Loads and preprocesses the data, splits it into estimation and validation
    parts, fits the model of ``[identify]``, validates it on the held-back
    part, and writes ``results.json`` with figures into a folder.

    Parameters
    ----------
    spec : ExperimentSpec or path
        The experiment (a TOML file path or a loaded spec).
    out : path, optional
        Results folder; default ``[report] folder`` or ``<toml name>-results``
        beside the TOML file.
    overwrite : bool
        Replace files of an earlier run in the folder.
    write : bool
        Write the folder (False: only compute).

    Notes
    -----
    ``[identify]`` keys: ``method`` (``"arx"``), ``input`` (``"u"`` or ``"r"``),
    ``output``, ``na``, ``nb``, ``nk`` (integers, or lists to search a grid),
    ``criterion`` (``"aic"``, ``"fpe"``, ``"mdl"``, ``"fit"``) and ``horizon``
    (k of the k-step prediction fit).
    """
    if not isinstance(spec, ExperimentSpec):
        spec = load_experiment_spec(spec)
    options = _identify_options(spec.identify)
    estimation, validation_data = spec.split_data()
    orders = {k: options[k] for k in ("na", "nb", "nk")}
    if any(isinstance(v, list) for v in orders.values()):
        grid = {k: v if isinstance(v, list) else [v] for k, v in orders.items()}
        selection = select_arx_order(
            estimation, grid["na"], grid["nb"], grid["nk"],
            criterion=options["criterion"], validation=validation_data,
            input=options["input"], output=options["output"],
        )
        estimate = selection.estimate
    else:
        estimate = fit_arx(
            estimation, orders["na"], orders["nb"], orders["nk"],
            input=options["input"], output=options["output"],
        )
    report = validate(
        estimate.model, validation_data, input=options["input"],
        output=estimate.options["output"], horizon=options["horizon"],
    )
    folder = None
    files: list[Path] = []
    result = IdentificationResult(spec, estimate, report, None, ())
    if write:
        folder = _folder(spec, out)
        files = _write(result, folder, overwrite, unit=validation_data.unit(report.output))
    return IdentificationResult(spec, estimate, report, folder, tuple(files))


def _identify_options(table: Mapping[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(table) - set(_IDENTIFY_KEYS))
    if unknown:
        raise OptionError(
            f"unknown key(s) in [identify]: {', '.join(unknown)}; valid keys are "
            f"{', '.join(_IDENTIFY_KEYS)}"
        )
    options = {"method": "arx", "input": "u", "output": None, "na": 2, "nb": 2, "nk": 1,
               "criterion": "aic", "horizon": 5}
    options.update({k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in table.items()})
    check_option("[identify] method", options["method"], METHODS)
    check_option("[identify] input", options["input"], ("u", "r"))
    check_option("[identify] criterion", options["criterion"], ("aic", "fpe", "mdl", "fit"))
    for key in ("na", "nb", "nk"):
        values = options[key] if isinstance(options[key], list) else [options[key]]
        if not values or any(isinstance(v, bool) or not isinstance(v, int) for v in values):
            raise DataError(f"[identify] {key} must be an integer or a list of integers, got {options[key]!r}")
    return options


def _folder(spec: ExperimentSpec, out: str | os.PathLike[str] | None) -> Path:
    if out is not None:
        return Path(out)
    report = dict(spec.report)
    unknown = sorted(set(report) - set(_REPORT_KEYS))
    if unknown:
        raise OptionError(f"unknown key(s) in [report]: {', '.join(unknown)}; valid: folder")
    base = spec.source.parent if spec.source else Path.cwd()
    if "folder" in report:
        return base / str(report["folder"])
    stem = spec.source.stem if spec.source else "experiment"
    return base / f"{stem}-results"


def _write(
    result: IdentificationResult, folder: Path, overwrite: bool, unit: str
) -> list[Path]:
    targets = [folder / "results.json", folder / "validation.png", folder / "residuals.png",
               folder / "report.html"]
    inputs = {result.spec.data_path.resolve()}
    if result.spec.source:
        inputs.add(Path(result.spec.source).resolve())
    for path in targets:
        if path.resolve() in inputs:
            raise OutputExistsError(f"refusing to write {path}: it is an input of this run")
        if path.exists() and not overwrite:
            raise OutputExistsError(
                f"{path} exists from an earlier run; pass --overwrite (overwrite=True) or "
                "choose another folder"
            )
    folder.mkdir(parents=True, exist_ok=True)
    plot_validation(result.validation, targets[1], unit=unit, overwrite=overwrite)
    plot_residuals(result.validation, targets[2], overwrite=overwrite)
    write_html(_page(result, targets[1], targets[2]), targets[3], overwrite=overwrite)
    write_json(result.to_dict(), targets[0], overwrite=overwrite)  # last: marks a complete run
    return targets


def parameter_table(estimate: Estimate, caption: str = "") -> Table:
    """Parameters with standard deviation and 95 % interval as a report table."""
    rows = tuple(
        (r.name, f"{r.value:.6g}", f"{r.std:.3g}", f"[{r.ci_low:.6g}, {r.ci_high:.6g}]", r.unit)
        for r in estimate.table(0.95)
    )
    return Table(("parameter", "estimate", "std", "95 % CI", "unit"), rows, caption)


def validation_section(report: ValidationReport, fig_sim: Path, fig_res: Path) -> Section:
    """Metrics, verdicts and figures of a validation as a report section."""
    res = report.residuals
    metrics = Table(
        ("metric", "value"),
        (
            ("samples", str(report.measured.size - report.first)),
            ("simulation fit", f"{report.fit_percent:.2f} %"),
            (f"{report.horizon}-step prediction fit", f"{report.prediction_fit_percent:.2f} %"),
            ("NRMSE", f"{report.nrmse:.4g}"),
            ("RMSE", f"{report.rmse:.4g}"),
            ("VAF", f"{report.vaf:.2f} %"),
            ("relative error", f"{report.relative_error:.3g} %"),
            ("residual whiteness (Ljung–Box p)",
             f"{res.whiteness_pvalue:.3g} → {'white' if res.is_white else 'not white'}"),
            ("input–residual independence (p)",
             "n/a" if res.independence_pvalue != res.independence_pvalue else
             f"{res.independence_pvalue:.3g} → "
             f"{'independent' if res.is_independent else 'correlated'}"),
        ),
        caption="On data not used for fitting",
    )
    return Section(
        "Validation",
        paragraphs=(
            "The model is simulated from the input alone on the held-back data (the first "
            f"{report.first} samples set the initial conditions) and compared with the "
            f"measurement. Residual correlations are tested at {100 * res.confidence:.0f} % "
            "confidence.",
        ),
        tables=(metrics,),
        figures=(
            Figure.from_file(fig_sim, "Measured vs simulated and predicted output"),
            Figure.from_file(fig_res, "Residual autocorrelation and input–residual "
                             "cross-correlation with confidence band"),
        ),
    )


def _page(result: IdentificationResult, fig_sim: Path, fig_res: Path) -> Page:
    spec, est = result.spec, result.estimate
    o = est.options
    orders = f"na = {o['na']}, nb = {o['nb']}, nk = {o['nk']}"
    data = Section(
        "Experiment",
        paragraphs=(
            f"Data file {spec.data_path.name} (sha256 {_sha256(spec.data_path)[:16]}…), "
            f"input {', '.join(o['inputs'])} ({o['input']}), output {o['output']}.",
        ),
    )
    model = Section(
        "Model",
        paragraphs=(
            f"ARX ({orders}) by least squares ({o['solver']} route, scaled condition number "
            f"{o['condition']:.3g}) on {est.n_samples} equations; residual variance "
            f"{est.noise_variance:.4g}.",
        ),
        tables=(parameter_table(est),),
    )
    name = spec.source.name if spec.source else "experiment"
    return Page(
        title=f"Identification report: {name}",
        subtitle="ARX model with parameter uncertainty and validation on held-back data",
        sections=(data, model, validation_section(result.validation, fig_sim, fig_res)),
        meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
              ("data file", str(spec.data_path))),
    )


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
