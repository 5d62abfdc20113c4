"""Identify from a TOML experiment file: spec → method → result → files."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .._errors import OptionError, check_option
from ..data import ExperimentSpec, load_experiment_spec
from ._common import check_outputs, report_options
from ._methods import METHODS
from ._registry import Identification, Method

__all__ = ["get_method", "identify", "method_names", "write_results"]

# [loop] describes the rig (what is known about its feedback) and may stay whatever the method;
# a [validation] record that a method cannot use would be silently ignored, so it is refused.
_OPTIONAL_TABLES = ("validation",)


def method_names() -> tuple[str, ...]:
    """Names ``[identify] method`` accepts, in registry order."""
    return tuple(METHODS)


def get_method(name: str) -> Method:
    """Return the registered method called ``name``.

    Raises
    ------
    OptionError
        No such method; the message lists the registered ones.
    """
    check_option("[identify] method", name, METHODS)
    return METHODS[name]


def identify(
    spec: ExperimentSpec | str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    overwrite: bool = False,
    write: bool = True,
    truth: Mapping[str, float] | None = None,
) -> Any:
    """Run the identification an experiment file describes.

    Loads the data, fits the model of ``[identify] method`` (see
    ``servoid methods`` for every method and its keys), validates it on
    held-back or separate validation data, and writes ``results.json``,
    the figures and ``report.html`` into a folder.

    Parameters
    ----------
    spec : ExperimentSpec or path
        The experiment (a TOML file path or a loaded spec).
    out : path, optional
        Results folder; default ``[report] folder`` or ``<toml name>-results``
        beside the TOML file.
    overwrite : bool
        Replace files of an earlier run in the folder (inputs never).
    write : bool
        Write the folder (False: only compute).
    truth : mapping, optional
        Known parameters to compare with (virtual-bench rehearsals);
        default ``[report] truth`` (a JSON file).

    Returns
    -------
    Identification
        The method's result (e.g. :class:`IdentificationResult` for the
        black-box methods), with ``folder`` and ``files`` when written.
    """
    if not isinstance(spec, ExperimentSpec):
        spec = load_experiment_spec(spec)
    method = get_method(spec.identify.get("method", "arx"))
    options = method.parse(spec.identify)
    _check_tables(spec, method)
    report_options(spec.report)
    folder = _folder(spec, out) if write else None
    result = method.run(spec, options, truth)
    if folder is None:
        return result
    return write_results(result, folder, overwrite=overwrite)


def write_results(result: Identification, folder: str | os.PathLike[str], *,
                  overwrite: bool = False) -> Any:
    """Write a result's figures, ``report.html`` and ``results.json``.

    Nothing is written until every target is known to be free (or
    ``overwrite``) and none is an input of the run; ``results.json`` is
    written last, so its presence marks a complete run.

    Returns
    -------
    Identification
        The same result with ``folder`` and ``files`` set.
    """
    folder = Path(folder)
    figures = result.figures()
    targets = {name: folder / name for name in ("results.json", "report.html", *figures)}
    check_outputs(list(targets.values()), list(result.inputs()), overwrite)
    folder.mkdir(parents=True, exist_ok=True)
    for name, writer in figures.items():
        writer(targets[name], overwrite)
    from ..report import write_html, write_json

    write_html(result.page(targets), targets["report.html"], overwrite=overwrite)
    write_json(result.to_dict(), targets["results.json"], overwrite=overwrite)
    return dataclasses.replace(result, folder=folder,  # type: ignore[type-var]
                               files=tuple(targets.values()))


def _check_tables(spec: ExperimentSpec, method: Method) -> None:
    present = {"validation": bool(spec.validation.files)}
    for table in _OPTIONAL_TABLES:
        if present[table] and table not in method.tables:
            raise OptionError(
                f"the experiment file has a [{table}] table, which method = \"{method.name}\" "
                f"does not use; remove it or choose a method that reads it"
            )


def _folder(spec: ExperimentSpec, out: str | os.PathLike[str] | None) -> Path:
    if out is not None:
        return Path(out)
    report = report_options(spec.report)
    base = spec.source.parent if spec.source else Path.cwd()
    if "folder" in report:
        return base / report["folder"]
    stem = spec.source.stem if spec.source else "experiment"
    return base / f"{stem}-results"
