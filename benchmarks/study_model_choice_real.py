"""``method = "auto"`` on measured records: is the chosen model near the best of its candidates?

For each record, ``identify`` runs ``[identify] method = "auto"`` (the default
candidate set, one hold-out of 30 % of the estimation part) from an
experiment file, and every candidate is validated on a validation part the
choice never saw.  The question (issue 25): does the chosen model's
validation fit lie within 2 points of the best candidate's — the best
found only in hindsight?

Records (the shipped ones; see ``servoid.datasets``):

robot_arm, dryer, ballbeam
    DaISy records, mean removed, first half estimation, second half
    validation (the ball and beam is closed loop, its controller unknown:
    it is identified from its input as if open, as a user would first try).
emps
    EMPS axis in its position loop, reference ``qg`` → motor voltage
    ``vir``, decimated by 10 to 100 Hz (as ``study_nonlinear_real.py``),
    halves.
wh (only when given)
    The SYSID 2009 Wiener–Hammerstein benchmark's ``WienerHammerBenchmark.csv``,
    read from the path given with ``--wh PATH`` (servoid ships none of it
    and looks nowhere else): the benchmark's split (samples 5200…184000,
    estimation the first 100 000, test the rest), of which auto gets the
    first ``--wh-n`` estimation samples (10 000) and is validated on the
    whole test part.

Usage, from the repository root::

    PYTHONPATH=src python benchmarks/study_model_choice_real.py            # print the table
    PYTHONPATH=src python benchmarks/study_model_choice_real.py --write    # ... and record it
    PYTHONPATH=src python benchmarks/study_model_choice_real.py --wh /path/WienerHammerBenchmark.csv
    PYTHONPATH=src python benchmarks/study_model_choice_real.py --only ballbeam --folds 5

``--write`` replaces ``benchmarks/results-model-choice-real.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any

if __name__ == "__main__":  # before numpy is imported
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from servoid.data import Experiment, decimate, write_csv, write_experiment_spec
from servoid.datasets import load_daisy, load_emps
from servoid.workflows import identify

HERE = Path(__file__).resolve().parent
RECORDED = HERE / "results-model-choice-real.json"


def records(wh: str | None, wh_n: int) -> dict[str, tuple[Experiment, Experiment]]:
    """(estimation, validation) of each record, as the module docstring says."""
    out = {}
    for name in ("robot_arm", "dryer", "ballbeam"):
        exp = load_daisy(name).detrend("mean")
        half = exp.n_samples // 2
        u, y = exp.names_of("u")[0], exp.names_of("y")[0]
        whole = Experiment.from_arrays(exp.dt, u=exp[u], y=exp[y])
        out[name] = (whole.slice(0, half), whole.slice(half, None))
    emps = decimate(load_emps(), 10)
    whole = Experiment.from_arrays(emps.dt, u=emps["qg"], y=emps["vir"])
    half = whole.n_samples // 2
    out["emps"] = (whole.slice(0, half), whole.slice(half, None))
    if wh:
        data = np.genfromtxt(wh, delimiter=",", skip_header=1, usecols=(0, 1))
        u, y = data[5200:184000, 0], data[5200:184000, 1]
        dt = 1 / 51200.0
        out["wh"] = (Experiment.from_arrays(dt, u=u[:wh_n], y=y[:wh_n]),
                     Experiment.from_arrays(dt, u=u[100_000:], y=y[100_000:]))
    return out


def identify_record(folder: Path, name: str, est: Experiment, val: Experiment,
                    table: dict[str, Any]) -> tuple[Any, float]:
    """``identify`` with the ``[identify]`` `table` on one record: (result, seconds)."""
    write_csv(est, folder / f"{name}-est.csv", overwrite=True)
    write_csv(val, folder / f"{name}-val.csv", overwrite=True)
    path = folder / f"{name}.toml"
    write_experiment_spec({"data": {"file": f"{name}-est.csv"},
                           "channels": {"u": {"source": "u", "role": "u"},
                                        "y": {"source": "y", "role": "y"}},
                           "validation": {"file": f"{name}-val.csv"},
                           "identify": table}, path, overwrite=True)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(path, write=False)
    return result, time.perf_counter() - start


def run_records(found: dict[str, tuple[Experiment, Experiment]], only: str | None,
                run_one: Any, table: Any) -> list[dict[str, Any]]:
    """`run_one` on each record (or those named in `only`), printing each row as it ends."""
    results = []
    with TemporaryDirectory() as tmp:
        for name, (est, val) in found.items():
            if only and name not in only.split(","):
                continue
            results.append(run_one(Path(tmp), name, est, val))
            print(table(results[-1:]).splitlines()[-1], flush=True)
    print(table(results))
    return results


def write_results(path: Path, results: list[dict[str, Any]]) -> None:
    """Record a study's rows with today's date (a whole file, replaced at once)."""
    text = json.dumps({"date": time.strftime("%Y-%m-%d"), "results": results}, indent=1)
    partial = path.with_suffix(".partial")
    partial.write_text(text + "\n", encoding="utf-8")
    partial.replace(path)


def run_one(folder: Path, name: str, est: Experiment, val: Experiment,
            folds: int = 0) -> dict[str, Any]:
    """``auto`` on one record: the chosen candidate, the best by validation, every row."""
    result, seconds = identify_record(folder, name, est, val,
                                      {"method": "auto", "workers": 2, "folds": folds})
    rows = []
    for e in result.entries:
        v = e.validation
        rows.append({"label": e.label, "status": e.score.status,
                     "n_parameters": e.score.n_parameters,
                     "held_out": None if not np.isfinite(e.score.mean) else round(e.score.mean, 2),
                     "held_out_blocks": [round(b, 2) for b in e.score.blocks],
                     "fold_fits": [None if not np.isfinite(f) else round(f, 2)
                                   for f in e.score.fold_fits],
                     "refit_gap": None if not np.isfinite(e.refit_gap) else round(e.refit_gap, 2),
                     "fitted_on": e.fitted_on,
                     "validation": None if v is None or not np.isfinite(v.fit_percent) else
                     round(float(v.fit_percent), 2)})
    fits = [r["validation"] for r in rows if r["validation"] is not None]
    chosen = next(r for r in rows if r["label"] == result.label)
    best = max(fits)
    return {"record": name, "n_estimation": est.n_samples, "n_validation": val.n_samples,
            "chosen": result.label, "chosen_validation": chosen["validation"],
            "best": next(r["label"] for r in rows if r["validation"] == best),
            "best_validation": best,
            "within_2": chosen["validation"] is not None and chosen["validation"] > best - 2.0,
            "rankable": result.rankable, "chosen_refit_gap": chosen["refit_gap"],
            "gate": result.gate, "reason": result.reason, "seconds": round(seconds, 1),
            "candidates": rows}


def table(results: list[dict[str, Any]]) -> str:
    """The Markdown table of the results."""
    lines = [("| record | samples (est./val.) | chosen | its validation fit % | best candidate "
              "| best fit % | within 2 points | chosen fit reproducible (refit gap) | nonlinear families "
              "| time s |"),
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        gate = "added" if "were added" in r["gate"] else "not added"
        lines.append(f"| {r['record']} | {r['n_estimation']}/{r['n_validation']} | "
                     f"{r['chosen']} | {r['chosen_validation']} | {r['best']} | "
                     f"{r['best_validation']} | {'yes' if r['within_2'] else 'no'} | "
                     f"{'yes' if r['rankable'] else 'no'} ({r['chosen_refit_gap']}) | {gate} | "
                     f"{r['seconds']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help=f"record in {RECORDED.name}")
    parser.add_argument("--wh", default=None, help="path of WienerHammerBenchmark.csv")
    parser.add_argument("--wh-n", type=int, default=10_000, help="WH estimation samples")
    parser.add_argument("--only", default=None, help="comma-separated record names")
    parser.add_argument("--folds", type=int, default=0,
                        help="[identify] folds (0: the hold-out; the recorded run)")
    args = parser.parse_args(argv)
    if args.write and args.folds:
        parser.error("--write records the default scheme: leave out --folds")
    results = run_records(records(args.wh, args.wh_n), args.only,
                          lambda *a: run_one(*a, folds=args.folds), table)
    if args.write:
        write_results(RECORDED, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
