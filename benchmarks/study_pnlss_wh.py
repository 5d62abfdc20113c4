"""PNLSS on the real Wiener–Hammerstein benchmark (SYSID 2009).

Reads the parts shipped with servoid (:func:`servoid.datasets.load_wiener_hammerstein`),
or the original ``WienerHammerBenchmark.csv`` from the path given as the first argument (or
``$SERVOID_WH_CSV``); the two give the same samples. The split is the benchmark's
(its PROVENANCE): samples [5200:184000], estimation the first 100 000,
test the remaining 78 800, the first 50 test samples only for the initial
state and left out of the score. Prints the test RMSE of the free run.

Usage::

    PYTHONPATH=src python benchmarks/study_pnlss_wh.py [RECORD.csv] [n_states] [degree] \\
        [monomials] [n_fit] [max_iter]

``n_fit`` takes the first n_fit estimation samples (default all 100 000).

    PYTHONPATH=src python benchmarks/study_pnlss_wh.py --score RESULTS/results.json

scores the model a ``servoid identify`` run wrote by the benchmark's rule: the initial state
from the first 50 test samples only, the RMSE over the rest.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from servoid import ServoidWarning
from servoid.data import Experiment
from servoid.datasets import load_wiener_hammerstein
from servoid.nonlinear import fit_pnlss


def score(results: str) -> int:
    """The benchmark's score of a fitted model: x(0) from the first 50 test samples alone."""
    from servoid.workflows import load_results

    model = load_results(results).models["G"]
    test = load_wiener_hammerstein("test")
    u, y = test["u"], test["y"]
    x0 = model.initial_state(y[:50], u[:50])
    rmse = float(np.sqrt(np.mean((model.simulate(u, x0)[50:] - y[50:]) ** 2)))
    print(f"{results}: test RMSE {1e3 * rmse:.3f} mV (initial state from the first 50 test "
          "samples, scored on the other 78 750)")
    return 0


def main(argv: list[str]) -> int:
    if argv[:1] == ["--score"]:
        return score(argv[1])
    given = argv[0] if argv and argv[0].endswith(".csv") else os.environ.get("SERVOID_WH_CSV")
    if argv and argv[0].endswith(".csv"):
        argv = argv[1:]
    if given and not Path(given).is_file():
        print(f"no Wiener–Hammerstein record at {given}")
        return 1
    nx = int(argv[0]) if argv else 6
    degree = int(argv[1]) if len(argv) > 1 else 3
    monomials = argv[2] if len(argv) > 2 else "state"
    n_fit = int(argv[3]) if len(argv) > 3 else 100_000
    max_iter = int(argv[4]) if len(argv) > 4 else 100
    if given:
        data = np.genfromtxt(given, delimiter=",", skip_header=1, usecols=(0, 1))
        u, y = data[5200:184000, 0], data[5200:184000, 1]
    else:
        parts = [load_wiener_hammerstein(p) for p in ("estimation", "test")]
        u = np.concatenate([p["u"] for p in parts])
        y = np.concatenate([p["y"] for p in parts])
    dt = 1 / 51200.0
    est_u, est_y = u[:100_000][:n_fit], y[:100_000][:n_fit]
    test_u, test_y = u[100_000:], y[100_000:]
    exp = Experiment.from_arrays(u=est_u, y=est_y, dt=dt)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        est = fit_pnlss(exp, nx, degree, monomials=monomials, max_iter=max_iter)
    took = time.perf_counter() - t0
    model = est.model
    x0 = model.initial_state(test_y[:50], test_u[:50])
    y_sim = model.simulate(test_u, x0)
    rmse = float(np.sqrt(np.mean((y_sim[50:] - test_y[50:]) ** 2)))
    lin = fit_pnlss(exp, nx, 1, max_iter=max_iter) if degree > 1 else est
    x0l = lin.model.initial_state(test_y[:50], test_u[:50])
    rmse_lin = float(np.sqrt(np.mean((lin.model.simulate(test_u, x0l)[50:] - test_y[50:]) ** 2)))
    print(f"PNLSS n_states={nx} degree={degree} monomials={monomials} on {n_fit} estimation "
          f"samples: {est.parameters.size} parameters, {est.options['iterations']} iterations, "
          f"{took:.0f} s; estimation RMS {1e3 * np.sqrt(est.options['cost']):.3f} mV; "
          f"test RMSE {1e3 * rmse:.3f} mV (linear state space of the same order: "
          f"{1e3 * rmse_lin:.3f} mV)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
