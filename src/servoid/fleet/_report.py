"""The fleet report: verdict, summary, limits, trends with control limits, outliers, units.

The verdict box decides on the batch from the table's own numbers: every
identified unit's acceptance limits (a unit fails when its 95 % interval
leaves a limit), the units that could not be identified, and each unit's
own model verdict (a unit whose model its data reject has no estimate to
accept).  Drift and outliers are reported beside them: they describe the
fleet, not one unit's acceptance.
"""

from __future__ import annotations

import base64
import io
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..report import Check, Conditions, Figure, Page, Section, Table, Verdict
from ..report._figures import fit_titles
from ..report._text import plain
from ..workflows._methods import method_of
from ..workflows._registry import toml_value
from ._limits import RULE
from ._stats import OUTLIER_Z

if TYPE_CHECKING:
    from ._result import FleetResult, ParameterStats

__all__ = ["fleet_page", "fleet_verdict"]


def fleet_page(result: FleetResult) -> Page:
    """The fleet's report page."""
    spec = result.spec
    counts = (f"{len(result.rows)} records: {result.count('ok')} identified, "
              f"{result.count('failed')} failed"
              + (f", {result.count('not run')} not run (the batch was interrupted)"
                 if result.interrupted else "") + ".")
    summary = Section("Summary", paragraphs=(
        counts,
        ("Identification: " + ", ".join(f"{k} = {toml_value(v)}" for k, v in spec.identify.items())
         + "." if spec.identify is not None else "Identification: each record's own [identify].")
        + f" Trend axis: {spec.trend}.",
        f"Acceptance rule: {RULE}.",
        (f"Outliers: robust z-score |θ − median|/(1.4826·MAD) > {OUTLIER_Z}, flagged even "
        "inside the acceptance limits. Control limits: median ± 3·1.4826·MAD."),
    ), tables=(_limits_table(result),) if spec.limits else ())
    sections = [summary]
    for p in result.parameters:
        sections.append(_parameter_section(result, p))
    failed = [r for r in result.rows if r["status"] == "failed"]
    if failed:
        sections.append(Section("Failed records", tables=(Table(
            ("record", "serial", "error"),
            tuple((r["record"], r["serial"], r["error"]) for r in failed)),)))
    sections.append(Section("Units", paragraphs=(
        "Click a column title to sort by it.",), tables=(_units_table(result),)))
    sections.insert(0, fleet_verdict(result).section())
    return Page("Fleet identification", tuple(sections),
                subtitle=str(spec.source) if spec.source else "",
                meta=(("records", str(len(result.rows))),
                      ("accepted", str(sum(_decision(r) == "accept" for r in result.rows))),
                      ("inside every limit", str(sum(bool(r["pass"]) for r in result.rows)))))


def fleet_verdict(result: FleetResult) -> Verdict:
    """The batch's verdict: limits, unidentified units, models their data reject."""
    rows = result.rows
    ok = [r for r in rows if r["status"] == "ok"]
    checks: list[Check] = []
    missing = [r for r in rows if r["status"] != "ok"]
    if missing:
        checks.append(Check("identified", f"{len(ok)} of {len(rows)}", "caution",
                            "not identified, so not judged: " + "; ".join(
                                f"{r['serial']} ({_short(r.get('error') or r['status'])})"
                                for r in missing[:6]) + (" …" if len(missing) > 6 else "")))
    else:
        checks.append(Check("identified", f"{len(ok)} of {len(rows)}", "pass",
                            "every record was identified"))
    rejected = [r["serial"] for r in ok if _decision(r) == "not judged: model rejected"]
    if rejected:
        checks.append(Check("unit models", f"{len(rejected)} rejected", "caution",
                            "the unit's own data reject its model, so its estimate cannot be "
                            "accepted: " + _serials(rejected)))
    elif any(r.get("decision") for r in ok):
        checks.append(Check("unit models", f"{len(ok)} checked", "pass",
                            "no unit's data reject its model"))
    for lim in result.spec.limits:
        failing = [r["serial"] for r in ok if r.get(f"pass_{lim.parameter}") is False]
        if failing:
            checks.append(Check(f"limit {lim.parameter}", f"{len(failing)} of {len(ok)} outside",
                                "fail", f"{_serials(failing)}: the 95 % interval leaves "
                                f"{lim.text}"))
        else:
            checks.append(Check(f"limit {lim.parameter}", f"{len(ok)} of {len(ok)} inside",
                                "pass", f"every unit's 95 % interval lies inside {lim.text}"))
    for p in result.parameters:
        if p.outliers:
            checks.append(Check(f"outliers in {p.name}", str(len(p.outliers)), "info",
                                f"robust z-score above {OUTLIER_Z}: " + _serials(p.outliers)))
        d = p.drift
        if d is not None:
            unit = "" if p.unit in ("", "-") else f" {p.unit}"
            checks.append(Check(f"drift of {p.name}", f"{d.slope:.3g}{unit}/{d.axis}", "info",
                                (f"significant: the parameter moves with the {result.spec.trend}"
                                 if d.significant else "not significant (its 95 % interval "
                                 "contains zero)")))
    accepted = [r["serial"] for r in ok if _decision(r) == "accept"]
    units = Table(("decision", "units", "serials"), (
        ("accept", str(len(accepted)), _serials(accepted, 8)),
        ("reject: outside a limit", str(len(result.failing_units)),
         _serials(result.failing_units)),
        ("not judged: its data reject its model", str(len(rejected)), _serials(rejected)),
        ("not judged: not identified", str(len(missing)),
         _serials([r["serial"] for r in missing]))), "Units")
    spec = result.spec
    method = ("each record's own [identify]" if spec.identify is None else
              f"method = {toml_value(method_of(spec.identify))}")
    tested = (f"{len(rows)} units of the fleet file, each record identified ({method}) and "
              "its parameters held against the acceptance limits"
              + (f" ({', '.join(lim.parameter for lim in spec.limits)})" if spec.limits
                 else " (none are set: no limit rejects a unit)") + ".")
    return Verdict(tested, tuple(checks), _conditions(ok), (units,))


def _decision(row: dict[str, Any]) -> str:
    """One unit's decision: limits first, then whether its own data reject its model."""
    if row["status"] != "ok":
        return "not judged: not identified"
    if not row["pass"]:
        return "reject"
    if row.get("decision") == "reject":
        return "not judged: model rejected"
    return "accept"


def _conditions(rows: list[dict[str, Any]]) -> tuple[Conditions, ...]:
    """The units' test conditions, one row per kind of record and rate, length, excitation."""
    groups: dict[tuple[Any, ...], list[Conditions]] = {}
    for r in rows:
        for entry in r.get("conditions") or ():
            try:
                c = Conditions.from_dict(entry)
            except (TypeError, ValueError, KeyError, IndexError):
                continue  # a checkpoint of another version: its conditions are not shown
            role = c.record.split(":")[0]
            groups.setdefault((role, c.sample_rate, c.n_samples, c.excitation, c.channel),
                              []).append(c)
    out = []
    for (role, rate, n, excitation, channel), items in groups.items():
        bands = [c.band for c in items if c.band is not None]
        band = (min(b[0] for b in bands), max(b[1] for b in bands)) if bands else None
        source = (f"the lowest and highest edge over {len(items)} units; each "
                  f"{items[0].band_source}" if len(items) > 1 else items[0].band_source)
        out.append(Conditions(f"{role}: {len(items)} unit{'s' if len(items) > 1 else ''}", rate,
                              n, excitation, channel, band, source))
    return tuple(out)


def _serials(serials: Any, most: int = 12) -> str:
    serials = list(serials)
    if not serials:
        return "none"
    return ", ".join(serials[:most]) + (f" and {len(serials) - most} more"
                                        if len(serials) > most else "")


def _short(text: str) -> str:
    text = str(text).split(": ", 1)[0] if ": " in str(text) else str(text)
    return text[:60]


def _limits_table(result: FleetResult) -> Table:
    rows = []
    for lim in result.spec.limits:
        passed = sum(r.get(f"pass_{lim.parameter}") is True for r in result.rows)
        failed = [r["serial"] for r in result.rows
                  if r["status"] == "ok" and r.get(f"pass_{lim.parameter}") is False]
        rows.append((lim.parameter, lim.text, str(passed), str(len(failed)),
                     ", ".join(failed[:12]) + (" …" if len(failed) > 12 else "")))
    return Table(("parameter", "limit", "pass", "fail", "failing units"), tuple(rows),
                 "Acceptance limits")


def _parameter_section(result: FleetResult, p: ParameterStats) -> Section:
    c, d = p.control, p.drift
    unit = "" if p.unit in ("", "-") else f" {p.unit}"
    text = [(f"Median {c.centre:.6g}{unit}, robust spread {c.spread:.3g}{unit} over {p.n} "
            f"units; control limits [{c.low:.6g}, {c.high:.6g}]{unit}.")]
    if d is not None:
        text.append((f"Drift against {d.axis}: {d.slope:.4g}{unit} per {d.axis}, 95 % "
                     f"interval [{d.ci_low:.4g}, {d.ci_high:.4g}] — ")
                    + ("significant: the parameter moves over the fleet's "
                       f"{result.spec.trend}." if d.significant else
                       "not significant (the interval contains zero)."))
    if p.outliers:
        text.append(f"Outliers: {', '.join(p.outliers)}.")
    return Section(f"{p.name} [{p.unit}]" if p.unit else p.name, paragraphs=tuple(text),
                   figures=(_trend_figure(result, p),))


def _trend_figure(result: FleetResult, p: ParameterStats) -> Figure:
    from matplotlib.figure import Figure as MplFigure  # pyplot-free: no backend chosen here

    from ._result import _axis

    ok = [r for r in result.rows if r["status"] == "ok"]
    x, axis_name = _axis(result.spec, ok)
    y = np.array([_f(r.get(p.name)) for r in ok])
    low = y - np.array([_f(r.get(f"{p.name}_ci_low")) for r in ok])
    high = np.array([_f(r.get(f"{p.name}_ci_high")) for r in ok]) - y
    passed = np.array([r.get(f"pass_{p.name}") is not False for r in ok])
    outlier = np.array([r["serial"] in p.outliers for r in ok])
    fig = MplFigure(figsize=(8.0, 3.4))
    ax = fig.add_subplot()
    err = np.vstack([np.nan_to_num(low), np.nan_to_num(high)])
    for mask, colour, label in ((passed, "tab:blue", "unit (95 % CI)"),
                                (~passed, "tab:red", "fails its limit")):
        if mask.any():
            ax.errorbar(x[mask], y[mask], yerr=err[:, mask], fmt="o", ms=3.5, lw=0.8,
                        color=colour, label=label)
    if outlier.any():
        ax.plot(x[outlier], y[outlier], "s", mfc="none", mec="k", ms=9, label="outlier")
    lim = next((lim for lim in result.spec.limits if lim.parameter == p.name), None)
    if lim is not None:
        for bound in (lim.low, lim.high):
            if math.isfinite(bound):
                ax.axhline(bound, color="tab:red", lw=1.2)
        ax.plot([], [], color="tab:red", lw=1.2, label=f"acceptance {plain(lim.text)}")
    c = p.control
    if math.isfinite(c.low):
        for bound in (c.low, c.high):
            ax.axhline(bound, color="0.4", lw=1, ls="--")
        ax.axhline(c.centre, color="0.4", lw=0.8, ls=":")
        ax.plot([], [], color="0.4", ls="--", label="control limits (median ± 3σ robust)")
    if p.drift is not None and p.drift.significant and x.size:
        xs = np.array([np.nanmin(x), np.nanmax(x)])
        ax.plot(xs, np.nanmean(y) + p.drift.slope * (xs - np.nanmean(x)), color="tab:orange",
                lw=1.2, label=f"drift {p.drift.slope:.3g}/{axis_name}")
    ax.set_xlabel(plain(axis_name if axis_name != "day" else "days since the first test"))
    ax.set_ylabel(plain(f"{p.name} [{p.unit}]" if p.unit else p.name))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fit_titles(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return Figure(base64.b64encode(buffer.getvalue()).decode("ascii"), "image/png",
                  f"{plain(p.name)} of every identified unit against {axis_name}")


def _units_table(result: FleetResult) -> Table:
    names = [p.name for p in result.parameters]
    cols = ("serial", "record", "status", *names, "fit %", "limits", "outlier", "decision")
    rows = []
    for r in result.rows:
        cells: list[Any] = [r["serial"], r["record"], r["status"]]
        for n in names:
            v, s = _f(r.get(n)), _f(r.get(f"{n}_std"))
            cells.append("" if not math.isfinite(v) else
                         f"{v:.6g} ± {s:.2g}" if math.isfinite(s) else f"{v:.6g}")
        fit = _f(r.get("fit_percent"))
        cells += ["" if not math.isfinite(fit) else f"{fit:.1f}",
                  "pass" if r["pass"] else "FAIL", r.get("outlier") or "", _decision(r)]
        rows.append(tuple(str(c) for c in cells))
    return Table(cols, tuple(rows), "Every record", sortable=True)


def _f(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan
