"""CSV rig files: one header row of names (with units), one row per sample.

Layout read and written::

    time [s],position [m],current [A]
    0.0,0.00123,0.5
    0.001,0.00125,0.51

A header cell ``name [unit]`` gives the channel name and its unit. Blank
lines and lines starting with ``#`` before the header or among the data are
skipped.

A file cut short inside its last number still parses: ``0.12345`` becomes
``0.12``, ``1.5e-05`` becomes ``1.5e-0``. So a last data line without a line
end is compared with the lines above it: fewer fields than the header, or a
last value written shorter than the column's format (fewer decimals or
exponent digits than every value above it in a fixed format, fewer
characters than every value above it otherwise; at least five lines above,
at most the last thousand) is a
:class:`FileFormatError`. An error rather than a warning and a dropped
line: the check is a heuristic, and a sample silently lost to a false alarm
is worse than a message whose fix (end the file with a newline) takes a
second.
"""

from __future__ import annotations

import csv
import io
import os
import re
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._atomic import atomic_path
from .._checks import as_bool, as_path, as_str
from .._errors import DataError, FileFormatError, ServoidWarning
from ._columns import (
    DEFAULT_MAX_BYTES,
    TIME_TOLERANCE,
    RolesArg,
    build_experiment,
    check_file_size,
    check_max_bytes,
    check_reader_options,
    existing_file,
)
from ._experiment import Experiment, check_experiment

__all__ = ["read_csv", "write_csv"]

_HEADER_CELL = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
# Sign, integer digits, decimals, exponent digits of a number as written.
_NUMBER_SHAPE = re.compile(
    r"^[+-]?(?P<int>\d*)(?:\.(?P<dec>\d*))?(?:[eE][+-]?(?P<exp>\d*))?$"
)
#: Lines above the last one that its format is compared with (at least, at most):
#: fewer than 5 say too little about a format to call a value short.
_FORMAT_MIN, _FORMAT_WINDOW = 5, 1000
_DECIMAL_COMMA = re.compile(r"[-+]?\d+,\d+")
_TIME_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}


def read_csv(
    path: str | os.PathLike[str],
    *,
    dt: float | None = None,
    time: str | None = "time",
    roles: RolesArg = None,
    delimiter: str = ",",
    decimal: str = ".",
    time_unit: str | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    jitter: float = TIME_TOLERANCE,
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
        Field separator. A file whose header splits only on ``;`` or a tab
        is refused with the fix.
    decimal : {".", ","}
        Decimal mark; ``","`` (European spreadsheets) needs another
        delimiter.
    time_unit : {"s", "ms", "us"}, optional
        Unit of the time column when its header gives none (a header
        ``time [ms]`` says it itself). Time stamps that step by 0.1 s or
        more over hundreds of samples draw a warning that they may be in
        another unit.
    max_bytes : int
        Memory budget [bytes]: a larger file is refused before it is read
        (its text is held while parsing); default 2 GiB.
    jitter : float
        Largest deviation of a time step from the mean step, as a fraction
        of it (default 1e-3); raise it for a logger with time-stamp jitter.

    Returns
    -------
    Experiment
        Named after the file stem.

    Raises
    ------
    FileFormatError
        Empty file, ragged rows or non-numeric cells (with line and column).
    DataError
        The file is larger than `max_bytes`.
    ChannelError
        A column named in ``roles`` is not in the file.
    """
    path = existing_file(path)
    dt = check_reader_options(dt=dt, roles=roles, names={"time": time})
    as_str("delimiter", delimiter)
    if len(delimiter) != 1:
        raise DataError(f"delimiter must be one character (',' or ';' or '\\t'), got {delimiter!r}")
    if decimal not in (".", ","):
        raise DataError(f"decimal must be '.' or ',', got {decimal!r}")
    if decimal == "," and delimiter == ",":
        raise DataError("a decimal comma needs another field separator: pass delimiter=';' "
                        "(or a tab) with decimal=','")
    if time_unit is not None and time_unit not in _TIME_UNITS:
        raise DataError(f"time_unit must be one of {', '.join(repr(u) for u in _TIME_UNITS if u)}"
                        f", got {time_unit!r}")
    check_file_size(path, check_max_bytes(max_bytes))
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
    _check_separator(path, lines, header_at, delimiter, decimal)
    if decimal == ",":
        lines = lines[: header_at + 1] + [line.replace(",", ".") for line in lines[header_at + 1:]]
    names, units = _parse_header(path, lines[header_at], header_at + 1, delimiter)
    unterminated = not text.endswith(("\n", "\r"))
    data = _parse_rows(path, lines, header_at + 1, names, delimiter, unterminated)
    columns = {n: data[:, k] for k, n in enumerate(names)}
    stamps = None
    if time is not None and time in columns:
        unit = units.get(time, "") or (time_unit or "")
        scale = _TIME_UNITS.get(unit)
        if scale is None:
            raise FileFormatError(
                f"{path}: time column {time!r} has unit {units[time]!r}; expected one of "
                f"{', '.join(repr(u) for u in _TIME_UNITS)}"
            )
        stamps = columns.pop(time) * scale
        _check_time_unit(path, stamps, time, bool(units.get(time)) or time_unit is not None)
    elif dt is None:
        hint = f"it has no column {time!r}; " if time is not None else ""
        raise DataError(
            f"{path}: no sample period: {hint}pass dt [s] or time=<column name> "
            f"(columns: {', '.join(names)})"
        )
    return build_experiment(path, columns, units, roles=roles, dt=dt, time=stamps,
                            jitter=jitter)


def _check_separator(path: Path, lines: list[str], header_at: int, delimiter: str,
                     decimal: str) -> None:
    """Refuse a file whose separator or decimal mark is not the one asked for, naming the fix."""
    header = lines[header_at]
    if delimiter not in header:
        for other, word in ((";", "';'"), ("\t", "'\\t' (a tab)"), (",", "','")):
            if other != delimiter and other in header:
                raise FileFormatError(
                    f"{path}: the header has no {delimiter!r} but is separated by {word}: pass "
                    f"delimiter={word.split()[0]}")
    row = next((line for line in lines[header_at + 1:] if line.strip()), "")
    comma = _DECIMAL_COMMA.search(row)
    if decimal == "." and delimiter != "," and comma:
        raise FileFormatError(f"{path}: numbers like {comma.group()} use a decimal comma: pass "
                              "decimal=','")


def _check_time_unit(path: Path, stamps: NDArray[np.float64], name: str, stated: bool) -> None:
    """Warn when time stamps without a stated unit step like milliseconds read as seconds."""
    if stated or stamps.size < 200:
        return
    step = float(np.median(np.diff(stamps[:1000])))
    if step >= 0.1:
        warnings.warn(
            f"{path}: time column {name!r} has no unit and steps by {step:g} s, a slow rate for "
            f"a servo test ({1 / step:g} Hz); if it is in milliseconds, say so: time_unit='ms' "
            f"([data] time_unit = \"ms\" in an experiment file) or a header '{name} [ms]'", ServoidWarning, stacklevel=4)


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
    check_experiment(exp, "exp")
    as_path("path", path)
    as_bool("overwrite", overwrite)
    as_bool("time", time)
    if time and "time" in exp.names:
        raise DataError("a channel is called 'time'; rename it or pass time=False")
    header = [_header_cell(ch.name, ch.unit) for ch in exp.channels]
    cols = [ch.values for ch in exp.channels]
    if time:
        header.insert(0, "time [s]")
        cols.insert(0, exp.time)
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(header)
    _check_header(buf.getvalue(), exp)
    # repr() is the shortest string that parses back to the same double.
    buf.writelines(",".join(map(repr, row)) + "\n" for row in np.column_stack(cols).tolist())
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
    return Path(path)


def _header_cell(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _check_header(text: str, exp: Experiment) -> None:
    """Refuse a header row that :func:`read_csv` would read back differently.

    A header cell is ``name [unit]``: a unit holding ``]``, a name ending
    in ``[...]`` without a unit, a name that is a number or a line break
    in either would come back as another name or unit, or not at all.
    (Spaces around a unit are dropped on reading, as typed by hand.)
    """
    for ch in exp.channels:
        cell = _header_cell(ch.name, ch.unit)
        got = _read_back(cell)
        if got == (ch.name, ch.unit.strip()) and not _is_number(ch.name):
            continue
        if ch.unit and _read_back(_header_cell(ch.name, "V")) == (ch.name, "V") \
                and not _is_number(ch.name):
            back = "holds a line break" if got is None else \
                f"would read back as channel {got[0]!r} with unit {got[1]!r}"
            raise DataError(
                f"unit = {ch.unit!r} of channel {ch.name!r} cannot be written to a CSV file: "
                f"its header cell {cell!r} {back}; a CSV header cell is 'name [unit]', so the "
                "unit must not contain ']' or a line break: choose another unit, or write TDMS"
            )
        back = ("is read as a number" if _is_number(ch.name) else
                "holds a line break" if got is None else
                f"would read back as channel {got[0]!r} with unit {got[1]!r}")
        raise DataError(
            f"channel name {ch.name!r} cannot be written to a CSV file: its header cell "
            f"{cell!r} {back}; a CSV header cell is 'name [unit]': choose a name that is not a "
            "number, has no line break or surrounding spaces and does not end in '[...]', or "
            "write TDMS"
        )
    if text.lstrip().startswith("#"):
        raise DataError(
            f"channel name {exp.channels[0].name!r} cannot head the first column of a CSV "
            "file: a header row starting with '#' is read as a comment; write the time column "
            "(time=True) or choose a name that does not start with '#'"
        )


def _read_back(cell: str) -> tuple[str, str] | None:
    """(name, unit) as :func:`_parse_header` reads ``cell``; None: not one line."""
    if "\n" in cell or "\r" in cell:
        return None
    match = _HEADER_CELL.match(cell)
    return (match.group("name"), (match.group("unit") or "").strip()) if match else None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


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
    path: Path, lines: list[str], start: int, names: list[str], delimiter: str,
    unterminated: bool,
) -> NDArray[np.float64]:
    width = len(names)
    rows = [
        (k + 1, line)
        for k, line in enumerate(lines[start:], start=start)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise FileFormatError(f"{path}: header but no data rows")
    # Only a data line that ends the file without a line end can be cut short.
    cut = unterminated and rows[-1][0] == len(lines)
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
        if cut:
            _check_last_line(path, rows, names, delimiter)
        return data
    # The fast parser failed: walk the rows to say where and what.
    for lineno, line in rows:
        cells = line.split(delimiter)
        if len(cells) != width:
            last = cut and lineno == rows[-1][0]
            raise FileFormatError(
                f"{path}, line {lineno}: {len(cells)} field(s), the header has {width}"
                + (" (the last line, with no line end: the file looks truncated; copy it "
                   "again or delete the partial line)" if last and len(cells) < width
                   else " (truncated line?)" if len(cells) < width else "")
            )
        for col, cell in enumerate(cells, start=1):
            try:
                float(cell.strip().strip('"'))
            except ValueError:
                raise FileFormatError(
                    f"{path}, line {lineno}, column {col}: {cell.strip()!r} is not a number"
                ) from None
    raise FileFormatError(f"{path}: unreadable numeric data")  # pragma: no cover


def _check_last_line(
    path: Path, rows: list[tuple[int, str]], names: list[str], delimiter: str
) -> None:
    """Raise if the unterminated last line's last value looks cut short."""
    if len(rows) <= _FORMAT_MIN:
        return  # too few lines above to know their format
    lineno, line = rows[-1]
    last = _cell(line, delimiter)
    above = [_cell(text, delimiter) for _, text in rows[-1 - _FORMAT_WINDOW : -1]]
    short = _shorter_than_format(last, above)
    if short is None:
        return
    raise FileFormatError(
        f"{path}, line {lineno}: the last line has no line end and its last value "
        f"{last!r} ({names[-1]!r}) is written shorter than the values above it ({short}): "
        "the file looks truncated inside that number. If the line is complete, end the file "
        "with a newline; otherwise delete the line or copy the file again"
    )


def _cell(line: str, delimiter: str) -> str:
    return line.rsplit(delimiter, 1)[-1].strip().strip('"').strip()


def _shorter_than_format(last: str, above: list[str]) -> str | None:
    """Why ``last`` is shorter than the format of ``above``, or None."""
    shape = _NUMBER_SHAPE.match(last)
    shapes = [_NUMBER_SHAPE.match(a) for a in above]
    if shape is None or not all(shapes):
        return None  # nan, inf or another spelling: no format to compare
    decimals = {len(m.group("dec") or "") for m in shapes if m}
    exponents = {m.group("exp") is not None and len(m.group("exp")) for m in shapes if m}
    (want_dec,), (want_exp,) = (
        (decimals, exponents) if len(decimals) == len(exponents) == 1 else ({0}, {False})
    )
    if want_dec or want_exp:  # a fixed format, e.g. %.6f or %.4e
        dec = len(shape.group("dec") or "")
        exp = shape.group("exp")
        if dec < want_dec:
            return f"{dec} decimals, every value above has {want_dec}"
        if want_exp and (exp is None or len(exp) < want_exp):
            return f"every value above has {want_exp} exponent digits"
        return None
    shortest = min(above, key=len)
    if len(last) < len(shortest):
        return f"{len(last)} characters, the shortest above is {shortest!r}"
    return None
