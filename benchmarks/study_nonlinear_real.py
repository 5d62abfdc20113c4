"""Nonlinear against linear models on measured records, judged on held-back data.

Do servoid's nonlinear black-box models earn their keep on real servo
records?  Two records shipped with servoid:

arm
    DaISy flexible robot arm (torque → arm acceleration, 1024 samples,
    mean removed).  An electric motor drives a flexible arm: mostly
    linear, lightly damped.
emps
    EMPS electromechanical axis in its position loop: reference position
    ``qg`` → motor voltage ``vir`` (the force the loop asks for), decimated
    by 10 to 100 Hz (2484 samples).  The force carries the axis's Coulomb
    friction, a sign nonlinearity in the velocity.

Each record is split in halves: the first half estimates, the second is
held back.  Each family chooses its structure on the estimation half only,
by a free-run BIC: N·ln σ̂²_sim + p·ln N, with σ̂²_sim the mean squared
error of the model's free-run simulation of the estimation half (a
candidate whose simulation diverges there is out).  The one-step BIC of
ARX and NARX is kept beside it: for NARX it picks models that predict one
step well and diverge in simulation, which is why it is not the rule.  The
chosen model is then scored by its free-run simulation fit [%] on the
held-back half (ARX and NARX from measured initial conditions, the others
from an estimated initial state).  The whole grid, with each candidate's
held-back fit, is kept in the JSON, so a reader can see how much the
choice costs against hindsight.

Run from the repository root::

    .venv/bin/python benchmarks/study_nonlinear_real.py            # the whole grid
    .venv/bin/python benchmarks/study_nonlinear_real.py --write    # ... and record it
    .venv/bin/python benchmarks/study_nonlinear_real.py --quick    # a few candidates
    .venv/bin/python benchmarks/study_nonlinear_real.py --table    # the recorded table

It prints a Markdown table and its run time.  It writes a file only when
asked: ``--write`` replaces the recorded results,
``benchmarks/results-nonlinear-real.json`` (the file docs/nonlinear-real.md and
``tests/nonlinear/test_nonlinear_real.py`` read), ``--out PATH`` writes
elsewhere.  ``--table`` prints the recorded table without fitting anything.

BLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise: the
grid is thousands of small factorisations, for which a multi-threaded BLAS
only adds hand-offs between threads (on a busy 2-core machine the whole
grid took 17 minutes with the default threads instead of about one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported (not when a test imports the module)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from servoid import Experiment, ServoidError, ServoidWarning
from servoid.data import decimate
from servoid.datasets import load_daisy, load_emps
from servoid.estimate import Estimate, fit_arx, fit_oe
from servoid.nonlinear import fit_block, fit_narx
from servoid.validate import validate

HERE = Path(__file__).resolve().parent
RECORDED = HERE / "results-nonlinear-real.json"


def records() -> dict[str, Experiment]:
    """The two records, prepared as the module docstring says."""
    arm = load_daisy("robot_arm").detrend("mean")
    emps = decimate(load_emps(), 10)
    force = Experiment.from_arrays(dt=emps.dt, u=emps["qg"], y=emps["vir"], name="emps",
                                   units={"u": "m", "y": "V"})
    return {"arm": arm, "emps": force}


def bic(variance: float, n: int, p: int) -> float:
    """N·ln σ̂² + p·ln N."""
    return n * math.log(max(variance, 1e-300)) + p * math.log(n)


def grids(quick: bool) -> dict[str, list[tuple[str, Callable[[Experiment], Estimate]]]]:
    """Each family's candidates: a label and a fit of the estimation half."""
    orders = [1, 2, 3, 4, 6, 8] if not quick else [2, 4]
    oe_orders = [1, 2, 3, 4, 6] if not quick else [2, 4]
    families: dict[str, list[tuple[str, Callable[[Experiment], Estimate]]]] = {
        "ARX": [(f"ARX na={na} nb={nb} nk={nk}",
                 lambda e, na=na, nb=nb, nk=nk: fit_arx(e, na, nb, nk))
                for na in orders for nb in orders for nk in (0, 1)],
        "OE": [(f"OE nb={nb} nf={nf} nk={nk}",
                lambda e, nb=nb, nf=nf, nk=nk: fit_oe(e, nb, nf, nk))
               for nb in oe_orders for nf in oe_orders for nk in (0, 1)],
        "NARX": [(f"NARX na={na} nb={nb} nk={nk} degree={d}",
                  lambda e, na=na, nb=nb, nk=nk, d=d: fit_narx(e, na=na, nb=nb, nk=nk, degree=d))
                 for na in ([2, 3, 4, 6] if not quick else [2])
                 for nb in ([2, 3, 4, 6] if not quick else [3])
                 for nk in (0, 1) for d in ((2, 3) if not quick else (3,))],
    }
    blocks = []
    for n in ([2, 4, 6] if not quick else [4]):
        for nk in (0, 1):
            for label, kw in (
                    ("Hammerstein cubic", {"structure": "hammerstein",
                                           "input_nonlinearity": "polynomial"}),
                    ("Hammerstein dead zone", {"structure": "hammerstein",
                                               "input_nonlinearity": "deadzone"}),
                    ("Wiener signed power", {"structure": "wiener",
                                             "output_nonlinearity": "power"}),
                    ("Wiener cubic", {"structure": "wiener", "output_nonlinearity": "polynomial"})):
                blocks.append((f"{label} nb=nf={n} nk={nk}",
                               lambda e, n=n, nk=nk, kw=kw: fit_block(e, nb=n, nf=n, nk=nk, **kw)))
    families["block"] = blocks
    return families


def run_family(candidates: Iterable[tuple[str, Callable[[Experiment], Estimate]]],
               fit_part: Experiment, held_back: Experiment) -> list[dict[str, Any]]:
    """Fit every candidate; its BIC on the estimation half, its held-back fit."""
    rows = []
    for label, fit in candidates:
        row: dict[str, Any] = {"model": label}
        try:
            est = fit(fit_part)
        except ServoidError as exc:
            row["error"] = str(exc)
            rows.append(row)
            continue
        p = int(est.parameters.size)
        row["parameters"] = p
        row["one_step_bic"] = bic(est.noise_variance, est.n_samples, p)
        try:  # a free run that diverges is a result, not a crash
            own = validate(est, fit_part)
            row["estimation_fit"] = own.fit_percent
            row["bic"] = bic(own.rmse**2, fit_part.n_samples - own.first, p)
        except ServoidError as exc:
            row["note"] = f"estimation half: {exc}"
        try:
            row["held_back_fit"] = validate(est, held_back).fit_percent
        except ServoidError as exc:
            row["held_back_fit"] = None
            row["note"] = f"held-back half: {exc}"
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few candidates per family")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--write", action="store_true",
                       help=f"replace the recorded results ({RECORDED.relative_to(HERE.parent)})")
    where.add_argument("--out", type=Path, help="write the results to this JSON file")
    where.add_argument("--table", action="store_true",
                       help="print the recorded results' table; fit nothing")
    args = parser.parse_args(argv)
    if args.table:
        recorded = json.loads(RECORDED.read_text(encoding="utf-8"))
        print(markdown(recorded))
        grid = "quick" if recorded.get("quick") else "whole"
        print(f"\nrecorded in {RECORDED.name}: {recorded['seconds']:.0f} s for the {grid} grid")
        return 0
    if args.write and args.quick:
        parser.error("--write records the whole grid; drop --quick (or use --out)")
    warnings.simplefilter("ignore", ServoidWarning)  # each verdict is in the rows
    out: dict[str, Any] = {"method": "choose by BIC on the first half, score the free run on "
                                     "the second half", "records": {}}
    started = time.perf_counter()
    for name, exp in records().items():
        half = exp.n_samples // 2
        fit_part, held_back = exp.slice(0, half), exp.slice(half, exp.n_samples)
        summary = {}
        for family, candidates in grids(args.quick).items():
            t0 = time.perf_counter()
            rows = run_family(candidates, fit_part, held_back)
            scored = [r for r in rows if "bic" in r]
            by_one_step = [r for r in rows if "one_step_bic" in r]
            chosen = min(scored, key=lambda r: r["bic"]) if scored else None
            finite = [r for r in scored if r.get("held_back_fit") is not None]
            hindsight = max(finite, key=lambda r: r["held_back_fit"]) if finite else None
            one_step = min(by_one_step, key=lambda r: r["one_step_bic"]) if by_one_step else None
            summary[family] = {"chosen": chosen, "chosen_by_one_step_bic": one_step,
                               "best_with_hindsight": hindsight,
                               "candidates": rows, "seconds": time.perf_counter() - t0}
            print(f"{name} {family}: {len(rows)} candidates in "
                  f"{summary[family]['seconds']:.1f} s", file=sys.stderr)
        out["records"][name] = summary
    out["seconds"] = time.perf_counter() - started
    out["quick"] = args.quick
    print(markdown(out))
    print(f"\n{out['seconds']:.0f} s for the {'quick' if args.quick else 'whole'} grid",
          file=sys.stderr)
    target = RECORDED if args.write else args.out
    if target is not None:
        target.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {target}", file=sys.stderr)
    return 0


def markdown(results: dict[str, Any]) -> str:
    """The summary table: per record and family, the BIC choice and its held-back fit."""
    lines = ["| record | family | chosen by free-run BIC (estimation half) | held-back fit | "
             "one-step BIC's choice | best in the family (hindsight) |",
             "|---|---|---|---|---|---|"]
    for name, summary in results["records"].items():
        for family, s in summary.items():
            c, o, h = s["chosen"], s["chosen_by_one_step_bic"], s["best_with_hindsight"]
            lines.append(f"| {name} | {family} | {c['model'] if c else '—'} | {_fit(c)} | "
                         f"{_fit(o)} ({o['model'] if o else '—'}) | {_fit(h)} "
                         f"({h['model'] if h else '—'}) |")
    return "\n".join(lines)


def _fit(row: dict[str, Any] | None) -> str:
    if row is None:
        return "—"
    value = row.get("held_back_fit")
    return "diverged" if value is None else f"{value:.1f} %"


if __name__ == "__main__":
    raise SystemExit(main())
