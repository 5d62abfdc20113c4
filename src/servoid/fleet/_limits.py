"""Acceptance limits per parameter, and the rule that decides a unit passes.

The rule: a unit passes a limit only when the whole 95 % confidence
interval of its estimate lies inside the limit.  A unit whose interval
straddles a limit fails ("not shown to be inside"), so a pass is evidence,
not the absence of it; a unit whose estimate has no interval fails too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .._errors import OptionError, OptionTypeError

__all__ = ["RULE", "Limit", "parse_limits"]

RULE = ("a unit passes a limit only when the whole 95 % confidence interval of its estimate "
        "lies inside it; an interval that straddles the limit, or a missing one, fails")

_KEYS = ("nominal", "tolerance", "tolerance_percent", "min", "max")


@dataclass(frozen=True)
class Limit:
    """An acceptance limit on one parameter: ``low <= θ <= high``.

    Attributes
    ----------
    parameter : str
        The parameter's name as the method reports it.
    low, high : float
        Bounds; ``-inf`` / ``inf`` for a one-sided limit.
    text : str
        The limit as the fleet file gave it ("163.3 ± 5", ">= 3000").
    """

    parameter: str
    low: float
    high: float
    text: str

    def passes(self, ci_low: float, ci_high: float) -> bool:
        """True when the interval [ci_low, ci_high] lies inside the limit."""
        if not (math.isfinite(ci_low) and math.isfinite(ci_high)):
            return False
        return self.low <= ci_low and ci_high <= self.high

    def contains(self, value: float) -> bool:
        """True when a point value lies inside the limit (for a truth check)."""
        return self.low <= value <= self.high


def parse_limits(table: Mapping[str, Any], where: str = "[limits]") -> tuple[Limit, ...]:
    """Read ``[limits.<parameter>]`` tables.

    Each takes ``nominal`` with ``tolerance`` (±, in the parameter's unit) or
    ``tolerance_percent``, or ``min`` and/or ``max``.
    """
    if not isinstance(table, Mapping):
        raise OptionTypeError(f"{where} must be a table of [limits.<parameter>] tables")
    return tuple(_limit(name, spec, f"[limits.{name}]") for name, spec in table.items())


def _limit(name: str, spec: Any, where: str) -> Limit:
    if not isinstance(spec, Mapping):
        raise OptionTypeError(f"{where} must be a table with nominal and tolerance, or min/max; "
                              f"got {spec!r}")
    unknown = sorted(set(spec) - set(_KEYS))
    if unknown:
        raise OptionError(f"unknown key(s) in {where}: {', '.join(unknown)}; valid keys are "
                          f"{', '.join(_KEYS)}")
    values = {k: _number(spec[k], where, k) for k in spec}
    if "nominal" in values:
        if ("tolerance" in values) == ("tolerance_percent" in values) or (
                "min" in values or "max" in values):
            raise OptionError(f"{where}: give nominal with exactly one of tolerance or "
                              "tolerance_percent (or min/max without nominal)")
        nominal = values["nominal"]
        tol = values.get("tolerance", abs(nominal) * values.get("tolerance_percent", 0.0) / 100)
        if not tol > 0 or not math.isfinite(nominal + tol) or not math.isfinite(nominal - tol):
            raise OptionError(f"{where}: the tolerance must be > 0 and nominal ± tolerance "
                              f"finite; got {nominal:g} ± {tol:g}")
        text = (f"{nominal:g} ± {tol:g}" if "tolerance" in values
                else f"{nominal:g} ± {values['tolerance_percent']:g} %")
        return Limit(name, nominal - tol, nominal + tol, text)
    if "min" not in values and "max" not in values:
        raise OptionError(f"{where}: give nominal and tolerance, or min and/or max")
    low, high = values.get("min", -math.inf), values.get("max", math.inf)
    if low >= high:
        raise OptionError(f"{where}: min ({low:g}) must be below max ({high:g})")
    text = (f"{low:g} … {high:g}" if math.isfinite(low) and math.isfinite(high)
            else f">= {low:g}" if math.isfinite(low) else f"<= {high:g}")
    return Limit(name, low, high, text)


def _number(value: Any, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise OptionTypeError(f"{where} {key} must be a number; got {value!r}")
    try:
        number = float(value)
    except OverflowError:  # an integer beyond the largest float, like 10**400
        raise OptionError(f"{where} {key} must be a finite number (at most about 1.8e308); "
                          "got a larger integer") from None
    if not math.isfinite(number):
        raise OptionError(f"{where} {key} must be finite; got {value!r}")
    return number
