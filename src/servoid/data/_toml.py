"""A TOML writer for the experiment file: exactly the types the file holds.

Strings, booleans, integers, floats (``repr``: the shortest text that
reads back as the same double), arrays and nested tables; nothing else.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from .._errors import FileFormatError
from ._spec_tables import _FREE_KEYS, _kind

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


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
