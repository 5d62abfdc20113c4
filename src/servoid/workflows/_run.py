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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .. import __version__
from .._checks import as_bool, as_mapping, as_path, read_json, type_error
from .._errors import (
    FileFormatError,
    OptionError,
    OutputExistsError,
    ServoidWarning,
)
from .._progress import stage
from .._warn import warn
from ..data import ExperimentSpec, load_experiment_spec
from ._common import check_outputs, check_sizes, report_options, sha256, spec_inputs
from ._methods import get_method, method_names
from ._provenance import provenance
from ._registry import Identification, Method
from ._summary import verdict_section

__all__ = ["MANIFEST", "get_method", "identify", "method_names", "write_results"]

#: The file a complete run writes last.
MANIFEST = "manifest.json"
# what servoid._atomic names its temporary files: .<target>.<12 hex>.tmp
_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp$")

# [loop] describes the rig (what is known about its feedback) and may stay whatever the method;
# a [validation] record that a method cannot use would be silently ignored, so it is refused.
_OPTIONAL_TABLES = ("validation",)
# methods that fit every output channel when [identify] output is not set
_MULTI_OUTPUT = ("n4sid",)


def identify(
    spec: ExperimentSpec | str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    overwrite: bool = False,
    write: bool = True,
    truth: Mapping[str, float] | None = None,
    allow_outside: bool = False,
    max_bytes: int | None = None,
    allow_code: bool = False,
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
    max_bytes : int, optional
        Refuse a rig file (estimation or validation record) larger than
        this before reading anything (``--max-bytes``); default no limit
        on the file.
    allow_code : bool
        Let the run execute Python code the experiment file names
        (``method = "greybox"``: ``model = "file.py:rhs"``); without it
        such a run stops before reading the file (``--allow-code``).

    Returns
    -------
    Identification
        The method's result (e.g. :class:`IdentificationResult` for the
        black-box methods), with ``folder`` and ``files`` when written.
    """
    overwrite = as_bool("overwrite", overwrite)
    write = as_bool("write", write)
    allow_outside = as_bool("allow_outside", allow_outside)
    allow_code = as_bool("allow_code", allow_code)
    if out is not None:
        out = as_path("out", out)
    if truth is not None:
        truth = as_mapping("truth", truth)
    if not isinstance(spec, ExperimentSpec):
        spec = load_experiment_spec(spec)
    method = get_method(spec.identify.get("method", "arx"))
    options = method.parse(spec.identify)
    if allow_code:  # never an [identify] key: only the caller may let a file run code
        options["allow_code"] = True
    _check_tables(spec, method)
    report = report_options(spec.report)
    if truth is None and "truth" in report and spec.source is not None:
        # read at the end of a run; a missing or malformed file should not cost the run first
        path = spec.source.parent / report["truth"]
        if path.exists() and not path.is_file():
            raise FileFormatError(f"[report] truth = {report['truth']!r} is {path}, a folder; "
                                  "name the JSON file of known values")
        read_json(path, "[report] truth file")
    _check_channels(spec, method, options)
    if max_bytes is not None:
        check_sizes([*spec.data_paths, *spec.validation_paths], max_bytes)
    folder = _folder(spec, out, allow_outside) if write else None
    if folder is not None:  # before a fit that may take minutes, what can be known now
        _check_folder(folder, spec, overwrite)
    with stage(f"identifying ({method.name})"):
        result = method.run(spec, options, truth)
    if folder is None:
        return result
    with stage("writing the figures and the report"):
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
    if not (dataclasses.is_dataclass(result) and not isinstance(result, type)
            and all(callable(getattr(result, a, None))
                    for a in ("figures", "inputs", "to_dict", "page"))):
        raise type_error("result", result, "an identification result (what "
                         "servoid.workflows.identify(..., write=False) returns)")
    folder = as_path("folder", folder)
    overwrite = as_bool("overwrite", overwrite)
    figures = result.figures()
    targets = {name: folder / name for name in ("results.json", "report.html", *figures)}
    manifest = folder / MANIFEST
    check_outputs([*targets.values(), manifest], list(result.inputs()), overwrite=True)
    _sweep_temporary(folder)
    left = [p for p in (*targets.values(), manifest) if p.exists()]
    interrupted = bool(left) and not _complete(manifest)
    if interrupted and not overwrite:
        warn(f"{folder} holds an interrupted earlier run (no complete {MANIFEST}); its "
             "files are replaced", ServoidWarning)
    check_outputs([*targets.values(), manifest], list(result.inputs()),
                  overwrite or interrupted)
    replace = overwrite or interrupted
    made = _missing_folders(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if replace and manifest.exists():
        manifest.unlink()  # from here on the folder is incomplete until the new manifest lands
    new = [p for p in targets.values() if not p.exists()]
    try:
        for name, writer in figures.items():
            writer(targets[name], replace)
        from ..report import write_html, write_json

        write_json(result.to_dict(), targets["results.json"], overwrite=replace)
        page = result.page(targets)
        done = {n: p for n, p in targets.items() if n != "report.html"}
        page = dataclasses.replace(page, meta=(*page.meta, *provenance(result, done)),
                                   sections=(verdict_section(result.to_dict()), *page.sections))
        write_html(page, targets["report.html"], overwrite=replace)
        write_json(_manifest(result, targets), manifest, overwrite=False)
    except BaseException:
        # no half-written results: what this run created goes (files it replaced are
        # already gone, and the missing manifest marks the folder incomplete)
        for path in new:
            path.unlink(missing_ok=True)
        for path in reversed(made):
            if path.is_dir() and not any(path.iterdir()):
                path.rmdir()
        raise
    return dataclasses.replace(result, folder=folder,  # type: ignore[type-var]
                               files=(*targets.values(), manifest))


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and its parents that do not exist yet, outermost first."""
    missing = []
    for path in (folder, *folder.parents):
        if path.exists():
            break
        missing.append(path)
    return missing[::-1]


def _check_folder(folder: Path, spec: ExperimentSpec, overwrite: bool) -> None:
    """Refuse a results folder that cannot take this run, before the run.

    The figure names depend on the result; the fixed names, the inputs and
    an earlier complete run are known now.  :func:`write_results` checks
    everything again once the result is there.
    """
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(
            f"{folder} is a file, not a folder; results go into a folder: pass --out <folder> "
            "(or change [report] folder)"
        )
    fixed = [folder / name for name in ("results.json", "report.html", MANIFEST)]
    check_outputs(fixed, list(spec_inputs(spec)), overwrite=True)
    if not overwrite and (folder / MANIFEST).exists() and _complete(folder / MANIFEST):
        check_outputs([folder / MANIFEST], [], overwrite=False)


def _check_channels(spec: ExperimentSpec, method: Method, options: Mapping[str, Any]) -> None:
    """The channels ``[identify]`` input/output name exist in ``[channels]``."""
    names = [c.name for c in spec.channels]
    listed = ", ".join(f"{c.name} (role {c.role})" for c in spec.channels)
    output = options.get("output")
    for name in [output] if isinstance(output, str) else list(output or []):
        if name not in names:
            raise OptionError(
                f"[identify] output = {name!r} is not a channel of the experiment file; its "
                f"[channels] are {listed}"
            )
    for key in ("position", "force", "reference"):  # a channel, or a role some channel has
        value = options.get(key)
        if isinstance(value, str) and value not in names and \
                not any(c.role == value for c in spec.channels):
            raise OptionError(
                f"[identify] {key} = {value!r} is not a channel of the experiment file; its "
                f"[channels] are {listed}"
            )
    role = options.get("input")
    if isinstance(role, str) and role in ("u", "r") and role not in names and \
            not any(c.role == role for c in spec.channels):
        raise OptionError(
            f"[identify] input = {role!r} needs a channel with role = {role!r}, and no "
            f"[channels.<name>] table has one (the channels are {listed}): set its role, or "
            f"choose input = {'r' if role == 'u' else 'u'!r}"
        )
    if "output" in method.keys and output is None:
        outputs = [c.name for c in spec.channels if c.role == "y"]
        if not outputs:
            raise OptionError(
                f"method = \"{method.name}\" fits a measured output, and no [channels.<name>] "
                f"table has role = \"y\" (the channels are {listed}): set role = \"y\" on the "
                "output channel"
            )
        if len(outputs) > 1 and method.name not in _MULTI_OUTPUT:
            raise OptionError(
                f"the experiment file has {len(outputs)} output channels ({', '.join(outputs)}) "
                f"and method = \"{method.name}\" fits one: set [identify] output = "
                f"\"{outputs[0]}\" (or another of them)"
            )


def _manifest(result: Identification, targets: Mapping[str, Path]) -> dict[str, Any]:
    return {
        "servoid_version": __version__,
        "complete": True,
        "files": [{"name": name, "bytes": path.stat().st_size, "sha256": sha256(path)}
                  for name, path in targets.items()],
        "inputs": [{"path": str(Path(p).resolve()), "sha256": sha256(p)}
                   for p in result.inputs() if p.is_file()],
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
