"""Excitation design: maximum-length PRBS generation.

Times ``servoid.signals.prbs`` for register lengths 16, 20 and 24 (one
period, clock 1) after a warm-up; the target is "well under a second" for
n = 20 (about a million samples).
"""

from __future__ import annotations

from _harness import Result, time_call

from servoid.signals import prbs


def run(quick: bool) -> list[Result]:
    """PRBS generation time per register length."""
    rows = []
    for n in (16, 20) if quick else (16, 20, 24):
        t = time_call(lambda n=n: prbs(n), repeats=3 if quick else 7)
        rows.append(Result("signals", f"prbs n={n}", 2**n - 1, "servoid.signals.prbs",
                           t.median * 1e3, t.best * 1e3, len(t.times), note="one period, clock 1"))
    return rows
