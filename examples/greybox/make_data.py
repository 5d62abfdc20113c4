"""Write the example records: two tanks with overflow and a saturating pump.

The truth is simulated independently of servoid: numpy RK4 at 20 steps per
sample period, the overflow as a projection of h1 onto [0, rim] after each
step, the pump saturation as a clip of the voltage; the level sensor adds
white noise (σ = 1 mm).  Two records (estimation and validation) with
different random steps of the pump voltage.

    python make_data.py [FOLDER]   # writes tanks.csv, tanks_validation.csv

Without FOLDER the files go beside this script, where ``tanks.toml`` reads them (the
records shipped there are this script's output).
"""

import csv
import math
import sys
from pathlib import Path

import numpy as np

TRUE = {"k": 1.0e-5, "a1": 3.0e-5, "a2": 3.5e-5, "A": 0.0154}
RIM = 0.30      # upper tank's overflow level [m]
U_MAX = 8.0     # the pump saturates above 8 V
DT = 1.0        # sample period [s]
FINE = 20       # generator steps per sample
NOISE = 1e-3    # level sensor noise [m]
G = 9.81


def pump_voltage(n, rng):
    """Random steps of 60 … 240 s between 2 and 10 V.

    Not below 2 V: a tank that runs dry puts the model at the kink of √h,
    where the fit's finite-difference Jacobian is meaningless.
    """
    u = np.empty(n)
    k = 0
    while k < n:
        length = int(rng.integers(60, 240))
        u[k:k + length] = rng.uniform(2.0, 10.0)
        k += length
    return u


def simulate(u, h0, true=TRUE):
    """Levels (N, 2) at the samples: RK4 at DT/FINE, overflow by projection."""
    k, a1, a2, area = true["k"], true["a1"], true["a2"], true["A"]

    def f(h, q_in):
        q12 = a1 * math.sqrt(2 * G * max(h[0], 0.0))
        q2 = a2 * math.sqrt(2 * G * max(h[1], 0.0))
        return np.array([(q_in - q12) / area, (q12 - q2) / area])

    h = np.array(h0, dtype=float)
    out = np.empty((u.size, 2))
    step = DT / FINE
    for i, v in enumerate(u):
        out[i] = h
        q_in = k * min(max(v, 0.0), U_MAX)
        for _ in range(FINE):
            s1 = f(h, q_in)
            s2 = f(h + step / 2 * s1, q_in)
            s3 = f(h + step / 2 * s2, q_in)
            s4 = f(h + step * s3, q_in)
            h = h + step / 6 * (s1 + 2 * s2 + 2 * s3 + s4)
            h[0] = min(max(h[0], 0.0), RIM)  # the rim: what flows in above it spills
    return out


def record(n, seed, h0):
    """(t, u, h2 measured, levels) of one record."""
    rng = np.random.default_rng(seed)
    u = pump_voltage(n, rng)
    levels = simulate(u, h0)
    return np.arange(n) * DT, u, levels[:, 1] + NOISE * rng.standard_normal(n), levels


def write(path, t, u, y):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "pump", "level"])
        for row in zip(t, u, y):
            w.writerow([f"{row[0]:.1f}", f"{row[1]:.4f}", f"{row[2]:.6f}"])


def main(folder=Path(__file__).resolve().parent):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, seed, h0 in (("tanks.csv", 1, (0.10, 0.05)),
                           ("tanks_validation.csv", 2, (0.05, 0.12))):
        t, u, y, _ = record(1500, seed, h0)
        write(folder / name, t, u, y)
        print(f"wrote {folder / name}")


if __name__ == "__main__":
    main(*sys.argv[1:])
