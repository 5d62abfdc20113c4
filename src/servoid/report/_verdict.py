"""The verdict a report opens with: what was tested, how, each check, one decision.

A :class:`Verdict` is plain data built from a result's own numbers (never
re-read from its ``results.json``), so the box on the page, the console
line, the notebook view and the ``"verdict"`` entry of ``results.json`` are
one object rendered four ways.  Its decision is not stored but derived from
its checks, so it cannot disagree with them:

- **reject** when any check fails (the data reject the model);
- **inconclusive** when none fails but one calls for caution, or when no
  check compared the model with data (nothing to accept it on);
- **accept** otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from .._errors import check_option
from ._html import Section, Table

__all__ = ["Check", "Conditions", "Verdict", "band_text", "pvalue_text"]

Decision = Literal["accept", "reject", "inconclusive"]
Outcome = Literal["pass", "fail", "caution", "info"]

_OUTCOMES = ("pass", "fail", "caution", "info")
_SHOWN = {"pass": "pass", "fail": "FAIL", "caution": "caution", "info": "info"}


@dataclass(frozen=True)
class Conditions:
    """The conditions of one record a model was fitted or tested on.

    Attributes
    ----------
    record : str
        Its role and name, e.g. ``"estimation: run0.csv"``.
    sample_rate : float
        Sampling rate of the data as identified (after decimation) [Hz].
    n_samples : int
        Samples in the record.
    excitation : str
        The excitation's name when the data file or the bench says it
        (``"prbs"``, ``"multisine"``), else ``""``.
    channel : str
        The channel whose spectrum gives the band (the excitation's).
    band : tuple of float or None
        Lowest and highest excited frequency [Hz]; None for a constant
        channel.
    band_source : str
        Where the band comes from (declared, or the spectrum and its rule).
    """

    record: str
    sample_rate: float
    n_samples: int
    excitation: str = ""
    channel: str = ""
    band: tuple[float, float] | None = None
    band_source: str = ""

    @property
    def duration(self) -> float:
        """Length of the record [s]."""
        return self.n_samples / self.sample_rate if self.sample_rate > 0 else math.nan

    def row(self) -> tuple[str, ...]:
        """The record's cells in the conditions table."""
        return (self.record, _rate_text(self.sample_rate),
                f"{_duration_text(self.duration)} ({self.n_samples} samples)",
                self.excitation or "not stated", self.band_text())

    def band_text(self) -> str:
        """The band with its channel and source, e.g. ``"0.98–74 Hz (r, …)"``."""
        if self.band is None:
            return f"none: {self.channel or 'the input'} is constant"
        where = ", ".join(x for x in (self.channel, self.band_source) if x)
        return band_text(self.band) + (f" ({where})" if where else "")

    def text(self) -> str:
        """One line for the console."""
        return (f"{self.record}: {_rate_text(self.sample_rate)}, {self.n_samples} samples "
                f"({_duration_text(self.duration)}), excitation "
                f"{self.excitation or 'not stated'}, band {self.band_text()}")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``results.json``."""
        return {"record": self.record, "sample_rate_hz": self.sample_rate,
                "n_samples": self.n_samples, "duration_s": self.duration,
                "excitation": self.excitation or None, "channel": self.channel,
                "band_hz": None if self.band is None else list(self.band),
                "band_source": self.band_source}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Conditions:
        """The conditions :meth:`to_dict` wrote."""
        band = data.get("band_hz")
        return cls(str(data.get("record", "")), float(data.get("sample_rate_hz") or math.nan),
                   int(data.get("n_samples") or 0), str(data.get("excitation") or ""),
                   str(data.get("channel") or ""),
                   None if band is None else (float(band[0]), float(band[1])),
                   str(data.get("band_source") or ""))


@dataclass(frozen=True)
class Check:
    """One check of a verdict: its number and what it says.

    Attributes
    ----------
    name : str
        What is checked (``"simulation fit"``).
    value : str
        The number as shown (``"96.8 %"``, ``"p = 0.67"``).
    outcome : {"pass", "fail", "caution", "info"}
        ``fail`` rejects the model, ``caution`` leaves the verdict
        inconclusive, ``info`` is a number the verdict does not rest on.
    meaning : str
        What the number says, in words.
    """

    name: str
    value: str
    outcome: Outcome
    meaning: str

    def __post_init__(self) -> None:
        check_option("outcome", self.outcome, _OUTCOMES)

    def to_dict(self) -> dict[str, str]:
        """Plain data for ``results.json``."""
        return {"name": self.name, "value": self.value, "outcome": self.outcome,
                "meaning": self.meaning}


@dataclass(frozen=True)
class Verdict:
    """What a report decides, and on which numbers.

    Attributes
    ----------
    tested : str
        What was tested, in one sentence.
    checks : tuple of Check
        Every check, with its number.
    conditions : tuple of Conditions
        The records: rate, length, excitation and band.
    tables : tuple of Table
        Further numbers the verdict carries (an FRF's spec numbers).
    """

    tested: str
    checks: tuple[Check, ...]
    conditions: tuple[Conditions, ...] = ()
    tables: tuple[Table, ...] = field(default=())

    @property
    def decision(self) -> Decision:
        """``"accept"``, ``"reject"`` or ``"inconclusive"``, from the checks."""
        outcomes = {c.outcome for c in self.checks}
        if "fail" in outcomes:
            return "reject"
        if "caution" in outcomes or "pass" not in outcomes:
            return "inconclusive"
        return "accept"

    @property
    def reason(self) -> str:
        """Why: the failing checks, the cautions, or what passed."""
        decision = self.decision
        if decision == "reject":
            return _join(c for c in self.checks if c.outcome == "fail")
        if decision == "inconclusive":
            cautions = [c for c in self.checks if c.outcome == "caution"]
            if cautions:
                return _join(cautions)
            return "no check compared the model with data it was not fitted to"
        return "passes every check: " + "; ".join(f"{c.name} {c.value}" for c in self.checks
                                                 if c.outcome == "pass")

    def line(self) -> str:
        """The decision in one line: ``ACCEPT — …``."""
        return f"{self.decision.upper()} — {self.reason}"

    def lines(self) -> list[str]:
        """The verdict for the console."""
        out = [f"verdict: {self.line()}"]
        out += [f"  tested on {c.text()}" for c in self.conditions]
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``results.json`` (the decision and its reason included)."""
        return {"decision": self.decision, "reason": self.reason, "tested": self.tested,
                "conditions": [c.to_dict() for c in self.conditions],
                "checks": [c.to_dict() for c in self.checks],
                "tables": [{"caption": t.caption, "columns": list(t.columns),
                            "rows": [list(r) for r in t.rows]} for t in self.tables]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Verdict:
        """The verdict :meth:`to_dict` wrote (its decision follows from its checks again)."""
        checks = tuple(Check(str(c["name"]), str(c["value"]), c["outcome"], str(c["meaning"]))
                       for c in data.get("checks", ()))
        tables = tuple(Table(tuple(t["columns"]), tuple(tuple(r) for r in t["rows"]),
                             str(t.get("caption", ""))) for t in data.get("tables", ()))
        return cls(str(data.get("tested", "")), checks,
                   tuple(Conditions.from_dict(c) for c in data.get("conditions", ())), tables)

    def section(self) -> Section:
        """The framed box the report opens with."""
        tables = []
        if self.conditions:
            tables.append(Table(("record", "sample rate", "length", "excitation", "band"),
                                tuple(c.row() for c in self.conditions), "Test conditions"))
        if self.checks:
            tables.append(Table(("check", "value", "result", "what it says"),
                                tuple((c.name, c.value, _SHOWN[c.outcome], c.meaning)
                                      for c in self.checks), "Checks"))
        return Section("Verdict", paragraphs=(f"Tested: {self.tested}",),
                       tables=(*tables, *self.tables), box=True,
                       decision=(self.decision, self.line()))


def pvalue_text(p: float) -> str:
    """A p-value as shown: ``p = 0.67``; an underflow to 0 as ``p < 1e-300``."""
    if p != p:  # NaN
        return "not tested"
    return "p < 1e-300" if p < 1e-300 else f"p = {p:.3g}"


def band_text(band: Sequence[float]) -> str:
    """``"0.98–74 Hz"``: a frequency band with three significant digits."""
    low, high = band
    return f"{low:.3g} Hz" if low == high else f"{low:.3g}–{high:.3g} Hz"


def _join(checks: Any) -> str:
    return "; ".join(f"{c.name} {c.value}: {c.meaning}" for c in checks)


def _rate_text(rate: float) -> str:
    return f"{rate / 1e3:.4g} kHz" if rate >= 1e3 else f"{rate:.4g} Hz"


def _duration_text(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "unknown length"
    if seconds >= 120:
        return f"{seconds / 60:.3g} min"
    if seconds >= 1:
        return f"{seconds:.3g} s"
    return f"{seconds * 1e3:.3g} ms"
