"""Checks for ``[identify]`` options, built from the shared boundary validators.

Each factory returns ``check(value, where, name) -> value`` for an
:class:`~servoid.workflows.Option`; the messages name the key, the value
and what is expected.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .._checks import as_bool, as_float, as_int, as_int_list, as_str, type_error
from .._errors import DataError, check_option
from ._registry import Check, Option

__all__ = ["HORIZON", "OUTPUT", "ROLE", "boolean", "choice", "choices", "integer", "number", "optional",
           "orders", "text"]


def integer(minimum: int | None = None, maximum: int | None = None) -> Check:
    """An integer within bounds."""
    def check(value: Any, where: str, name: str) -> int:
        return as_int(name, value, minimum=minimum, maximum=maximum, where=where)
    return check


def number(*, positive: bool = False, nonneg: bool = False, unit: str = "") -> Check:
    """A finite number."""
    def check(value: Any, where: str, name: str) -> float:
        return as_float(name, value, positive=positive, nonneg=nonneg, unit=unit, where=where)
    return check


def boolean() -> Check:
    """``true`` or ``false``."""
    def check(value: Any, where: str, name: str) -> bool:
        return as_bool(name, value, where=where)
    return check


def text() -> Check:
    """A non-empty string (a channel name, a file)."""
    def check(value: Any, where: str, name: str) -> str:
        return as_str(name, value, where=where)
    return check


def choice(valid: Sequence[str]) -> Check:
    """One of a set of strings."""
    def check(value: Any, where: str, name: str) -> str:
        check_option(f"{where} {name}", value, valid)  # lists the valid values
        return str(value)
    return check


def choices(valid: Sequence[str]) -> Check:
    """One string of a set, or a non-empty list of them (duplicates dropped)."""
    def check(value: Any, where: str, name: str) -> list[str]:
        items = [value] if isinstance(value, str) else value
        if not isinstance(items, (list, tuple)):
            raise type_error(name, value, "a string or a list of strings", where=where)
        if not items:
            raise DataError(f"{where} {name} is empty; choose from {', '.join(valid)}")
        for item in items:
            check_option(f"{where} {name}", item, valid)
        return list(dict.fromkeys(items))
    return check


def orders(minimum: int) -> Check:
    """An order: an integer, or a list of integers.

    A list is a grid to search for single-input data and one value per
    input for multi-input data; the method reads it once the data are known.
    """
    def check(value: Any, where: str, name: str) -> int | list[int]:
        if isinstance(value, (list, tuple)):
            return as_int_list(name, value, min_length=1, minimum=minimum, where=where)
        if isinstance(value, bool) or not isinstance(value, int):
            raise type_error(name, value, "an integer or a list of integers", where=where)
        return as_int(name, value, minimum=minimum, where=where)
    return check


def optional(inner: Check) -> Check:
    """``inner``, or absent (None)."""
    def check(value: Any, where: str, name: str) -> Any:
        return None if value is None else inner(value, where, name)
    return check


# The options several methods share.
#: the role of the input channel(s)
ROLE = Option("input", "u", choice(("u", "r")),
              'role of the input channel(s): "u" (plant input) or "r" (reference, closed loop)')
#: the output channel
OUTPUT = Option("output", None, optional(text()), "output channel when the data have several")
#: k of the k-step prediction fit
HORIZON = Option("horizon", 5, integer(minimum=1),
                 "k of the k-step prediction fit on validation data [samples]")
