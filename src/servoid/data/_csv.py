"""CSV rig files: one header row of names (with units), one row per sample.

Layout read and written::

    time [s],position [m],current [A]
    0.0,0.00123,0.5
    0.001,0.00125,0.51

A header cell ``name [unit]`` gives the channel name and its unit. Blank
lines and lines starting with ``#`` before the header or among the data are
skipped.
"""

from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._atomic import atomic_path
from .._errors import DataError, FileFormatError
from ._columns import RolesArg, build_experiment, existing_file
from ._experiment import Experiment

__all__ = ["read_csv", "write_csv"]

_HEADER_CELL = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
_TIME_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}


def read_csv(
    path: str | os.PathLike[str],
    *,
    dt: float | None = None,
    time: str | None = "time",
    roles: RolesArg = None,
    delimiter: str = ",",
) -> Experiment:
    """Read a CSV file with a header row into an Experiment.

    Parameters
    ----------
    path : path-like
        The file.
    dt : float, optional
        Sample period [s]. Required when the file has no time column; when
        it has one, ``dt`` must agree with it.
    time : str or None
        Name of the time column [s] (``ms`` and ``us`` are converted); it
        gives ``dt`` and ``t0`` and must be uniform. ``None``: no time column.
        A time column that is absent is not an error when ``dt`` is given.
    roles : mapping of str to list of str, optional
        Role to column names, e.g. ``{"r": ["yr"], "y": ["y"]}``. Columns not
        mapped become side channels.
    delimiter : str
        Field separator.

    Returns
    -------
    Experiment
        Named after the file stem.

    Raises
    ------
    FileFormatError
        Empty file, ragged rows or non-numeric cells (with line and column).
    ChannelError
        A column named in ``roles`` is not in the file.
    """
    path = existing_file(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(
            f"{path}: not a text CSV file (byte {exc.start} is not UTF-8)"
        ) from exc
    lines = text.splitlines()
    header_at = next(
        (k for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")),
        None,
    )
    if header_at is None:
        raise FileFormatError(f"{path}: empty CSV file, expected a header row of channel names")
    names, units = _parse_header(path, lines[header_at], header_at + 1, delimiter)
    data = _parse_rows(path, lines, header_at + 1, len(names), delimiter)
    columns = {n: data[:, k] for k, n in enumerate(names)}
    stamps = None
    if time is not None and time in columns:
        scale = _TIME_UNITS.get(units.get(time, ""))
        if scale is None:
            raise FileFormatError(
                f"{path}: time column {time!r} has unit {units[time]!r}; expected one of "
                f"{', '.join(repr(u) for u in _TIME_UNITS)}"
            )
        stamps = columns.pop(time) * scale
    elif dt is None:
        hint = f"it has no column {time!r}; " if time is not None else ""
        raise DataError(
            f"{path}: no sample period: {hint}pass dt [s] or time=<column name> "
            f"(columns: {', '.join(names)})"
        )
    return build_experiment(path, columns, units, roles=roles, dt=dt, time=stamps)


def write_csv(
    exp: Experiment,
    path: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    time: bool = True,
) -> Path:
    """Write an Experiment as CSV, atomically, at full precision.

    Parameters
    ----------
    exp : Experiment
        The record; roles and notes are not stored in CSV.
    path : path-like
        Target file.
    overwrite : bool
        Replace an existing file; otherwise :class:`OutputExistsError`.
    time : bool
        Write a first column ``time [s]`` (``t0 + k·dt``).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    if time and "time" in exp.names:
        raise DataError("a channel is called 'time'; rename it or pass time=False")
    header = [_header_cell(ch.name, ch.unit) for ch in exp.channels]
    cols = [ch.values for ch in exp.channels]
    if time:
        header.insert(0, "time [s]")
        cols.insert(0, exp.time)
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(header)
    # repr() is the shortest string that parses back to the same double.
    buf.writelines(",".join(map(repr, row)) + "\n" for row in np.column_stack(cols).tolist())
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
    return Path(path)


def _header_cell(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _parse_header(
    path: Path, line: str, lineno: int, delimiter: str
) -> tuple[list[str], dict[str, str]]:
    cells = next(csv.reader([line], delimiter=delimiter))
    names: list[str] = []
    units: dict[str, str] = {}
    for col, cell in enumerate(cells, start=1):
        match = _HEADER_CELL.match(cell)
        name = match.group("name") if match else ""
        if not name:
            raise FileFormatError(f"{path}, line {lineno}, column {col}: empty channel name")
        try:
            float(name)
        except ValueError:
            pass
        else:
            raise FileFormatError(
                f"{path}, line {lineno}: the first row holds numbers ({cell!r}), expected a "
                "header row of channel names"
            )
        if name in units:
            raise FileFormatError(f"{path}, line {lineno}: channel name {name!r} is repeated")
        names.append(name)
        units[name] = (match.group("unit") or "").strip() if match else ""
    return names, units


def _parse_rows(
    path: Path, lines: list[str], start: int, width: int, delimiter: str
) -> NDArray[np.float64]:
    rows = [
        (k + 1, line)
        for k, line in enumerate(lines[start:], start=start)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise FileFormatError(f"{path}: header but no data rows")
    try:
        data = np.loadtxt(
            io.StringIO("\n".join(line for _, line in rows)),
            delimiter=delimiter,
            ndmin=2,
            dtype=float,
            comments=None,
            quotechar='"',
        )
    except ValueError:
        data = None
    if data is not None and data.shape == (len(rows), width):
        return data
    # The fast parser failed: walk the rows to say where and what.
    for lineno, line in rows:
        cells = line.split(delimiter)
        if len(cells) != width:
            raise FileFormatError(
                f"{path}, line {lineno}: {len(cells)} field(s), the header has {width}"
                f"{' (truncated line?)' if len(cells) < width else ''}"
            )
        for col, cell in enumerate(cells, start=1):
            try:
                float(cell.strip().strip('"'))
            except ValueError:
                raise FileFormatError(
                    f"{path}, line {lineno}, column {col}: {cell.strip()!r} is not a number"
                ) from None
    raise FileFormatError(f"{path}: unreadable numeric data")  # pragma: no cover
