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

The file is checked before it is opened (a regular file within the
budget: a FIFO, a device or a link loop is refused by name) and read no
further than its size then. Text in another encoding than UTF-8 (UTF-16
from a spreadsheet's "Unicode text", UTF-32) is named with the fix; a
leading byte-order mark is dropped, one inside the file is named.

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
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from .._checks import as_bool, as_int, as_path, as_str, type_error
from .._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    OptionError,
    ServoidError,
)
from .._files import check_input_file, describe_encoding
from .._spreadsheet import is_formula
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
from ._csv_rows import LINE_LIMIT as _LINE_LIMIT
from ._csv_rows import Rows as _Rows
from ._csv_rows import not_utf8 as _not_utf8
from ._csv_rows import open_text as _open_text
from ._csv_rows import parse_rows as _parse_rows
from ._experiment import Experiment, check_experiment

__all__ = ["header_names", "read_csv", "write_csv"]

ColumnsArg = Sequence[str | int] | None

_HEADER_CELL = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
_DECIMAL_COMMA = re.compile(r"[-+]?\d+,\d+")
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
    time_unit : {"s", "ms", "us", "ns"}, optional
        Unit of the time column when its header gives none (a header
        ``time [ms]`` says it itself). Without a unit, time stamps of whole
        numbers stepping by 1 or more (milliseconds written 0, 1, 2, …) are
        refused: read as seconds, every result would be 1000 times off;
        ``time_unit="s"`` takes them as seconds. Stamps stepping by 0.1 s
        or more over hundreds of samples draw a warning.
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
        Budget [bytes]: a larger file is refused before it is opened;
        default 2 GiB. The text is streamed, not held: memory goes to
        the columns read. A file that grows while it is read is read as
        it was when checked.
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
        Empty file, ragged rows, non-numeric cells (with line and column,
        naming digit grouping or a byte-order mark), a preamble before the
        header, text in UTF-16 or another encoding (named), time stamps of
        whole numbers without a unit, or a path that is not a regular file
        (a folder, FIFO, device or link loop, named).
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
    formula = next((cell for cell in header if is_formula(cell)), None)
    if formula is not None:  # a spreadsheet opening the file would run it
        raise DataError(f"the CSV header cell {formula!r} starts with {formula[0]!r}, which a "
                        "spreadsheet runs as a formula; rename the channel, or write TDMS")
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
