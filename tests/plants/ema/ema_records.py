"""Bench records in SI units for the identification tests."""

from __future__ import annotations

from servoid.data import Channel, Experiment
from servoid.plants.ema import EmaBench, bench_reference, run_bench

GEAR, LEAD = 3.0, 5e-3


def record(seed: int, bench: EmaBench | None = None, duration: float = 8.0, **reference):
    """(estimation half in SI, truth, bench) of one bench run."""
    bench = EmaBench() if bench is None else bench
    run = run_bench(bench, bench_reference(bench, duration=duration, **reference), rng=seed)
    cal = bench.calibration()
    exp = Experiment(tuple(Channel(c.name, c.role, c.values * cal[c.name], "")
                           for c in run.raw.channels), run.raw.dt)
    return exp.slice(0, exp.n_samples // 2), run.truth(), bench


def z_scores(result, truth, every=False):
    """(name, error in standard deviations) of every identified (or every) estimated parameter."""
    return [(n, (v - truth[n]) / s) for n, v, s in zip(result.names, result.values, result.std,
                                                      strict=True)
            if (every or result.identifiable[n]) and n not in result.given]
