"""One identification in brief: parameters, fit, test verdicts, flags — the fleet row.

Every result gives its :class:`RecordSummary` (``result.summary()``, part of
the result contract of :mod:`._registry`), built from its own objects, and
writes it into ``results.json`` as ``"summary"``.  The fleet row, the fleet
report and :func:`~servoid.workflows.load_results` read that summary; only
:func:`summarise`, for a ``results.json`` on disk, reads the file — its
``"summary"`` entry, or for a file written before there was one, the
parameters in the shapes older runs wrote them.  :func:`verdict_of`
rebuilds the verdict of such a file.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._errors import ServoidError

if TYPE_CHECKING:
    from ..report import Section, Verdict

__all__ = ["Displayed", "ParameterValue", "RecordSummary", "input_digest", "summarise",
           "summary_of", "verdict_of"]


@dataclass(frozen=True)
class ParameterValue:
    """One estimated scalar of one record: value, standard deviation, 95 % interval, unit.

    A scalar read from data without an uncertainty (an FRF's bandwidth) has
    NaN for its std and interval.
    """

    name: str
    value: float
    std: float
    ci_low: float
    ci_high: float
    unit: str = ""

    @classmethod
    def from_row(cls, row: Any) -> ParameterValue:
        """From an estimate's table row (``name, value, std, ci_low, ci_high, unit``)."""
        return cls(str(row.name), _num(row.value), _num(row.std), _num(row.ci_low),
                   _num(row.ci_high), str(row.unit or ""))

    def to_dict(self) -> dict[str, Any]:
        """Plain data (NaN where undefined; ``results.json`` writes it as null)."""
        return {"name": self.name, "value": self.value, "std": self.std,
                "ci_low": self.ci_low, "ci_high": self.ci_high, "unit": self.unit}


@dataclass(frozen=True)
class RecordSummary:
    """What a fleet row keeps of one identification.

    Attributes
    ----------
    parameters : tuple of ParameterValue
        The primary estimate's parameters, in the method's order, then any
        scalar the method reports beside them (an FRF's spec numbers).
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
    decision : str or None
        The verdict's ``"accept"``, ``"reject"`` or ``"inconclusive"``
        (None for a results file that predates verdicts).
    reason : str
        Why, in words.
    conditions : tuple of dict
        The test conditions of each record (rate, length, excitation,
        band), as ``results.json`` holds them.
    method : str
        The registered method that made it ('' for an older file without
        one).
    """

    parameters: tuple[ParameterValue, ...]
    fit_percent: float | None = None
    white: bool | None = None
    independent: bool | None = None
    structure_rejected: bool | None = None
    flags: tuple[str, ...] = ()
    notes: int = 0
    diverged: tuple[str, ...] = ()
    decision: str | None = None
    reason: str = ""
    conditions: tuple[dict[str, Any], ...] = field(default=())
    method: str = ""

    def names(self) -> tuple[str, ...]:
        """Parameter names, in order."""
        return tuple(p.name for p in self.parameters)

    def to_dict(self) -> dict[str, Any]:
        """Plain data: ``results.json``'s ``"summary"`` and a fleet record's outcome."""
        return {"method": self.method, "parameters": [p.to_dict() for p in self.parameters],
                "fit_percent": self.fit_percent, "white": self.white,
                "independent": self.independent, "structure_rejected": self.structure_rejected,
                "flags": list(self.flags), "notes": self.notes, "diverged": list(self.diverged),
                "decision": self.decision, "reason": self.reason,
                "conditions": [dict(c) for c in self.conditions]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RecordSummary:
        """The summary :meth:`to_dict` wrote (null numbers read as NaN)."""
        fit = data.get("fit_percent")
        return cls(
            tuple(_row(p) for p in data.get("parameters") or () if _has_value(p)),
            fit_percent=None if fit is None else _num(fit),
            white=_flag(data.get("white")), independent=_flag(data.get("independent")),
            structure_rejected=_flag(data.get("structure_rejected")),
            flags=tuple(str(f) for f in data.get("flags") or ()),
            notes=int(data.get("notes") or 0),
            diverged=tuple(str(d) for d in data.get("diverged") or ()),
            decision=str(data["decision"]) if isinstance(data.get("decision"), str) else None,
            reason=str(data.get("reason") or ""),
            conditions=tuple(dict(c) for c in data.get("conditions") or ()
                             if isinstance(c, Mapping)),
            method=str(data.get("method") or ""))


def summary_of(method: str, parameters: Sequence[Any], verdict: Verdict, *,
               validation: Any = None, notes: Sequence[str] = (), flags: Sequence[str] = (),
               structure_rejected: bool | None = None, diverged: Sequence[str] = (),
               extra: Sequence[ParameterValue] = ()) -> RecordSummary:
    """Build a result's :class:`RecordSummary` from its own objects.

    Parameters
    ----------
    method : str
        The registered method.
    parameters : sequence
        Estimate table rows (``Estimate.table()``) or :class:`ParameterValue`
        (a None where there is no interval is read as NaN).
    verdict : Verdict
        The result's verdict (decision, reason, test conditions).
    validation : ValidationReport, optional
        The primary model's first validation (fit and residual tests).
    notes, flags : sequence of str
        The run's notes (counted) and the estimate's flags.
    structure_rejected : bool, optional
        The structure test's verdict, when there is one.
    diverged : sequence of str
        Where the free run diverged, per record.
    extra : sequence of ParameterValue
        Scalars reported beside the parameters.
    """
    # every number a float (None, where a method has no interval, as NaN)
    rows = tuple(ParameterValue.from_row(p) for p in parameters)
    fit = white = independent = None
    if validation is not None:
        fit = _num(validation.fit_percent)
        fit = fit if math.isfinite(fit) else None  # results.json writes a NaN fit as null
        residuals = validation.residuals
        white, independent = bool(residuals.is_white), bool(residuals.is_independent)
    return RecordSummary(
        (*rows, *(ParameterValue.from_row(p) for p in extra)), fit_percent=fit, white=white, independent=independent,
        structure_rejected=structure_rejected, flags=tuple(flags), notes=len(notes),
        diverged=tuple(diverged), decision=verdict.decision, reason=verdict.reason,
        conditions=tuple(c.to_dict() for c in verdict.conditions), method=method)


def summarise(results: Mapping[str, Any]) -> RecordSummary:
    """Return the summary of a ``results.json`` dictionary.

    A file holds it whole (``"summary"``, what ``result.summary()`` gave);
    for an older file it is rebuilt from the shapes its parameters were
    written in (see :func:`_summarise`).
    """
    held = results.get("summary")
    if isinstance(held, Mapping):
        try:
            return RecordSummary.from_dict(held)
        except (TypeError, ValueError, KeyError):
            pass  # a damaged entry (check_results names its fields): the older shapes instead
    summary = _summarise(results)
    notes = results.get("notes")
    verdict = results.get("verdict")
    verdict = verdict if isinstance(verdict, Mapping) else {}
    decision = verdict.get("decision")
    conditions = verdict.get("conditions")
    return replace(summary, notes=len(notes) if isinstance(notes, list) else 0,
                   diverged=_diverged(results),
                   decision=str(decision) if isinstance(decision, str) else None,
                   reason=str(verdict.get("reason") or ""),
                   conditions=tuple(dict(c) for c in conditions if isinstance(c, Mapping))
                   if isinstance(conditions, list) else (),
                   method=str(results.get("method") or ""))


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
    except (TypeError, ValueError, OverflowError):
        return math.nan


def _flag(x: Any) -> bool | None:
    return x if isinstance(x, bool) else None


def verdict_of(results: Mapping[str, Any]) -> Verdict:
    """The verdict of a ``results.json``: its own, or one rebuilt from its numbers.

    A file written with a verdict holds it whole (``"verdict"``); for an
    older file the fit, the residual tests, the structure test, the flags
    and the notes become checks, so its report still opens with a decision.
    """
    from ..report import Check, Verdict

    held = results.get("verdict")
    if isinstance(held, Mapping):
        try:
            return Verdict.from_dict(held)
        except (KeyError, TypeError, ValueError, ServoidError):
            pass  # a damaged entry: judge the numbers instead
    s = summarise(results)
    checks = [Check(f"free run ({where})", "diverges", "fail",
                    "the model is unstable in simulation there; no metrics")
              for where in s.diverged]
    if s.fit_percent is not None:
        checks.append(Check("simulation fit", f"{s.fit_percent:.1f} %",
                            "fail" if s.fit_percent < 0 else "pass",
                            "worse than the output's mean" if s.fit_percent < 0 else
                            "on data not used for fitting"))
    if s.independent is not None:
        checks.append(Check("input–residual independence",
                            "independent" if s.independent else "correlated",
                            "pass" if s.independent else "fail",
                            "no input dynamics left" if s.independent else
                            "the dynamics from the input are not captured"))
    if s.white is not None:
        checks.append(Check("residual whiteness", "white" if s.white else "not white", "info",
                            "what it means for the model is in the notes"))
    if s.structure_rejected is not None:
        checks.append(Check("structure test", "rejected" if s.structure_rejected else "passed",
                            "fail" if s.structure_rejected else "pass",
                            "a richer structure explains the data better" if s.structure_rejected
                            else "no richer structure explains the data significantly better"))
    if s.flags:
        checks.append(Check("flags", str(len(s.flags)), "caution", "; ".join(s.flags)))
    checks.append(Check("notes", str(s.notes), "info", "listed under Notes" if s.notes
                        else "none"))
    method = results.get("method")
    run = f"a {method} run" if isinstance(method, str) and method else "a run"
    return Verdict(f"the results of {run}, judged from its results.json.", tuple(checks))


class Displayed:
    """What every workflow result shares: a short ``repr``, a notebook view, contract defaults.

    The defaults of the result contract (:class:`~._registry.Identification`):
    :meth:`sections` are the page's, :meth:`models` none; :meth:`digest` is
    the SHA-256 of an input, computed once per result (``write_results``
    fills the table ``digests`` for every input before anything reads it).
    """

    def sections(self, files: Mapping[str, Path]) -> tuple[Section, ...]:
        """The report's sections after the verdict box (those of :meth:`page`)."""
        return tuple(self.page(files).sections)  # type: ignore[attr-defined]

    def models(self) -> dict[str, Any]:
        """Name → identified model; none by default."""
        return {}

    def digest(self, path: str | os.PathLike[str]) -> str:
        """SHA-256 of an input file (hex), hashed at most once for this result."""
        return input_digest(getattr(self, "digests", None), path)

    def __repr__(self) -> str:
        first = str(self).splitlines()[0] if str(self) else ""
        return f"<{type(self).__name__}: {first}>"

    def _repr_html_(self) -> str:
        import html

        try:
            verdict = self.verdict()  # type: ignore[attr-defined]
            rows = "".join(f"<tr><td>{html.escape(c.name)}</td><td>{html.escape(c.value)}</td>"
                           f"<td>{html.escape(c.meaning)}</td></tr>" for c in verdict.checks)
            head = (f"<div><b>{html.escape(verdict.decision.upper())}</b> — "
                    f"{html.escape(verdict.reason)}</div><table>{rows}</table>")
        except Exception:  # noqa: BLE001 - a result without a verdict still shows its text
            head = ""
        return (f'<div style="border:1px solid #aaa;padding:.3em .6em;margin:.3em 0">{head}'
                f"</div><pre>{html.escape(str(self))}</pre>")


def input_digest(table: dict[str, str] | None, path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file from ``table`` (real path → hex), hashing it there once if absent."""
    from ._common import sha256

    key = os.path.realpath(path)
    if table is None:
        return sha256(Path(path))
    if key not in table:
        table[key] = sha256(Path(path))
    return table[key]
