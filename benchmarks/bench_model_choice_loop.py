"""Model choice in a loop (issue 25): what ``method = "auto"`` picks on closed-loop records.

Cases
-----
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
feedback-level-white, -coloured, -wiener, -saturation
    The feedback test every open-loop method runs (``servoid.closedloop.
    feedback_test``, at its 1 % level) on 200 open-loop records each (20
    under ``--quick``): a continuous second-order plant simulated far above
    the rate from a random input held two samples, with white or AR(1)
    coloured noise, or through tanh or a saturation after it (coloured
    noise): its false alarms at the 1, 5 and 10 % levels.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
from _harness import Result
from scipy.signal import lfilter

from servoid.bench import simulate_lti
from servoid.closedloop import feedback_test
from servoid.data import Experiment
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


def _open_loop(kind: str, seed: int, n: int = 3000) -> Experiment:
    """An open-loop record of the plant of ``bench_model_choice`` (ω_n = 4π, ζ = 0.5)."""
    dt, wn = 0.01, 2 * np.pi * 2.0
    plant = TransferFunction([wn**2], [1.0, 2 * 0.5 * wn, wn**2])
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.standard_normal(n // 2), 2)
    x = simulate_lti(plant, u, dt, rng=seed)["y"]
    x = np.tanh(1.2 * x) if kind == "wiener" else np.clip(x, -0.8, 0.8) \
        if kind == "saturation" else x
    e = 0.01 * rng.standard_normal(n)
    return Experiment.from_arrays(dt, u=u, y=x + (e if kind == "white" else
                                                  lfilter([1.0], [1.0, -0.9], e)))


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
    tests = 20 if quick else 200
    for kind in ("white", "coloured", "wiener", "saturation"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p = np.array([feedback_test(_open_loop(kind, s)).pvalue for s in range(tests)])
        rates = {f"{100 * a:g} %": int(np.sum(p < a)) for a in (0.01, 0.05, 0.10)}
        out.append(Result(SUITE, f"feedback-level-{kind}", 3000, "feedback_test", float("nan"),
                          float("nan"), tests,
                          note="false alarms " + ", ".join(f"{v}/{tests} at {k}"
                                                           for k, v in rates.items()),
                          extra={"false_alarms": rates, "mean_p": round(float(p.mean()), 3)}))
    return out


if __name__ == "__main__":
    import sys

    for r in run("--quick" in sys.argv):
        print(f"{r.case:<28} {r.note}")
