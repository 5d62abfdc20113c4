"""Flag values checked where they are typed, and library messages in the flags' words.

The library names its parameters (``f_acq must be > 0``); a user at the
command line typed ``--facq``.  The commands check what only the command
line knows (a value that is not a finite number, a folder that is a file)
and pass the rest to the library, whose errors :func:`in_flags` rewords:
a parameter becomes the flag that sets it.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from ._errors import DataError, ServoidError

__all__ = ["at_least", "finite", "folder_out", "in_flags", "out_path", "positive", "reword"]


def finite(flag: str, value: float, unit: str = "") -> float:
    """Refuse NaN and inf for a number flag."""
    if not math.isfinite(value):
        raise DataError(f"{flag} must be a finite number{_unit(unit)}, got {value}")
    return value


def positive(flag: str, value: float, unit: str = "") -> float:
    """Refuse a number flag that is not finite and > 0."""
    if not math.isfinite(value) or value <= 0:
        raise DataError(f"{flag} must be a finite number > 0{_unit(unit)}, got {value:g}")
    return value


def at_least(flag: str, value: int, minimum: int) -> int:
    """Refuse an integer flag below ``minimum``."""
    if value < minimum:
        raise DataError(f"{flag} must be an integer >= {minimum}, got {value}")
    return value


def out_path(value: str) -> Path:
    """The ``type`` of an ``--out`` (or other path) flag: a path, never an empty string.

    ``Path("")`` is ``.``: an empty ``--out ""`` (an unset shell variable)
    would write into the working directory, among the inputs.
    """
    if not value.strip():
        raise argparse.ArgumentTypeError(
            "got an empty path (an unset shell variable?): name a file or folder, or leave "
            "the flag out for its default")
    return Path(value)


def folder_out(flag: str, path: Path) -> Path:
    """Refuse an output folder that is an existing file."""
    if path.exists() and not path.is_dir():
        raise DataError(f"{flag} {path} is a file; this command writes several files into a "
                        f"folder: give {flag} a folder")
    return path


@contextmanager
def in_flags(words: Mapping[str, str], phrases: Mapping[str, str] | None = None) -> Iterator[None]:
    """Re-raise a servoid error naming the flags that set the parameters it names.

    ``words`` maps a parameter to its flag.  The subject of the message
    (``f_acq must be ...``, ``amplitude = ...``) becomes the flag; a
    parameter with an underscore or a space mentioned later (``... a
    multiple of f_s``) keeps its name and gains the flag in brackets at its
    first mention; a plain word later in the sentence is left alone, since
    it may be an ordinary word.  ``phrases`` are replaced verbatim first
    (advice worded for the Python API, such as ``pass time=False``).
    """
    try:
        yield
    except ServoidError as exc:
        text = str(exc)
        new = reword(text, words, phrases or {})
        if new == text:
            raise
        raise _like(exc, new) from None


def reword(text: str, words: Mapping[str, str], phrases: Mapping[str, str]) -> str:
    """``text`` with parameter names replaced or explained by flags (see :func:`in_flags`)."""
    for old, replacement in phrases.items():
        text = text.replace(old, replacement)
    subject = None
    for name, flag in sorted(words.items(), key=lambda kv: -len(kv[0])):
        if re.match(rf"{re.escape(name)}(?= must| =)", text):
            text = flag + text[len(name):]
            subject = name
            break
    for name, flag in sorted(words.items(), key=lambda kv: -len(kv[0])):
        if name == subject or not ("_" in name or " " in name) or flag in text:
            continue
        text = re.sub(rf"(?<![\w-]){re.escape(name)}(?![\w(])(?! \()", f"{name} ({flag})",
                      text, count=1)
    return text


def _like(exc: ServoidError, message: str) -> ServoidError:
    try:
        return type(exc)(message)
    except TypeError:  # an error class with a richer constructor keeps its family
        return ServoidError(message)


def _unit(unit: str) -> str:
    return f" [{unit}]" if unit else ""
