"""TOML in and out: the reader of experiment and fleet files, and the experiment file's writer.

:func:`read_toml` reads a TOML file into plain data, turning every way the
text can fail to parse (not UTF-8, a syntax error, nesting too deep for the
parser, an integer past Python's digit limit) into one
:class:`~servoid.FileFormatError` that names the file.  The writer emits
exactly the types the experiment file holds: strings, booleans, integers,
floats (``repr``: the shortest text that reads back as the same double),
arrays and nested tables; nothing else.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .._checks import read_text
from .._errors import FileFormatError
from ._spec_tables import _FREE_KEYS, _kind

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def read_toml(path: Path, what: str, label: str | None = None) -> dict[str, Any]:
    """Parse a TOML file; ``what`` names it (``"fleet file"``), ``label`` prefixes parse errors.

    Raises :class:`~servoid.MissingFileError` for a missing file and
    :class:`~servoid.FileFormatError` for anything else that stops the
    parse (see :func:`servoid._checks.read_text` for the file checks).
    """
    text = read_text(path, what, "TOML")
    label = f"{what} {path}" if label is None else label
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        detail = str(exc)
    except RecursionError:
        detail = ("its arrays or inline tables are nested too deeply to read; an experiment "
                  "file needs at most two levels")
    except ValueError as exc:  # int(): more digits than sys.get_int_max_str_digits()
        detail = str(exc).split("; use sys.")[0] + "; no setting takes a number that long"
    raise FileFormatError(f"{label}: not a valid TOML file ({detail})") from None


# -- TOML emitter ----------------------------------------------------------------------------


def _emit_document(doc: Mapping[str, Any]) -> str:
    parts = [_emit_table(["data"], doc["data"])]
    for name, entry in doc["channels"].items():
        parts.append(_emit_table(["channels", name], entry))
    for key in ("preprocess", "split", "validation", "rig", *_FREE_KEYS):
        if key in doc:
            parts.append(_emit_table([key], doc[key]))
    return "\n".join(parts)


def _emit_table(header: list[str], table: Mapping[str, Any]) -> str:
    lines = [f"[{'.'.join(_emit_key(h) for h in header)}]"]
    nested = []
    for k, v in table.items():
        if isinstance(v, Mapping):
            nested.append((k, v))
        else:
            lines.append(f"{_emit_key(k)} = {_emit_value(v)}")
    text = "\n".join(lines) + "\n"
    for k, v in nested:
        text += "\n" + _emit_table([*header, k], v)
    return text


def _emit_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else _emit_string(key)


def _emit_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        # repr is the shortest text that reads back as the same double; inf/nan are TOML too.
        return repr(value)
    if isinstance(value, str):
        return _emit_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_emit_value(v) for v in value) + "]"
    raise FileFormatError(f"cannot write {_kind(value)} to TOML")


def _emit_string(text: str) -> str:
    escapes = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b",
               "\f": "\\f"}
    out = []
    for c in text:
        if c in escapes:
            out.append(escapes[c])
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'
