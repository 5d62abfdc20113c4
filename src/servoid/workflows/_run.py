"""Identify from a TOML experiment file: spec → method → result → files.

A results folder is complete when its ``manifest.json`` — written last —
lists every file with its SHA-256 and every file is there unchanged.

One run owns the folder from before the fit to the manifest
(:func:`servoid._lock.hold_folder`): a second run into it is refused.  The
lock journals the files the run sets out to write, so a run killed half
way leaves a stale lock naming them: the next run replaces those (with a
warning) and deletes the temporary files named with the dead run's token.
Any other file already there — an earlier complete run's, one edited since,
one the user put there — is replaced only with ``--overwrite``, and an
input of the run never.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from .._checks import as_bool, as_mapping, as_path, read_json, type_error
from .._errors import (
    MissingFileError,
    OptionError,
    OutputExistsError,
    ServoidWarning,
)
from .._files import check_input_file
from .._lock import FolderLock, hold_folder
from .._progress import stage
from .._version import __version__
from .._warn import warn
from .._words import option
from ..data import ExperimentSpec, load_experiment_spec
from ._choice import choice_method, is_choice
from ._common import check_outputs, check_sizes, report_options, sha256, spec_inputs
from ._methods import get_method, method_names, method_of
from ._provenance import provenance
from ._registry import CONTRACT, Identification, Method
from ._summary import input_digest

__all__ = ["MANIFEST", "get_method", "identify", "method_names", "write_results"]

#: The file a complete run writes last.
MANIFEST = "manifest.json"

# [loop] describes the rig (what is known about its feedback) and may stay whatever the method;
# a [validation] record that a method cannot use would be silently ignored, so it is refused.
_OPTIONAL_TABLES = ("validation",)


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
    return _identify(spec, out, overwrite=overwrite, write=write, truth=truth,
                     allow_outside=allow_outside, max_bytes=max_bytes, allow_code=allow_code)


def _identify(spec: ExperimentSpec | str | os.PathLike[str], out: Path | None, *,
              overwrite: bool, write: bool, truth: Mapping[str, float] | None,
              allow_outside: bool, max_bytes: int | None, allow_code: bool,
              own_run: bool = False, code_sha256: Mapping[str, str] | None = None,
              digests: Mapping[str, str] | None = None) -> Any:
    """:func:`identify` with its arguments checked, and what only a re-render asks.

    ``own_run`` lets the files of the complete run in the folder be
    replaced (a re-render into the run's own folder); ``code_sha256`` maps
    a grey-box model file (resolved path) to the SHA-256 its code must
    have, checked on the very bytes that run; ``digests`` are the inputs'
    SHA-256 by real path, already computed (a re-render checked them), so
    that each input is hashed once per run.
    """
    if not isinstance(spec, ExperimentSpec):
        spec = load_experiment_spec(spec)
    name = method_of(spec.identify)
    method = choice_method(spec.identify) if is_choice(name) else get_method(name)
    options = method.parse(spec.identify)
    # the other tables of the method's own keys ([loop]), checked like [identify] when read
    options.update(method.parse_tables({name: getattr(spec, name, None) or {}
                                        for name in method.schemas}, options))
    if allow_code:  # never an [identify] key: only the caller may let a file run code
        options["allow_code"] = True
        if code_sha256 is not None:
            options["code_sha256"] = dict(code_sha256)
    _check_tables(spec, method)
    report = report_options(spec.report)
    for key, names, paths in (("[data] file", spec.files, spec.data_paths),
                              ("[validation] file", spec.validation.files, spec.validation_paths)):
        for name, path in zip(names, paths, strict=True):  # the records before the truth file
            try:  # a regular file: a pipe, a device or a loop of links is named, not opened
                check_input_file(path, f"{key} {name!r}")
            except MissingFileError:
                raise MissingFileError(f"{key} {name!r} is {path}: no such file (paths in an "
                                       "experiment file are relative to its folder)") from None
    if truth is None and "truth" in report and spec.source is not None:
        # read at the end of a run; a missing or malformed file should not cost the run first
        path = spec.source.parent / report["truth"]
        read_json(path, "[report] truth file")  # checked before it is read: not a folder or pipe
    _check_channels(spec, method, options)
    if max_bytes is not None:
        check_sizes([*spec.data_paths, *spec.validation_paths], max_bytes)
    if not write:
        with stage(f"identifying ({method.name})"):
            return method.run(spec, options, truth)
    folder = _folder(spec, out, allow_outside)
    _check_folder_path(folder)
    with hold_folder(folder) as lock:  # the folder is this run's until its manifest is written
        # before a fit that may take minutes, what can be known now
        _check_folder(folder, spec, overwrite, lock, own_run)
        with stage(f"identifying ({method.name})"):
            result = method.run(spec, options, truth)
        with stage("writing the figures and the report"):
            return _write(result, folder, overwrite, lock, own_run, digests)


def write_results(result: Identification, folder: str | os.PathLike[str], *,
                  overwrite: bool = False) -> Any:
    """Write a result's figures, report, results and manifest.

    The folder is locked for the writing (a run already writing there is
    refused).  Nothing is written until every target is known to be free,
    or left by an interrupted run of servoid (named in its stale lock), or
    ``overwrite``; an input of the run is never written.
    ``manifest.json`` is written last, so a complete manifest marks a
    complete run.

    Returns
    -------
    Identification
        The same result with ``folder`` and ``files`` set.
    """
    if not (dataclasses.is_dataclass(result) and not isinstance(result, type)
            and all(callable(getattr(result, a, None)) for a in CONTRACT)):
        missing = [a for a in CONTRACT if not callable(getattr(result, a, None))]
        raise type_error("result", result, "an identification result (what "
                         "servoid.workflows.identify(..., write=False) returns"
                         + (f"; this one has no {', '.join(missing)}" if missing and
                            dataclasses.is_dataclass(result) else "") + ")")
    folder = as_path("folder", folder)
    overwrite = as_bool("overwrite", overwrite)
    _check_folder_path(folder)
    with hold_folder(folder) as lock:
        return _write(result, folder, overwrite, lock, False)


def _write(result: Identification, folder: Path, overwrite: bool, lock: FolderLock,
           own_run: bool, digests: Mapping[str, str] | None = None) -> Any:
    """:func:`write_results` in a folder this run holds.

    Each input is hashed once (into the result's ``digests``, which its
    ``results.json``, its page, the provenance and the manifest read), each
    output once, after it is written; nothing is read back.
    """
    table = getattr(result, "digests", None)
    table = table if isinstance(table, dict) else {}
    table.update(digests or {})
    for path in result.inputs():
        if Path(path).is_file():
            input_digest(table, path)
    figures = result.figures()
    targets = {name: folder / name for name in ("results.json", "report.html", *figures)}
    manifest = folder / MANIFEST
    replaced = _refuse_foreign([*targets.values(), manifest], list(result.inputs()), overwrite,
                               lock, own_run)
    if replaced and not overwrite and not own_run:
        warn(f"{folder} holds an interrupted earlier run (its lock names "
             f"{', '.join(sorted(p.name for p in replaced))}); those files are replaced",
             ServoidWarning)
    lock.claim([*targets.values(), manifest])  # a run killed from here on left these half done
    if manifest.exists():
        manifest.unlink()  # from here on the folder is incomplete until the new manifest lands
    new = [p for p in targets.values() if not p.exists()]
    try:
        for name, writer in figures.items():
            writer(targets[name], True)
        from ..report import write_html, write_json

        write_json(result.to_dict(), targets["results.json"], overwrite=True)
        page = result.page(targets)
        done = {n: p for n, p in targets.items() if n != "report.html"}
        written = {n: sha256(p) for n, p in done.items() if p.is_file()}
        page = dataclasses.replace(page, meta=(*page.meta, *provenance(result, done, written)),
                                   sections=(result.verdict().section(), *page.sections))
        write_html(page, targets["report.html"], overwrite=True)
        written["report.html"] = sha256(targets["report.html"])
        write_json(_manifest(result, targets, table, written), manifest, overwrite=False)
    except BaseException:
        # no half-written results: what this run created goes (files it replaced are
        # already gone, and the missing manifest marks the folder incomplete); the folder
        # is this run's, so nothing of another run's is deleted here
        for path in new:
            path.unlink(missing_ok=True)
        raise
    return dataclasses.replace(result, folder=folder,  # type: ignore[type-var]
                               files=(*targets.values(), manifest))


def _check_folder_path(folder: Path) -> None:
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(
            f"{folder} is a file, not a folder; results go into a folder: pass --out <folder> "
            "(or change [report] folder)"
        )


def _check_folder(folder: Path, spec: ExperimentSpec, overwrite: bool, lock: FolderLock,
                  own_run: bool) -> None:
    """Refuse a results folder that cannot take this run, before the run.

    The figure names depend on the result; the fixed names and the inputs
    are known now.  :func:`_write` checks everything again once the result
    is there.
    """
    fixed = [folder / name for name in ("results.json", "report.html", MANIFEST)]
    _refuse_foreign(fixed, list(spec_inputs(spec)), overwrite, lock, own_run)


def _refuse_foreign(targets: Sequence[Path], inputs: Sequence[Path], overwrite: bool,
                    lock: FolderLock, own_run: bool) -> list[Path]:
    """Refuse targets that are inputs, or files servoid did not leave here for this run.

    A target may be replaced when ``overwrite``; when an interrupted run's
    stale lock names it; or, with ``own_run`` (a re-render into the run's
    folder), when the folder's manifest lists it with its SHA-256 of now.
    Returns the existing targets an interrupted run left.
    """
    check_outputs(targets, inputs, overwrite=True)
    if overwrite:
        return []
    folder = lock.folder
    complete = _complete(folder / MANIFEST)
    ours = _unchanged(folder / MANIFEST) if own_run else set()
    left = []
    for path in targets:
        if not path.exists() and not path.is_symlink():
            continue
        if path.name in ours:
            continue
        if path.name in lock.inherited:
            left.append(path)
            continue
        if complete and path.name in _manifest_names(folder / MANIFEST):
            raise OutputExistsError(f"{path} exists from an earlier run; pass "
                                    f"{option('overwrite=True', '--overwrite')} or choose "
                                    "another folder")
        raise OutputExistsError(
            f"{path} exists and is not a file of this run or of an interrupted servoid run "
            "(neither a complete manifest.json nor the lock of a run killed there lists it "
            f"as it is): servoid replaces it only with {option('overwrite=True', '--overwrite')}; "
            "or choose another folder")
    return left


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
        if len(outputs) > 1 and not method.multi_output:
            raise OptionError(
                f"the experiment file has {len(outputs)} output channels ({', '.join(outputs)}) "
                f"and method = \"{method.name}\" fits one: set [identify] output = "
                f"\"{outputs[0]}\" (or another of them)"
            )


def _manifest(result: Identification, targets: Mapping[str, Path], inputs: dict[str, str],
              outputs: Mapping[str, str]) -> dict[str, Any]:
    """The manifest from the digests already computed (inputs by real path, outputs by name)."""
    return {
        "servoid_version": __version__,
        "complete": True,
        "files": [{"name": name, "bytes": path.stat().st_size,
                   "sha256": outputs.get(name) or sha256(path)}
                  for name, path in targets.items()],
        "inputs": [{"path": str(Path(p).resolve()), "sha256": input_digest(inputs, p)}
                   for p in result.inputs() if p.is_file()],
    }


def _complete(manifest: Path) -> bool:
    """True when the manifest parses and every file it lists is there, unchanged."""
    try:
        doc = json.loads(manifest.read_text(encoding="utf-8"))
        files = doc["files"]
        return bool(doc.get("complete")) and all(
            _plain(f["name"]) and (manifest.parent / f["name"]).is_file()
            and sha256(manifest.parent / f["name"]) == f["sha256"] for f in files)
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _unchanged(manifest: Path) -> set[str]:
    """The manifest and the files it lists that still have their SHA-256."""
    try:
        doc = json.loads(manifest.read_text(encoding="utf-8"))
        return {MANIFEST, *(str(f["name"]) for f in doc["files"]
                            if _plain(f["name"]) and (manifest.parent / f["name"]).is_file()
                            and sha256(manifest.parent / f["name"]) == f["sha256"])}
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return set()


def _plain(name: object) -> bool:
    """A manifest entry names a file of the folder itself (never a path out of it)."""
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name \
        and "\\" not in name and "\0" not in name


def _manifest_names(manifest: Path) -> set[str]:
    """The manifest and the files it lists (call after :func:`_complete`)."""
    doc = json.loads(manifest.read_text(encoding="utf-8"))
    return {MANIFEST, *(str(f["name"]) for f in doc["files"])}


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
