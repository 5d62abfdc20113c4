"""CSV rig files: one header row of names (with units), one row per sample.

Layout read and written::

    time [s],position [m],current [A]
    0.0,0.00123,0.5
    0.001,0.00125,0.51

A header cell ``name [unit]`` gives the channel name and its unit. Blank
lines and lines starting with ``#`` before the header or among the data are
skipped. Rig loggers often write more: a preamble of lines before the
header (``skip_rows`` skips it; a preamble that is not skipped is detected
and refused naming that fix), columns nobody needs (``columns`` or
``skip_columns``: the others are never converted to numbers, so a wide file
costs memory only for the columns read), and a trailing delimiter on every
line (an unnamed empty last column, tolerated).

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

import codecs
import csv
import io
import os
import re
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._atomic import atomic_path
from .._checks import as_bool, as_int, as_path, as_str, type_error
from .._files import check_input_file, describe_encoding, open_input
from .._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    OptionError,
    ServoidError,
    ServoidWarning,
)
from ._columns import (
    DEFAULT_MAX_BYTES,
    TIME_TOLERANCE,
    TIME_UNITS,
    RolesArg,
    build_experiment,
    check_file_size,
    check_max_bytes,
    check_reader_options,
    existing_file,
    time_in_seconds,
)
from ._experiment import Experiment, check_experiment

__all__ = ["header_names", "read_csv", "write_csv"]

ColumnsArg = Sequence[str | int] | None

_HEADER_CELL = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
# Sign, integer digits, decimals, exponent digits of a number as written.
_NUMBER_SHAPE = re.compile(
    r"^[+-]?(?P<int>\d*)(?:\.(?P<dec>\d*))?(?:[eE][+-]?(?P<exp>\d*))?$"
)
#: Lines above the last one that its format is compared with (at least, at most):
#: fewer than 5 say too little about a format to call a value short.
_FORMAT_MIN, _FORMAT_WINDOW = 5, 1000
_DECIMAL_COMMA = re.compile(r"[-+]?\d+,\d+")
_LINE_END = re.compile(r"\r\n|\r|\n")
#: Longest line read while looking for the header [characters]: a header or data row is a
#: few kilobytes; a file without line ends (binary data, one huge line) is refused at it.
_LINE_LIMIT = 1 << 24
#: Characters that cannot separate fields: they are part of numbers, quotes or line ends.
_BAD_DELIMITERS = set("0123456789.+-eE\"#\r\n\0")
_BOM = "\ufeff"


def read_csv(
    path: str | os.PathLike[str],
    *,
    dt: float | None = None,
    time: str | None = "time",
    roles: RolesArg = None,
    delimiter: str = ",",
    decimal: str = ".",
    time_unit: str | None = None,
    columns: ColumnsArg = None,
    skip_columns: ColumnsArg = None,
    skip_rows: int = 0,
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
    columns : sequence of str or int, optional
        The columns to read, by header name or 0-based index; the time
        column is read too when it is in the file. Default: all. Only
        these are converted to numbers.
    skip_columns : sequence of str or int, optional
        Columns not to read, by name or 0-based index (e.g. a logger's
        status text or an unnamed column); not with ``columns``.
    skip_rows : int
        Lines at the start of the file to skip before looking for the
        header: a logger's preamble. A preamble left unskipped is refused
        with the number to pass.
    max_bytes : int
        Budget [bytes]: a larger file is refused before it is read;
        default 2 GiB. The text is streamed, not held: memory goes to
        the columns read.
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
        Empty file, ragged rows, non-numeric cells (with line and column),
        or a preamble before the header.
    DataError
        The file is larger than `max_bytes`.
    ChannelError
        A column named in ``roles``, ``columns`` or ``skip_columns`` is not
        in the file.
    """
    path = existing_file(path)
    dt = check_reader_options(dt=dt, roles=roles, names={"time": time})
    _check_delimiter(delimiter)
    if decimal not in (".", ","):
        raise DataError(f"decimal must be '.' or ',', got {decimal!r}")
    if decimal == "," and delimiter == ",":
        raise DataError("a decimal comma needs another field separator: pass delimiter=';' "
                        "(or a tab) with decimal=','")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise DataError(f"time_unit must be one of {', '.join(repr(u) for u in TIME_UNITS)}"
                        f", got {time_unit!r}")
    wanted = _column_list("columns", columns)
    skipped = _column_list("skip_columns", skip_columns)
    if wanted is not None and skipped is not None:
        raise OptionError("give columns= (what to read) or skip_columns= (what not to read), "
                          "not both")
    skip_rows = as_int("skip_rows", skip_rows, minimum=0)
    max_bytes = check_max_bytes(max_bytes)
    check_file_size(path, max_bytes)
    lines, header_at = _read_head(path, skip_rows, max_bytes)
    _check_preamble(path, lines, header_at, delimiter)
    _check_separator(path, lines, header_at, delimiter, decimal)
    cells, units_of = _parse_header(path, lines[header_at], header_at + 1, delimiter)
    first = next((line for line in lines[header_at + 1:]
                  if line.strip() and not line.lstrip().startswith("#")), None)
    if first is None:
        raise FileFormatError(f"{path}: header but no data rows")
    if decimal == ",":
        first = first.replace(",", ".")
    width = _row_width(cells, first, delimiter)
    keep = _kept_columns(path, cells, wanted, skipped, time)
    names = [cells[k] for k in keep]
    _check_names(path, cells, keep, header_at + 1)
    units = {cells[k]: units_of[k] for k in keep}
    rows = _Rows(path, header_at + 1, delimiter, decimal, count=keep != list(range(width)),
                 max_bytes=max_bytes)
    data = _parse_rows(path, rows, keep, width, cells)
    columns_read = {n: data[:, j] for j, n in enumerate(names)}
    stamps = None
    if time is not None and time in columns_read:
        unit = units.get(time, "") or time_unit
        if unit is not None and unit not in TIME_UNITS:
            raise FileFormatError(
                f"{path}: time column {time!r} has unit {units[time]!r}; expected one of "
                f"{', '.join(repr(u) for u in TIME_UNITS)}"
            )
        stamps = time_in_seconds(
            path, columns_read.pop(time), time, unit,
            f"time_unit='ms' (or 'us', or 's' if they are seconds; [data] time_unit = \"ms\" in "
            f"an experiment file) or a header '{time} [ms]'")
    elif dt is None:
        hint = f"it has no column {time!r}; " if time is not None else ""
        raise DataError(
            f"{path}: no sample period: {hint}pass dt [s] or time=<column name> "
            f"(columns: {', '.join(c for c in cells if c)})"
        )
    return build_experiment(path, columns_read, units, roles=roles, dt=dt, time=stamps,
                            jitter=jitter)


def header_names(path: Path, *, delimiter: str = ",", skip_rows: int = 0) -> list[str] | None:
    """The names in a CSV file's header row ("" for an unnamed cell).

    Parameters
    ----------
    path : pathlib.Path
        The file; only its head is read.
    delimiter : str
        Field separator.
    skip_rows : int
        Lines skipped before looking for the header.

    Returns
    -------
    list of str or None
        The names, or None when the file or its header cannot be read
        (:func:`read_csv` then says why).
    """
    try:
        _check_delimiter(delimiter)
        check_input_file(path, "file")
        lines, header_at = _read_head(path, skip_rows, None)
        return _parse_header(path, lines[header_at], header_at + 1, delimiter)[0]
    except (ServoidError, OSError):
        return None


def _check_delimiter(delimiter: object) -> None:
    """Refuse a field separator that is not one character that can separate numbers."""
    as_str("delimiter", delimiter)
    assert isinstance(delimiter, str)
    if len(delimiter) != 1:
        raise DataError(f"delimiter must be one character (',' or ';' or '\\t'), got "
                        f"{delimiter!r}")
    if delimiter in _BAD_DELIMITERS:
        raise DataError(f"delimiter {delimiter!r} cannot separate fields: it is part of numbers, "
                        "quotes, comments or line ends; use ',' or ';' or '\\t' (a tab)")


def _column_list(key: str, value: ColumnsArg) -> list[str | int] | None:
    """``columns`` or ``skip_columns`` as a list of names and indices, checked."""
    if value is None:
        return None
    expected = "a list of column names or 0-based column indices"
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise type_error(key, value, expected)
    items = list(value)
    if not items:
        raise DataError(f"{key} must name at least one column, got []")
    for item in items:
        if isinstance(item, bool) or not isinstance(item, (str, int)):
            raise type_error(key, value, expected)
        if isinstance(item, int) and item < 0:
            raise DataError(f"{key} holds the index {item}: indices count from 0 (the first "
                            "column) and must be >= 0")
        if isinstance(item, str) and not item.strip():
            raise DataError(f"{key} holds an empty name; name a column of the header, or give "
                            "its 0-based index")
    repeated = sorted({repr(i) for i in items if items.count(i) > 1})
    if repeated:
        raise DataError(f"{key} lists {', '.join(repeated)} more than once")
    return items


def _check_preamble(path: Path, lines: list[str], header_at: int, delimiter: str) -> None:
    """Refuse lines of text before the header row, naming ``skip_rows``.

    The header row is taken as the last line without numbers before the
    first line of (mostly) numbers; text lines above it are a preamble
    left unskipped. A units row under the header looks the same, so the
    message names both readings.
    """
    first_data = None
    for k in range(header_at + 1, min(len(lines), header_at + _PREAMBLE_WINDOW)):
        line = lines[k]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if _mostly_numbers(line, delimiter):
            first_data = k
            break
    if first_data is None:
        return
    width = len(lines[first_data].split(delimiter))
    candidates = [k for k in range(header_at, first_data)
                  if lines[k].strip() and not lines[k].lstrip().startswith("#")]
    real = candidates[-1]
    if real == header_at or _any_number(lines[real], delimiter):
        return
    if len(lines[real].split(delimiter)) < width - 1:
        return  # not a header for these rows either: leave the field-count error to say so
    above = lines[header_at].strip()
    raise FileFormatError(
        f"{path}: line {real + 1} ({_short(lines[real])!r}) looks like the header row and "
        f"the lines above it, from line {header_at + 1} ({_short(above)!r}), like a logger's "
        f"preamble: pass skip_rows={real} to skip the lines before the header "
        f"(if line {real + 1} is a row of units instead, write the units into the header "
        "cells as 'name [unit]')"
    )


#: Lines after the header searched for the first line of numbers (preamble detection).
_PREAMBLE_WINDOW = 200


def _short(text: str, n: int = 40) -> str:
    text = text.strip()
    return text if len(text) <= n else text[: n - 1] + "…"


def _mostly_numbers(line: str, delimiter: str) -> bool:
    """A data line: more than half its non-empty cells are numbers (status text allowed)."""
    cells = [c.strip().strip('"') for c in line.split(delimiter)]
    cells = [c for c in cells if c]
    numbers = sum(_is_number(c) or _is_number(c.replace(",", ".")) for c in cells)
    return 2 * numbers > len(cells)


def _any_number(line: str, delimiter: str) -> bool:
    return any(_is_number(c.strip().strip('"')) for c in line.split(delimiter) if c.strip())


def _row_width(cells: list[str], first_row: str, delimiter: str) -> int:
    """The number of fields every data row must have.

    The header's, or the first row's when the two differ only by unnamed
    empty columns at the end (a trailing delimiter on either).
    """
    fields = first_row.split(delimiter)
    named = len(cells)
    while named and not cells[named - 1]:
        named -= 1
    if len(fields) != len(cells) and len(fields) >= named and \
            all(not f.strip() for f in fields[named:]):
        return len(fields)
    return len(cells)


def _kept_columns(path: Path, cells: list[str], wanted: list[str | int] | None,
                  skipped: list[str | int] | None, time: str | None) -> list[int]:
    """Indices of the columns to read, in file order."""
    named = len(cells)
    while named and not cells[named - 1]:
        named -= 1  # unnamed trailing columns: a trailing delimiter
    if wanted is None and skipped is None:
        return list(range(named))
    key = "columns" if wanted is not None else "skip_columns"
    chosen = {_column_index(path, key, item, cells) for item in (wanted or skipped or [])}
    if wanted is not None:
        if time is not None and time in cells:
            chosen.add(cells.index(time))
        return sorted(chosen)
    return [k for k in range(named) if k not in chosen]


def _column_index(path: Path, key: str, item: str | int, cells: list[str]) -> int:
    listing = ", ".join(f"{k}: {c!r}" if c else f"{k}: (unnamed)" for k, c in enumerate(cells))
    if isinstance(item, int):
        if item >= len(cells):
            raise ChannelError(
                f"{key}= holds the index {item}, but {path} has {len(cells)} column(s), "
                f"0..{len(cells) - 1}: {listing}"
            )
        return item
    found = [k for k, c in enumerate(cells) if c == item]
    if not found:
        raise ChannelError(
            f"{key}= names the column {item!r}, which is not in the header of {path}; its "
            f"columns are {listing}"
        )
    if len(found) > 1:
        raise FileFormatError(
            f"{key}= names the column {item!r}, but {path} has {len(found)} columns of that "
            f"name (indices {', '.join(map(str, found))}): give the 0-based index instead"
        )
    return found[0]


def _check_names(path: Path, cells: list[str], keep: list[int], lineno: int) -> None:
    """Refuse an empty or repeated name among the columns read."""
    for k in keep:
        if not cells[k]:
            raise FileFormatError(
                f"{path}, line {lineno}, column {k + 1}: empty channel name; name the column "
                f"in the header, or leave it out with skip_columns=[{k}] (0-based index)"
            )
    seen: dict[str, int] = {}
    for k in keep:
        if cells[k] in seen:
            raise FileFormatError(
                f"{path}, line {lineno}: channel name {cells[k]!r} is repeated (columns "
                f"{seen[cells[k]] + 1} and {k + 1}); rename one, or leave one out with "
                f"skip_columns=[{k}] (0-based index)"
            )
        seen[cells[k]] = k


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
) -> tuple[list[str], list[str]]:
    """Names and units of the header cells; an unnamed cell is ``""``."""
    if _BOM in line:
        raise FileFormatError(
            f"{path}, line {lineno}: the header row holds a byte-order mark (U+FEFF) at "
            f"character {line.index(_BOM) + 1}, the mark a text editor writes at the start of "
            "a file: two files were probably joined here; delete the mark (and any lines of "
            "the other file)"
        )
    try:
        cells = next(csv.reader([line], delimiter=delimiter))
    except csv.Error as exc:
        longest = max(len(c) for c in line.split(delimiter))
        raise FileFormatError(
            f"{path}, line {lineno}: the header row cannot be split into cells ({exc}; its "
            f"longest cell has {longest:,} characters): a header names the channels, such as "
            "'time [s],u [V],y [m]'; if the header is further down, pass skip_rows="
        ) from None
    names: list[str] = []
    units: list[str] = []
    for cell in cells:
        match = _HEADER_CELL.match(cell)
        name = match.group("name") if match else ""
        if name:
            try:
                float(name)
            except ValueError:
                pass
            else:
                raise FileFormatError(
                    f"{path}, line {lineno}: the first row holds numbers ({cell!r}), expected "
                    "a header row of channel names"
                )
        names.append(name)
        units.append((match.group("unit") or "").strip() if match and name else "")
    return names, units


def _read_head(path: Path, skip_rows: int, max_bytes: int | None) -> tuple[list[str], int]:
    """The lines up to the header and a window after it; the header's index.

    The window reaches the first data line and at least
    :data:`_PREAMBLE_WINDOW` lines past the header (or the end of the file):
    enough to check the separator, the header and a preamble without
    reading the data, which are streamed later. No line longer than
    :data:`_LINE_LIMIT` is read whole.
    """
    lines: list[str] = []
    header_at = first_row = None
    try:
        with _open_text(path, max_bytes) as f:
            found = describe_encoding(f.buffer.peek(4096)[:4096])
            if found:
                raise _not_utf8(path, found)
            while line := f.readline(_LINE_LIMIT):
                if len(line) >= _LINE_LIMIT and not line.endswith(("\n", "\r")):
                    raise FileFormatError(
                        f"{path}, line {len(lines) + 1}: more than {_LINE_LIMIT:,} characters "
                        "without a line end: not a CSV file of text lines (a binary file, or "
                        "one whose line ends were lost)"
                    )
                lines.append(line.rstrip("\r\n"))
                k = len(lines) - 1
                text = lines[-1]
                if k < skip_rows or not text.strip() or text.lstrip().startswith("#"):
                    continue
                if header_at is None:
                    header_at = k
                elif first_row is None:
                    first_row = k
                if first_row is not None and k - header_at >= _PREAMBLE_WINDOW:
                    break
    except UnicodeDecodeError:
        raise _not_utf8(path) from None
    if skip_rows and skip_rows >= len(lines):
        raise FileFormatError(
            f"{path}: skip_rows={skip_rows} skips every line (the file has {len(lines)}); "
            "set it to the number of lines before the header row"
        )
    if header_at is None:
        raise FileFormatError(f"{path}: empty CSV file, expected a header row of channel names")
    return lines, header_at


def _open_text(path: Path, max_bytes: int | None) -> io.TextIOWrapper:
    """The file as UTF-8 text (a leading BOM dropped), checked and bounded."""
    return io.TextIOWrapper(open_input(path, "file", max_bytes=max_bytes),
                            encoding="utf-8-sig", newline=None)


def _not_utf8(path: Path, found: str | None = None) -> FileFormatError:
    """The error for a file that is not UTF-8 text: its encoding, or the first bad byte."""
    if found is None:
        with open_input(path, "file") as f:
            found = describe_encoding(f.read(4096))
    if found:
        return FileFormatError(
            f"{path}: not a text CSV file in UTF-8: it is {found}. servoid reads CSV files "
            "in UTF-8: save it as 'CSV UTF-8' (a spreadsheet's 'Unicode text' is UTF-16), or "
            "convert it, e.g. iconv -f UTF-16 -t UTF-8 in.csv > out.csv"
        )
    decoder = codecs.getincrementaldecoder("utf-8")()
    done = 0
    with open_input(path, "file") as f:
        while chunk := f.read(1 << 20):
            try:
                decoder.decode(chunk)
            except UnicodeDecodeError as exc:
                return FileFormatError(f"{path}: not a text CSV file (byte {done + exc.start} "
                                       "is not UTF-8)")
            done += len(chunk)
    return FileFormatError(f"{path}: not a text CSV file (it ends inside a UTF-8 character)")


class _Rows:
    """The data lines of a CSV file, streamed from disk (never all in memory).

    Blank and comment lines are dropped, a decimal comma becomes a point,
    and with ``count`` the fewest and most delimiters on a line are kept:
    when only some columns are converted, loadtxt does not see the others.
    """

    def __init__(self, path: Path, start: int, delimiter: str, decimal: str,
                 count: bool, max_bytes: int | None = None) -> None:
        self.path, self.start, self.delimiter = path, start, delimiter
        self.max_bytes = max_bytes
        self.comma, self.count = decimal == ",", count
        self.n = self.lines = 0
        self.fewest = self.most = -1

    def __iter__(self) -> Iterator[str]:
        self.n = self.lines = 0
        fewest = most = -1
        d = self.delimiter
        for _, line in self.numbered():
            if self.count:
                c = line.count(d)
                if c < fewest or fewest < 0:
                    fewest = c
                most = max(most, c)
                self.fewest, self.most = fewest, most
            self.n += 1
            yield line

    def numbered(self) -> Iterator[tuple[int, str]]:
        """(line number, text) of each data line."""
        with _open_text(self.path, self.max_bytes) as f:
            for _ in range(self.start):
                f.readline(_LINE_LIMIT)
            lineno = self.start
            for line in f:
                lineno += 1
                self.lines = lineno
                stripped = line.strip()
                if not stripped or stripped[0] == "#":
                    continue
                yield lineno, line.replace(",", ".") if self.comma else line

    def tail(self, n: int) -> list[tuple[int, str]]:
        """The last ``n`` data lines (numbered), read from the end of the file."""
        step = 1 << 16
        while True:
            with open_input(self.path, "file", max_bytes=self.max_bytes) as f:
                begin = max(0, f.size - step)
                f.seek(begin)
                chunk = f.read().decode("utf-8", errors="replace").lstrip("\ufeff")
            lines = _LINE_END.split(chunk)  # as the text-mode reader splits, not splitlines
            if begin:
                lines = lines[1:]  # the first is partial
            first = self.lines - len(lines) + 1  # number of the first line in the chunk
            out = [(first + k, line.replace(",", ".") if self.comma else line)
                   for k, line in enumerate(lines)
                   if first + k > self.start and line.strip()
                   and not line.lstrip().startswith("#")]
            if len(out) > n or begin == 0:
                return out[-n - 1:]
            step *= 4


def _parse_rows(
    path: Path, rows: _Rows, keep: list[int], width: int, cells: list[str],
) -> NDArray[np.float64]:
    """The kept columns of the data rows; every row must have ``width`` fields."""
    every = keep == list(range(width))
    try:
        data = np.loadtxt(
            rows,
            delimiter=rows.delimiter,
            ndmin=2,
            dtype=float,
            comments=None,
            quotechar='"',
            usecols=None if every else keep,
        )
    except ValueError:  # UnicodeDecodeError too: the walk below says where
        data = None
    if data is not None and data.shape == (rows.n, len(keep)) and (
            every or rows.fewest == rows.most == width - 1):
        if _unterminated(path, rows.max_bytes):
            _check_last_line(path, rows, cells)
        return data
    return _diagnose(path, rows, keep, width, cells)


def _diagnose(path: Path, rows: _Rows, keep: list[int], width: int,
              cells: list[str]) -> NDArray[np.float64]:
    """The fast parser failed: walk the rows to say where and what."""
    cut = _unterminated(path, rows.max_bytes)
    lines = rows.numbered()
    try:
        ahead = next(lines, None)
        while ahead is not None:
            (lineno, line), ahead = ahead, next(lines, None)
            # the last data line, and the file's last line: rows.lines is final once read
            last = cut and ahead is None and lineno == rows.lines
            _check_row(path, lineno, line, rows.delimiter, keep, width, cells, last)
    except UnicodeDecodeError:
        raise _not_utf8(path) from None
    raise FileFormatError(  # pragma: no cover - every cell loadtxt refuses is named above
        f"{path}: unreadable numeric data (no single line or cell could be named: please "
        "report the file)")


def _check_row(path: Path, lineno: int, line: str, delimiter: str, keep: list[int], width: int,
               cells: list[str], last: bool) -> None:
    """Raise naming the line and column if one data line is not ``width`` numbers."""
    fields = line.rstrip("\r\n").split(delimiter)
    if len(fields) != width:
        raise FileFormatError(
            f"{path}, line {lineno}: {len(fields)} field(s), the header has {width}"
            + (" (the last line, with no line end: the file looks truncated; copy it "
               "again or delete the partial line)" if last and len(fields) < width
               else " (truncated line?)" if len(fields) < width else "")
        )
    for k in keep:
        cell = fields[k]
        problem = _cell_problem(cell.strip().strip('"'))
        if problem is None:
            continue
        where = f"{path}, line {lineno}, column {k + 1}"
        if problem:
            raise FileFormatError(f"{where}: {cell.strip()!r} {problem}")
        hint = "" if len(keep) == 1 or not cells[k] else (
            f" (column {cells[k]!r}; if it holds text, leave it out with "
            f"skip_columns=[{k}] or choose the columns to read with columns=[...])")
        raise FileFormatError(f"{where}: {cell.strip()!r} is not a number" + hint)


def _cell_problem(text: str) -> str | None:
    """Why a data cell is not a number servoid reads: None (it is one), "" (it is text), or why.

    ``float()`` accepts more than the CSV parser does (``1_000``, digits of
    other scripts), so a cell it reads is checked for those spellings too.
    """
    try:
        float(text)
    except ValueError:
        if _BOM in text:
            return ("holds a byte-order mark (U+FEFF), the mark a text editor writes at the "
                    "start of a file: two files were probably joined here; delete the mark")
        return ""
    if "_" in text:
        return ("groups its digits with '_' (as in 1_000), which a CSV number may not: write "
                "the number without grouping (1000)")
    if not text.isascii():
        return ("is written with digits other than 0-9 (of another script, or full-width): "
                "write the number with the digits 0-9")
    return None


def _unterminated(path: Path, max_bytes: int | None) -> bool:
    """Whether the file's last line has no line end (it may be cut short)."""
    with open_input(path, "file", max_bytes=max_bytes) as f:
        f.seek(max(0, f.size - 1))
        return f.read(1) not in (b"\n", b"\r")


def _check_last_line(path: Path, rows: _Rows, cells: list[str]) -> None:
    """Raise if the unterminated last line's last value looks cut short."""
    tail = rows.tail(_FORMAT_WINDOW)
    if not tail or tail[-1][0] != rows.lines:
        return  # the file ends in a comment or blank line: no number was cut
    if len(tail) <= _FORMAT_MIN:
        return  # too few lines above to know their format
    lineno, line = tail[-1]
    last = _cell(line, rows.delimiter)
    above = [_cell(text, rows.delimiter) for _, text in tail[:-1]]
    short = _shorter_than_format(last, above)
    if short is None:
        return
    name = cells[-1] or "the last column"
    raise FileFormatError(
        f"{path}, line {lineno}: the last line has no line end and its last value "
        f"{last!r} ({name!r}) is written shorter than the values above it ({short}): "
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
