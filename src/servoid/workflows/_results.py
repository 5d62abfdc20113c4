"""A ``results.json`` read back: its models, its parameters, its verdicts; a report re-made.

:func:`load_results` turns what ``servoid identify`` wrote into objects —
the identified models (the black-box model ``G``; each closed-loop
approach's continuous plant and closed loop) and the parameter summary with
standard deviations and intervals. :func:`rerender` writes the report of a
results folder again from the run's own experiment file, after checking
that every input is byte-for-byte the one the run read (its manifest's
SHA-256), so the new report describes the same data; it reads only files
in the run's folder or named by its caller.

A grey-box run (``method = "greybox"``) holds a model that calls the user's
Python file: it is rebuilt, and the run re-rendered, only with
``allow_code=True`` (``--allow-code``), and only while that file still has
the SHA-256 recorded at the fit.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._checks import as_bool, as_path, read_json
from .._errors import (
    FileFormatError,
    MissingFileError,
    OptionError,
    OutputExistsError,
    ServoidError,
)
from ._common import sha256, spec_inputs
from ._results_check import check_results, read_manifest
from ._summary import RecordSummary, summarise

__all__ = ["Results", "greybox_record", "load_results", "rerender"]

_FIX = "write it again with servoid identify"


@dataclass(frozen=True)
class Results:
    """What a ``results.json`` holds, as objects.

    Attributes
    ----------
    path : Path
        The file.
    data : mapping
        Its whole content.
    models : mapping
        Name → model (``G`` for a black-box method, a NarxModel for
        ``narx``, a BlockModel for ``hammerstein``, ``wiener`` and
        ``hammerstein-wiener``, an OdeModel for ``greybox``;
        ``<approach>_plant`` and
        ``<approach>_closed_loop`` for the closed-loop method); empty when
        the method's result is not a model servoid can rebuild.  Each
        replays on a new record: ``validate(results.models["G"], record)``.
    summary : RecordSummary
        Parameters with std and 95 % intervals, validation fit, verdicts.
    """

    path: Path
    data: Mapping[str, Any]
    models: Mapping[str, Any] = field(default_factory=dict)
    summary: RecordSummary = field(default_factory=lambda: RecordSummary(()))

    def __repr__(self) -> str:
        return (f"<Results {self.path.name}: {len(self.summary.parameters)} parameters, "
                f"models {', '.join(self.models) or 'none'}>")


def load_results(path: str | Path, *, allow_code: bool = False) -> Results:
    """Read a ``results.json`` back into models and parameters.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``results.json`` that ``servoid identify`` wrote.
    allow_code : bool
        Let a grey-box run's model run the user's Python file it names
        (checked first against the SHA-256 recorded at the fit); without
        it the results of a grey-box run are refused and nothing runs.

    Returns
    -------
    Results
        Its models (rebuilt with the floats of the file, so bit for bit
        the ones the run fitted), parameters and verdicts.

    Raises
    ------
    MissingFileError
        No such file.
    FileFormatError
        Not JSON, not a servoid results file, or a model in it is damaged.
    OptionError
        A grey-box run without ``allow_code=True`` (the message names its
        Python file).
    ModelError
        A grey-box run whose Python file changed since (both SHA-256 named).
    """
    path = as_path("results file", path)
    allow_code = as_bool("allow_code", allow_code)
    data = read_json(path, "results file")
    models = _models(data, path, allow_code)
    return Results(path, data, models, summarise(data))


def greybox_record(path: str | Path) -> dict[str, Any] | None:
    """A grey-box run's model file data, read without running any code.

    Parameters
    ----------
    path : str or pathlib.Path
        A ``results.json``.

    Returns
    -------
    dict or None
        The servoid model file of the fitted ODE (what
        :func:`servoid.models.save_model` writes for it), checked; None
        when the run is not a grey-box run (or predates saved grey-box
        models).
    """
    path = as_path("results file", path)
    data = read_json(path, "results file")
    _check_results(data, path)
    model = data.get("model")
    record = model.get("model_file") if isinstance(model, Mapping) and \
        model.get("type") == "greybox_ode" else None
    if not isinstance(record, Mapping):
        return None
    from ..estimate import OdeModel

    if record.get("type") != "OdeModel":
        raise FileFormatError(f"{path}: model.model_file is not the record of an OdeModel; the "
                              f"file is damaged: {_FIX}")
    OdeModel.check_record(record, where=f"results file {path}")
    return dict(record)


def rerender(results: str | Path, out: str | Path | None = None, *,
             experiment: str | Path | None = None, allow_code: bool = False,
             overwrite: bool = False) -> Any:
    """Write a run's report again from its unchanged inputs.

    Only files inside the run's folder, or named by the caller, are read:
    the experiment file ``results.json`` names is used as is only when it
    lies in the run's folder (with every file it reads), or when the run's
    folder is that file's default results folder (``<stem>-results`` beside
    ``<stem>.toml``: then the folder holding both is the run's); one
    elsewhere must be named (``experiment``, ``--experiment``), so an edited
    results file cannot make servoid run an experiment of its choosing.  Every input
    must have the SHA-256 the run's manifest records; they are read once,
    from the paths resolved here, whatever the working directory.

    Parameters
    ----------
    results : path
        ``results.json`` of the run (its folder holds ``manifest.json``).
    out : path, optional
        Folder for the new report and results; default the run's own folder
        (its files, as its complete manifest lists them, are replaced).
    experiment : path, optional
        The run's experiment file (needed when it is not in the run's
        folder); it must be the file the run read, byte for byte.
    allow_code : bool
        Let a grey-box run execute its Python model file again (the
        identification is re-run); without it such a run is refused.  The
        code that runs is the bytes whose SHA-256 was checked.
    overwrite : bool
        Replace files in ``out`` that are not the run's own.

    Raises
    ------
    OptionError
        A grey-box run without ``allow_code=True`` (its file is named), or
        an experiment file outside the run's folder not named by the caller.
    OutputExistsError
        An input changed since the run (the message names it; for a
        grey-box run the Python file too): run ``servoid identify``
        instead; or a file in ``out`` that is not the run's own.
    """
    from ._run import _identify

    allow_code = as_bool("allow_code", allow_code)
    overwrite = as_bool("overwrite", overwrite)
    path = as_path("results file", results).resolve()
    folder = path.parent
    data = read_json(path, "results file")
    _check_results(data, path)
    recorded = data.get("experiment_file") or data.get("campaign_file")
    if not isinstance(recorded, str) or not recorded:
        raise FileFormatError(f"{path} does not name its experiment file; {_FIX}")
    code = _code_files(data)
    method = _runs_code(data)
    if method is not None and not allow_code:
        listed = " and ".join(sorted({str(f) for f, _ in code})) or \
            "the file its [identify] model names"
        raise OptionError(
            f"{path} is a run of method = \"{method}\", whose model is Python code ({listed}), "
            "and re-rendering runs the identification again: check the file, then run servoid "
            "report with --allow-code (allow_code=True in servoid.workflows.rerender)")
    inputs = _manifest_inputs(folder)
    named = experiment is not None
    source = (as_path("experiment", experiment).resolve() if named
              else _recorded_experiment(recorded, inputs, path))
    # the default layout, known from the folder's own path (not from what results.json says):
    # <dir>/<stem>.toml wrote <dir>/<stem>-results, and <dir> holds the run's inputs
    base = (folder.parent if not named and source.parent == folder.parent
            and folder.name == f"{source.stem}-results" else folder)
    if not named and not source.is_relative_to(base):
        raise OptionError(
            f"{path} names its experiment file {source}, outside the run's folder {folder}; "
            "servoid report reads only files in the run's folder or named on its command line: "
            f"check that it is the file you mean, then pass --experiment {source} "
            "(experiment= in servoid.workflows.rerender)")
    spec = _spec_from_checked(source, inputs, data, path)
    checked = {os.path.realpath(source): inputs[source]}  # hashed here once, not again
    for file in spec_inputs(spec):
        file = file.resolve()
        if not named and not file.is_relative_to(base):
            raise OptionError(
                f"the experiment file {source} reads {file}, outside the run's folder {base}; "
                "servoid report reads only files in the run's folder or named on its command "
                f"line: pass --experiment {source} if it is the file you mean")
        _check_input(file, inputs, source)
        checked[os.path.realpath(file)] = inputs[file]
    for file, digest in code:  # the model code is an input the manifest does not list
        if not named and not file.resolve().is_relative_to(base):
            raise OptionError(
                f"{path} names the model code {file}, outside the run's folder {base}; "
                "servoid report runs only code in the run's folder or named by the experiment "
                f"file on its command line: pass --experiment {source}")
        if not file.is_file() or sha256(file) != digest:
            raise OutputExistsError(
                f"{file} is not the model file this run fitted (missing or changed since its "
                f"SHA-256 {digest}): the report would describe other code; run servoid "
                f"identify {source} --allow-code instead")
    pinned = {str(f.resolve()): d for f, d in code}
    target = folder if out is None else as_path("out", out)
    own = out is None or target.resolve() == folder
    return _identify(spec, target, overwrite=overwrite, write=True, truth=None,
                     allow_outside=True, max_bytes=None, allow_code=allow_code, own_run=own,
                     code_sha256=pinned if allow_code else None, digests=checked)


def _manifest_inputs(folder: Path) -> dict[Path, str]:
    """The run's inputs as its manifest lists them: absolute path → SHA-256."""
    from ._run import MANIFEST

    manifest_path = folder / MANIFEST
    inputs = dict(read_manifest(manifest_path))  # every field checked, named when damaged
    relative = next((p for p in inputs if not p.is_absolute()), None)
    if relative is not None:
        raise FileFormatError(f"{manifest_path} lists the input {relative} by a relative path; "
                              f"a run records its inputs resolved; {_FIX}")
    return inputs


def _recorded_experiment(recorded: str, inputs: Mapping[Path, str], path: Path) -> Path:
    """The experiment file a results file names, as the manifest recorded it (absolute).

    A run records the path it was given, perhaps relative to a working
    directory that is gone; the manifest records every input resolved.
    The experiment file is the manifest input the recorded path ends with,
    so the answer does not depend on where the report is made.
    """
    wanted = Path(recorded)
    if wanted.is_absolute():
        return wanted.resolve()
    tail = [p for p in wanted.parts if p not in (".", "..")]
    found = [p for p in inputs if list(p.parts[-len(tail):]) == tail] if tail else []
    if len(found) != 1:
        raise FileFormatError(
            f"{path} names its experiment file as {recorded!r}, relative to a folder it does not "
            "record, and its manifest lists "
            f"{'no' if not found else 'more than one'} input of that name: pass the experiment "
            "file with --experiment (experiment= in servoid.workflows.rerender)")
    return found[0]


def _spec_from_checked(source: Path, inputs: Mapping[Path, str], data: Mapping[str, Any],
                       path: Path) -> Any:
    """The experiment file parsed from the very bytes whose SHA-256 was checked."""
    import tomllib

    from ..data import ExperimentSpec

    try:
        text = source.read_bytes()
    except OSError:
        raise MissingFileError(f"{source}: no such experiment file; pass the file the run read "
                               "with --experiment") from None
    digest = hashlib.sha256(text).hexdigest()
    if inputs.get(source) != digest:
        raise OutputExistsError(
            f"{source} is not the experiment file this run read (missing from its manifest or "
            f"changed since): the report would describe another experiment; run servoid "
            f"identify {source} instead")
    try:
        doc = tomllib.loads(text.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        # RecursionError: nested too deep; ValueError: an integer past Python's digit limit
        detail = str(exc).split("; use sys.")[0] or type(exc).__name__
        raise FileFormatError(f"{source}: not a valid TOML file ({detail})") from None
    return ExperimentSpec.from_dict(doc, base_dir=source.parent, source=source)


def _check_input(file: Path, inputs: Mapping[Path, str], source: Path) -> None:
    if file not in inputs or not file.is_file() or sha256(file) != inputs[file]:
        raise OutputExistsError(
            f"{file} is not the file this run read (missing from its manifest, or changed "
            f"since): the report would describe other data; run servoid identify {source} "
            "instead")


def _runs_code(data: Mapping[str, Any]) -> str | None:
    """The method of a results file when its model runs the user's code (else None)."""
    from ._methods import METHODS

    name = data.get("method")
    if not isinstance(name, str) or name not in METHODS:
        return None
    return name if METHODS[name].runs_code else None


def _check_results(data: object, path: Path) -> None:
    check_results(data, path)  # every field the readers below use, named when damaged


def _code_files(data: Mapping[str, Any]) -> list[tuple[Path, str]]:
    """The Python files a grey-box run's model calls, with their recorded SHA-256."""
    model = data.get("model")
    record = model.get("model_file") if isinstance(model, Mapping) else None
    if not isinstance(record, Mapping):
        return []
    return [(Path(record[file]), record[digest])
            for file, digest in (("model_file", "model_sha256"), ("output_file", "output_sha256"))
            if isinstance(record.get(file), str) and isinstance(record.get(digest), str)]


def _models(data: object, path: Path, allow_code: bool = False) -> dict[str, Any]:
    """Name → servoid model of every model a results file holds."""
    _check_results(data, path)
    assert isinstance(data, Mapping)
    models: dict[str, Any] = {}
    if isinstance(data.get("model"), Mapping):
        estimate = data.get("estimate")
        variance = estimate.get("noise_variance") if isinstance(estimate, Mapping) else None
        model = _from_model_dict(data["model"], path, variance, allow_code)
        if model is not None:
            models["G"] = model
    approaches = data.get("approaches")
    if isinstance(approaches, Mapping):
        for approach, result in approaches.items():
            label = re.sub(r"\W", "_", str(approach))
            for key, suffix in (("plant_continuous", "plant"), ("closed_loop", "closed_loop")):
                tf = result.get(key) if isinstance(result, Mapping) else None
                if tf is not None:
                    models[f"{label}_{suffix}"] = _build(
                        path, f"approaches.{approach}.{key}", "TransferFunction",
                        num=tf.get("num"), den=tf.get("den"), dt=tf.get("dt"))
    return models


def _from_model_dict(model: Mapping[str, Any], path: Path, variance: object,
                     allow_code: bool = False) -> Any:
    kind = model.get("type")
    if kind == "polynomial_state_space":  # a PnlssModel: its model file record inside
        record = model.get("model_file")
        if not isinstance(record, Mapping):
            raise FileFormatError(f"{path}: model.model_file is missing; the file is damaged: "
                                  f"{_FIX}")
        from ..models import model_from_record

        return model_from_record(record, where=f"results file {path}")
    if kind == "greybox_ode":
        record = model.get("model_file")
        if not isinstance(record, Mapping):
            return None  # a run that predates saved grey-box models: nothing to rebuild
        from ..models import model_from_record

        return model_from_record(record, where=f"results file {path}", allow_code=allow_code)
    if kind == "transfer_function":
        return _build(path, "model", "TransferFunction", num=model.get("num"),
                      den=model.get("den"), dt=model.get("dt"), delay=model.get("delay", 0.0))
    if kind == "state_space":
        return _build(path, "model", "StateSpace", **{k: model.get(k) for k in "ABCD"},
                      dt=model.get("dt"))
    if kind == "polynomial":
        return _build(path, "model", "PolynomialModel", a=model.get("a"),
                      b=tuple(model.get("b") or ()), nk=tuple(model.get("nk") or ()),
                      dt=model.get("dt"), c=model.get("c"), d=model.get("d"),
                      f=tuple(model.get("f") or ()),
                      noise_variance=variance if isinstance(variance, float) else 0.0)
    if kind == "narx":
        return _build(path, "model", "NarxModel", terms=model.get("terms"),
                      coefficients=model.get("coefficients"), dt=model.get("dt"),
                      covariance=_finite_matrix(model.get("covariance")),
                      noise_variance=model.get("noise_variance", 0.0),
                      input_names=tuple(model.get("inputs") or ("u",)),
                      output_name=model.get("output", "y"),
                      output_unit=model.get("output_unit", ""),
                      input_units=tuple(model.get("input_units") or ()))
    if kind == "block":
        from ..nonlinear import StaticNonlinearity

        linear = model.get("linear")
        fields: dict[str, Any] = {
            "structure": model.get("structure"), "dt": model.get("dt"),
            "offset": model.get("offset", 0.0),
            "linear": _from_model_dict(linear, path, None) if isinstance(linear, Mapping)
            else None}
        for key in ("input_nonlinearity", "output_nonlinearity"):
            shape = model.get(key)
            try:
                fields[key] = None if shape is None else StaticNonlinearity.from_record(shape)
            except ServoidError as exc:
                raise FileFormatError(f"{path}: model.{key} is not a valid static block ({exc}); "
                                      f"the file is damaged: {_FIX}") from None
        return _build(path, "model", "BlockModel", **fields)
    return None


def _finite_matrix(value: object) -> object:
    """A covariance as written, or None when results.json nulled a non-finite entry."""
    if isinstance(value, list) and any(
            not isinstance(row, list) or any(v is None for v in row) for row in value):
        return None
    return value


def _build(path: Path, where: str, kind: str, **fields: Any) -> Any:
    from .. import models, nonlinear

    home = nonlinear if kind in ("NarxModel", "BlockModel") else models
    try:
        return getattr(home, kind)(**fields)
    except (ServoidError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{path}: {where} is not a valid {kind} ({exc}); the file is "
                              f"damaged: {_FIX}") from None


