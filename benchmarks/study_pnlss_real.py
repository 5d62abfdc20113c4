"""PNLSS on the shipped measured records, beside the best linear model of ``auto``.

Issue 27 asks that on the shared records PNLSS be at least as good as the
best linear model in free-run validation.  For each record (the same split
as ``study_model_choice_real.py``: first half estimation, second half
validation), ``identify`` runs ``[identify] method = "pnlss"`` with the
states and degree chosen on held-out estimation data from a grid
(``n_states`` 1–4, ``degree`` 2–3, state monomials; each search guarded
by the held-out quarter, so a candidate whose nonlinear terms do not pay
there is its linear part; a chosen candidate that kept its linear part is
then refitted by output error on all the estimation half), and its
validation fit is set beside two linear
models of ``auto`` on the same records (ARX, OE, BJ, tf, n4sid), read from
``results-model-choice-real.json``: the best found in hindsight on the
validation part, which favours the linear side, and the one ``auto``'s own
held-out score ranks first among the linear candidates.

Usage, from the repository root::

    PYTHONPATH=src python benchmarks/study_pnlss_real.py            # print the table
    PYTHONPATH=src python benchmarks/study_pnlss_real.py --write    # ... and record it

    PYTHONPATH=src python benchmarks/study_pnlss_real.py --linear n4sid --write
    PYTHONPATH=src python benchmarks/study_pnlss_real.py --linear n4sid,oe --write
    PYTHONPATH=src python benchmarks/study_pnlss_real.py --linear auto --write

The default ``--linear n4sid,auto`` is the method's default start: n4sid's
grid of states and, beside it, the linear model that model choice picks on
the fitted part (at its own order), the lowest held-out RMS kept.
``--write`` replaces ``benchmarks/results-pnlss-real.json`` (with
``--linear n4sid``, n4sid's start alone: ``benchmarks/results-pnlss-real-n4sid.json``;
with ``--linear n4sid,oe``, each order's linear start chosen between n4sid and
OE on the held-out part: ``benchmarks/results-pnlss-real-starts.json``;
with ``--linear auto``, the start the linear model that model choice picks
on the fitted part, ``n_states`` its order and only ``degree`` a grid:
``benchmarks/results-pnlss-real-auto.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from functools import partial
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from study_model_choice_real import identify_record, records, run_records, write_results

from servoid.data import Experiment

HERE = Path(__file__).resolve().parent
LINEAR = HERE / "results-model-choice-real.json"
RECORDED = HERE / "results-pnlss-real.json"
RECORDED_STARTS = HERE / "results-pnlss-real-starts.json"
RECORDED_N4SID = HERE / "results-pnlss-real-n4sid.json"
RECORDED_AUTO = HERE / "results-pnlss-real-auto.json"
_LINEAR_FAMILIES = ("arx", "oe", "bj", "tf", "n4sid")


def best_linear(name: str, by: str = "validation") -> tuple[str, float | None]:
    """The best linear candidate of ``auto`` on `name`, by its validation fit (hindsight) or
    as ``auto`` chose it on held-out data (``by = "held_out"``: as a user would choose, its
    one-standard-error rule included; the best held-out score among the linear candidates
    when ``auto`` chose a nonlinear one); (label, its validation fit)."""
    saved = {r["record"]: r for r in json.loads(LINEAR.read_text())["results"]}
    record = saved[name]
    if by == "held_out" and record["chosen"].split(" ")[0] in _LINEAR_FAMILIES:
        return record["chosen"], record["chosen_validation"]
    rows = [c for c in record["candidates"]
            if c["label"].split(" ")[0] in _LINEAR_FAMILIES and c[by] is not None]
    best = max(rows, key=lambda c: c[by])
    return best["label"], best["validation"]  # None: its free run diverged there


def run_one(folder: Path, name: str, est: Experiment, val: Experiment,
            linear: str | list[str] = ("n4sid", "auto"), states: list[int] | None = None
            ) -> dict[str, Any]:
    """PNLSS on one record, with the grid's choice and the validation fit."""
    table: dict[str, Any] = {"method": "pnlss", "n_states": states or [1, 2, 3, 4],
                             "degree": [2, 3], "monomials": "state", "linear": linear}
    if linear == "auto":  # the states are the order of the linear model model choice picks
        del table["n_states"]
    result, seconds = identify_record(folder, name, est, val, table)
    o = result.estimate.options
    refit = o.get("refit")
    chosen = result.grid[0]
    label, linear = best_linear(name)
    held_label, held_linear = best_linear(name, "held_out")
    v = result.validation
    fit = round(float(v.fit_percent), 2) if hasattr(v, "fit_percent") else None  # diverged
    kept = o["held_out"]["kept"]
    choice = o.get("linear_choice")
    return {"record": name, "linear_start": chosen.linear,
            "linear_choice": None if choice is None else
            {"chosen": choice["chosen"], "reason": choice["reason"],
             "n_states": choice["n_states"], "samples": choice["samples"]},
            "returned_linear": refit.get("by") if refit else None,
            "pnlss": f"n_states = {chosen.n_states}, degree = {chosen.degree}",
            "kept": kept, "refitted": refit is not None, "why": o["held_out"]["why"],
            "pnlss_validation": fit, "best_linear": label, "best_linear_validation": linear,
            "held_out_linear": held_label, "held_out_linear_validation": held_linear,
            "at_least_as_good": fit is not None and fit >= linear,
            "at_least_as_good_as_held_out_linear": fit is not None and (
                held_linear is None or fit >= held_linear),
            "seconds": round(seconds, 1),
            "grid": [{"n_states": c.n_states, "degree": c.degree, "linear": c.linear,
                      "held_out_rms": c.rms, "linear_part_held_out_rms": c.linear_rms,
                      "status": c.status} for c in result.grid]}


def table(results: list[dict[str, Any]]) -> str:
    """The Markdown table of the results."""
    lines = [("| record | PNLSS chosen (start) | kept on held-out data | its validation fit % "
              "| best linear (hindsight) | its fit % | PNLSS ≥ it | linear by held-out score "
              "| its fit % | PNLSS ≥ it | time s |"),
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        fit = "diverged" if r["pnlss_validation"] is None else r["pnlss_validation"]
        kept = {"nonlinear": "nonlinear terms", "linear": "linear part (E = F = 0)",
                "the linear start": "linear start (E = F = 0)"}[r["kept"]]
        if r.get("returned_linear"):
            kept += f"; model choice on all: {r['returned_linear']}"
        elif r["refitted"]:
            kept += ", refitted on all"
        lines.append(f"| {r['record']} | {r['pnlss']} ({r['linear_start']}) | {kept} | {fit} | "
                     f"{r['best_linear']} | {r['best_linear_validation']} | "
                     f"{'yes' if r['at_least_as_good'] else 'no'} | {r['held_out_linear']} | "
                     f"{_or_diverged(r['held_out_linear_validation'])} | "
                     f"{'yes' if r['at_least_as_good_as_held_out_linear'] else 'no'} | "
                     f"{r['seconds']} |")
    return "\n".join(lines)


def _or_diverged(fit: float | None) -> str:
    return "diverged" if fit is None else f"{fit}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help=f"record in {RECORDED.name}")
    parser.add_argument("--only", default=None, help="comma-separated record names")
    parser.add_argument("--linear", default="n4sid,auto",
                        help="the [identify] linear start; comma-separated: a list, chosen "
                             "per order on the held-out part (e.g. n4sid,oe)")
    parser.add_argument("--states", default="1,2,3,4",
                        help="the n_states grid, comma-separated (only the default is recorded)")
    args = parser.parse_args(argv)
    starts = args.linear.split(",")
    states = [int(n) for n in args.states.split(",")]
    if args.write and (states != [1, 2, 3, 4] or args.only):
        parser.error("--write records the whole study: all records, the default --states")
    results = run_records(records(None, 0), args.only,
                          partial(run_one, linear=starts[0] if len(starts) == 1 else starts,
                                  states=states), table)
    if args.write:
        write_results({("n4sid", "auto"): RECORDED, ("n4sid",): RECORDED_N4SID,
                       ("auto",): RECORDED_AUTO}.get(tuple(starts), RECORDED_STARTS), results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
