"""A ``results.json`` read back: its models, its parameters, its verdicts; a report re-made.

:func:`load_results` turns what ``servoid identify`` wrote into objects —
the identified models (the black-box model ``G``; each closed-loop
approach's continuous plant and closed loop) and the parameter summary with
standard deviations and intervals. :func:`rerender` writes the report of a
results folder again from the run's own experiment file, after checking
that every input is byte-for-byte the one the run read (its manifest's
SHA-256), so the new report describes the same data.

A grey-box run (``method = "greybox"``) holds a model that calls the user's
Python file: it is rebuilt, and the run re-rendered, only with
``allow_code=True`` (``--allow-code``), and only while that file still has
the SHA-256 recorded at the fit.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._checks import as_bool, as_path, read_json
from .._errors import FileFormatError, OptionError, OutputExistsError, ServoidError
from ._common import sha256
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
    from ..estimate._ode_model import OdeModel

    if record.get("type") != "OdeModel":
        raise FileFormatError(f"{path}: model.model_file is not the record of an OdeModel; the "
                              f"file is damaged: {_FIX}")
    OdeModel.check_record(record, where=f"results file {path}")
    return dict(record)


def rerender(results: str | Path, out: str | Path | None = None, *,
             allow_code: bool = False) -> Any:
    """Write a run's report again from its unchanged inputs.

    Parameters
    ----------
    results : path
        ``results.json`` of the run (its folder holds ``manifest.json``).
    out : path, optional
        Folder for the new report and results; default the run's own folder
        (its files are replaced).
    allow_code : bool
        Let a grey-box run execute its Python model file again (the
        identification is re-run); without it such a run is refused.

    Raises
    ------
    OptionError
        A grey-box run without ``allow_code=True`` (its file is named).
    OutputExistsError
        An input changed since the run (the message names it; for a
        grey-box run the Python file too): run ``servoid identify``
        instead.
    """
    from ._run import MANIFEST, identify

    allow_code = as_bool("allow_code", allow_code)
    path = as_path("results file", results)
    data = read_json(path, "results file")
    _check_results(data, path)
    source = data.get("experiment_file") or data.get("campaign_file")
    if not source:
        raise FileFormatError(f"{path} does not name its experiment file; {_FIX}")
    code = _code_files(data)
    if data.get("method") == "greybox" and not allow_code:
        listed = " and ".join(sorted({str(f) for f, _ in code})) or \
            "the file its [identify] model names"
        raise OptionError(
            f"{path} is a run of method = \"greybox\", whose model is Python code ({listed}), "
            "and re-rendering runs the identification again: check the file, then run servoid "
            "report with --allow-code (allow_code=True in servoid.workflows.rerender)")
    for read, digest in read_manifest(path.parent / MANIFEST):
        if not read.is_file() or sha256(read) != digest:
            raise OutputExistsError(
                f"{read} is not the file this run read (missing or changed since): the report "
                f"would describe other data; run servoid identify {source} instead")
    for file, digest in code:  # the model code is an input the manifest does not list
        if not file.is_file() or sha256(file) != digest:
            raise OutputExistsError(
                f"{file} is not the model file this run fitted (missing or changed since its "
                f"SHA-256 {digest}): the report would describe other code; run servoid "
                f"identify {source} --allow-code instead")
    folder = path.parent if out is None else as_path("out", out)
    return identify(source, folder, overwrite=True, allow_outside=True, allow_code=allow_code)


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
    if kind == "greybox_ode":
        record = model.get("model_file")
        if not isinstance(record, Mapping):
            return None  # a run that predates saved grey-box models: nothing to rebuild
        from ..models._file import model_from_record

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


