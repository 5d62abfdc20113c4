"""A value as a message shows it: its ``repr``, cut to a readable length.

A long value keeps its head and its tail: a path's tail is the file's name,
where the damage a message names (a NUL, a bad suffix) usually sits.
"""

from __future__ import annotations

__all__ = ["shown"]

#: Longest repr shown whole; a longer one keeps this many characters at each end.
_LIMIT, _HEAD, _TAIL = 80, 30, 40


def shown(value: object) -> str:
    """``repr(value)``, or its head and tail with the length when it is long."""
    try:
        text = repr(value)
    except ValueError:  # an integer past str()'s digit limit
        return "an integer of more than 4300 digits"
    if len(text) <= _LIMIT:
        return text
    return f"{text[:_HEAD]}…{text[-_TAIL:]} ({len(text)} characters)"
