"""Closed-loop IV with its filter of r chosen on the data, against the default filter alone.

On the motor loop under a slow PRBS (0.5 s bit, 10 000 samples at 1 kHz)
this fits each seed twice: ``fit_iv(instrument="r")`` with the default
auxiliary ARX model r → u only (what ``fit_cliv`` did before it chose the
filter), and ``fit_cliv``, which tries five filters of r and keeps the
strongest instruments (:mod:`servoid.closedloop._instruments`).  For each
it prints the refusals, the seeds held (every coefficient within 4σ), the
seeds claimed and held among them, the 95 % coverage over the claimed
seeds, and which filters ``fit_cliv`` chose.

Run from ``tests/closedloop`` with ``src`` on the path:
``python anyloop_cliv_filters.py [--seeds 30] [--clock 500]``.
"""

from __future__ import annotations

import warnings
from collections import Counter

import numpy as np
from anyloop_rigs import RIGS

from servoid import ServoidError, ServoidWarning
from servoid.closedloop import fit_cliv
from servoid.estimate import fit_iv


def main(seeds: int = 30, clock: int = 500) -> None:
    rig = RIGS["motor"]
    nb, nf, nk = rig.orders
    truth = rig.theta_arx()
    rows: dict[str, list[tuple[np.ndarray, bool] | None]] = {"default filter": [],
                                                             "chosen filter": []}
    chosen: Counter[str] = Counter()
    for seed in range(seeds):
        exp = rig.closed(seed, 10_000, clock=clock).experiment()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            for label in rows:
                try:
                    if label == "default filter":
                        est = fit_iv(exp, nf, nb, nk, instrument="r", iterations=1)
                    else:
                        est = fit_cliv(exp, nf, nb, nk)
                        chosen[est.options["instruments"]] += 1
                except ServoidError:
                    rows[label].append(None)
                    continue
                z = np.abs((est.parameters - truth) / est.std)
                rows[label].append((z, bool(est.options.get("consistent", True))))
    print(f"motor loop, PRBS bit {clock} ms, {seeds} seeds of 10 000 samples")
    for label, outcomes in rows.items():
        fitted = [o for o in outcomes if o is not None]
        claimed = [z for z, claims in fitted if claims]
        cover = float(np.mean(np.concatenate(claimed) < 1.96)) if claimed else float("nan")
        print(f"{label}: refused {len(outcomes) - len(fitted)}, held "
              f"{sum(bool(np.all(z < 4)) for z, _ in fitted)}/{len(fitted)}, claimed "
              f"{len(claimed)}, held among claimed {sum(bool(np.all(z < 4)) for z in claimed)}, "
              f"cover {cover:.2f}")
    print("filters chosen: " + "; ".join(f"{k}: {v}" for k, v in chosen.most_common()))


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--clock", type=int, default=500)
    args = parser.parse_args()
    main(args.seeds, args.clock)
