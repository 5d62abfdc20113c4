"""User text in figures: channel names, units and labels shown as typed.

Matplotlib reads ``$…$`` as math text and fails on an unbalanced or
unknown expression (a unit written ``$m/s``); every string that comes from
the user's data or experiment file goes through :func:`plain` first.
"""

from __future__ import annotations

__all__ = ["plain"]


def plain(text: object) -> str:
    """Return ``text`` with matplotlib's math-text markers escaped."""
    return str(text).replace("$", r"\$")
