"""Model choice in a loop (issue 25): what ``method = "auto"`` picks on closed-loop records.

Case
----
picks-loop-reference, picks-loop-controller
    ``auto`` on 20 seeds (2 under ``--quick``) of the closed-loop record
    ``servoid.workflows._examples.closed_loop`` writes: a continuous
    second-order plant (ω_n = 4π rad/s, ζ = 0.4, gain 1) simulated far above
    the 50 Hz rate under a digital PI controller by
    ``servoid.bench.simulate_lti_loop``, a random binary reference, coloured
    noise in the loop (2000 samples to estimate, another seed's record to
    validate).  The reference channel declares the loop, so the closed-loop
    candidates (``closedloop-auto`` over plant orders 1–3) join the linear
    set; ``-controller`` also gives the PI under ``[loop] controller``.
    Recorded per variant: the share of seeds whose chosen candidate is of the
    true family — a method consistent under feedback (a closed-loop method,
    or the direct BJ with its noise model; OE, tf, n4sid and ARX on (u, y)
    are biased in a loop) — whose validation fit lies within 2 points of
    the best candidate's, and the
    median and largest relative error of the chosen model's frequency
    response against the true plant's over 0.1–2 ω_n (the band the
    reference excites; a discrete model against the plant sampled with a
    zero-order hold, as the DAC drives it).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
from _harness import Result

from servoid.models import TransferFunction, c2d, freqresp
from servoid.workflows import identify
from servoid.workflows._examples import closed_loop

SUITE = "model-choice-loop"
WN = 2 * np.pi * 2.0
PLANT = TransferFunction([WN**2], [1.0, 2 * 0.4 * WN, WN**2])  # as closed_loop writes it
PI = {"controller": {"num": [0.5 + 3.0 * 0.02, -0.5], "den": [1.0, -1.0]}}
#: The candidates consistent under feedback: the closed-loop methods, and the direct BJ
#: (its noise model in the predictor); OE, tf, n4sid and ARX on (u, y) are biased there.
CONSISTENT = {"closedloop-auto", "bj"}
OMEGA = np.linspace(0.1, 2.0, 40) * WN


def run(quick: bool = False) -> list[Result]:
    out: list[Result] = []
    seeds = 2 if quick else 20
    truths = {None: freqresp(PLANT, OMEGA), 0.02: freqresp(c2d(PLANT, 0.02), OMEGA)}
    for variant in ("reference", "controller"):
        right = near = 0
        chosen, errors = [], []
        for seed in range(seeds):
            with TemporaryDirectory() as tmp, warnings.catch_warnings():
                warnings.simplefilter("ignore")
                path = closed_loop(Path(tmp), 300 + seed, identify={"method": "auto"},
                                   loop=PI if variant == "controller" else None)
                res = identify(path, write=False)
            entry = next(e for e in res.entries if e.label == res.label)
            chosen.append(res.label)
            right += entry.score.candidate.method in CONSISTENT
            model = res.estimate.model
            truth = truths[getattr(model, "dt", None)]
            errors.append(float(np.max(np.abs(freqresp(model, OMEGA) - truth) / np.abs(truth))))
            fits = [e.validation.fit_percent for e in res.entries if e.validation is not None]
            near += entry.validation is not None and \
                entry.validation.fit_percent > max(fits) - 2.0
        out.append(Result(SUITE, f"picks-loop-{variant}", 2000, "auto", float("nan"),
                          float("nan"), seeds,
                          note=(f"consistent under feedback {right}/{seeds}, "
                                f"within 2 points {near}/{seeds}, frequency-response error "
                                f"median {np.median(errors):.3f} largest {max(errors):.3f}"),
                          extra={"consistent": right / seeds,
                                 "within_2": near / seeds, "chosen": chosen,
                                 "response_error": [round(e, 4) for e in errors]}))
    return out


if __name__ == "__main__":
    import sys

    for r in run("--quick" in sys.argv):
        print(f"{r.case:<28} {r.note}")
