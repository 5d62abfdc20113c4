"""The fleet report: summary, limits, trends with control limits, outliers and every unit."""

from __future__ import annotations

import base64
import io
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..report import Figure, Page, Section, Table
from ..report._text import plain
from ..workflows._registry import toml_value
from ._limits import RULE
from ._stats import OUTLIER_Z

if TYPE_CHECKING:
    from ._result import FleetResult, ParameterStats

__all__ = ["fleet_page"]


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
    return Page("Fleet identification", tuple(sections),
                subtitle=str(spec.source) if spec.source else "",
                meta=(("records", str(len(result.rows))),
                      ("passed", str(sum(bool(r["pass"]) for r in result.rows)))))


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
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure as MplFigure

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
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return Figure(base64.b64encode(buffer.getvalue()).decode("ascii"), "image/png",
                  f"{plain(p.name)} of every identified unit against {axis_name}")


def _units_table(result: FleetResult) -> Table:
    names = [p.name for p in result.parameters]
    cols = ("serial", "record", "status", *names, "fit %", "pass", "outlier")
    rows = []
    for r in result.rows:
        cells: list[Any] = [r["serial"], r["record"], r["status"]]
        for n in names:
            v, s = _f(r.get(n)), _f(r.get(f"{n}_std"))
            cells.append("" if not math.isfinite(v) else
                         f"{v:.6g} ± {s:.2g}" if math.isfinite(s) else f"{v:.6g}")
        fit = _f(r.get("fit_percent"))
        cells += ["" if not math.isfinite(fit) else f"{fit:.1f}",
                  "pass" if r["pass"] else "FAIL", r.get("outlier") or ""]
        rows.append(tuple(str(c) for c in cells))
    return Table(cols, tuple(rows), "Every record", sortable=True)


def _f(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan
