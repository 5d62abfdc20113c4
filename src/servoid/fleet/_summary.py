"""One identification's ``results.json`` as a fleet row: parameters, fit and flags.

The fleet runner calls the registered method like ``servoid identify``
does and reads only the dictionary every result writes to
``results.json``.  Each method family writes its parameters in one of a
few shapes; :func:`summarise` knows them and returns the same plain
:class:`RecordSummary` for all.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["ParameterValue", "RecordSummary", "summarise"]


@dataclass(frozen=True)
class ParameterValue:
    """One estimated parameter of one record."""

    name: str
    value: float
    std: float
    ci_low: float
    ci_high: float
    unit: str = ""


@dataclass(frozen=True)
class RecordSummary:
    """What a fleet row keeps of one identification.

    Attributes
    ----------
    parameters : tuple of ParameterValue
        The primary estimate's parameters, in the method's order.
    fit_percent : float or None
        Validation fit [%] of the primary model (NaN-free or None).
    white, independent : bool or None
        Residual whiteness and input–residual independence verdicts.
    structure_rejected : bool or None
        The structure test rejected the model structure (closed loop).
    flags : tuple of str
        The estimate's flags (unresolved resonance, boundary, …).
    """

    parameters: tuple[ParameterValue, ...]
    fit_percent: float | None = None
    white: bool | None = None
    independent: bool | None = None
    structure_rejected: bool | None = None
    flags: tuple[str, ...] = ()

    def names(self) -> tuple[str, ...]:
        """Parameter names, in order."""
        return tuple(p.name for p in self.parameters)


def summarise(results: Mapping[str, Any]) -> RecordSummary:
    """Return the fleet summary of a ``results.json`` dictionary.

    Known shapes: the closed-loop physical fit (``parameters`` per
    approach, ``primary_approach``), the black-box estimators
    (``estimate.parameters``), the inverse-dynamics fit (``estimates``) and
    the servopneumatic multi-step fit (``parameters`` rows).
    """
    if "primary_approach" in results:
        return _closed_loop(results)
    if isinstance(results.get("estimate"), Mapping):
        return _with_validation(_estimate_parameters(results["estimate"]), results)
    if isinstance(results.get("estimates"), Mapping) and results["estimates"]:
        first = next(iter(results["estimates"].values()))
        return RecordSummary(_estimate_parameters(first))
    if isinstance(results.get("parameters"), list):
        return RecordSummary(tuple(_row(p) for p in results["parameters"] if _has_value(p)))
    return RecordSummary(())


def _closed_loop(results: Mapping[str, Any]) -> RecordSummary:
    primary = results["primary_approach"]
    rows = []
    for entry in results.get("parameters", []):
        value = entry.get(primary)
        if isinstance(value, Mapping):
            low, high = value.get("ci95", (math.nan, math.nan))
            rows.append(ParameterValue(entry["name"], _num(value.get("value")),
                                       _num(value.get("std")), _num(low), _num(high),
                                       str(value.get("unit", ""))))
    approach = results.get("approaches", {}).get(primary, {})
    structure = results.get("structure_test") or {}
    summary = _with_validation(tuple(rows), approach)
    return RecordSummary(
        summary.parameters, summary.fit_percent, summary.white, summary.independent,
        structure_rejected=bool(structure["rejected"]) if "rejected" in structure else None,
        flags=tuple(str(f) for f in approach.get("flags", ())),
    )


def _with_validation(parameters: tuple[ParameterValue, ...],
                     holder: Mapping[str, Any]) -> RecordSummary:
    validation = holder.get("validation") or {}
    residuals = validation.get("residuals") or {}
    fit = validation.get("fit_percent")
    return RecordSummary(
        parameters,
        fit_percent=None if fit is None else _num(fit),
        white=residuals.get("is_white"),
        independent=residuals.get("is_independent"),
    )


def _estimate_parameters(estimate: Mapping[str, Any]) -> tuple[ParameterValue, ...]:
    return tuple(_row(p) for p in estimate.get("parameters", []) if _has_value(p))


def _has_value(p: Any) -> bool:
    return isinstance(p, Mapping) and "name" in p and "value" in p


def _row(p: Mapping[str, Any]) -> ParameterValue:
    low, high = p.get("ci_low"), p.get("ci_high")
    if low is None and isinstance(p.get("ci95"), (list, tuple)):
        low, high = p["ci95"]
    return ParameterValue(str(p["name"]), _num(p["value"]), _num(p.get("std")), _num(low),
                          _num(high), str(p.get("unit", "") or ""))


def _num(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan
