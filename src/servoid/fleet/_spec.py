"""The fleet file: which records, which identification, which limits.

::

    [records]
    manifest = "units.csv"      # a "path" column (relative to the manifest) + metadata
    # glob = "runs/*.toml"      # or every experiment file a glob finds (serial = file stem)

    [identify]                  # optional: one method for every record; absent = each
    method = "closedloop"       # record's own [identify]
    approach = "one-step"

    [limits.omega_hp]
    nominal = 163.3
    tolerance = 6.0             # or tolerance_percent, or min / max

    [trend]
    by = "date"                 # "date" | "serial" | "order" | a metadata column

    [report]
    folder = "fleet-results"

Everything that can be checked before the batch starts is checked here:
the manifest's files exist, serial numbers are unique, the method and its
options are valid.
"""

from __future__ import annotations

import codecs
import csv
import io
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from types import MappingProxyType
from typing import Any

from .._checks import file_name_problem
from .._errors import DataError, FileFormatError, OptionError, OptionTypeError
from .._shown import shown
from ..data import read_toml
from ._files import REGULAR_ONLY, file_problem
from ._limits import Limit, parse_limits

__all__ = ["FleetRecord", "FleetSpec", "load_fleet_spec"]

#: Folder levels a records glob may have (pathlib's walk recurses once per level).
_MAX_PARTS = 32

_TABLES = ("records", "identify", "limits", "trend", "report")
_TREND_AXES = ("date", "serial", "order")


@dataclass(frozen=True)
class FleetRecord:
    """One record of the fleet: its experiment file and its metadata."""

    path: Path
    meta: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))

    @property
    def serial(self) -> str:
        """The unit's serial number (metadata ``serial``, else the file's stem)."""
        return str(self.meta.get("serial") or self.path.stem)


@dataclass(frozen=True)
class FleetSpec:
    """A validated fleet file.

    Attributes
    ----------
    records : tuple of FleetRecord
        The experiment files, in manifest (or sorted glob) order.
    identify : mapping or None
        The ``[identify]`` table applied to every record; None: each
        record's own.
    limits : tuple of Limit
        Acceptance limits.
    trend : str
        The trend axis: ``"date"``, ``"serial"``, ``"order"`` or a
        metadata column.
    report : mapping
        ``[report]`` (``folder``).
    source : Path or None
        The fleet file.
    manifest : Path or None
        The manifest, when the records come from one.
    """

    records: tuple[FleetRecord, ...]
    identify: Mapping[str, Any] | None
    limits: tuple[Limit, ...]
    trend: str = "order"
    report: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    source: Path | None = None
    manifest: Path | None = None

    @property
    def meta_columns(self) -> tuple[str, ...]:
        """Metadata columns, in first-seen order."""
        seen: dict[str, None] = {}
        for r in self.records:
            seen.update(dict.fromkeys(r.meta))
        return tuple(seen)


def load_fleet_spec(path: str | os.PathLike[str]) -> FleetSpec:
    """Read and check a fleet file (see the module docstring for its tables)."""
    from ..workflows import method_for

    source = Path(path)
    problem = file_problem(source)
    if problem == "does not exist":
        raise DataError(f"fleet file {source} not found; check the path")
    if problem is not None:
        raise DataError(f"fleet file {source} {problem}; {REGULAR_ONLY}")
    doc = read_toml(source, "fleet file")
    unknown = sorted(set(doc) - set(_TABLES))
    if unknown:
        raise OptionError(f"unknown table(s) in {source.name}: {', '.join(unknown)}; a fleet "
                          f"file has {', '.join(f'[{t}]' for t in _TABLES)}")
    base = source.parent
    table = _table(doc, "records")
    records = _records(table, base)
    manifest = base / table["manifest"] if "manifest" in table else None
    identify = doc.get("identify")
    if identify is not None:
        identify = _table(doc, "identify")
        method = method_for(identify)  # one method, a list of candidates or "auto"
        method.parse(identify)  # every option checked before any record runs
    limits = parse_limits(doc.get("limits", {}))
    trend = _trend(_table(doc, "trend", required=False), records)
    report = _table(doc, "report", required=False)
    if set(report) - {"folder"}:
        raise OptionError(f"unknown key(s) in [report]: {', '.join(sorted(set(report) - {'folder'}))}"
                          "; a fleet file's [report] has folder")
    return FleetSpec(tuple(records), None if identify is None else MappingProxyType(identify),
                     limits, trend, MappingProxyType(report), source, manifest)


def _table(doc: Mapping[str, Any], name: str, required: bool = True) -> dict[str, Any]:
    if name not in doc:
        if required:
            raise OptionError(f"the fleet file needs a [{name}] table")
        return {}
    value = doc[name]
    if not isinstance(value, Mapping):
        raise OptionTypeError(f"[{name}] must be a table; got {value!r}")
    return dict(value)


def _records(table: Mapping[str, Any], base: Path) -> list[FleetRecord]:
    if ("glob" in table) == ("manifest" in table) or set(table) - {"glob", "manifest"}:
        raise OptionError("[records] takes exactly one of glob = \"runs/*.toml\" or "
                          "manifest = \"units.csv\"")
    if "glob" in table:
        records = [FleetRecord(p) for p in _glob(table["glob"], base)]
    else:
        manifest = table["manifest"]
        if not isinstance(manifest, str):
            raise OptionTypeError(f"[records] manifest must be a file name; got {manifest!r}")
        problem = file_name_problem(manifest)
        if problem is not None:
            raise OptionError(f"[records] manifest = {shown(manifest)} {problem}; name the "
                              "manifest CSV or Parquet file beside the fleet file")
        records = _manifest(base / manifest)
    _check_unique(records)
    return records


def _glob(pattern: Any, base: Path) -> list[Path]:
    """The files a glob finds in the fleet file's folder and its subfolders, sorted.

    The pattern is relative to that folder (an absolute one must lie in
    it) and has no ``..``; ``**`` does not descend into linked folders, so
    a link cannot lead the walk elsewhere or round a loop.  Hidden files
    and folders are found only when the pattern names them.  Folders it
    matches are left out; any other match that is not a regular file is
    refused by name.
    """
    if not isinstance(pattern, str):
        raise OptionTypeError(f"[records] glob must be text; got {pattern!r}")
    if not pattern.strip():
        raise OptionError(f"[records] glob = {pattern!r} is not a pattern; write one like "
                          "\"units/**/*.toml\", relative to the fleet file's folder")
    problem = file_name_problem(pattern)
    if problem is not None:
        raise OptionError(f"[records] glob = {shown(pattern)} {problem}; write a pattern "
                          "like \"units/**/*.toml\", relative to the fleet file's folder")
    if len(PurePath(pattern).parts) > _MAX_PARTS:  # the walk recurses once per part
        raise OptionError(f"[records] glob = {shown(pattern)} has "
                          f"{len(PurePath(pattern).parts)} folder levels; a glob of records "
                          f"goes at most {_MAX_PARTS} deep (\"units/**/*.toml\" reaches any "
                          "depth)")
    relative = PurePath(pattern)
    if relative.is_absolute():
        inside = [relative.relative_to(b) for b in {base.absolute(), base.resolve()}
                  if relative.is_relative_to(b)]
        if inside:
            relative = inside[0]
        else:
            raise OptionError(
                f"[records] glob = {pattern!r} is outside the fleet file's folder ({base}); a "
                "glob finds records in that folder and its subfolders: write it relative to "
                "the folder, like \"units/**/*.toml\", or move the fleet file")
    if ".." in relative.parts:
        raise OptionError(f"[records] glob = {pattern!r} leaves the fleet file's folder with "
                          f"'..'; a glob finds records in {base} and its subfolders: move the "
                          "fleet file up, or list the records in a manifest")
    if not relative.parts:
        raise OptionError(f"[records] glob = {pattern!r} names the fleet file's folder itself; "
                          "write a pattern of files, like \"units/**/*.toml\"")
    hidden = any(part.startswith(".") for part in relative.parts)
    paths, refused = [], []
    for p in sorted(base.glob(str(relative))):
        if not hidden and any(part.startswith(".") for part in p.relative_to(base).parts):
            continue
        problem = file_problem(p)
        if problem is None:
            paths.append(p)
        elif problem != "is a folder, not a file":
            refused.append(f"{p} {problem}")
    if refused:
        raise DataError(f"[records] glob = {pattern!r} finds {len(refused)} path(s) that are not "
                        f"regular files: {_listing(refused)}; {REGULAR_ONLY}, or narrow the "
                        "pattern")
    if not paths:
        raise DataError(f"[records] glob = {pattern!r} finds no file under {base}; "
                        "check the pattern")
    return paths


def _text(path: Path, what: str) -> str:
    """A text file as UTF-8, with or without a byte-order mark (spreadsheets write one)."""
    data = path.read_bytes()
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise FileFormatError(f"{what} {path} is UTF-16 text (it starts with a UTF-16 byte-order "
                              "mark); save it as UTF-8")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise FileFormatError(f"{what} {path} is not UTF-8 text (byte {data[exc.start]:#04x} on "
                              f"line {line}); save it as UTF-8") from None




def _listing(items: list[str]) -> str:
    more = f" and {len(items) - 5} more" if len(items) > 5 else ""
    return "; ".join(items[:5]) + more


def _manifest(path: Path) -> list[FleetRecord]:
    problem = file_problem(path)
    if problem == "does not exist":
        raise DataError(f"[records] manifest {path} not found; check the path")
    if problem is not None:
        raise DataError(f"[records] manifest {path} {problem}; {REGULAR_ONLY}")
    rows = _parquet_rows(path) if path.suffix.lower() == ".parquet" else _csv_rows(path)
    if not rows:
        raise DataError(f"manifest {path} lists no records")
    if "path" not in rows[0]:
        raise DataError(f"manifest {path} needs a 'path' column (the experiment file of each "
                        f"row); it has {', '.join(rows[0])}")
    records, missing, refused = [], [], []
    for row in rows:
        file = Path(str(row["path"]))
        file = file if file.is_absolute() else path.parent / file
        problem = file_problem(file)
        if problem == "does not exist":
            missing.append(str(file))
        elif problem is not None:
            refused.append(f"{file} {problem}")
        meta = {k: "" if v is None else str(v) for k, v in row.items() if k != "path"}
        records.append(FleetRecord(file, MappingProxyType(meta)))
    if missing:
        shown = ", ".join(missing[:5]) + (f" and {len(missing) - 5} more" if len(missing) > 5
                                          else "")
        raise DataError(f"manifest {path.name} names {len(missing)} file(s) that do not exist: "
                        f"{shown}; fix the paths or remove the rows")
    if refused:
        raise DataError(f"manifest {path.name} names {len(refused)} path(s) that are not regular "
                        f"files: {_listing(refused)}; {REGULAR_ONLY}")
    return records


def _csv_rows(path: Path) -> list[dict[str, Any]]:
    try:
        with io.StringIO(_text(path, "the manifest"), newline="") as f:
            rows = list(csv.DictReader(f))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise FileFormatError(f"manifest {path} is not a readable CSV file: {exc}") from None
    if any(None in row for row in rows):
        raise FileFormatError(f"manifest {path} has rows with more fields than its header")
    return [dict(r) for r in rows]


def _parquet_rows(path: Path) -> list[dict[str, Any]]:
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise OptionError("a Parquet manifest needs pyarrow: pip install 'servoid[fleet]', or "
                          "give the manifest as CSV") from None
    try:
        return list(pq.read_table(path).to_pylist())
    except Exception as exc:  # noqa: BLE001 - pyarrow raises its own error classes for a damaged file
        raise FileFormatError(f"manifest {path} is not a readable Parquet file: {exc}") from None


def _check_unique(records: list[FleetRecord]) -> None:
    """A unit may be tested many times (a life test), but not twice on the same date."""
    seen: dict[tuple[str, str], Path] = {}
    for r in records:
        if "serial" not in r.meta:
            continue
        key = (r.serial, r.meta.get("date", ""))
        if key in seen:
            when = f" on {key[1]}" if key[1] else ""
            raise DataError(f"serial {r.serial!r} appears twice{when} in the manifest "
                            f"({seen[key].name} and {r.path.name}); make serials unique, or add "
                            "a date column when the rows are repeated tests of one unit")
        seen[key] = r.path
    paths = [r.path.resolve() for r in records]
    if len(set(paths)) != len(paths):
        raise DataError("the fleet names the same experiment file twice; list each record once")


def _trend(table: Mapping[str, Any], records: list[FleetRecord]) -> str:
    columns = {k for r in records for k in r.meta}
    default = "date" if "date" in columns else "serial" if "serial" in columns else "order"
    by = table.get("by", default)
    if set(table) - {"by"}:
        raise OptionError("[trend] takes by = \"date\" | \"serial\" | \"order\" | a manifest column")
    if not isinstance(by, str) or (by not in _TREND_AXES and by not in columns):
        raise OptionError(f"[trend] by must be one of {', '.join(_TREND_AXES)} or a manifest "
                          f"column ({', '.join(sorted(columns)) or 'none'}); got {by!r}")
    if by == "date" and "date" not in columns:
        raise OptionError("[trend] by = \"date\" needs a 'date' column in the manifest")
    return by
