"""Write the two records of the NARX example and their truth: python make_data.py [FOLDER].

A valve-driven axis with a flow law that depends on the load: a plain
difference equation with a bilinear and a quadratic term, white equation
error, two independent random-level tests at 100 Hz. The truth is in
``truth.json``; ``servoid identify narx.toml`` should find these six
terms among the 15 candidates.

Without FOLDER the files go beside this script, where ``narx.toml`` reads them (the
records shipped there are this script's output).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from servoid.data import Experiment, write_csv

DT = 0.01
TRUTH = {"position(t-1)": 0.6, "position(t-2)": -0.15, "valve(t-1)": 0.8,
         "valve(t-2)": 0.3, "position(t-1)*valve(t-1)": -0.25, "valve(t-1)^2": 0.2}


def record(n: int, seed: int) -> Experiment:
    """One test: random levels held for 2 samples, σ = 0.02 mm equation error."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 2), 2)
    e = 0.02 * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = (0.6 * y[t - 1] - 0.15 * y[t - 2] + 0.8 * u[t - 1] + 0.3 * u[t - 2]
                - 0.25 * y[t - 1] * u[t - 1] + 0.2 * u[t - 1] ** 2 + e[t])
    return Experiment.from_arrays(DT, u=u, y=y)


def main(folder: Path) -> None:
    """Write the two records and the truth into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(record(3000, 1), folder / "narx_run1.csv", overwrite=True)
    write_csv(record(3000, 2), folder / "narx_run2.csv", overwrite=True)
    (folder / "truth.json").write_text(json.dumps(TRUTH, indent=1), encoding="utf-8")
    print(f"wrote narx_run1.csv, narx_run2.csv, truth.json in {folder}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
