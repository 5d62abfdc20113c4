"""One identification's ``results.json`` in brief: parameters, fit, test verdicts, flags.

The report's verdict box and the fleet runner read only the dictionary
every result writes to ``results.json``.  Each method family writes its
parameters in one of a few shapes; :func:`summarise` knows them and
returns the same plain :class:`RecordSummary` for all.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..report import Section

__all__ = ["ParameterValue", "RecordSummary", "summarise", "verdict_section"]


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
    notes : int
        Number of notes (warnings) of the run.
    diverged : tuple of str
        The validation records on which the model's free run diverged
        (the model failed there; they have no metrics).
    """

    parameters: tuple[ParameterValue, ...]
    fit_percent: float | None = None
    white: bool | None = None
    independent: bool | None = None
    structure_rejected: bool | None = None
    flags: tuple[str, ...] = ()
    notes: int = 0
    diverged: tuple[str, ...] = ()

    def names(self) -> tuple[str, ...]:
        """Parameter names, in order."""
        return tuple(p.name for p in self.parameters)


def summarise(results: Mapping[str, Any]) -> RecordSummary:
    """Return the summary of a ``results.json`` dictionary (see :func:`_summarise`)."""
    summary = _summarise(results)
    notes = results.get("notes")
    return replace(summary, notes=len(notes) if isinstance(notes, list) else 0,
                   diverged=_diverged(results))


def _diverged(results: Mapping[str, Any]) -> tuple[str, ...]:
    """Where the free run diverged: 'record' (sample k, t = … s), per diverged record."""
    entries = results.get("validations")
    out = []
    for entry in entries if isinstance(entries, list) else ():
        where = entry.get("diverged_at") if isinstance(entry, Mapping) else None
        if isinstance(where, Mapping):
            name = entry.get("experiment") or "the held-back part"
            out.append(f"{name} (sample {where.get('sample')}, t = "
                       f"{_num(where.get('time')):.6g} s)")
    return tuple(out)


def _summarise(results: Mapping[str, Any]) -> RecordSummary:
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


def verdict_section(results: Mapping[str, Any]) -> Section:
    """The report's verdict box: fit, residual tests, structure test, warnings."""
    from ..report import Section

    s = summarise(results)
    lines = []
    if s.diverged:
        lines.append(f"Validation: FAILED — the model's free run diverges on "
                     f"{'; '.join(s.diverged)}. The model is unstable in simulation there, "
                     "whatever its one-step fit; that record has no metrics.")
    if s.fit_percent is not None:
        lines.append(f"Validation fit: {s.fit_percent:.1f} %"
                     + (" — the model does worse than the output's mean." if s.fit_percent < 0
                        else "."))
    elif not s.diverged:
        lines.append("Validation fit: not computed by this method.")
    for verdict, good, bad in (
            (s.white, "Residuals: white — no structure left that the model misses.",
             ("Residuals: NOT white — the noise model or the model order is too simple; the "
             "intervals assume more than the data show.")),
            (s.independent, "Residuals independent of the input — no input dynamics left.",
             ("Residuals correlated with the input — the model structure is rejected by the "
             "data."))):
        if verdict is not None:
            lines.append(good if verdict else bad)
    if s.structure_rejected is not None:
        lines.append("Structure test: the data reject the reduced model — its intervals "
                     "understate the error (see the structure test)." if s.structure_rejected
                     else "Structure test: no richer structure explains the data significantly "
                     "better.")
    if s.flags:
        lines.append("Flags: " + "; ".join(s.flags) + ".")
    lines.append(f"Warnings: {s.notes} (see the notes)." if s.notes else "Warnings: none.")
    return Section("Verdict", paragraphs=tuple(lines), box=True)


class Displayed:
    """Short ``repr`` and a notebook view for a workflow result (its verdict and its text)."""

    def __repr__(self) -> str:
        first = str(self).splitlines()[0] if str(self) else ""
        return f"<{type(self).__name__}: {first}>"

    def _repr_html_(self) -> str:
        import html

        try:
            section = verdict_section(self.to_dict())  # type: ignore[attr-defined]
            verdict = "".join(f"<div>{html.escape(p)}</div>" for p in section.paragraphs)
        except Exception:  # noqa: BLE001 - a result without a summary still shows its text
            verdict = ""
        return (f'<div style="border:1px solid #aaa;padding:.3em .6em;margin:.3em 0">{verdict}'
                f"</div><pre>{html.escape(str(self))}</pre>")
