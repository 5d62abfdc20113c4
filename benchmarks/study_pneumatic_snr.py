"""Coverage of the servopneumatic multi-step intervals at low SNR.

Each seed writes the virtual rig's default campaign (``servoid bench
pneumatic``: five records, every sensor at the given SNR) and identifies it
from its ``pneumatic.toml`` as a user would (``servoid identify``).  For
every identified parameter it records z = (estimate − truth)/σ, σ the std
servoid reports, and the 95 % interval's coverage is the share of |z| <=
1.96.

The generator does not share the estimator's path: the bench simulates the
actuator (numba RK4, stick–slip) four times finer than the sample rate, adds
the sensor noise to the analog signals before the 2 kHz anti-alias filter,
samples, quantises to 16 bits and writes TDMS files that servoid reads,
calibrates and splits like any rig's; the steps' equations are regressions
on those measured channels.

Run from the repository root (a seed takes ~10 s; run niced)::

    nice -n 10 .venv/bin/python benchmarks/study_pneumatic_snr.py --seeds 100 \\
        --snr 25 30 40 --out benchmarks/results-pneumatic-snr.json
    .venv/bin/python benchmarks/study_pneumatic_snr.py --table benchmarks/results-pneumatic-snr.json

``--out`` is rewritten after every seed, so an interrupted run keeps what it
has.  ``--table`` prints the coverage table of a saved run.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
import warnings
from pathlib import Path

from servoid.data import load_experiment_spec
from servoid.plants.pneumatic import REFINABLE, write_pneumatic_campaign
from servoid.workflows import identify

Z95 = 1.959964


def run_seed(seed: int, snr: float) -> dict[str, object]:
    """Identify one campaign; return z, relative error and the verdict's notes."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            write_pneumatic_campaign(folder, seed=seed, snr_db=snr)
            ident = identify(load_experiment_spec(folder / "pneumatic.toml"), write=False)
        truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    rows = {r["name"]: r for r in ident.result.table()}
    z = {n: (rows[n]["value"] - truth[n]) / rows[n]["std"] for n in REFINABLE if n in rows}
    rel = {n: (rows[n]["value"] - truth[n]) / truth[n] for n in REFINABLE if n in rows}
    return {"seed": seed, "snr_db": snr, "z": z, "rel": rel,
            "warnings": sorted({str(w.message)[:160] for w in caught
                                if "SNR" in str(w.message) or "noise" in str(w.message)})}


def summarise(runs: list[dict[str, object]]) -> dict[str, dict[str, float]]:
    """Per SNR: coverage per parameter and pooled, and the RMS of z."""
    out: dict[str, dict[str, float]] = {}
    for snr in sorted({float(r["snr_db"]) for r in runs}):
        sel = [r for r in runs if float(r["snr_db"]) == snr]
        row: dict[str, float] = {"seeds": len(sel)}
        pooled = []
        for n in REFINABLE:
            col = [float(r["z"][n]) for r in sel if n in r["z"]]
            if not col:
                continue
            pooled += col
            row[f"cov_{n}"] = sum(abs(v) <= Z95 for v in col) / len(col)
            row[f"zrms_{n}"] = math.sqrt(sum(v * v for v in col) / len(col))
            row[f"zmean_{n}"] = sum(col) / len(col)
        row["coverage"] = sum(abs(v) <= Z95 for v in pooled) / len(pooled)
        row["z_rms"] = math.sqrt(sum(v * v for v in pooled) / len(pooled))
        out[f"{snr:g}"] = row
    return out


def table(summary: dict[str, dict[str, float]]) -> str:
    """Markdown: coverage (z mean / z RMS) per parameter, one column per SNR."""
    snrs = list(summary)
    lines = ["| parameter | " + " | ".join(f"{s} dB" for s in snrs) + " |",
             "|---|" + "---|" * len(snrs)]
    for n in REFINABLE:
        cells = []
        for s in snrs:
            row = summary[s]
            if f"cov_{n}" not in row:
                cells.append("–")
                continue
            cells.append(f"{row[f'cov_{n}']:.2f} ({row[f'zmean_{n}']:+.2f} / "
                         f"{row[f'zrms_{n}']:.2f})")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    lines.append("| **all** | " + " | ".join(
        f"**{summary[s]['coverage']:.3f}** (RMS z {summary[s]['z_rms']:.2f}, "
        f"{int(summary[s]['seeds'])} seeds)" for s in snrs) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100, help="number of seeds (0..N-1)")
    ap.add_argument("--first", type=int, default=0, help="first seed")
    ap.add_argument("--snr", type=float, nargs="+", default=[25.0, 30.0, 40.0])
    ap.add_argument("--out", type=Path, help="JSON file, rewritten after every seed")
    ap.add_argument("--table", type=Path, help="print the table of a saved run and stop")
    args = ap.parse_args(argv)
    if args.table:
        saved = json.loads(args.table.read_text(encoding="utf-8"))
        print(table(summarise(saved["runs"])))
        return 0
    runs: list[dict[str, object]] = []
    t0 = time.perf_counter()
    for seed in range(args.first, args.first + args.seeds):
        for snr in args.snr:
            runs.append(run_seed(seed, snr))
            if args.out:
                args.out.write_text(json.dumps(
                    {"command": " ".join(sys.argv), "runs": runs,
                     "summary": summarise(runs)}, indent=1), encoding="utf-8")
        print(f"seed {seed} done, {time.perf_counter() - t0:.0f} s", file=sys.stderr,
              flush=True)
    print(table(summarise(runs)))
    print(f"\n{len(runs)} runs in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
