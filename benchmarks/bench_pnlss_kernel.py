"""Free-run speed of the compiled PNLSS simulation kernel alone (no model fitting).

2 states, 1 input, every monomial of degree 2–3, 1e6 samples; the median of 7 runs after a
warm-up, in million samples (state updates) per second::

    PYTHONPATH=src python benchmarks/bench_pnlss_kernel.py
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from servoid.nonlinear._pnlss_kernel import simulate


def main(n: int = 1_000_000, repeats: int = 7) -> float:
    nx, nu = 2, 1
    powers = np.array([e for d in (2, 3) for e in itertools.product(range(d + 1), repeat=nx + nu)
                       if sum(e) == d], dtype=np.int64)
    rng = np.random.default_rng(0)
    a = np.array([[0.9, 0.1], [-0.1, 0.8]])
    b = 0.1 * rng.standard_normal((nx, nu))
    c, d = rng.standard_normal(nx), np.zeros(nu)
    e = 1e-3 * rng.standard_normal((nx, powers.shape[0]))
    f = 1e-3 * rng.standard_normal(powers.shape[0])
    u = 0.3 * rng.standard_normal((n, nu))
    y, x = np.empty(n), np.empty((n + 1, nx))
    simulate(a, b, c, d, e, f, powers, u[:100], np.zeros(nx), y[:100], x[:101])  # compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        simulate(a, b, c, d, e, f, powers, u, np.zeros(nx), y, x)
        times.append(time.perf_counter() - t0)
    rate = n / float(np.median(times))
    print(f"PNLSS free run, 2 states, degree 3, {n:.0e} samples: {rate / 1e6:.2f} M samples/s")
    return rate


if __name__ == "__main__":
    main()
