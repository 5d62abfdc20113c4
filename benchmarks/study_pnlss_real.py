"""PNLSS on the shipped measured records, beside the best linear model of ``auto``.

Issue 27 asks that on the shared records PNLSS be at least as good as the
best linear model in free-run validation.  For each record (the same split
as ``study_model_choice_real.py``: first half estimation, second half
validation), ``identify`` runs ``[identify] method = "pnlss"`` with the
states and degree chosen on held-out estimation data from a grid
(``n_states`` 1–4, ``degree`` 2–3, state monomials), and its validation fit
is set beside the best *linear* candidate (ARX, OE, BJ, tf, n4sid) of
``auto`` on the same records, read from ``results-model-choice-real.json``
— the best found in hindsight on the validation part, which favours the
linear side.

Usage, from the repository root::

    PYTHONPATH=src python benchmarks/study_pnlss_real.py            # print the table
    PYTHONPATH=src python benchmarks/study_pnlss_real.py --write    # ... and record it

``--write`` replaces ``benchmarks/results-pnlss-real.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from study_model_choice_real import identify_record, records, run_records

from servoid.data import Experiment

HERE = Path(__file__).resolve().parent
LINEAR = HERE / "results-model-choice-real.json"
RECORDED = HERE / "results-pnlss-real.json"
_LINEAR_FAMILIES = ("arx", "oe", "bj", "tf", "n4sid")


def best_linear(name: str) -> tuple[str, float]:
    """The best linear candidate of ``auto`` on `name`, by its validation fit."""
    saved = {r["record"]: r for r in json.loads(LINEAR.read_text())["results"]}
    rows = [c for c in saved[name]["candidates"]
            if c["label"].split(" ")[0] in _LINEAR_FAMILIES and c["validation"] is not None]
    best = max(rows, key=lambda c: c["validation"])
    return best["label"], best["validation"]


def run_one(folder: Path, name: str, est: Experiment, val: Experiment) -> dict[str, Any]:
    """PNLSS on one record, with the grid's choice and the validation fit."""
    result, seconds = identify_record(folder, name, est, val, {
        "method": "pnlss", "n_states": [1, 2, 3, 4], "degree": [2, 3], "monomials": "state"})
    o = result.estimate.options
    label, linear = best_linear(name)
    v = result.validation
    fit = round(float(v.fit_percent), 2) if hasattr(v, "fit_percent") else None  # diverged
    return {"record": name, "pnlss": f"n_states = {o['n_states']}, degree = {o['degree']}",
            "pnlss_validation": fit, "best_linear": label, "best_linear_validation": linear,
            "at_least_as_good": fit is not None and fit >= linear, "seconds": round(seconds, 1)}


def table(results: list[dict[str, Any]]) -> str:
    """The Markdown table of the results."""
    lines = ["| record | PNLSS chosen | its validation fit % | best linear (hindsight) | its fit % "
             "| PNLSS ≥ linear | time s |", "|---|---|---|---|---|---|---|"]
    for r in results:
        fit = "diverged" if r["pnlss_validation"] is None else r["pnlss_validation"]
        lines.append(f"| {r['record']} | {r['pnlss']} | {fit} | "
                     f"{r['best_linear']} | {r['best_linear_validation']} | "
                     f"{'yes' if r['at_least_as_good'] else 'no'} | {r['seconds']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help=f"record in {RECORDED.name}")
    parser.add_argument("--only", default=None, help="comma-separated record names")
    args = parser.parse_args(argv)
    results = run_records(records(None, 0), args.only, run_one, table)
    if args.write:
        RECORDED.write_text(json.dumps({"date": time.strftime("%Y-%m-%d"), "results": results},
                                       indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
