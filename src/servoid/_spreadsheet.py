"""CSV cells that a spreadsheet would run as formulas.

A spreadsheet opening a CSV file treats a cell starting with ``=``, ``+``,
``-`` or ``@`` as a formula (a tab or a carriage return in front is
skipped), so text from a user's files — a manifest serial
``=HYPERLINK(...)``, a channel name — can run when a colleague opens
servoid's output.  Every CSV file servoid writes either writes such text
with a leading ``'`` (:func:`neutralise`, for tables meant to be read) or
refuses it (rig files, which must read back as they were written).
Numbers are not formulas and are left alone.
"""

from __future__ import annotations

import re

__all__ = ["FORMULA_START", "is_formula", "neutralise"]

FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def is_formula(text: str) -> bool:
    """True when a spreadsheet would read `text` as a formula (a number is not one)."""
    return text.startswith(FORMULA_START) and _NUMBER.fullmatch(text) is None


def neutralise(text: str) -> str:
    """`text` as a CSV cell that no spreadsheet runs: a leading ``'`` on a formula."""
    return "'" + text if is_formula(text) else text
