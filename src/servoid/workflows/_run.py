"""Identify from a TOML experiment file: spec → method → result → files.

A results folder is complete when its ``manifest.json`` — written last —
lists every file with its SHA-256 and every file is there unchanged.  A
folder with results but no complete manifest holds an interrupted run: its
files are replaced without ``--overwrite`` (with a warning), and temporary
files an earlier run left behind are swept first.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .. import __version__
from .._errors import OptionError, ServoidWarning, check_option
from ..data import ExperimentSpec, load_experiment_spec
from ._common import check_outputs, report_options, sha256
from ._methods import METHODS
from ._registry import Identification, Method

__all__ = ["MANIFEST", "get_method", "identify", "method_names", "write_results"]

#: The file a complete run writes last.
MANIFEST = "manifest.json"
# what servoid._atomic names its temporary files: .<target>.<12 hex>.tmp
_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp$")

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
    allow_outside: bool = False,
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
    allow_outside : bool
        Let ``[report] folder`` point outside the experiment file's folder
        (the command line decides where outputs may go, not the TOML).

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
    folder = _folder(spec, out, allow_outside) if write else None
    result = method.run(spec, options, truth)
    if folder is None:
        return result
    return write_results(result, folder, overwrite=overwrite)


def write_results(result: Identification, folder: str | os.PathLike[str], *,
                  overwrite: bool = False) -> Any:
    """Write a result's figures, report, results and manifest.

    Nothing is written until every target is known to be free (or
    ``overwrite``, or left by an interrupted run) and none is an input of
    the run; ``manifest.json`` is written last, so a complete manifest
    marks a complete run.

    Returns
    -------
    Identification
        The same result with ``folder`` and ``files`` set.
    """
    folder = Path(folder)
    figures = result.figures()
    targets = {name: folder / name for name in ("results.json", "report.html", *figures)}
    manifest = folder / MANIFEST
    check_outputs([*targets.values(), manifest], list(result.inputs()), overwrite=True)
    _sweep_temporary(folder)
    left = [p for p in (*targets.values(), manifest) if p.exists()]
    interrupted = bool(left) and not _complete(manifest)
    if interrupted and not overwrite:
        warnings.warn(f"{folder} holds an interrupted earlier run (no complete {MANIFEST}); its "
                      "files are replaced", ServoidWarning, stacklevel=3)
    check_outputs([*targets.values(), manifest], list(result.inputs()),
                  overwrite or interrupted)
    replace = overwrite or interrupted
    folder.mkdir(parents=True, exist_ok=True)
    if replace and manifest.exists():
        manifest.unlink()  # from here on the folder is incomplete until the new manifest lands
    for name, writer in figures.items():
        writer(targets[name], replace)
    from ..report import write_html, write_json

    write_html(result.page(targets), targets["report.html"], overwrite=replace)
    write_json(result.to_dict(), targets["results.json"], overwrite=replace)
    write_json(_manifest(result, targets), manifest, overwrite=False)
    return dataclasses.replace(result, folder=folder,  # type: ignore[type-var]
                               files=(*targets.values(), manifest))


def _manifest(result: Identification, targets: Mapping[str, Path]) -> dict[str, Any]:
    return {
        "servoid_version": __version__,
        "complete": True,
        "files": [{"name": name, "bytes": path.stat().st_size, "sha256": sha256(path)}
                  for name, path in targets.items()],
        "inputs": [{"path": str(p), "sha256": sha256(p)} for p in result.inputs() if p.is_file()],
    }


def _complete(manifest: Path) -> bool:
    """True when the manifest parses and every file it lists is there, unchanged."""
    try:
        doc = json.loads(manifest.read_text(encoding="utf-8"))
        files = doc["files"]
        return bool(doc.get("complete")) and all(
            (manifest.parent / f["name"]).is_file()
            and sha256(manifest.parent / f["name"]) == f["sha256"] for f in files)
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _sweep_temporary(folder: Path) -> None:
    """Remove temporary files an interrupted earlier run left in ``folder``."""
    if not folder.is_dir():
        return
    for path in folder.iterdir():
        if _TEMPORARY.match(path.name) and path.is_file():
            path.unlink()


def _check_tables(spec: ExperimentSpec, method: Method) -> None:
    present = {"validation": bool(spec.validation.files)}
    for table in _OPTIONAL_TABLES:
        if present[table] and table not in method.tables:
            raise OptionError(
                f"the experiment file has a [{table}] table, which method = \"{method.name}\" "
                f"does not use; remove it or choose a method that reads it"
            )


def _folder(spec: ExperimentSpec, out: str | os.PathLike[str] | None,
            allow_outside: bool = False) -> Path:
    if out is not None:
        return Path(out)
    report = report_options(spec.report)
    base = spec.source.parent if spec.source else Path.cwd()
    if "folder" in report:
        folder = base / report["folder"]
        if not allow_outside and not folder.resolve().is_relative_to(base.resolve()):
            raise OptionError(
                f"[report] folder = {report['folder']!r} points outside the experiment file's "
                f"folder ({base}); where outputs go outside it is the command line's choice: "
                "pass --out <folder> (or --allow-outside)"
            )
        return folder
    stem = spec.source.stem if spec.source else "experiment"
    return base / f"{stem}-results"
