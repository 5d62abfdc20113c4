"""Structural check of MAT v4 and v5 files before scipy reads them.

scipy's v5 reader is Cython that trusts the file. A data-type code outside
its table indexes past a C array of dtype pointers (SIGSEGV/SIGBUS); a flipped
complex flag makes it read the next element's tag as data; a declared name
or data size is allocated before it is read. Its v4 reader is Python but
reads ``rows × cols × itemsize`` bytes as declared, and negative dimensions
move its file pointer backwards. So a hostile or damaged file must be walked
by a parser that checks every declared size against the bytes present
before scipy sees it. This module is that parser.

What it checks, mirroring exactly what ``scipy.io.loadmat(...,
variable_names=...)`` will parse:

* **v4** (every header, as scipy reads them all): ``MOPT`` digits (IEEE
  byte order, O = 0, a known precision and a full/char/sparse class), the
  name length, the imaginary flag, non-negative dimensions, and that the
  declared data ``rows × cols × itemsize (× 2 if complex)`` lies inside the
  file.
* **v5 headers** (every top-level element, as scipy reads each header):
  tag type miMATRIX or miCOMPRESSED, byte count inside the file, and the
  matrix header scipy parses (array flags present, a dimensions element of
  type miINT32/miUINT32 of at most 32 dimensions, a name element of type
  miINT8/miUTF8 no longer than :data:`MAX_NAME_BYTES`), each inside its
  element. A compressed element is inflated only as far as its header.
* **v5 data** (only variables that will be loaded): numeric or char class,
  real, at least two non-negative dimensions (scipy's ``chars_to_strings``
  indexes the last dimension unchecked), a data element whose type code is one scipy
  knows for that class, whose byte count is exactly ``prod(dims) × itemsize``
  and lies inside the element. A compressed element is inflated in full, to
  at most the memory budget: zlib gives no size up front, so the budget is
  the only bound on what a few kilobytes can expand to.

Anything else (cells, structs, objects, sparse, complex, function handles,
unknown classes) is listed with its class and shape but never loaded, so
scipy never parses its body.

* **v5 struct fields** (only the dotted paths asked for, ``data.signals.y``):
  a 1×1 struct's field-name length and names, and each field's matrix tag
  inside the struct, are walked down the path; the numeric field at its
  end is checked like a wanted variable and decoded here, from the checked
  bytes, so scipy never parses a struct. A struct array or a cell on the
  way is an error naming the path.

Walking checks structure, not values: a flipped bit inside the numbers of a
vector is still read (MAT files carry no checksum outside zlib's).
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Collection
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, BinaryIO, Literal

import numpy as np

from .._errors import ChannelError, FileFormatError
from .._files import format_bytes, open_input

__all__ = ["MAX_NAME_BYTES", "MatEntry", "check_mat", "format_bytes"]

#: Longest variable name accepted [bytes]; MATLAB's limit is 63 characters.
MAX_NAME_BYTES = 4096
#: Largest char variable read as a note [characters].
MAX_NOTE_CHARS = 65536

Kind = Literal[
    "numeric", "char", "complex", "sparse", "cell", "struct", "object", "function",
    "opaque", "external", "unknown",
]

# v5 data-type codes (miINT8 ...) with their item sizes, as in scipy's table.
_MI_NUMERIC = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}
_MI_DTYPE = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8", 12: "i8",
             13: "u8"}
_MI_CHAR = {1: 1, 2: 1, 4: 2, 16: 1, 17: 2, 18: 4}  # int8, uint8, uint16, utf8/16/32
_MI_INT8, _MI_INT32, _MI_UINT32 = 1, 5, 6
_MI_MATRIX, _MI_COMPRESSED, _MI_UTF8 = 14, 15, 16
# v5 array classes (mxCELL_CLASS ...).
_MX_KIND: dict[int, Kind] = {
    1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 16: "function", 17: "opaque",
    **{k: "numeric" for k in range(6, 16)},
}
_MX_ITEMSIZE = {6: 8, 7: 4, 8: 1, 9: 1, 10: 2, 11: 2, 12: 4, 13: 4, 14: 8, 15: 8}
_MX_CHAR, _MX_OPAQUE = 4, 17
_MAX_DIMS = 32  # scipy's _MAT_MAXDIMS
# A compressed variable's header fits in: matrix tag, flags, 32 dims, a name.
_HEADER_BYTES = 8 + 16 + 8 + 4 * _MAX_DIMS + 8 + MAX_NAME_BYTES + 8
# v4: precision digit P -> item size (double, single, int32, int16, uint16, uint8).
_V4_ITEMSIZE = (8, 4, 4, 2, 2, 1)
_V4_HEADER = 20


@dataclass(frozen=True)
class MatEntry:
    """One variable of a MAT file as its header declares it.

    Attributes
    ----------
    name : str
        Variable name.
    kind : str
        ``"numeric"`` (real), ``"char"``, or a kind servoid does not load.
    shape : tuple of int
        MATLAB dimensions.
    loadable : bool
        Its data passed the full check: scipy may read it.
    value : numpy.ndarray or None
        A struct field's values, decoded by the walker (scipy does not
        read fields); None for a top-level variable.
    span : tuple of int or None
        Where a loadable variable's element lies in the file: ``(start,
        stop)`` bytes; scipy is shown these elements alone.
    """

    name: str
    kind: Kind
    shape: tuple[int, ...]
    loadable: bool = False
    value: Any = field(default=None, compare=False, repr=False)
    span: tuple[int, int] | None = field(default=None, compare=False, repr=False)

    @property
    def is_note(self) -> bool:
        """Whether it is a scalar or a one-row string (an entry of notes)."""
        if self.kind == "numeric":
            return _prod(self.shape) == 1
        if self.kind == "char":
            return len(self.shape) == 2 and self.shape[0] <= 1 and self.shape[1] <= MAX_NOTE_CHARS
        return False


def check_mat(
    path: Path, version: int, wanted: Collection[str] | None, max_bytes: int,
    file: BinaryIO | None = None,
) -> dict[str, MatEntry]:
    """Walk a v4 (``version`` 0) or v5 (1) MAT file and list its variables.

    Parameters
    ----------
    path : Path
        The file.
    version : int
        Major version as :func:`scipy.io.matlab.matfile_version` gives it.
    wanted : collection of str or None
        Variables to check in full (None: all); scalars and one-row strings
        are always checked in full, as candidate notes.
    max_bytes : int
        Memory budget [bytes] of one variable.
    file : binary file, optional
        The file, already opened and checked (a :class:`~servoid._files.BoundedFile`):
        only its first ``size`` bytes are mapped. Default: open ``path``.

    Returns
    -------
    dict of str to MatEntry
        First occurrence of each name, in file order; ``loadable`` marks the
        ones scipy may read.

    Raises
    ------
    FileFormatError
        A header or a wanted variable that scipy must not parse.
    """
    with nullcontext(file) if file is not None else open_input(path, "file") as f:
        size = getattr(f, "size", None)
        if size is None:
            size = f.seek(0, 2)
        if size == 0:
            raise FileFormatError(f"{path}: empty file, not a MAT file")
        # Mapped, not read: the walk touches only tags and headers of unwanted variables.
        # The map is not closed explicitly: views of it may live on in a traceback, and
        # it is unmapped when the last one goes.
        data = memoryview(mmap.mmap(f.fileno(), size, access=mmap.ACCESS_READ))
    walker = _V4(path, data) if version == 0 else _V5(path, data, max_bytes)
    return walker.walk(wanted)


class _DamagedError(Exception):
    """Internal: a structural fault, reported with the variable it hit."""


def _prod(shape: tuple[int, ...]) -> int:
    n = 1
    for d in shape:
        n *= d
    return n


class _V4:
    """The v4 walker: a sequence of fixed 20-byte headers, name, data."""

    def __init__(self, path: Path, data: memoryview) -> None:
        self.path = path
        self.data = data
        # As scipy guesses it: a first MOPT outside 0..5000 must be byte-swapped.
        (mopt,) = struct.unpack_from("<i", data, 0) if len(data) >= 4 else (0,)
        self.order = "<" if 0 <= mopt <= 5000 else ">"

    def walk(self, wanted: Collection[str] | None) -> dict[str, MatEntry]:
        data, size, pos = self.data, len(self.data), 0
        entries: dict[str, MatEntry] = {}
        while pos < size:
            start = pos
            where = f"{self.path}: variable {len(entries) + 1} (header at byte {pos})"
            if size - pos < _V4_HEADER:
                raise FileFormatError(
                    f"{where}: truncated: {size - pos} bytes left, a MAT v4 header needs "
                    f"{_V4_HEADER}; the file is cut short, copy it again"
                )
            mopt, rows, cols, imagf, namlen = struct.unpack_from(self.order + "5i", data, pos)
            pos += _V4_HEADER
            problem = self._header_problem(mopt, rows, cols, imagf, namlen, size - pos)
            name = bytes(data[pos : pos + max(0, min(namlen, size - pos))])
            name_text = name.strip(b"\x00").decode("latin1")
            if problem:
                what = f" {name_text!r}" if name_text.isprintable() and name_text else ""
                raise FileFormatError(
                    f"{self.path}: variable{what} (header at byte {pos - _V4_HEADER}): "
                    f"{problem}: not a valid MAT v4 file, or damaged"
                )
            pos += namlen
            precision, cls = (mopt % 100) // 10, mopt % 10
            is_complex = imagf == 1
            nbytes = rows * cols * _V4_ITEMSIZE[precision] * (2 if is_complex and cls != 2 else 1)
            if nbytes > size - pos:
                raise FileFormatError(
                    f"{self.path}: variable {name_text!r} declares {rows}×{cols} values "
                    f"({format_bytes(nbytes)}) but only {format_bytes(size - pos)} follow: a "
                    "truncated or damaged MAT v4 file"
                )
            pos += nbytes
            kind: Kind = ("complex" if is_complex else "numeric", "char", "sparse")[cls]
            if name_text not in entries:
                loadable = kind in ("numeric", "char")
                entries[name_text] = MatEntry(name_text, kind, (rows, cols), loadable=loadable,
                                              span=(start, pos) if loadable else None)
        return entries

    @staticmethod
    def _header_problem(mopt: int, rows: int, cols: int, imagf: int, namlen: int,
                        left: int) -> str | None:
        if not 0 <= mopt <= 5000:
            return f"type code MOPT = {mopt} is outside 0..5000"
        order, rest = divmod(mopt, 1000)
        unused, rest = divmod(rest, 100)
        precision, cls = divmod(rest, 10)
        if order not in (0, 1):
            return f"MOPT {mopt}: byte order {order} is not IEEE (VAX/Cray files are not read)"
        if unused != 0 or precision >= len(_V4_ITEMSIZE) or cls > 2:
            return f"MOPT {mopt} is not a known precision and matrix class"
        if rows < 0 or cols < 0:
            return f"negative dimensions {rows}×{cols}"
        if imagf not in (0, 1):
            return f"imaginary flag {imagf} is neither 0 nor 1"
        if not 1 <= namlen <= min(MAX_NAME_BYTES, left):
            return f"name length {namlen} is outside 1..{min(MAX_NAME_BYTES, left)}"
        return None


class _Cursor:
    """Reads v5 tags and elements from a buffer, never past ``end``."""

    def __init__(self, buf: memoryview, order: str, pos: int, end: int) -> None:
        self.buf, self.order, self.pos, self.end = buf, order, pos, end

    def need(self, n: int, what: str) -> None:
        if n > self.end - self.pos:
            raise _DamagedError(
                f"{what} needs {n} bytes, only {max(0, self.end - self.pos)} are left in the "
                "element"
            )

    def u32s(self, what: str) -> tuple[int, int]:
        self.need(8, what)
        a, b = struct.unpack_from(self.order + "2I", self.buf, self.pos)
        self.pos += 8
        return a, b

    def element(self, what: str) -> tuple[int, memoryview]:
        """One data element as scipy's ``read_element``: (type, payload)."""
        start = self.pos
        self.need(8, what)
        (first,) = struct.unpack_from(self.order + "I", self.buf, self.pos)
        if first >> 16:  # small data element: type and count packed in 4 bytes
            mdtype, count = first & 0xFFFF, first >> 16
            if count > 4:
                raise _DamagedError(
                    f"{what}: a small data element declares {count} bytes (at most 4)"
                )
            self.pos += 8
            return mdtype, self.buf[start + 4 : start + 4 + count]
        mdtype, count = self.u32s(what)
        self.need(count, what)
        payload = self.buf[self.pos : self.pos + count]
        self.pos += count + (-count % 8)  # scipy skips the padding without reading it
        return mdtype, payload


class _V5:
    """The v5 walker: a 128-byte header, then one element per variable."""

    def __init__(self, path: Path, data: memoryview, max_bytes: int) -> None:
        self.path = path
        self.data = data
        self.max_bytes = max_bytes
        if len(data) < 128:
            raise FileFormatError(
                f"{path}: truncated MAT v5 file: {len(data)} bytes, the header alone is 128"
            )
        # As scipy decides it: 'IM' at byte 126 is little-endian, anything else big.
        self.order = "<" if bytes(data[126:128]) == b"IM" else ">"
        self.fields: dict[str, MatEntry] = {}  # struct fields decoded on the way

    def walk(self, wanted: Collection[str] | None) -> dict[str, MatEntry]:
        data, size, pos = self.data, len(self.data), 128
        entries: dict[str, MatEntry] = {}
        while pos < size:
            index = len(entries) + 1
            if size - pos < 8:
                raise FileFormatError(
                    f"{self.path}: truncated after variable {index - 1}: {size - pos} stray "
                    "byte(s) at the end where an element tag (8 bytes) belongs; copy the file "
                    "again"
                )
            mdtype, count = struct.unpack_from(self.order + "2I", data, pos)
            start, pos = pos, pos + 8
            where = f"element {index} at byte {start}"
            if mdtype not in (_MI_MATRIX, _MI_COMPRESSED):
                raise FileFormatError(
                    f"{self.path}: {where} has type code {mdtype}, not a variable "
                    f"({_MI_MATRIX}: matrix, {_MI_COMPRESSED}: compressed): a damaged MAT file"
                )
            if count == 0 or count > size - pos:
                raise FileFormatError(
                    f"{self.path}: {where} declares {format_bytes(count)} but "
                    f"{format_bytes(size - pos)} follow: a truncated or damaged MAT file"
                )
            body = data[pos : pos + count]
            pos += count
            if mdtype == _MI_COMPRESSED:
                entry = self._compressed(body, where, wanted, entries)
            else:
                entry = self._matrix(body, where, wanted, entries)
            if entry.name not in entries:
                entries[entry.name] = replace(entry, span=(start, pos)) if entry.loadable \
                    else entry
        entries.update(self.fields)
        return entries

    def _check_level(self, entry: MatEntry, wanted: Collection[str] | None,
                     entries: dict[str, MatEntry]) -> str:
        """How far to check a variable's data: "strict", "note" or "none".

        A wanted numeric or char variable is checked strictly (damage is an
        error); a scalar or one-row string is checked as a candidate note
        (damage leaves it out); the rest, and repeats of a name (scipy reads
        the first), are never loaded.
        """
        if entry.name in entries or entry.kind not in ("numeric", "char"):
            return "none"
        if wanted is None or entry.name in wanted:
            return "strict"
        return "note" if entry.is_note else "none"

    def _compressed(self, body: memoryview, where: str, wanted: Collection[str] | None,
                    entries: dict[str, MatEntry]) -> MatEntry:
        try:
            head = self._inflate(body, _HEADER_BYTES)
            cursor = _Cursor(memoryview(head), self.order, 0, len(head))
            mdtype, count = cursor.u32s("the compressed matrix tag")
            if mdtype != _MI_MATRIX:
                raise _DamagedError(
                    f"inflates to type code {mdtype}, not a matrix ({_MI_MATRIX})"
                )
            entry, flags = self._header(cursor)
        except _DamagedError as exc:
            raise FileFormatError(
                f"{self.path}: {where} (compressed): {exc}: a damaged MAT file"
            ) from None
        paths = _paths_under(entry, wanted, entries)
        level = "strict" if paths else self._check_level(entry, wanted, entries)
        if level == "none":
            return entry
        try:
            if count > self.max_bytes + _HEADER_BYTES:
                raise _DamagedError(
                    f"declares {format_bytes(count)} when inflated, over the "
                    f"{format_bytes(self.max_bytes)} budget (pass max_bytes= if it is real)"
                )
            if not paths:
                # Inflate no more than the header and the declared data take: a scalar whose
                # element declares 2 GiB (zeros compress 1000:1) is refused, not inflated.
                need = self._needed(cursor, entry, flags)
                if count > need:
                    raise _DamagedError(
                        f"declares {format_bytes(count)} inflated, but its header and data "
                        f"take {format_bytes(need)}: the element holds something else"
                    )
            full = self._inflate(body, 8 + count, whole=True)
            cursor = _Cursor(memoryview(full), self.order, 8, len(full))
            _, flags = self._header(cursor)
            if paths:
                self._descend(cursor, entry, paths)
                return entry
            self._data(cursor, entry, flags)
        except _DamagedError as exc:
            if level == "note":  # a damaged note nobody asked for is left out
                return entry
            raise FileFormatError(
                f"{self.path}: variable {entry.name!r} ({where}, compressed): {exc}: the "
                "variable is damaged"
            ) from None
        return MatEntry(entry.name, entry.kind, entry.shape, loadable=True)

    def _needed(self, cursor: _Cursor, entry: MatEntry, flags: int) -> int:
        """Bytes after the matrix tag that a numeric or char variable's header and data take.

        ``cursor`` stands after the name; the data element's tag follows. The
        declared shape is checked against the budget first.
        """
        self._check_shape(entry, flags)
        peek = _Cursor(cursor.buf, self.order, cursor.pos, cursor.end)
        peek.need(8, "the data tag")
        (first,) = struct.unpack_from(self.order + "I", peek.buf, peek.pos)
        if first >> 16:  # a small data element: 8 bytes in all
            return peek.pos + 8 - 8
        _, count = peek.u32s("the data tag")
        return peek.pos + count + (-count % 8) - 8

    def _check_shape(self, entry: MatEntry, flags: int) -> None:
        """Refuse dimensions that are not an array's, or a shape over the budget."""
        if len(entry.shape) < 2:
            # MATLAB writes at least two; scipy's chars_to_strings reads dims[ndim - 1]
            # unchecked, so a char array of no dimensions reads before the array (SIGSEGV).
            raise _DamagedError(
                f"{len(entry.shape)} dimension(s), a MATLAB array has at least 2"
            )
        if any(d < 0 for d in entry.shape):
            raise _DamagedError(f"negative dimensions {entry.shape}")
        n = _prod(entry.shape)
        mclass = flags & 0xFF
        itemsize = 4 if mclass == _MX_CHAR else _MX_ITEMSIZE[mclass]
        if n * itemsize > self.max_bytes:
            raise _DamagedError(
                f"shape {entry.shape} needs {format_bytes(n * itemsize)}, over the "
                f"{format_bytes(self.max_bytes)} budget (pass max_bytes= if it is real)"
            )

    @staticmethod
    def _inflate(body: memoryview, limit: int, *, whole: bool = False) -> bytes:
        """Inflate at most ``limit`` bytes; ``whole``: they must be all there is."""
        inflater = zlib.decompressobj()
        try:
            out = inflater.decompress(body, limit + 1 if whole else limit)
        except zlib.error as exc:
            raise _DamagedError(f"damaged compressed data ({exc})") from None
        if whole and (len(out) > limit or inflater.unconsumed_tail):
            raise _DamagedError(f"inflates to more than its declared {format_bytes(limit - 8)}")
        return out

    def _header(self, cursor: _Cursor) -> tuple[MatEntry, int]:
        """Parse what scipy's ``read_header`` parses; return the entry and flags."""
        cursor.u32s("the array-flags tag")  # scipy reads and ignores it
        flags, _nzmax = cursor.u32s("the array flags")
        mclass = flags & 0xFF
        dims: tuple[int, ...] = ()
        if mclass != _MX_OPAQUE:
            mdtype, payload = cursor.element("the dimensions")
            if len(payload) > 4 * _MAX_DIMS:
                raise _DamagedError(f"{len(payload) // 4} dimensions, at most {_MAX_DIMS}")
            if mdtype not in (_MI_INT32, _MI_UINT32):
                raise _DamagedError(
                    f"dimensions of type code {mdtype}, expected int32 ({_MI_INT32})"
                )
            n = len(payload) // 4
            dims = struct.unpack_from(f"{self.order}{n}i", payload, 0)
        mdtype, payload = cursor.element("the name")
        if mdtype not in (_MI_INT8, _MI_UTF8):
            raise _DamagedError(f"name of type code {mdtype}, expected int8 ({_MI_INT8})")
        if len(payload) > MAX_NAME_BYTES:
            raise _DamagedError(f"a name of {len(payload)} bytes, at most {MAX_NAME_BYTES}")
        raw = bytes(payload)
        if mdtype == _MI_UTF8 and any(b > 127 for b in raw):
            raise _DamagedError("a name that is not ASCII")
        kind = _MX_KIND.get(mclass, "unknown")
        if kind == "numeric" and flags >> 11 & 1:
            kind = "complex"
        return MatEntry(raw.decode("latin1"), kind, dims), flags

    def _matrix(self, body: memoryview, where: str, wanted: Collection[str] | None,
                entries: dict[str, MatEntry]) -> MatEntry:
        cursor = _Cursor(body, self.order, 0, len(body))
        try:
            entry, flags = self._header(cursor)
        except _DamagedError as exc:
            raise FileFormatError(f"{self.path}: {where}: {exc}: a damaged MAT file") from None
        paths = _paths_under(entry, wanted, entries)
        if paths:
            try:
                self._descend(cursor, entry, paths)
            except _DamagedError as exc:
                raise FileFormatError(
                    f"{self.path}: variable {entry.name!r} ({where}): {exc}: the struct is "
                    "damaged"
                ) from None
            return entry
        level = self._check_level(entry, wanted, entries)
        if level == "none":
            return entry
        try:
            self._data(cursor, entry, flags)
        except _DamagedError as exc:
            if level == "note":
                return entry
            raise FileFormatError(
                f"{self.path}: variable {entry.name!r} ({where}): {exc}: the variable is damaged"
            ) from None
        return MatEntry(entry.name, entry.kind, entry.shape, loadable=True)

    def _data(self, cursor: _Cursor, entry: MatEntry, flags: int) -> None:
        """Check the data element scipy will read for a numeric or char variable."""
        self._check_shape(entry, flags)
        n = _prod(entry.shape)
        mclass = flags & 0xFF
        mdtype, payload = cursor.element("the data")
        if mclass == _MX_CHAR:
            if mdtype not in _MI_CHAR:
                raise _DamagedError(f"char data of type code {mdtype}, not a text encoding")
            if mdtype in (_MI_INT8, 2, 4) and len(payload) not in (0, n * _MI_CHAR[mdtype]):
                raise _DamagedError(f"{len(payload)} bytes of text for {n} characters")
            return
        if mdtype not in _MI_NUMERIC:
            raise _DamagedError(f"numeric data of type code {mdtype}, not a number type")
        if len(payload) != n * _MI_NUMERIC[mdtype]:
            raise _DamagedError(
                f"{len(payload)} data bytes for shape {entry.shape} of "
                f"{_MI_NUMERIC[mdtype]}-byte values ({n * _MI_NUMERIC[mdtype]} expected)"
            )

    def _descend(self, cursor: _Cursor, entry: MatEntry, paths: list[str]) -> None:
        """Decode the numeric fields at ``paths`` (dotted, under struct ``entry``)."""
        start = cursor.pos
        for path in paths:
            cursor.pos = start
            parts = path.split(".")
            node, sub = entry, cursor
            for depth, part in enumerate(parts[1:], start=1):
                here = ".".join(parts[:depth])
                fields = self._struct_fields(sub, node, here)
                if part not in fields:
                    raise ChannelError(
                        f"variable {path!r} is not in {self.path}: the struct {here!r} has the "
                        f"field(s) {', '.join(fields) or '(none)'}"
                    )
                lo, hi = fields[part]
                sub = _Cursor(sub.buf, self.order, lo, hi)
                name = ".".join(parts[: depth + 1])
                if hi == lo:  # an empty field: a matrix tag of no bytes
                    node = MatEntry(name, "numeric", (0, 0))
                    flags = 0
                    continue
                field_entry, flags = self._header(sub)
                node = MatEntry(name, field_entry.kind, field_entry.shape)
            if node.kind != "numeric" or hi == lo:
                self.fields[path] = node  # the reader says what it is
                continue
            self._data(_Cursor(sub.buf, self.order, sub.pos, sub.end), node, flags)
            self.fields[path] = MatEntry(path, "numeric", node.shape, value=self._decode(
                sub, node))

    def _struct_fields(self, cursor: _Cursor, node: MatEntry,
                       here: str) -> dict[str, tuple[int, int]]:
        """Field name → byte range of its matrix body, for a 1×1 struct."""
        if node.kind != "struct":
            raise ChannelError(
                f"{self.path}: {here!r} is {_KIND_WORDS.get(node.kind, node.kind)} of shape "
                f"{node.shape}, not a struct: it has no fields to name with a dot"
            )
        if _prod(node.shape) != 1:
            raise FileFormatError(
                f"{self.path}: {here!r} is a struct array of shape {node.shape}; servoid reads "
                "fields of a 1×1 struct only: save each element as its own struct (or the "
                "signals as numeric fields of one struct)"
            )
        mdtype, payload = cursor.element("the field-name length")
        if mdtype not in (_MI_INT32, _MI_UINT32) or len(payload) != 4:
            raise _DamagedError("a field-name length that is not one int32")
        (length,) = struct.unpack_from(self.order + "i", payload, 0)
        mdtype, payload = cursor.element("the field names")
        if mdtype not in (_MI_INT8, _MI_UTF8) or length <= 0 or len(payload) % length:
            raise _DamagedError(f"field names of {len(payload)} bytes, not a multiple of "
                                f"{length}")
        raw = bytes(payload)
        names = [raw[k: k + length].split(b"\0", 1)[0].decode("latin1")
                 for k in range(0, len(raw), length)]
        out: dict[str, tuple[int, int]] = {}
        for name in names:
            mdtype, count = cursor.u32s(f"the tag of field {name!r}")
            if mdtype != _MI_MATRIX:
                raise _DamagedError(f"field {name!r} has type code {mdtype}, not a matrix")
            cursor.need(count, f"field {name!r}")
            out.setdefault(name, (cursor.pos, cursor.pos + count))
            cursor.pos += count + (-count % 8)
        return out

    def _decode(self, cursor: _Cursor, node: MatEntry) -> np.ndarray:
        """The checked numeric data element after a field's header, as float64."""
        mdtype, payload = cursor.element("the data")
        values = np.frombuffer(payload, dtype=self.order + _MI_DTYPE[mdtype])
        # a copy (the payload is a view of the mapped file) in the stored type: a time
        # field of integer ticks must still look like one to the reader
        return values.reshape(node.shape, order="F").astype(values.dtype.newbyteorder("="))


_KIND_WORDS = {
    "numeric": "a numeric array", "char": "text", "complex": "a complex array",
    "sparse": "a sparse matrix", "cell": "a cell array", "struct": "a struct",
    "object": "an object", "function": "a function handle", "opaque": "an opaque object",
    "external": "an external link to another file", "unknown": "of an unknown class",
}


def _paths_under(entry: MatEntry, wanted: Collection[str] | None,
                 entries: dict[str, MatEntry]) -> list[str]:
    """The dotted names asked for inside variable ``entry`` (first occurrence only)."""
    if wanted is None or entry.name in entries:
        return []
    prefix = entry.name + "."
    return sorted(w for w in wanted if w.startswith(prefix))
