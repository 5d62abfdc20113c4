"""Boundary validators shared across servoid.

Each ``as_*`` function returns the value in its canonical Python type or
raises a servoid error whose message names the parameter (prefixed by
``where``, e.g. ``"[identify]"``), the value received and the expectation::

    as_int("na", "three", where="[identify]")
    # OptionTypeError: [identify] na must be an integer, got 'three' (str)

A wrong type raises :class:`~servoid.OptionTypeError` (a ``TypeError``), a
wrong value :class:`~servoid.DataError` (a ``ValueError``), a malformed
file :class:`~servoid.FileFormatError`. Run these at the boundary (public
functions, file readers); inner helpers trust their inputs.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from numbers import Integral, Real
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from ._errors import DataError, FileFormatError, MissingFileError, OptionTypeError

__all__ = [
    "as_array",
    "as_bool",
    "as_float",
    "as_float_list",
    "as_instance",
    "as_int",
    "as_int_list",
    "as_mapping",
    "as_path",
    "as_str",
    "as_str_list",
    "file_name_problem",
    "parse_json",
    "read_json",
    "read_text",
    "type_error",
]

_T = TypeVar("_T")
_NAME_MAX = 255  # [bytes] of one file name: ext4, XFS, APFS, NTFS (in UTF-16 units) alike
_PATH_MAX = 4096  # [bytes] of a whole path, with its terminating NUL (Linux PATH_MAX)


def _label(name: str, where: str) -> str:
    return f"{where} {name}" if where else name


def type_error(name: str, value: object, expected: str, *, where: str = "") -> OptionTypeError:
    """The error for ``value`` not being ``expected`` (e.g. ``"an integer"``).

    Returned, not raised, so the caller writes ``raise type_error(...)``.
    """
    return OptionTypeError(
        f"{_label(name, where)} must be {expected}, got {value!r} ({type(value).__name__})"
    )


def as_int(
    name: str,
    value: object,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    where: str = "",
) -> int:
    """Return ``value`` as an int, optionally within ``[minimum, maximum]``.

    Booleans and floats (even ``2.0``) are refused: a count is an integer.
    """
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise type_error(name, value, "an integer", where=where)
    out = int(value)
    label = _label(name, where)
    if minimum is not None and maximum is not None:
        if not minimum <= out <= maximum:
            raise DataError(f"{label} must lie in {minimum}..{maximum}, got {out}")
    elif minimum is not None and out < minimum:
        raise DataError(f"{label} must be >= {minimum}, got {out}")
    elif maximum is not None and out > maximum:
        raise DataError(f"{label} must be <= {maximum}, got {out}")
    return out


def as_float(
    name: str,
    value: object,
    *,
    positive: bool = False,
    nonneg: bool = False,
    finite: bool = True,
    unit: str = "",
    where: str = "",
) -> float:
    """Return ``value`` (an int or a float, not a bool) as a float.

    ``finite`` refuses inf and NaN; ``positive`` requires > 0, ``nonneg``
    >= 0. ``unit`` (e.g. ``"Hz"``) is appended to the value messages.
    """
    if isinstance(value, bool) or not isinstance(value, Real):
        raise type_error(name, value, "a number", where=where)
    label = _label(name, where)
    try:
        out = float(value)
    except OverflowError:  # an integer past the largest float (10**400)
        raise DataError(f"{label} must be a number within ±1.8e308, got an integer of "
                        f"{_digits(value)} digits") from None
    suffix = f" {unit}" if unit else ""
    if finite and not math.isfinite(out):
        raise DataError(f"{label} must be finite, got {out}")
    if positive and not out > 0:
        raise DataError(f"{label} must be > 0{suffix}, got {out:g}")
    if nonneg and not out >= 0:
        raise DataError(f"{label} must be >= 0{suffix}, got {out:g}")
    return out


def _digits(value: object) -> str:
    """How many digits an integer has (a bound past Python's str() digit limit)."""
    try:
        return str(len(str(abs(int(value)))))  # type: ignore[call-overload]
    except ValueError:
        return "more than 4300"


def as_bool(name: str, value: object, *, where: str = "") -> bool:
    """Return ``value`` if it is ``True`` or ``False`` (not 0/1, not ``"yes"``)."""
    if not isinstance(value, bool):
        raise type_error(name, value, "true or false", where=where)
    return value


def as_str(name: str, value: object, *, where: str = "", empty: bool = False) -> str:
    """Return ``value`` if it is a string, non-empty unless ``empty``."""
    if not isinstance(value, str):
        raise type_error(name, value, "a string", where=where)
    if not value and not empty:
        raise DataError(f"{_label(name, where)} must be a non-empty string, got ''")
    return value


def as_mapping(name: str, value: object, *, where: str = "") -> Mapping[str, Any]:
    """Return ``value`` if it is a mapping (a TOML table, a JSON object)."""
    if not isinstance(value, Mapping):
        raise type_error(name, value, "a table", where=where)
    return value


def _as_list(name: str, value: object, expected: str, where: str,
             length: int | None, min_length: int) -> list[Any]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise type_error(name, value, expected, where=where)
    items = list(value)
    label = _label(name, where)
    if length is not None and len(items) != length:
        raise DataError(f"{label} must have {length} entries, got {len(items)}: {items!r}")
    if len(items) < min_length:
        raise DataError(f"{label} must have at least {min_length} "
                        f"{'entry' if min_length == 1 else 'entries'}, got {items!r}")
    return items


def as_int_list(
    name: str,
    value: object,
    *,
    length: int | None = None,
    min_length: int = 0,
    minimum: int | None = None,
    maximum: int | None = None,
    where: str = "",
) -> list[int]:
    """Return a list or tuple of integers as a list, each checked by :func:`as_int`.

    An entry is named ``name[i]`` in messages.
    """
    items = _as_list(name, value, "a list of integers", where, length, min_length)
    return [as_int(f"{name}[{i}]", v, minimum=minimum, maximum=maximum, where=where)
            for i, v in enumerate(items)]


def as_float_list(
    name: str,
    value: object,
    *,
    length: int | None = None,
    min_length: int = 0,
    finite: bool = True,
    where: str = "",
) -> list[float]:
    """Return a list or tuple of numbers as a list of floats (see :func:`as_float`)."""
    items = _as_list(name, value, "a list of numbers", where, length, min_length)
    return [as_float(f"{name}[{i}]", v, finite=finite, where=where) for i, v in enumerate(items)]


def as_array(
    name: str,
    value: object,
    *,
    ndim: int | None = None,
    min_size: int = 0,
    finite: bool = True,
    where: str = "",
) -> NDArray[np.float64]:
    """Return ``value`` as a float array, refusing text, None and complex numbers.

    ``ndim`` fixes the number of dimensions, ``min_size`` the fewest
    elements, ``finite`` refuses NaN and inf (naming the first). The input
    is never modified: a float array comes back as is (no copy), so the
    caller must copy before writing into it.
    """
    label = _label(name, where)
    if value is None or isinstance(value, (str, bytes, Mapping)):
        raise type_error(name, value, "an array of real numbers", where=where)
    try:
        raw = np.asarray(value)
    except ValueError as exc:  # a ragged nested list
        raise DataError(f"{label} must be a rectangular array of numbers ({exc})") from None
    if raw.dtype.kind == "c":
        raise OptionTypeError(f"{label} must hold real numbers, got complex values; pass the "
                              "real part (or the magnitude) explicitly")
    if raw.dtype.kind not in "biuf":
        try:
            raw = raw.astype(float)
        except OverflowError:  # an integer past the largest float (10**400)
            raise DataError(f"{label} must hold numbers within ±1.8e308, got an integer too "
                            "large for a float") from None
        except (TypeError, ValueError):
            raise type_error(name, value, "an array of real numbers", where=where) from None
    arr = np.asarray(raw, dtype=float)
    if ndim is not None and arr.ndim != ndim:
        shape = "a scalar" if arr.ndim == 0 else f"an array of shape {arr.shape}"
        raise DataError(f"{label} must be {ndim}-D, got {shape}")
    if arr.size < min_size:
        raise DataError(f"{label} needs at least {min_size} values, got {arr.size}")
    if finite:
        bad = ~np.isfinite(arr)
        if bad.any():
            first = int(np.flatnonzero(bad.ravel())[0])
            kind = "NaN" if np.isnan(arr.ravel()[first]) else "inf"
            raise DataError(f"{label} has {int(bad.sum())} non-finite value(s), the first ({kind}) "
                            f"at index {first}; remove or interpolate them first")
    return arr


def as_instance(name: str, value: object, cls: type[_T] | tuple[type, ...], expected: str = "",
                *, where: str = "") -> _T:
    """Return ``value`` if it is an instance of ``cls``, else an :class:`OptionTypeError`.

    ``expected`` words the type for the message (default: the class name).
    """
    if not isinstance(value, cls):
        if not expected:
            names = [c.__name__ for c in (cls if isinstance(cls, tuple) else (cls,))]
            expected = "a " + " or ".join(names)
        raise type_error(name, value, expected, where=where)
    return value  # type: ignore[return-value]


def as_path(name: str, value: object, *, must_exist: bool = False, where: str = "") -> Path:
    """Return ``value`` (a str or path-like) as a Path.

    ``must_exist`` raises :class:`~servoid.MissingFileError` naming the path
    when nothing exists there.
    """
    if isinstance(value, bytes) or not isinstance(value, (str, os.PathLike)):
        raise type_error(name, value, "a file path (str or pathlib.Path)", where=where)
    if isinstance(value, str) and not value.strip():
        raise DataError(f"{_label(name, where)} must be a file path, got an empty string")
    path = Path(value)
    if must_exist and not path.exists():
        raise MissingFileError(f"{path}: no such file; check the {name} (relative paths are "
                               f"taken from {Path.cwd()})")
    return path


def as_str_list(
    name: str,
    value: object,
    *,
    length: int | None = None,
    min_length: int = 0,
    where: str = "",
) -> list[str]:
    """Return a list or tuple of strings (names, units) as a list.

    A single string is refused: ``"abc"`` is not ``["a", "b", "c"]``.
    """
    items = _as_list(name, value, "a list of strings", where, length, min_length)
    if not all(isinstance(v, str) for v in items):
        raise type_error(name, value, "a list of strings", where=where)
    return items


def read_json(path: str | Path, what: str) -> Any:
    """Parse a JSON file; ``what`` says what it is (``"truth file"``).

    A missing file raises :class:`~servoid.MissingFileError` (a
    ``FileNotFoundError``); a folder or other non-regular file, bytes that
    are not UTF-8 text (see :func:`read_text`), malformed JSON, nesting too
    deep to parse or an integer past Python's digit limit raise
    :class:`~servoid.FileFormatError` naming the file and the problem.
    """
    path = as_path(what, path)
    return parse_json(read_text(path, what, "JSON"), path, what)


def parse_json(text: str, path: Path, what: str) -> Any:
    """Parse the JSON ``text`` of ``path``, with the errors of :func:`read_json`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"{what} {path} is not valid JSON: {exc.msg} (line {exc.lineno}, "
                              f"column {exc.colno})") from exc
    except RecursionError:
        raise FileFormatError(f"{what} {path} is not valid JSON for servoid: its arrays or "
                              "objects are nested too deeply to read (servoid writes at most a "
                              "few levels)") from None
    except ValueError as exc:  # int(): more digits than sys.get_int_max_str_digits()
        raise FileFormatError(f"{what} {path} is not valid JSON for servoid: {exc}".split(
            "; use sys.")[0] + " (no number servoid writes has that many)") from None


def file_name_problem(text: str) -> str | None:
    """Why ``text`` can name no file on this system (None: it can).

    A NUL character, a character with no encoding (a lone UTF-16
    surrogate), a name (one part between slashes) over 255 bytes or a path
    of 4096 bytes or more: the operating system refuses these with an error
    of its own, so a path read from a file is checked first and the problem
    said in words.
    """
    if "\x00" in text:
        return "holds a NUL character (\\u0000), which no file name can"
    try:
        encoded = os.fsencode(text)
    except UnicodeError:
        return ("holds a character this system cannot write in a file name (a lone UTF-16 "
                "surrogate)")
    longest = max(len(part) for part in encoded.replace(b"\\", b"/").split(b"/"))
    if longest > _NAME_MAX:
        return f"has a name of {longest} bytes; file systems allow {_NAME_MAX}"
    if len(encoded) >= _PATH_MAX:
        return f"is {len(encoded)} bytes long; paths stop at {_PATH_MAX - 1}"
    return None


def read_text(path: Path, what: str, kind: str = "text") -> str:
    """The text of a UTF-8 file (a leading byte-order mark dropped), checked first.

    ``what`` names the file in messages, ``kind`` its format (``"TOML"``).
    A missing path raises :class:`~servoid.MissingFileError`; a folder,
    FIFO or device, text in UTF-16/32 (named by its byte-order mark) or
    bytes that are not UTF-8 (with the line of the first bad byte) raise
    :class:`~servoid.FileFormatError`.
    """
    from ._files import check_input_file, read_input_bytes

    check_input_file(path, what)  # a folder, pipe, device or loop of links named, not opened
    try:  # opened without waiting, re-checked, bounded
        raw = read_input_bytes(path, what)
    except OSError as exc:
        raise FileFormatError(f"{what} {path} cannot be read ({exc.strerror or exc}); check "
                              "the file's permissions") from None
    for bom, encoding in ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
                          (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16")):
        if raw.startswith(bom):
            raise FileFormatError(f"{what} {path} is {encoding} text (its byte-order mark says "
                                  f"so); servoid reads {kind} files in UTF-8: save it as UTF-8")
    try:
        return raw.decode("utf-8").removeprefix("\ufeff")  # the UTF-8 mark some editors write
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise FileFormatError(f"{what} {path} is not UTF-8 text: {exc.reason} at byte "
                              f"{exc.start} (line {line}); save it as UTF-8") from None


def as_generator(rng: object) -> np.random.Generator:
    """A random generator from ``rng``: a Generator, an integer seed >= 0, or None (fresh)."""
    if rng is None or isinstance(rng, np.random.Generator):
        return np.random.default_rng(rng)
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        if rng < 0:
            raise DataError(f"rng seed must be >= 0, got {rng}")
        return np.random.default_rng(int(rng))
    raise OptionTypeError(
        f"rng must be a numpy.random.Generator, an integer seed or None, got {type(rng).__name__}")
