"""The any-plant closed-loop methods on a 2e4-sample record, beside open-loop OE.

Cases
-----
motor, fast PRBS
    ``tests/closedloop/anyloop_rigs.py`` "motor": a DC motor with gear and
    ball screw (third order with the 100 Hz anti-alias filter) under a
    Tustin PI at 1 kHz, ARMA(1, 1) noise, PRBS reference with a 2 ms bit,
    seed 0, N = 20 000.  The plant is fitted at its true orders
    (nb = nf = 3, nk = 1).
unstable
    10/((s − 3)(s + 20)) with a 20 Hz anti-alias filter under a PD at
    100 Hz, seed 0, N = 20 000.

Methods
-------
Each is the public function with its default options: ``fit_two_stage``,
``fit_cliv``, ``fit_direct_bj`` (BJ with nc = nd = 1), ``fit_indirect_tf``
(the controller as it ran) and, for comparison, ``servoid.estimate.fit_oe``
on (u, y) as if the record were open loop (biased under feedback).  One
warm-up call, then the median of the timed repeats; ``rel_diff`` is the
largest relative error of the plant coefficients against the truth, and
``extra["max_abs_z"]`` the largest (estimate − truth)/σ.  Consistency over
seeds is the study (``tests/closedloop/anyloop_study.py``), not timed here.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
from _harness import Result, time_call

SUITE = "closedloop-any"
TESTS = Path(__file__).resolve().parent.parent / "tests" / "closedloop"
N = 20_000


def run(quick: bool = False) -> list[Result]:
    """Each method once per record, ``quick``: 3 repeats instead of 7."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    from anyloop_rigs import RIGS
    from anyloop_study import controller

    from servoid.closedloop import fit_cliv, fit_direct_bj, fit_indirect_tf, fit_two_stage
    from servoid.estimate import fit_oe

    repeats = 3 if quick else 7
    rows = []
    for case, name, clock in (("motor, fast PRBS", "motor", 2), ("unstable", "unstable", None)):
        rig = RIGS[name]
        exp = rig.closed(0, N, clock=clock).experiment()
        nb, nf, nk = rig.orders
        c = controller(rig)
        methods = {
            "fit_two_stage": (lambda: fit_two_stage(exp, nb, nf, nk), rig.theta(), False),
            "fit_cliv": (lambda: fit_cliv(exp, nf, nb, nk), rig.theta_arx(), False),
            "fit_direct_bj": (lambda: fit_direct_bj(exp, nb, 1, 1, nf, nk), rig.theta(), False),
            "fit_indirect_tf": (lambda: fit_indirect_tf(exp, c, nb, nf, nk), rig.theta(),
                                False),
            "fit_oe (open loop, biased)": (lambda: fit_oe(exp, nb, nf, nk), rig.theta(), True),
        }
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for method, (fn, truth, reference) in methods.items():
                timing = time_call(fn, repeats, warmup=1)
                est = fn()
                theta = np.asarray(est.parameters[: truth.size])
                z = (theta - truth) / np.asarray(est.std[: truth.size])
                consistent = est.options.get("consistent", True)
                note = "open-loop reference" if reference else (
                    "claims consistency" if consistent else "says: not consistent here")
                row = Result(SUITE, case, exp.n_samples, method, timing.median * 1e3,
                             timing.best * 1e3, repeats,
                             rel_diff=float(np.max(np.abs(theta - truth) / np.abs(truth))),
                             note=note)
                row.extra["max_abs_z"] = float(np.max(np.abs(z)))
                rows.append(row)
    return rows


if __name__ == "__main__":
    from _harness import format_table

    print(format_table(run(quick="--quick" in sys.argv)))
