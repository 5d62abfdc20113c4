"""Crosstalk study: the recorded reference carries the output's noise.

The loop runs on the clean reference r; the record logs ``r + α·(y − y₀)``
(y₀ the noise-free output of the same run), as ADC crosstalk from the
position channel would.  Prints, per rig, the plain closed-loop IV's errors
in σ and how often its over-identification test rejects.

    PYTHONPATH=src python tests/closedloop/anyloop_crosstalk.py --seeds 100 --alpha 1 \
        --noise-std 0.05 unstable
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).parent))
from anyloop_rigs import RIGS, Rig, prbs_reference

from servoid.closedloop import fit_cliv
from servoid.data import Experiment


def crosstalk_record(rig: Rig, seed: int, n: int, alpha: float,
                     noise_std: float | None = None, clock: int | None = None) -> Experiment:
    """A closed-loop record whose logged reference carries α × the output's noise."""
    if noise_std is not None:
        rig = dataclasses.replace(rig, noise_std=noise_std)
    r = prbs_reference(n, clock or rig.clock, rig.amplitude, 10_000 + seed)
    rec = rig.run(r, seed)
    clean = dataclasses.replace(rig, noise_std=0.0).run(r, seed)
    return Experiment.from_arrays(rig.dt, r=r + alpha * (rec.y - clean.y), u=rec.u, y=rec.y)


def outer_loop_record(rig: Rig, seed: int, n: int, beta: float,
                      noise_std: float | None = None, clock: int | None = None) -> Experiment:
    """A closed loop whose reference an outer program sets from the measured output.

    ``r(k) = r₀(k) + β·y(k − 1)``: the loop runs on that r and the record logs
    it, so r carries the output's past noise (the fed-back-reference case).
    """
    if noise_std is not None:
        rig = dataclasses.replace(rig, noise_std=noise_std)
    r0 = prbs_reference(n, clock or rig.clock, rig.amplitude, 10_000 + seed)
    a_s, b_s, c = rig._maps()
    rng = np.random.default_rng(seed)
    v = signal.lfilter(rig.noise[0], rig.noise[1], rng.standard_normal(n) * rig.noise_std)
    cn, cd = rig.controller
    cn = np.concatenate([np.zeros(cd.size - cn.size), cn]) / cd[0]
    cd = cd / cd[0]
    x = np.zeros(a_s.shape[0])
    r, u, y = np.zeros(n), np.zeros(n), np.zeros(n)
    ein, uout, fifo = np.zeros(cd.size), np.zeros(cd.size), np.zeros(rig.delay + 1)
    for k in range(n):
        y[k] = c @ x + v[k]
        r[k] = r0[k] + (beta * y[k - 1] if k else 0.0)
        ein = np.roll(ein, 1)
        ein[0] = r[k] - y[k]
        uk = cn @ ein - cd[1:] @ uout[:-1]
        uout = np.roll(uout, 1)
        uout[0] = uk
        u[k] = uk
        fifo = np.roll(fifo, -1)
        fifo[-1] = uk
        x = a_s @ x + b_s * fifo[0]
    return Experiment.from_arrays(rig.dt, r=r, u=u, y=y)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--alpha", type=float, default=0.0, help="crosstalk gain α")
    parser.add_argument("--noise-std", type=float, default=None, help="the rig's own if unset")
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--clock", type=int, default=None, help="PRBS bit [samples]")
    parser.add_argument("--outer", type=float, default=None,
                        help="β: log r(k) = r₀(k) + β·y(k − 1), set from the measured output, "
                        "instead of crosstalk")
    parser.add_argument("rigs", nargs="*", default=list(RIGS))
    args = parser.parse_args()
    alpha = args.alpha
    for name in args.rigs:
        rig = RIGS[name]
        na, nb, nk = rig.orders
        truth = rig.theta_arx()
        zmax, fired, held, pvals = [], 0, 0, []
        for seed in range(args.seeds):
            if args.outer is None:
                exp = crosstalk_record(rig, seed, args.samples, alpha, args.noise_std, args.clock)
            else:
                exp = outer_loop_record(rig, seed, args.samples, args.outer, args.noise_std,
                                        args.clock)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                est = fit_cliv(exp, na, nb, nk)
            z = np.abs((est.parameters[: truth.size] - truth) / est.std[: truth.size])
            zmax.append(float(np.max(z)))
            held += bool(zmax[-1] <= 4.0)
            test = est.options["overidentification"]
            pvals.append(np.nan if test is None else test["p_value"])
            fired += any("correlated with the noise" in b
                         for b in est.options["broken_assumptions"])
        print(f"{name} (clock {args.clock or rig.clock}, noise σ {args.noise_std or rig.noise_std}, "
              f"{f'α = {alpha:g}' if args.outer is None else f'outer β = {args.outer:g}'}, "
              f"{args.samples} samples): held {held}/{args.seeds}, "
              f"median max|z| {np.median(zmax):.3g}, test fired {fired}/{args.seeds} "
              f"(p < 0.05 in {np.sum(np.array(pvals) < 0.05)}, no test in "
              f"{np.sum(np.isnan(pvals))})", flush=True)


if __name__ == "__main__":
    main()
