"""Write the two records of the block-model example and their truth: make_data.py [FOLDER].

A valve with a dead band drives a second-order axis (Hammerstein): the
commanded opening u [V] passes a dead zone from −0.4 V to 0.6 V, then
x(t) = 1.2 x(t−1) − 0.5 x(t−2) + 0.5 v(t−1) + 0.3 v(t−2) [mm], measured
with white noise σ = 0.02 mm. Two independent random-level tests at 100 Hz,
the second starting away from rest. The truth is in ``truth.json``;
``servoid identify blocks.toml`` should find it within its intervals.

Without FOLDER the files go beside this script, where ``blocks.toml`` reads them (the
records shipped there are this script's output).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from servoid.data import Experiment, write_csv

DT = 0.01
TRUTH = {"deadzone.lower": -0.4, "deadzone.upper": 0.6, "b0": 0.5, "b1": 0.3,
         "f1": -1.2, "f2": 0.5}


def record(n: int, seed: int, start: float = 0.0) -> Experiment:
    """One test: random levels held for 2 samples; the axis starts at ``start`` mm."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-2.0, 2.0, n // 2), 2)
    v = np.where(u > 0.6, u - 0.6, np.where(u < -0.4, u + 0.4, 0.0))
    x = np.full(n, start)
    for t in range(2, n):
        x[t] = 1.2 * x[t - 1] - 0.5 * x[t - 2] + 0.5 * v[t - 1] + 0.3 * v[t - 2]
    y = x + 0.02 * rng.standard_normal(n)
    return Experiment.from_arrays(DT, u=u, y=y, names={"u": "valve", "y": "position"},
                                  units={"valve": "V", "position": "mm"})


def main(folder: Path) -> None:
    """Write the two records and the truth into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(record(3000, 1), folder / "blocks_run1.csv", overwrite=True)
    write_csv(record(3000, 2, start=2.0), folder / "blocks_run2.csv", overwrite=True)
    (folder / "truth.json").write_text(json.dumps(TRUTH, indent=1), encoding="utf-8")
    print(f"wrote blocks_run1.csv, blocks_run2.csv, truth.json in {folder}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
