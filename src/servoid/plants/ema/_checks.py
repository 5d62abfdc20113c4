"""Boundary checks shared by the EMA's parameter sets and its loop."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..._errors import ModelError, OptionTypeError

__all__ = ["Bounds", "check_fields"]

#: field → (lower bound, strict?, may be +inf?)
Bounds = Mapping[str, tuple[float, bool, bool]]


def check_fields(obj: Any, bounds: Bounds) -> None:
    """Validate the numeric fields of a frozen dataclass and store them as floats.

    A bool or non-number is an :class:`OptionTypeError`; NaN, an infinity
    the field does not allow, or a value below its bound a
    :class:`ModelError`; messages start ``ClassName.field``.
    """
    cls = type(obj).__name__
    for name, (low, strict, infinite) in bounds.items():
        value = getattr(obj, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise OptionTypeError(f"{cls}.{name} must be a real number, got {value!r}")
        value = float(value)
        if math.isnan(value) or (math.isinf(value) and not (infinite and value > 0)):
            raise ModelError(f"{cls}.{name} must be finite{' or +inf' if infinite else ''}, "
                             f"got {value}")
        if (value <= low) if strict else (value < low):
            raise ModelError(f"{cls}.{name} must be {'>' if strict else '>='} {low:g}, "
                             f"got {value:g}")
        object.__setattr__(obj, name, value)


def field_names(obj: Any) -> tuple[str, ...]:
    """The dataclass's field names."""
    return tuple(f.name for f in dataclasses.fields(obj))
