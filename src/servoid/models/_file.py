"""Model files: servoid's own JSON format and a MATLAB ``.mat`` export.

A model file is one JSON object::

    {"servoid_model": 1, "type": "TransferFunction", "dt": null,
     "method": null, "prewarp": null, "num": [...], "den": [...],
     "delay": 0.0, "covariance": null, "units": null}

``"type"`` is ``"TransferFunction"`` (``num``, ``den``, ``delay``),
``"StateSpace"`` (``A``, ``B``, ``C``, ``D`` as lists of rows),
``"PolynomialModel"`` (``a``, ``b``, ``nk``, ``c``, ``d``, ``f``,
``noise_variance``, ``input_names``, ``output_name``), or one of the
nonlinear models:

- ``"NarxModel"``: ``terms`` (each a list of ``[signal, lag]`` factors,
  signal 0 the output, i ≥ 1 input i; ``[]`` the constant),
  ``coefficients``, ``noise_variance``, ``input_names``, ``output_name``,
  ``input_units``, ``output_unit``, ``term_names`` (readable labels, not
  read back) and ``covariance`` (the coefficients', or null);
- ``"BlockModel"``: ``structure``, ``offset``, ``input_nonlinearity`` and
  ``output_nonlinearity`` (null or ``{"kind": ..., "parameters": {name:
  value}}``, plus ``breakpoints`` for a piecewise-linear shape) and
  ``linear``, the linear block as a nested model record;
- ``"PnlssModel"``: ``A``, ``B``, ``C``, ``D``, ``E``, ``F`` (on the
  normalised signals), ``powers`` (each monomial's exponent row),
  ``u_mean``, ``u_scale``, ``y_mean``, ``y_scale``, ``monomials``, names,
  units, ``monomial_names`` (not read back) and ``covariance``;
- ``"OdeModel"``: a fitted grey-box ODE, as a reference to the user's
  Python file (absolute path, SHA-256, function names) with its numbers;
  read back only with ``allow_code=True`` and an unchanged file.

Every file ends with ``covariance`` (null or a square matrix; with
``parameter_names`` when saved from an Estimate) and ``units``.  Floats are
written with ``repr``, so a model read back equals the one saved bit for
bit.  ``"servoid_model"`` is the format version: a reader refuses a version
it does not know rather than guess.
"""

from __future__ import annotations

import importlib
import json
import re
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._atomic import atomic_path
from .._checks import as_array, as_bool, as_path, file_name_problem, parse_json, read_text
from .._errors import (
    DataError,
    FileFormatError,
    MissingFileError,
    ModelError,
    OptionError,
    OptionTypeError,
    ServoidError,
    ServoidWarning,
)
from .._shown import shown
from .._warn import warn
from ._polynomial import PolynomialModel
from ._statespace import StateSpace
from ._transfer import TransferFunction

__all__ = [
    "FORMAT_VERSION",
    "RECORD_TYPES",
    "export_mat",
    "load_model",
    "model_from_record",
    "model_record",
    "past_float",
    "record_text",
    "save_model",
    "write_mat",
]

FORMAT_VERSION = 1
_TYPES = ("TransferFunction", "StateSpace", "PolynomialModel")
#: Model types defined outside ``servoid.models``: ``"type"`` → ``"module:Class"``.  They
#: import ``models``, so this module imports them only when a file of their type is written
#: or read (no import cycle).  Each class gives ``to_record()`` (its data without the header:
#: format version, type, dt) and a classmethod ``from_record(data)`` (the whole file's data,
#: raising KeyError for a missing key and a ServoidError for bad values); a new model type
#: plugs in with one line here.  A model that holds user code (the grey-box ODE model runs the
#: user's Python functions) must store a reference to that code, not the code, and its loader
#: must not run it without the caller's consent (the CLI's ``--allow-code``).
RECORD_TYPES: dict[str, str] = {
    "NarxModel": "servoid.nonlinear._narx_model:NarxModel",
    "BlockModel": "servoid.nonlinear._block:BlockModel",
    "PnlssModel": "servoid.nonlinear._pnlss:PnlssModel",
    "OdeModel": "servoid.estimate._ode_model:OdeModel",
}
_MATLAB_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")
_FLOAT_MAX = int(sys.float_info.max)  # integers above it have no float
Model = TransferFunction | StateSpace | PolynomialModel


def save_model(
    model: Any,
    path: str | Path,
    *,
    overwrite: bool = False,
    covariance: ArrayLike | None = None,
    units: Mapping[str, str] | None = None,
) -> Path:
    """Write a model to a servoid model file (JSON).

    The file is written atomically: a failure leaves no partial file and
    an existing file untouched.

    Parameters
    ----------
    model : model or Estimate
        A TransferFunction, StateSpace or PolynomialModel (its
        discretisation method, prewarp and delay are kept), a NarxModel,
        a BlockModel or a grey-box OdeModel (a reference to its Python
        file, never the code); or an :class:`~servoid.estimate.Estimate`, whose
        model is written with its covariance and parameter names.
    path : str or pathlib.Path
        The file to write (``.json`` by convention); its folder must exist.
    overwrite : bool
        Replace an existing file; otherwise an existing file is an error.
    covariance : array_like or None
        Square covariance matrix of the estimated parameters, stored as is
        for other tools (MATLAB, a report); finite values only.  Default:
        the Estimate's, or a NarxModel's own (read back with the model).
    units : mapping of str to str or None
        Units to record, e.g. ``{"u": "V", "y": "mm"}``.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    OptionTypeError
        For an object that is no model a file can hold (a measured
        FrequencyResponseData).
    ModelError
        For a BlockModel with a user StaticFunction: a file holds numbers,
        not code (the message says what to save instead); for an OdeModel
        whose functions are not defined in a Python file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> g = TransferFunction([2.0], [0.1, 1.0], delay=0.01)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     file = save_model(g, pathlib.Path(tmp) / "g.json")
    ...     back = load_model(file)
    >>> back.num.tolist(), back.den.tolist(), back.delay
    ([20.0], [1.0, 10.0], 0.01)
    """
    names = None
    if _is_estimate(model):
        names = [str(n) for n in model.names]
        if covariance is None and model.covariance is not None:
            if np.all(np.isfinite(model.covariance)):
                covariance = model.covariance
            else:
                warn("the estimate's covariance has non-finite entries (a parameter "
                     "the data do not determine): the model file is written without "
                     "it", ServoidWarning)
        model = model.model
    record = model_record(model)
    if covariance is not None:
        record["covariance"] = _covariance(covariance)
    record.setdefault("covariance", None)
    if names is not None:
        record["parameter_names"] = names
    record["units"] = None if units is None else _units(units)
    kind = record["type"]
    if kind in RECORD_TYPES:  # the file must read back: e.g. a covariance of the wrong shape
        cls = _record_class(kind)
        if getattr(cls, "runs_code", False):  # checked without running the user's code
            cls.check_record(record)
        else:
            cls.from_record(record)
    path = as_path("path", path)
    text = record_text(record)
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def load_model(path: str | Path, *, allow_code: bool = False) -> Any:
    """Read a model written by :func:`save_model`.

    Parameters
    ----------
    path : str or pathlib.Path
        A servoid model file.
    allow_code : bool
        Let a grey-box ODE model run the user's Python file its record
        names (checked first against the SHA-256 recorded at the fit);
        without it such a file is refused and nothing runs.

    Returns
    -------
    TransferFunction, StateSpace, PolynomialModel, NarxModel, BlockModel or OdeModel
        The model, equal to the one saved (same floats).  A NarxModel and
        an OdeModel get their covariance back; otherwise the file's
        ``covariance`` and ``units`` are for other tools: read them from
        the JSON if needed.

    Raises
    ------
    MissingFileError
        When no file exists at `path` (or a grey-box model's Python file
        is gone).
    FileFormatError
        For a file that is not JSON, not a servoid model file, of another
        format version, or with coefficients that make no model.
    OptionError
        A grey-box ODE model without ``allow_code=True`` (its Python file
        is named; nothing runs).
    ModelError
        A grey-box model's Python file changed since the fit (both SHA-256
        are named).
    """
    path = as_path("path", path)
    allow_code = as_bool("allow_code", allow_code)
    try:
        text = read_text(path, "model file", "JSON")
    except MissingFileError as exc:
        raise MissingFileError(f"{exc}; check the path (relative paths are taken from "
                               f"{Path.cwd()})") from None
    try:
        data = parse_json(text, path, "model file")
    except FileFormatError as exc:
        raise FileFormatError(f"{exc}; the file is damaged: write it again with "
                              "servoid.models.save_model") from None
    return model_from_record(data, where=f"model file {path}", allow_code=allow_code)


def export_mat(model: Model, path: str | Path, *, name: str = "G",
               overwrite: bool = False) -> Path:
    """Write a model to a MATLAB ``.mat`` file as one struct.

    The struct `name` holds, as MATLAB names them:

    - a TransferFunction: ``num``, ``den``, ``Ts``, ``InputDelay`` [s];
    - a StateSpace: ``A``, ``B``, ``C``, ``D``, ``Ts``, ``InputDelay`` (0);
    - a PolynomialModel: ``A``, ``B``, ``C``, ``D``, ``F``, ``nk``, ``Ts``,
      ``NoiseVariance``, ``InputDelay`` (0).  ``B`` and ``F`` have one row
      per input, padded with zeros on the right; ``B`` starts with
      ``nk`` zeros, as MATLAB's ``idpoly`` expects;

    plus ``type`` (``"tf"``, ``"ss"`` or ``"idpoly"``: the MATLAB function
    that rebuilds it) and ``Method`` (the discretisation method, or "").
    ``Ts`` is 0 for a continuous model.  In MATLAB::

        s = load("g.mat");
        G = tf(s.G.num, s.G.den, s.G.Ts, "InputDelay", s.G.InputDelay);

    Parameters
    ----------
    model : TransferFunction, StateSpace or PolynomialModel
        The model.
    path : str or pathlib.Path
        The ``.mat`` file to write; its folder must exist.
    name : str
        The MATLAB variable (a valid identifier, at most 63 characters).
    overwrite : bool
        Replace an existing file; otherwise an existing file is an error.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = as_path("path", path)
    write_mat({name: model}, path, overwrite=overwrite)
    return path


# -- shared with the command line -------------------------------------------------------------


def model_record(model: object) -> dict[str, Any]:
    """A model as the plain data of a model file.

    The caller adds ``units`` and, but for a NarxModel (whose record holds
    its own), ``covariance``.
    """
    header = {"servoid_model": FORMAT_VERSION, "type": type(model).__name__}
    if not isinstance(model, (TransferFunction, StateSpace, PolynomialModel)):
        kind = type(model).__name__
        if kind in RECORD_TYPES and isinstance(model, _record_class(kind)):
            return {**header, "dt": model.dt, **model.to_record()}  # type: ignore[attr-defined]
    if isinstance(model, TransferFunction):
        body = {"num": _floats(model.num), "den": _floats(model.den), "delay": model.delay}
    elif isinstance(model, StateSpace):
        body = {k: _floats(getattr(model, k)) for k in ("A", "B", "C", "D")}
    elif isinstance(model, PolynomialModel):
        body = {"a": _floats(model.a), "b": [_floats(b) for b in model.b],
                "nk": list(model.nk), "c": _floats(model.c), "d": _floats(model.d),
                "f": [_floats(f) for f in model.f or ()], "noise_variance": model.noise_variance,
                "input_names": None if model.input_names is None else list(model.input_names),
                "output_name": model.output_name}
    else:
        raise OptionTypeError(
            f"model must be a TransferFunction, StateSpace, PolynomialModel, NarxModel or "
            f"BlockModel, got {type(model).__name__}; a model file holds a parametric model (a "
            "measured FrequencyResponseData is data: keep it with its experiment)"
        )
    return {**header, "dt": model.dt, "method": getattr(model, "method", None),
            "prewarp": getattr(model, "prewarp", None), **body}


def record_text(record: Mapping[str, Any]) -> str:
    """A model file's text: one key a line, each value compact (readable, diffable)."""
    return "{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v, allow_nan=False)}"
                               for k, v in record.items()) + "\n}\n"


def model_from_record(data: object, *, where: str, allow_code: bool = False) -> Any:
    """The model a model file's data describe; ``where`` names the file in errors.

    ``allow_code`` lets a model that calls the user's code (``runs_code``)
    run it; such a class checks its own record and asks for consent.
    """
    fix = "write it again with servoid.models.save_model"
    if not isinstance(data, Mapping) or "servoid_model" not in data:
        raise FileFormatError(f"{where} is not a servoid model file (no \"servoid_model\" "
                              f"format version at the top); {fix}")
    huge = past_float(data)
    if huge is not None:
        raise FileFormatError(f"{where}: {huge} is an integer past the largest float (1.8e308), "
                              f"which no model holds; the file is damaged: {fix}")
    version = data["servoid_model"]
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise FileFormatError(
            f"{where} has format version {shown(version)}; this servoid reads version "
            f"{FORMAT_VERSION}: read it with the servoid that wrote it (pip install -U servoid "
            f"for a newer one) and {fix}"
        )
    kind = data.get("type")
    if not isinstance(kind, str) or (kind not in _TYPES and kind not in RECORD_TYPES):
        listed = ", ".join(repr(t) for t in (*_TYPES, *RECORD_TYPES))
        raise FileFormatError(f"{where}: \"type\" must be one of {listed}, got {shown(kind)} (a "
                              f"model type this servoid does not know: read the file with the "
                              f"servoid that wrote it, pip install -U servoid for a newer one); "
                              f"{fix}")
    for key in ("model_file", "output_file") if kind == "OdeModel" else ():
        problem = file_name_problem(data[key]) if isinstance(data.get(key), str) else None
        if problem is not None:  # before any file system call on it
            raise FileFormatError(f"{where}: {key} = {shown(data[key])} {problem}; the file is "
                                  f"damaged: {fix}")
    if kind in RECORD_TYPES and getattr(_record_class(kind), "runs_code", False):
        return _record_class(kind).from_record(data, allow_code=allow_code, where=where)
    linear = data.get("linear") if kind == "BlockModel" else None
    if isinstance(linear, Mapping) and "servoid_model" in linear and linear.get("type") not in (
            "TransferFunction", "PolynomialModel"):  # not a block in a block in a block ...
        raise FileFormatError(f"{where}: the BlockModel's \"linear\" must be the record of a "
                              f"TransferFunction or PolynomialModel, got "
                              f"{shown(linear.get('type'))}; the file is damaged: {fix}")
    try:
        if kind in RECORD_TYPES:
            return _record_class(kind).from_record(data)
        common = {"dt": data["dt"], "method": data.get("method"), "prewarp": data.get("prewarp")}
        if kind == "TransferFunction":
            return TransferFunction(_arr(data, "num"), _arr(data, "den"), **common,
                                    delay=data.get("delay", 0.0))
        if kind == "StateSpace":
            return StateSpace(*(_arr(data, k) for k in ("A", "B", "C", "D")), **common)
        if common["method"] is not None or common["prewarp"] is not None:
            raise DataError("a PolynomialModel has no method or prewarp")
        names = data.get("input_names")
        return PolynomialModel(
            _arr(data, "a"), tuple(_arr({"b": b}, "b") for b in _list(data, "b")),
            tuple(_list(data, "nk")), data["dt"], c=_arr(data, "c"), d=_arr(data, "d"),
            f=tuple(_arr({"f": f}, "f") for f in _list(data, "f")),
            noise_variance=data.get("noise_variance", 0.0),
            input_names=None if names is None else tuple(_list(data, "input_names")),
            output_name=data.get("output_name"),
        )
    except KeyError as exc:
        raise FileFormatError(f"{where}: the {kind} has no {exc.args[0]!r}; the file is "
                              f"damaged: {fix}") from None
    except (ServoidError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{where}: the {kind} is damaged ({exc}); {fix}") from None


def past_float(data: object) -> str | None:
    """Where in parsed JSON an integer lies past the float range (``"num[2]"``), or None.

    Such an integer (``1e400`` written without its exponent) parses, then
    fails as an ``OverflowError`` wherever a model turns it into a float;
    the walk is iterative, so any depth the JSON parser accepted is fine.
    """
    stack: list[tuple[str, object]] = [("", data)]
    while stack:
        where, node = stack.pop()
        if isinstance(node, int) and not isinstance(node, bool):
            if abs(node) > _FLOAT_MAX:
                return where or "the value"
        elif isinstance(node, Mapping):
            stack.extend((f"{where}.{k}" if where else str(k), v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((f"{where}[{i}]", v) for i, v in enumerate(node))
    return None


def write_mat(models: Mapping[str, Model], path: Path, *, overwrite: bool = False) -> None:
    """Write each model as a MATLAB struct named by its key, atomically."""
    from scipy.io import savemat

    structs = {}
    for name, model in models.items():
        if not isinstance(name, str) or not _MATLAB_NAME.fullmatch(name):
            raise OptionError(f"name must be a MATLAB variable name (a letter, then letters, "
                              f"digits or _; at most 63 characters), got {name!r}")
        structs[name] = _mat_struct(model)
    with atomic_path(path, overwrite) as tmp, open(tmp, "wb") as handle:
        savemat(handle, structs, oned_as="row")


# -- private ----------------------------------------------------------------------------------


def _mat_struct(model: object) -> dict[str, Any]:
    if type(model).__name__ in RECORD_TYPES:
        raise ModelError(
            f"a {type(model).__name__} has no MATLAB form (tf, ss and idpoly are linear): write "
            "it as a servoid model file instead, save_model(model, \"model.json\") (from the "
            "command line: servoid export RESULTS.json --to json), and read it back with "
            "servoid.load_model")
    if not isinstance(model, (TransferFunction, StateSpace, PolynomialModel)):
        raise OptionTypeError(
            f"model must be a TransferFunction, StateSpace or PolynomialModel, got "
            f"{type(model).__name__}; MATLAB export holds parametric models only"
        )
    ts = 0.0 if model.dt is None else model.dt
    method = getattr(model, "method", None) or ""
    if isinstance(model, TransferFunction):
        return {"type": "tf", "num": np.array(model.num), "den": np.array(model.den), "Ts": ts,
                "InputDelay": model.delay, "Method": method}
    if isinstance(model, StateSpace):
        return {"type": "ss", **{k: np.array(getattr(model, k)) for k in ("A", "B", "C", "D")},
                "Ts": ts, "InputDelay": 0.0, "Method": method}
    b = [np.concatenate([np.zeros(k), bi]) for k, bi in zip(model.nk, model.b, strict=True)]
    return {"type": "idpoly", "A": np.array(model.a), "B": _rows(b), "C": np.array(model.c),
            "D": np.array(model.d), "F": _rows(list(model.f or ())),
            "nk": np.array(model.nk, dtype=float), "Ts": ts,
            "NoiseVariance": model.noise_variance, "InputDelay": 0.0, "Method": ""}


def _record_class(kind: str) -> Any:
    """The class a ``RECORD_TYPES`` entry names, imported on first use."""
    module, name = RECORD_TYPES[kind].split(":")
    return getattr(importlib.import_module(module), name)


def _is_estimate(value: object) -> bool:
    # an Estimate of a model, recognised by what it carries (servoid.estimate sits above models)
    return all(hasattr(value, name) for name in ("model", "names", "covariance", "parameters"))


def _rows(polys: list[np.ndarray]) -> np.ndarray:
    out = np.zeros((len(polys), max(p.size for p in polys)))
    for i, p in enumerate(polys):
        out[i, :p.size] = p
    return out


def _floats(values: np.ndarray) -> Any:
    return np.asarray(values, dtype=float).tolist()  # Python floats: json writes their repr


def _arr(data: Mapping[str, Any], key: str) -> np.ndarray:
    return as_array(key, data[key])


def _list(data: Mapping[str, Any], key: str) -> list[Any]:
    value = data[key]
    if not isinstance(value, list):
        raise DataError(f"{key} must be a list, got {value!r}")
    return value



def _covariance(value: ArrayLike) -> list[list[float]]:
    cov = as_array("covariance", value, ndim=2)
    if cov.shape[0] != cov.shape[1]:
        raise DataError(f"covariance must be a square matrix, got shape {cov.shape}")
    return cov.tolist()


def _units(value: object) -> dict[str, str]:
    if not isinstance(value, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in value.items()
    ):
        raise OptionTypeError(f"units must be a mapping of names to unit strings, e.g. "
                              f"{{'u': 'V', 'y': 'mm'}}, got {value!r}")
    return dict(value)

