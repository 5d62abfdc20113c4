"""Identify from a TOML experiment file and write a results folder."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._checks import as_int, as_int_list, as_str, type_error
from .._errors import OptionError, check_option
from ..data import ExperimentSpec, load_experiment_spec
from ..estimate import Estimate, fit_arx, select_arx_order
from ..report import (
    Page,
    Section,
    plot_residuals,
    plot_validation,
    write_html,
    write_json,
)
from ..validate import ValidationReport, validate
from ._closedloop import ClosedLoopIdentification, identify_closed_loop_spec
from ._common import (
    check_outputs,
    parameter_table,
    report_options,
    sha256,
    validation_section,
)
from ._inverse import InverseDynamicsIdentification, identify_inverse_dynamics_spec
from ._pneumatic import PneumaticIdentification, identify_pneumatic_spec

__all__ = ["IdentificationResult", "identify"]

METHODS = ("arx", "closedloop", "inverse-dynamics", "pneumatic-multistep")
_IDENTIFY_KEYS = ("method", "input", "output", "na", "nb", "nk", "criterion", "horizon")
_ORDER_MINIMUM = {"na": 0, "nb": 1, "nk": 0}


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """What :func:`identify` produced: estimate, validation and files."""

    spec: ExperimentSpec
    estimate: Estimate
    validation: ValidationReport
    folder: Path | None
    files: tuple[Path, ...]

    def __str__(self) -> str:
        lines = [str(self.estimate), str(self.validation)]
        if self.folder:
            lines.append(f"report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        model = self.estimate.model
        poles = np.roots(model.a) if model.a.size > 1 else np.empty(0)
        return {
            "servoid_version": __version__,
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": sha256(self.spec.data_path),
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
    truth: Mapping[str, float] | None = None,
) -> (
    IdentificationResult
    | ClosedLoopIdentification
    | InverseDynamicsIdentification
    | PneumaticIdentification
):
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
    truth : mapping, optional
        Known physical parameters (K, omega_hp, delta_hp) to compare with,
        for rehearsals on a virtual bench; default ``[report] truth`` (a JSON file).

    Returns
    -------
    IdentificationResult, ClosedLoopIdentification, InverseDynamicsIdentification or PneumaticIdentification
        By ``[identify] method``: ``"arx"``, ``"closedloop"`` (see
        :func:`~servoid.workflows.identify_closed_loop_spec` for its keys),
        ``"inverse-dynamics"`` (see
        :func:`~servoid.workflows.identify_inverse_dynamics_spec`) or
        ``"pneumatic-multistep"`` (see
        :func:`~servoid.workflows.identify_pneumatic_spec`).

    Notes
    -----
    ``[identify]`` keys for ``method = "arx"``: ``input`` (``"u"`` or ``"r"``),
    ``output``, ``na``, ``nb``, ``nk`` (integers, or lists to search a grid),
    ``criterion`` (``"aic"``, ``"fpe"``, ``"mdl"``, ``"fit"``) and ``horizon``
    (k of the k-step prediction fit).
    """
    if not isinstance(spec, ExperimentSpec):
        spec = load_experiment_spec(spec)
    method = spec.identify.get("method", "arx")
    check_option("[identify] method", method, METHODS)
    report_options(spec.report)
    folder = _folder(spec, out) if write else None
    if method == "closedloop":
        return identify_closed_loop_spec(spec, folder, overwrite=overwrite, truth=truth)
    if method == "inverse-dynamics":
        return identify_inverse_dynamics_spec(spec, folder, overwrite=overwrite)
    if method == "pneumatic-multistep":
        return identify_pneumatic_spec(spec, folder, overwrite=overwrite)
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
    result = IdentificationResult(spec, estimate, report, None, ())
    if folder is None:
        return result
    files = _write(result, folder, overwrite, unit=validation_data.unit(report.output))
    return IdentificationResult(spec, estimate, report, folder, tuple(files))


def _identify_options(table: Mapping[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(table) - set(_IDENTIFY_KEYS))
    if unknown:
        raise OptionError(
            f"unknown key(s) in [identify]: {', '.join(unknown)}; valid keys are "
            f"{', '.join(_IDENTIFY_KEYS)}"
        )
    options: dict[str, Any] = {"method": "arx", "input": "u", "output": None, "na": 2, "nb": 2,
                               "nk": 1, "criterion": "aic", "horizon": 5}
    options.update({k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in table.items()})
    check_option("[identify] input", options["input"], ("u", "r"))
    check_option("[identify] criterion", options["criterion"], ("aic", "fpe", "mdl", "fit"))
    if options["output"] is not None:
        as_str("output", options["output"], where="[identify]")
    for key, minimum in _ORDER_MINIMUM.items():
        value = options[key]
        if isinstance(value, list):
            options[key] = as_int_list(key, value, min_length=1, minimum=minimum,
                                       where="[identify]")
        elif isinstance(value, int) and not isinstance(value, bool):
            options[key] = as_int(key, value, minimum=minimum, where="[identify]")
        else:
            raise type_error(key, value, "an integer or a list of integers", where="[identify]")
    options["horizon"] = as_int("horizon", options["horizon"], minimum=1, where="[identify]")
    return options


def _folder(spec: ExperimentSpec, out: str | os.PathLike[str] | None) -> Path:
    if out is not None:
        return Path(out)
    report = report_options(spec.report)
    base = spec.source.parent if spec.source else Path.cwd()
    if "folder" in report:
        return base / report["folder"]
    stem = spec.source.stem if spec.source else "experiment"
    return base / f"{stem}-results"


def _write(
    result: IdentificationResult, folder: Path, overwrite: bool, unit: str
) -> list[Path]:
    targets = [folder / "results.json", folder / "validation.png", folder / "residuals.png",
               folder / "report.html"]
    inputs = [result.spec.data_path] + ([Path(result.spec.source)] if result.spec.source else [])
    check_outputs(targets, inputs, overwrite)
    folder.mkdir(parents=True, exist_ok=True)
    plot_validation(result.validation, targets[1], unit=unit, overwrite=overwrite)
    plot_residuals(result.validation, targets[2], overwrite=overwrite)
    write_html(_page(result, targets[1], targets[2]), targets[3], overwrite=overwrite)
    write_json(result.to_dict(), targets[0], overwrite=overwrite)  # last: marks a complete run
    return targets


def _page(result: IdentificationResult, fig_sim: Path, fig_res: Path) -> Page:
    spec, est = result.spec, result.estimate
    o = est.options
    orders = f"na = {o['na']}, nb = {o['nb']}, nk = {o['nk']}"
    data = Section(
        "Experiment",
        paragraphs=(
            (f"Data file {spec.data_path.name} (sha256 {sha256(spec.data_path)[:16]}…), "
            f"input {', '.join(o['inputs'])} ({o['input']}), output {o['output']}."),
        ),
    )
    model = Section(
        "Model",
        paragraphs=(
            (f"ARX ({orders}) by least squares ({o['solver']} route, scaled condition number "
            f"{o['condition']:.3g}) on {est.n_samples} equations; residual variance "
            f"{est.noise_variance:.4g}."),
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


