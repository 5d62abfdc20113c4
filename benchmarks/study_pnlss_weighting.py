"""PNLSS weighted by the output's noise variance per DFT line against the plain fit.

The cases of ``tests/nonlinear/test_pnlss_weighting.py`` over many seeds:
a Duffing-type hardening spring (RK4 at 20 steps a sample) under an odd
random-phase multisine, 2 realisations × (1 transient + 2 measured)
periods of 512 samples at 50 Hz; output noise either coloured (σ = 0.05
in 6–12 Hz plus σ = 0.002 white) or white (σ = 0.02).  Each seed fits
2 states, degree 3, state monomials, 50 iterations a stage, with
``weighting = "none"`` and ``"bla"`` on the same record, and scores the
free run against the noise-free output of a fresh multisine.  Then two
variants of the weighting on the first ``--variant-seeds`` seeds (the
transient periods left out of the cost, as Paduart et al.; the noise
variance smoothed to 20 degrees of freedom instead of 40), and the cost of
one fit at 1e4 samples (2 states, degree 3, full monomials).

Usage::

    PYTHONPATH=src python benchmarks/study_pnlss_weighting.py [--seeds 100]
        [--variant-seeds 20] [--write]

``--write`` replaces ``benchmarks/results-pnlss-weighting.json`` (the summaries the docs
quote) and ``benchmarks/results-pnlss-weighting-seeds.json`` (each seed's two errors, apart so
that a figure quoted from the summary cannot be matched by chance in 400 per-seed numbers).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nonlinear"))

from test_pnlss_weighting import COLOURED, WHITE, case, fits, plan

from servoid import ServoidError, ServoidWarning
from servoid.nonlinear import _pnlss_fit, _pnlss_weight, fit_pnlss

RESULTS = Path(__file__).with_name("results-pnlss-weighting.json")
SEEDS = Path(__file__).with_name("results-pnlss-weighting-seeds.json")


def study(noise: tuple[float, float], seeds: int) -> dict:
    """Both fits' errors over `seeds` seeds and their summary."""
    pairs = []
    for seed in range(seeds):
        try:
            pairs.append(fits(seed, noise))
        except ServoidError as exc:  # a failed fit counts as inf, not as a skipped seed
            print(f"  seed {seed}: {type(exc).__name__}: {exc}", flush=True)
            pairs.append((np.inf, np.inf))
    a = np.array(pairs)
    ratio = a[:, 1] / a[:, 0]
    q = [5, 25, 50, 75, 95]

    def stats(x: np.ndarray) -> dict:
        ok = np.isfinite(x)
        return {"median": float(np.median(x)), "mean_finite": float(np.mean(x[ok])),
                "std_finite": float(np.std(x[ok])), "iqr": [float(v) for v in
                                                            np.percentile(x, [25, 75])],
                "not_finite": int((~ok).sum())}

    return {"noise_white": noise[0], "noise_band_6_12_hz": noise[1], "seeds": seeds,
            "unweighted": stats(a[:, 0]), "weighted": stats(a[:, 1]),
            "ratio_percentiles": dict(zip([f"p{p}" for p in q],
                                          [float(v) for v in np.percentile(ratio, q)])),
            "weighted_lower_share": float(np.mean(a[:, 1] < a[:, 0])),
            "ratio_max": float(np.max(ratio)),
            "per_seed": [[float(x), float(y)] for x, y in a]}


@contextlib.contextmanager
def variant(transients: bool = True, min_dof: int = _pnlss_weight.MIN_DOF):
    """The weighting with its transient periods in or out, or another smoothing."""
    saved = _pnlss_fit.periodic_weights, _pnlss_weight.MIN_DOF
    _pnlss_fit.periodic_weights = functools.partial(_pnlss_weight.periodic_weights,
                                                    transients=transients)
    _pnlss_weight.MIN_DOF = min_dof
    try:
        yield
    finally:
        _pnlss_fit.periodic_weights, _pnlss_weight.MIN_DOF = saved


def cost_at_1e4() -> dict:
    """Wall time of one fit either way at 1e4 samples (2 states, degree 3, full)."""
    big = plan(period=500, realisations=4, periods=4)  # 4 × (1 + 4) × 500 = 1e4 samples
    exp, _, _ = case(0, COLOURED, big)
    out: dict = {"samples": exp.n_samples, "model": "2 states, degree 3, full monomials",
                 "max_iter": 30}
    for weighting in ("none", "bla", "none", "bla"):  # the first pair warms the compiler
        t = time.perf_counter()
        est = fit_pnlss(exp, 2, 3, monomials="full", max_iter=30, weighting=weighting,
                        plan=big)
        wall = time.perf_counter() - t
        out[weighting] = {"seconds": wall, "iterations": est.options["iterations"],
                          "seconds_per_iteration": wall / max(est.options["iterations"], 1)}
    out["ratio_per_iteration"] = (out["bla"]["seconds_per_iteration"]
                                  / out["none"]["seconds_per_iteration"])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--variant-seeds", type=int, default=20)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    warnings.simplefilter("ignore", ServoidWarning)
    t0 = time.process_time()
    results = {"command": "PYTHONPATH=src python benchmarks/study_pnlss_weighting.py "
                          f"--seeds {args.seeds} --variant-seeds {args.variant_seeds}",
               "machine": f"{platform.machine()}, {os.cpu_count()} cores shared, "
                          f"Python {platform.python_version()}, "
                          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}",
               "date": time.strftime("%Y-%m-%d")}
    for name, noise in (("coloured", COLOURED), ("white", WHITE)):
        results[name] = study(noise, args.seeds)
        r = results[name]
        print(f"{name}: median error unweighted {r['unweighted']['median']:.4g}, weighted "
              f"{r['weighted']['median']:.4g}; ratio weighted/unweighted percentiles "
              f"{r['ratio_percentiles']}; weighted lower in "
              f"{100 * r['weighted_lower_share']:.0f} %", flush=True)
    variants = {"transient periods out of the cost": {"transients": False},
                "noise variance smoothed to 20 dof": {"min_dof": 20}}
    results["variants"] = {}
    for label, kw in variants.items():
        with variant(**kw):
            out = {name: study(noise, args.variant_seeds)
                   for name, noise in (("coloured", COLOURED), ("white", WHITE))}
        for r in out.values():
            del r["per_seed"]
        results["variants"][label] = out
        print(f"{label}: ratio medians coloured "
              f"{out['coloured']['ratio_percentiles']['p50']:.3f}, white "
              f"{out['white']['ratio_percentiles']['p50']:.3f}", flush=True)
    results["cost"] = cost_at_1e4()
    c = results["cost"]
    print(f"1e4 samples: unweighted {c['none']['seconds']:.2f} s ({c['none']['iterations']} "
          f"iterations), weighted {c['bla']['seconds']:.2f} s ({c['bla']['iterations']}); "
          f"per iteration × {c['ratio_per_iteration']:.2f}")
    results["cpu_seconds"] = time.process_time() - t0
    if args.write:
        seeds = {name: results[name].pop("per_seed") for name in ("coloured", "white")}
        RESULTS.write_text(json.dumps(results, indent=1) + "\n")
        SEEDS.write_text(json.dumps({"command": results["command"], "columns":
                                     ["unweighted", "weighted"], **seeds}) + "\n")
        print(f"wrote {RESULTS} and {SEEDS}")


if __name__ == "__main__":
    main()
