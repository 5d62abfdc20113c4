"""A fleet's outcome: the table of units, its statistics, its files."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .._atomic import atomic_path
from .._version import __version__
from ._limits import RULE
from ._spec import FleetSpec
from ._stats import OUTLIER_Z, ControlLimits, Drift, control_limits, drift, robust_z
from ._table import columns, write_csv, write_parquet

__all__ = ["FleetResult", "ParameterStats", "assemble"]


@dataclass(frozen=True)
class ParameterStats:
    """Population statistics of one parameter across the fleet's successful records."""

    name: str
    unit: str
    n: int
    control: ControlLimits
    drift: Drift | None
    outliers: tuple[str, ...]  # serials

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``fleet.json``."""
        d = self.drift
        return {
            "name": self.name, "unit": self.unit, "n": self.n,
            "control_limits": _clean(dataclasses.asdict(self.control)),
            "drift": None if d is None else {**_clean(dataclasses.asdict(d)),
                                             "significant": d.significant},
            "outliers": list(self.outliers),
        }


@dataclass(frozen=True)
class FleetResult:
    """The fleet table and what it says.

    Attributes
    ----------
    spec : FleetSpec
        The fleet file.
    rows : tuple of dict
        One row per record (see :mod:`servoid.fleet._table` for the columns),
        in the fleet's order; records not run (Ctrl-C) have status
        ``"not run"``.
    columns : tuple of str
        Column names.
    parameters : tuple of ParameterStats
        Statistics per parameter.
    folder : Path
        Results folder.
    interrupted : bool
        Ctrl-C stopped the batch before every record was identified.
    """

    FILES: ClassVar[tuple[str, ...]] = ("fleet.csv", "fleet.parquet", "fleet.json",
                                        "report.html")

    spec: FleetSpec
    rows: tuple[dict[str, Any], ...]
    columns: tuple[str, ...]
    parameters: tuple[ParameterStats, ...]
    folder: Path
    interrupted: bool = False
    files: tuple[Path, ...] = field(default=())

    # -- counts -----------------------------------------------------------------------------
    def count(self, status: str) -> int:
        """Rows with this status ("ok", "failed", "not run")."""
        return sum(r["status"] == status for r in self.rows)

    @property
    def failing_units(self) -> tuple[str, ...]:
        """Serials of identified records that fail an acceptance limit."""
        return tuple(r["serial"] for r in self.rows if r["status"] == "ok" and not r["pass"])

    @property
    def peak_rss_mb(self) -> float | None:
        """Largest memory high-water mark of a process that identified a record [MB]."""
        peaks = [r["peak_rss_mb"] for r in self.rows if r.get("peak_rss_mb") is not None]
        return max(peaks) if peaks else None

    def column(self, name: str) -> np.ndarray:
        """One column as a float array (NaN where empty)."""
        return np.array([_float(r.get(name)) for r in self.rows])

    # -- outputs ----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The summary in ``fleet.json``."""
        spec = self.spec
        return {
            "servoid_version": __version__,
            "fleet_file": str(spec.source) if spec.source else None,
            "identify": dict(spec.identify) if spec.identify is not None else "each record's own",
            "records": len(self.rows), "identified": self.count("ok"),
            "failed": self.count("failed"), "not_run": self.count("not run"),
            "interrupted": self.interrupted,
            "worker_peak_rss_mb": self.peak_rss_mb,
            "passed": sum(bool(r["pass"]) for r in self.rows),
            "failing_units": list(self.failing_units),
            "failed_records": [{"record": r["record"], "error": r["error"]}
                               for r in self.rows if r["status"] == "failed"],
            "acceptance_rule": RULE,
            "limits": [{"parameter": lim.parameter, "low": _finite(lim.low),
                        "high": _finite(lim.high), "text": lim.text} for lim in spec.limits],
            "trend_axis": spec.trend,
            "outlier_rule": f"robust z-score |θ − median|/(1.4826·MAD) > {OUTLIER_Z}",
            "parameters": [p.to_dict() for p in self.parameters],
            "columns": list(self.columns),
        }

    def write(self) -> FleetResult:
        """Write ``fleet.csv``, ``fleet.parquet``, ``fleet.json`` and ``report.html``."""
        from ..report import write_html
        from ._report import fleet_page

        folder = self.folder
        written = [folder / "fleet.csv"]
        write_csv(self.rows, self.columns, written[0])
        if write_parquet(self.rows, self.columns, folder / "fleet.parquet"):
            written.append(folder / "fleet.parquet")
        with atomic_path(folder / "fleet.json", overwrite=True) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=2, allow_nan=False),
                           encoding="utf-8")
        written.append(folder / "fleet.json")
        write_html(fleet_page(self), folder / "report.html", overwrite=True)
        written.append(folder / "report.html")
        return dataclasses.replace(self, files=tuple(written))

    def __str__(self) -> str:
        lines = [f"fleet: {len(self.rows)} records, {self.count('ok')} identified, "
                 f"{self.count('failed')} failed"
                 + (f", {self.count('not run')} not run (interrupted)" if self.interrupted
                    else "")]
        if self.spec.limits:
            lines.append(f"acceptance: {sum(bool(r['pass']) for r in self.rows)} pass, "
                         f"{len(self.failing_units)} identified units fail a limit"
                         + (f" ({', '.join(self.failing_units[:10])}"
                            f"{' …' if len(self.failing_units) > 10 else ''})"
                            if self.failing_units else ""))
        for p in self.parameters:
            c, d = p.control, p.drift
            unit = "" if p.unit in ("", "-") else f" {p.unit}"
            text = (f"  {p.name}: median {c.centre:.6g}{unit}, control limits "
                    f"[{c.low:.6g}, {c.high:.6g}]")
            if d is not None:
                text += (f"; drift {d.slope:.3g}{unit}/{d.axis} "
                         f"[{d.ci_low:.3g}, {d.ci_high:.3g}]"
                         + (" (significant)" if d.significant else ""))
            if p.outliers:
                text += f"; outliers {', '.join(p.outliers)}"
            lines.append(text)
        for r in self.rows:
            if r["status"] == "failed":
                lines.append(f"  failed {r['record']}: {r['error']}")
        if self.files:
            lines.append(f"written: {self.folder}")
        return "\n".join(lines)


def assemble(spec: FleetSpec, outcomes: Mapping[int, Mapping[str, Any]], keys: Sequence[str],
             folder: Path, *, interrupted: bool = False) -> FleetResult:
    """Build the table and its statistics from the records' outcomes."""
    names: dict[str, str] = {}  # parameter → unit, in first-seen order
    for i in sorted(outcomes):
        summary = outcomes[i].get("summary") or {}
        for p in summary.get("parameters", ()):
            names.setdefault(p["name"], p.get("unit", ""))
    limited = [lim.parameter for lim in spec.limits]
    base = spec.source.parent if spec.source else Path.cwd()
    rows = []
    for i, record in enumerate(spec.records):
        row: dict[str, Any] = {"record": _relative(record.path, base), **record.meta,
                               "serial": record.serial}
        outcome = outcomes.get(i)
        rows.append(_row(row, outcome, names, spec))
    stats = _statistics(spec, rows, names)
    outlying: dict[str, list[str]] = {}
    for p in stats:
        for serial in p.outliers:
            outlying.setdefault(serial, []).append(p.name)
    for row in rows:
        row["outlier"] = ", ".join(outlying.get(row["serial"], [])) if row["status"] == "ok" \
            else None
    meta = [c for c in spec.meta_columns if c != "serial"]
    cols = columns(["serial", *meta], list(names), limited)
    if any(row.get("candidate") for row in rows):  # a multi-method run: the chosen candidate
        cols.insert(cols.index("method") + 1, "candidate")
    return FleetResult(spec, tuple(rows), tuple(cols), tuple(stats), folder, interrupted)


def _row(row: dict[str, Any], outcome: Mapping[str, Any] | None, names: Mapping[str, str],
         spec: FleetSpec) -> dict[str, Any]:
    if outcome is None:
        row.update(status="not run", error="the batch was interrupted before this record",
                   **{f"pass_{lim.parameter}": None for lim in spec.limits}, **{"pass": False})
        return row
    row.update(status=outcome["status"], error=outcome.get("error", ""),
               method=outcome.get("method"), candidate=outcome.get("candidate"),
               seconds=_float(outcome.get("seconds")),
               cpu_seconds=_float(outcome.get("cpu_seconds")),
               peak_rss_mb=outcome.get("peak_rss_mb"))
    summary = outcome.get("summary")
    if not summary:
        row.update({f"pass_{lim.parameter}": None for lim in spec.limits}, **{"pass": False})
        return row
    row.update(fit_percent=summary.get("fit_percent"), white=summary.get("white"),
               independent=summary.get("independent"),
               structure_rejected=summary.get("structure_rejected"),
               flags="; ".join(summary.get("flags", ())),
               # the record's own verdict and test conditions, for the report (not columns)
               decision=summary.get("decision"), reason=summary.get("reason", ""),
               conditions=tuple(summary.get("conditions") or ()))
    values = {p["name"]: p for p in summary["parameters"]}
    for name in names:
        p = values.get(name)
        if p is not None:
            row.update({name: _float(p["value"]), f"{name}_std": _float(p["std"]),
                        f"{name}_ci_low": _float(p["ci_low"]),
                        f"{name}_ci_high": _float(p["ci_high"])})
    verdicts = []
    for lim in spec.limits:
        p = values.get(lim.parameter)
        ok = p is not None and lim.passes(_float(p["ci_low"]), _float(p["ci_high"]))
        row[f"pass_{lim.parameter}"] = ok
        verdicts.append(ok)
    row["pass"] = all(verdicts)
    return row


def _statistics(spec: FleetSpec, rows: Sequence[dict[str, Any]],
                names: Mapping[str, str]) -> list[ParameterStats]:
    ok = [r for r in rows if r["status"] == "ok"]
    axis, axis_name = _axis(spec, ok)
    out = []
    for name, unit in names.items():
        values = np.array([_float(r.get(name)) for r in ok])
        stds = np.array([_float(r.get(f"{name}_std")) for r in ok])
        z = robust_z(values)
        outliers = tuple(r["serial"] for r, zi in zip(ok, z, strict=True)
                         if np.isfinite(zi) and abs(zi) > OUTLIER_Z)
        trend = drift(axis, values, np.where(np.isfinite(stds), stds, 0.0), axis_name) \
            if spec.trend != "serial" or np.isfinite(axis).all() else None
        out.append(ParameterStats(name, unit, int(np.isfinite(values).sum()),
                                  control_limits(values), trend, outliers))
    return out


def _axis(spec: FleetSpec, rows: Sequence[Mapping[str, Any]]) -> tuple[np.ndarray, str]:
    """The trend axis as numbers: days since the first date, a numeric serial or the order."""
    by = spec.trend
    if by == "order":
        return np.arange(len(rows), dtype=float), "run"
    raw = [str(r.get(by, "")) for r in rows]
    if by == "date":
        days = [_days(v) for v in raw]
        first = min((d for d in days if math.isfinite(d)), default=0.0)
        return np.array(days) - first, "day"
    numbers = np.array([_float(v) for v in raw])
    if np.isfinite(numbers).all():
        return numbers, by
    order = {v: k for k, v in enumerate(sorted(set(raw)))}
    return np.array([float(order[v]) for v in raw]), f"{by} rank"


def _days(text: str) -> float:
    try:
        when = dt.datetime.fromisoformat(text)
    except ValueError:
        return math.nan
    return when.timestamp() / 86400.0 if when.tzinfo else \
        (when - dt.datetime(1970, 1, 1)).total_seconds() / 86400.0


def _relative(path: Path, base: Path) -> str:
    try:
        return str(path.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(path)


def _float(x: Any) -> float:
    if x is None or isinstance(x, bool):
        return math.nan
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _clean(d: Mapping[str, Any]) -> dict[str, Any]:
    return {k: (_finite(v) if isinstance(v, float) else v) for k, v in d.items()}
