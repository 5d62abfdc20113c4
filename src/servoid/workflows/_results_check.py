"""The shape of a ``results.json`` and its ``manifest.json``, checked before they are read.

A results folder is a user's file as soon as it is written: it is edited,
merged, half-copied.  :func:`load_results`, ``greybox_record`` and
``rerender`` read only a few of its fields, and :func:`check_results`
walks exactly those — the model record, the result's own summary (or the
parameter rows of each method family in an older file), the validation
verdicts, the closed-loop approaches, the paths of
the experiment file — so a field of the wrong type is a
:class:`~servoid.FileFormatError` naming it (``estimate.parameters[2].value``),
the value found and the fix, instead of an ``AttributeError`` deep in the
summary.  :func:`read_manifest` does the same for the manifest's list of
inputs.  Fields no reader uses are not checked: a newer servoid may add
them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .._checks import file_name_problem, parse_json, read_text
from .._errors import FileFormatError, MissingFileError
from .._shown import shown
from ..models import past_float

__all__ = ["check_results", "read_manifest"]

_FIX = "the file is damaged: write it again with servoid identify"
_HEX = frozenset("0123456789abcdef")


def check_results(data: object, path: Path) -> Mapping[str, Any]:
    """Check the fields of a parsed ``results.json`` that servoid reads back.

    Parameters
    ----------
    data : object
        The parsed JSON.
    path : pathlib.Path
        The file, for messages.

    Returns
    -------
    mapping
        ``data``, checked.

    Raises
    ------
    FileFormatError
        Not a results file, or a field servoid reads has the wrong type
        (the message names the field, the value and the fix).
    """
    if not isinstance(data, Mapping) or "servoid_version" not in data:
        raise FileFormatError(f"{path} is not a results.json of servoid identify (no "
                              f"\"servoid_version\"); give the results.json of a run")
    c = _Check(f"results file {path}")
    huge = past_float(data)
    if huge is not None:
        raise FileFormatError(f"results file {path}: {huge} is an integer past the largest "
                              f"float (1.8e308), which servoid never writes; {_FIX}")
    c.text(data, "servoid_version")
    for key in ("method", "primary_approach"):
        c.text(data, key, optional=True)
    for key in ("experiment_file", "campaign_file"):
        c.path(data, key)
    if data.get("model") is not None:
        c.model(c.table(data, "model"), "model")
    c.summary(data)
    c.record_summary(data)
    approaches = c.table(data, "approaches", optional=True)
    for name, approach in approaches.items():
        where = f"approaches.{name}"
        approach = c.table(approaches, name, where=where)
        for key in ("plant_continuous", "closed_loop"):
            if approach.get(key) is not None:
                c.table(approach, key, where=f"{where}.{key}")
    for k, entry in enumerate(c.rows_of(data, "validations", optional=True)):
        if isinstance(entry, Mapping) and entry.get("diverged_at") is not None:
            where = f"validations[{k}].diverged_at"
            c.number(c.table(entry, "diverged_at", where=where), "time", f"{where}.time")
    return data


def read_manifest(path: Path) -> list[tuple[Path, str]]:
    """The inputs a run's ``manifest.json`` lists: (path as written, SHA-256) each.

    Parameters
    ----------
    path : pathlib.Path
        The manifest.

    Returns
    -------
    list of (pathlib.Path, str)
        Each input's path and its SHA-256 in lowercase hex.

    Raises
    ------
    FileFormatError
        The manifest is missing, not JSON, or its ``inputs`` are not a list
        of ``{"path": ..., "sha256": ...}`` (the entry and field named).
    """
    fix = ("so the inputs of this run cannot be checked; write the run again with servoid "
           "identify")
    try:
        data = parse_json(read_text(path, "manifest"), path, "manifest")
    except (FileFormatError, MissingFileError) as exc:
        raise FileFormatError(f"{exc}; {fix}") from None
    c = _Check(f"manifest {path}", fix)
    if not isinstance(data, Mapping):
        raise FileFormatError(f"manifest {path} must be a JSON object, got {_kind(data)}; {fix}")
    out = []
    for k, entry in enumerate(c.rows_of(data, "inputs")):
        where = f"inputs[{k}]"
        entry = c.table(data["inputs"], k, where=where)
        name = c.path(entry, "path", where=f"{where}.path", optional=False)
        digest = c.text(entry, "sha256", where=f"{where}.sha256")
        if len(digest) != 64 or not set(digest) <= _HEX:
            raise FileFormatError(f"manifest {path}: {where}.sha256 must be a SHA-256 in "
                                  f"lowercase hex (64 digits), got {_shown(digest)}; {fix}")
        out.append((Path(name), digest))
    return out


# -- private ----------------------------------------------------------------------------------


class _Check:
    """Field checks with messages naming the file, the field, the value and the fix."""

    def __init__(self, label: str, fix: str = _FIX) -> None:
        self.label = label
        self.fix = fix

    def fail(self, where: str, expected: str, value: object) -> FileFormatError:
        return FileFormatError(f"{self.label}: {where} must be {expected}, got {_kind(value)}; "
                               f"{self.fix}")

    def table(self, holder: Any, key: Any, *, where: str = "", optional: bool = False,
              absent: bool = False) -> Mapping[str, Any]:
        """An object; ``optional``: or null or absent; ``absent``: or absent (not null)."""
        if isinstance(holder, Mapping) and key not in holder and (optional or absent):
            return {}
        value = holder.get(key) if isinstance(holder, Mapping) else holder[key]
        if value is None and optional:
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(where or str(key), "an object {...}", value)
        return value

    def rows_of(self, holder: Mapping[str, Any], key: str, *, where: str = "",
                optional: bool = False, absent: bool = False) -> list[Any]:
        """An array; ``optional``: or null or absent; ``absent``: or absent (not null)."""
        if key not in holder and (optional or absent):
            return []
        value = holder.get(key)
        if value is None and optional:
            return []
        if not isinstance(value, list):
            raise self.fail(where or key, "an array [...]", value)
        return value

    def text(self, holder: Mapping[str, Any], key: str, *, where: str = "",
             optional: bool = False) -> str:
        value = holder.get(key)
        if value is None and optional:
            return ""
        if not isinstance(value, str):
            raise self.fail(where or key, "a string", value)
        return value

    def path(self, holder: Mapping[str, Any], key: str, *, where: str = "",
             optional: bool = True) -> str:
        """A path servoid opens: text a file name can hold (no NUL, encodable)."""
        where = where or key
        value = self.text(holder, key, where=where, optional=optional)
        if optional and not value:
            return value
        problem = file_name_problem(value) if value else "is empty"
        if problem is not None:
            raise FileFormatError(f"{self.label}: {where} = {_shown(value)} {problem}, so it "
                                  f"names no file; {self.fix}")
        return value

    def number(self, holder: Mapping[str, Any], key: str, where: str) -> None:
        """A number or null; a float servoid can hold (NaN and inf as written)."""
        value = holder.get(key)
        if value is None:
            return
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, "a number or null", value)
        try:
            float(value)
        except OverflowError:
            raise self.fail(where, "a number within ±1.8e308", value) from None

    def flag(self, holder: Mapping[str, Any], key: str, where: str) -> None:
        value = holder.get(key)
        if value is not None and not isinstance(value, bool):
            raise self.fail(where, "true, false or null", value)

    def row(self, row: Any, where: str) -> None:
        """A parameter row: name, value, std, interval, unit."""
        if not isinstance(row, Mapping) or "value" not in row:
            return  # not a parameter row: the summary skips it
        self.text(row, "name", where=f"{where}.name")
        for key in ("value", "std", "ci_low", "ci_high"):
            self.number(row, key, f"{where}.{key}")
        self.interval(row, f"{where}.ci95")
        self.text(row, "unit", where=f"{where}.unit", optional=True)

    def interval(self, holder: Mapping[str, Any], where: str, absent: bool = False) -> None:
        """``ci95``: [low, high]; null too unless ``absent`` (then only a missing key)."""
        value = holder.get("ci95")
        if "ci95" not in holder or (value is None and not absent):
            return
        if not isinstance(value, list) or len(value) != 2:
            raise self.fail(where, "[low, high] or null", value)
        for k in range(2):
            self.number({"v": value[k]}, "v", f"{where}[{k}]")

    def validation(self, holder: Mapping[str, Any], where: str) -> None:
        """What the verdicts read: fit [%] and the residual tests."""
        if not holder.get("validation"):
            return
        validation = self.table(holder, "validation", where=f"{where}validation")
        self.number(validation, "fit_percent", f"{where}validation.fit_percent")
        if validation.get("residuals"):
            residuals = self.table(validation, "residuals",
                                   where=f"{where}validation.residuals")
            for key in ("is_white", "is_independent"):
                self.flag(residuals, key, f"{where}validation.residuals.{key}")

    def summary(self, data: Mapping[str, Any]) -> None:
        """The fields of the summary, in the order it looks for them (``_summarise``)."""
        if "primary_approach" in data:
            primary = data["primary_approach"]
            for k, entry in enumerate(self.rows_of(data, "parameters", absent=True)):
                where = f"parameters[{k}]"
                entry = self.table(data["parameters"], k, where=where)
                value = entry.get(primary)
                if isinstance(value, Mapping):
                    self.text(entry, "name", where=f"{where}.name")
                    for key in ("value", "std"):
                        self.number(value, key, f"{where}.{primary}.{key}")
                    self.interval(value, f"{where}.{primary}.ci95", absent=True)
            approaches = self.table(data, "approaches", absent=True)
            approach = self.table(approaches, primary, where=f"approaches.{primary}",
                                  absent=True)
            self.validation(approach, f"approaches.{primary}.")
            self.rows_of(approach, "flags", where=f"approaches.{primary}.flags", absent=True)
            if data.get("structure_test"):
                self.table(data, "structure_test")
        elif isinstance(data.get("estimate"), Mapping):
            estimate = data["estimate"]
            for k, row in enumerate(self.rows_of(estimate, "parameters",
                                                 where="estimate.parameters", absent=True)):
                self.row(row, f"estimate.parameters[{k}]")
            self.validation(data, "")
        elif isinstance(data.get("estimates"), Mapping) and data["estimates"]:
            name, first = next(iter(data["estimates"].items()))
            first = self.table(data["estimates"], name, where=f"estimates.{name}")
            for k, row in enumerate(self.rows_of(first, "parameters", absent=True,
                                                 where=f"estimates.{name}.parameters")):
                self.row(row, f"estimates.{name}.parameters[{k}]")
        elif isinstance(data.get("parameters"), list):
            for k, row in enumerate(data["parameters"]):
                self.row(row, f"parameters[{k}]")

    def record_summary(self, data: Mapping[str, Any]) -> None:
        """The ``"summary"`` a result writes of itself (what load_results returns)."""
        if data.get("summary") is None:
            return
        summary = self.table(data, "summary")
        for k, row in enumerate(self.rows_of(summary, "parameters", where="summary.parameters",
                                             absent=True)):
            if not isinstance(row, Mapping) or "value" not in row:
                raise self.fail(f"summary.parameters[{k}]", "an object with name and value", row)
            self.row(row, f"summary.parameters[{k}]")
        self.number(summary, "fit_percent", "summary.fit_percent")
        self.number(summary, "notes", "summary.notes")
        for key in ("white", "independent", "structure_rejected"):
            self.flag(summary, key, f"summary.{key}")
        for key in ("decision", "reason", "method"):
            self.text(summary, key, where=f"summary.{key}", optional=True)
        for key in ("flags", "diverged", "conditions"):
            self.rows_of(summary, key, where=f"summary.{key}", absent=True)

    def model(self, model: Mapping[str, Any], where: str) -> None:
        """The containers a model record is rebuilt from (the values: by the model)."""
        self.text(model, "type", where=f"{where}.type", optional=True)
        for key in ("b", "f", "nk", "terms", "inputs", "input_units"):
            if model.get(key) is not None:
                self.rows_of(model, key, where=f"{where}.{key}")
        if model.get("model_file") is not None:
            self.table(model, "model_file", where=f"{where}.model_file")
        for key in ("input_nonlinearity", "output_nonlinearity"):
            if model.get(key) is not None:
                self.table(model, key, where=f"{where}.{key}")
        if model.get("type") == "block" and model.get("linear") is not None:
            linear = self.table(model, "linear", where=f"{where}.linear")
            if linear.get("type") not in ("transfer_function", "polynomial"):
                raise self.fail(f"{where}.linear.type", "\"transfer_function\" or "
                                "\"polynomial\" (the linear block of a block model)",
                                linear.get("type"))
            self.model(linear, f"{where}.linear")


def _kind(value: object) -> str:
    name = {dict: "an object", list: "an array", str: "the string", bool: "",
            type(None): ""}.get(type(value), type(value).__name__)
    return f"{name} {_shown(value)}".strip()


def _shown(value: object) -> str:
    """``repr(value)`` cut to a readable length for a message."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return shown(value)
