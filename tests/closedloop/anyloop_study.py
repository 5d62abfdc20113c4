"""How often each closed-loop method holds on the independent rigs of ``anyloop_rigs``.

A method *holds* on a seed when every plant coefficient lies within 4σ of
the truth (σ from its own covariance); it *covers* a coefficient when the
95 % interval (±1.96σ) holds it.  A method that refuses a record (a
servoid error naming why) neither holds nor fails: it claims nothing, and
the study counts the refusals.  A method *claims* consistency on a record
when it returns an estimate without a caution about consistency (see
:func:`claims`).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from anyloop_rigs import RIGS, Record, Rig

from servoid import ServoidError
from servoid.closedloop import fit_cliv, fit_direct_bj, fit_indirect_tf, fit_two_stage
from servoid.estimate import fit_bj, fit_oe
from servoid.models import TransferFunction

METHODS = ("two-stage", "cliv", "bj", "indirect", "oe")


@dataclass
class Outcome:
    """One method on one record."""

    method: str
    seed: int
    z: np.ndarray | None = None  # (estimate − truth)/σ per coefficient
    error: str = ""  # the refusal's message
    notes: tuple[str, ...] = ()  # warnings the fit raised
    seconds: float = 0.0
    claims: bool = True

    @property
    def refused(self) -> bool:
        return self.z is None

    @property
    def held(self) -> bool:
        return self.z is not None and bool(np.all(np.abs(self.z) < 4.0))


@dataclass
class Tally:
    """Outcomes of one method over the seeds."""

    method: str
    outcomes: list[Outcome] = field(default_factory=list)

    def counts(self) -> dict[str, float]:
        fitted = [o for o in self.outcomes if not o.refused]
        claimed = [o for o in fitted if o.claims]
        z = np.concatenate([o.z for o in claimed]) if claimed else np.zeros(0)
        return {
            "runs": len(self.outcomes),
            "refused": len(self.outcomes) - len(fitted),
            "held": sum(o.held for o in fitted),
            "claimed": len(claimed),
            "claimed_held": sum(o.held for o in claimed),
            "coverage": float(np.mean(np.abs(z) < 1.96)) if z.size else float("nan"),
            "max_abs_z": float(np.max(np.abs(np.concatenate([o.z for o in fitted]))))
            if fitted else float("nan"),
            "seconds": float(np.mean([o.seconds for o in self.outcomes])),
        }


def controller(rig: Rig) -> TransferFunction:
    """The rig's controller as it ran (discrete at the rig's dt)."""
    return TransferFunction(rig.controller[0], rig.controller[1], rig.dt)


def fit(method: str, rec: Record, **options: object):  # type: ignore[no-untyped-def]
    """Run one method with its default options at the rig's true orders."""
    rig = rec.rig
    nb, nf, nk = rig.orders
    exp = rec.experiment()
    c, d = (len(p) - 1 for p in rig.noise)
    if method == "two-stage":
        return fit_two_stage(exp, nb, nf, nk, **options)
    if method == "cliv":
        return fit_cliv(exp, nf, nb, nk, **options)
    if method == "bj":
        return fit_direct_bj(exp, nb, c, d, nf, nk, **options)
    if method == "bj-plain":
        return fit_bj(exp, nb, c, d, nf, nk, **options)
    if method == "indirect":
        return fit_indirect_tf(exp, controller(rig), nb, nf, nk, **options)
    if method == "oe":
        return fit_oe(exp, nb, nf, nk, **options)
    raise ValueError(method)


def claims(est) -> bool:  # type: ignore[no-untyped-def]
    """Whether the estimate claims consistency (no ``consistent = False`` in its options)."""
    return bool(est.options.get("consistent", True))


def outcome(method: str, rec: Record, **options: object) -> Outcome:
    """Fit, score against the truth, never raise for a servoid refusal."""
    rig = rec.rig
    truth = rig.theta_arx() if method == "cliv" else rig.theta()
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        try:
            est = fit(method, rec, **options)
        except ServoidError as exc:
            return Outcome(method, rec.seed, error=f"{type(exc).__name__}: {exc}",
                           notes=tuple(str(w.message) for w in said),
                           seconds=time.perf_counter() - t0, claims=False)
    z = (est.parameters[: truth.size] - truth) / est.std[: truth.size]
    return Outcome(method, rec.seed, z, notes=tuple(str(w.message) for w in said),
                   seconds=time.perf_counter() - t0, claims=claims(est))


def study(rig: Rig | str, seeds: Iterable[int], n: int, methods: Iterable[str] = METHODS,
          clock: int | None = None, progress: Callable[[str], None] | None = None,
          **options: object) -> dict[str, Tally]:
    """Every method on every seed of one rig."""
    rig = RIGS[rig] if isinstance(rig, str) else rig
    tallies = {m: Tally(m) for m in methods}
    for seed in seeds:
        rec = rig.closed(seed, n, clock=clock)
        for m, tally in tallies.items():
            o = outcome(m, rec, **options.get(m, {}))  # type: ignore[arg-type]
            tally.outcomes.append(o)
            if progress is not None:
                progress(f"{rig.name} seed {seed} {m}: "
                         + ("refused " + o.error[:80] if o.refused else
                            f"held={o.held} max|z|={np.max(np.abs(o.z)):.3g}")
                         + f" {o.seconds:.2f}s")
    return tallies


def table(results: dict[str, dict[str, Tally]]) -> str:
    """Markdown: loop × method → held/runs (refused), coverage."""
    methods = list(next(iter(results.values())))
    lines = ["| loop | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for loop, tallies in results.items():
        cells = []
        for m in methods:
            c = tallies[m].counts()
            cell = f"held {c['held']}/{c['runs']}"
            if c["refused"]:
                cell += f", refused {c['refused']}"
            if c["claimed"] != c["runs"] - c["refused"]:
                cell += f", claims {c['claimed_held']}/{c['claimed']}"
            cell += f"; cover {c['coverage']:.2f}; max|z| {c['max_abs_z']:.3g}; {c['seconds']:.2f} s"
            cells.append(cell)
        lines.append(f"| {loop} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--loop", action="append", default=None)
    parser.add_argument("--method", action="append", default=None)
    parser.add_argument("-v", action="store_true")
    parser.add_argument("--json", default=None, help="also write the counts to this file")
    args = parser.parse_args()
    loops = {"motor (slow PRBS, 50 ms bit)": ("motor", None),
             "motor (fast PRBS, 2 ms bit)": ("motor", 2),
             "unstable": ("unstable", None), "delay": ("delay", None)}
    out = {}
    for label, (name, clock) in loops.items():
        if args.loop and name not in args.loop and label not in args.loop:
            continue
        out[label] = study(name, range(args.seeds), args.n, args.method or METHODS,
                           clock=clock, progress=print if args.v else None)
    print(table(out))
    if args.json:
        import json

        counts = {loop: {m: t.counts() for m, t in tallies.items()}
                  for loop, tallies in out.items()}
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"seeds": args.seeds, "n": args.n, "counts": counts}, fh, indent=1)
