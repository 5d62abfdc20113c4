"""CSV rig files: the data rows, streamed from disk and checked where they fail.

The text is read through :func:`servoid._files.open_input` (a regular
file, within the budget, never past the size checked) and decoded as UTF-8.
``numpy.loadtxt`` converts the rows; when it fails, the rows are walked
again to name the line and column and what is wrong with the cell (text,
digit grouping, a byte-order mark, digits of another script). A last line
without a line end is compared with the lines above it: a number cut short
is refused (see :mod:`servoid.data._csv`).
"""

from __future__ import annotations

import codecs
import io
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._errors import FileFormatError
from .._files import describe_encoding, open_input

__all__ = ["LINE_LIMIT", "Rows", "not_utf8", "open_text", "parse_rows"]

#: Longest line read while looking for the header [characters]: a header or data row is a
#: few kilobytes; a file without line ends (binary data, one huge line) is refused at it.
LINE_LIMIT = 1 << 24
_LINE_END = re.compile(r"\r\n|\r|\n")
_BOM = "\ufeff"
# Sign, integer digits, decimals, exponent digits of a number as written.
_NUMBER_SHAPE = re.compile(
    r"^[+-]?(?P<int>\d*)(?:\.(?P<dec>\d*))?(?:[eE][+-]?(?P<exp>\d*))?$"
)
#: Lines above the last one that its format is compared with (at least, at most):
#: fewer than 5 say too little about a format to call a value short.
_FORMAT_MIN, _FORMAT_WINDOW = 5, 1000


def open_text(path: Path, max_bytes: int | None) -> io.TextIOWrapper:
    """The file as UTF-8 text (a leading BOM dropped), checked and bounded."""
    return io.TextIOWrapper(open_input(path, "file", max_bytes=max_bytes),
                            encoding="utf-8-sig", newline=None)


def not_utf8(path: Path, found: str | None = None) -> FileFormatError:
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


class Rows:
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
        with open_text(self.path, self.max_bytes) as f:
            for _ in range(self.start):
                f.readline(LINE_LIMIT)
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


def parse_rows(
    path: Path, rows: Rows, keep: list[int], width: int, cells: list[str],
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


def _diagnose(path: Path, rows: Rows, keep: list[int], width: int,
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
        raise not_utf8(path) from None
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


def _check_last_line(path: Path, rows: Rows, cells: list[str]) -> None:
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
