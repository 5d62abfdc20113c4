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

``--steps`` is the component check behind the σ of S1 and S2: per seed it
writes only the valve and thermo records, runs those two steps with the
campaign's options, and prints per parameter the seed-to-seed spread of the
estimates against the mean σ the step reports (about 1 s a seed)::

    nice -n 10 .venv/bin/python benchmarks/study_pneumatic_snr.py --steps --seeds 100 \\
        --snr 30 --out benchmarks/results-pneumatic-steps.json
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


def step_spread(seeds: range, snr: float) -> dict[str, dict[str, float]]:
    """S1 and S2 alone: spread of the estimates against their reported σ."""
    import statistics

    from servoid.plants.pneumatic import KnownConstants, identify_thermodynamics, identify_valve

    values: dict[str, list[float]] = {}
    stds: dict[str, list[float]] = {}
    truth: dict[str, float] = {}
    for seed in seeds:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                write_pneumatic_campaign(folder, tests=["valve", "thermo"], seed=seed,
                                         snr_db=snr)
                truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
                known = KnownConstants(**truth["known"], mdot_sensor_bandwidth=1000.0)
                # the campaign's options (pneumatic.toml): cubic u, measured velocity
                s1 = identify_valve(load_experiment_spec(folder / "valve.toml").load(),
                                    u_hold="cubic")
                s2 = identify_thermodynamics(load_experiment_spec(folder / "thermo.toml").load(),
                                             known, derivatives="measured")
        for step, names in ((s1, ("k_v", "xi_v", "omega_v")), (s2, ("kappa", "R"))):
            for n in names:
                values.setdefault(n, []).append(step[n])
                stds.setdefault(n, []).append(step.std(n))
    out = {}
    for n, v in values.items():
        z = [(x - truth[n]) / s for x, s in zip(v, stds[n], strict=True)]
        out[n] = {"spread": statistics.stdev(v), "mean_std": statistics.fmean(stds[n]),
                  "ratio": statistics.stdev(v) / statistics.fmean(stds[n]),
                  "z_rms": math.sqrt(statistics.fmean([x * x for x in z])),
                  "coverage": sum(abs(x) <= Z95 for x in z) / len(z)}
    return out


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
    ap.add_argument("--steps", action="store_true",
                    help="S1 and S2 alone: spread of the estimates against their σ")
    args = ap.parse_args(argv)
    if args.steps:
        saved: dict[str, object] = {"command": " ".join(sys.argv), "steps": {}}
        for snr in args.snr:
            rows = step_spread(range(args.first, args.first + args.seeds), snr)
            saved["steps"][f"{snr:g}"] = rows  # type: ignore[index]
            print(f"{snr:g} dB, {args.seeds} seeds: parameter | spread / mean σ | RMS z | "
                  "coverage")
            for n, row in rows.items():
                print(f"  {n} | {row['ratio']:.2f} | {row['z_rms']:.2f} | {row['coverage']:.2f}")
        if args.out:
            args.out.write_text(json.dumps(saved, indent=1), encoding="utf-8")
        return 0
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
