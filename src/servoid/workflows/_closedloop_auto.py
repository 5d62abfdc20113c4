"""``method = "closedloop-auto"``: the loop's known facts pick the closed-loop methods.

What is known about the loop decides which methods can be consistent on
the record:

- the reference r recorded: closed-loop IV and the two-stage method (they
  need it), and the closed-loop IV estimate says whether the plant is
  stable;
- the controller known (``[loop] controller``) and r recorded: the
  indirect approach;
- always (u and y): the direct approach, Box–Jenkins on (u, y), with the
  stabilised predictor for an unstable plant;
- an unstable plant: not the two-stage method (its output-error predictor
  is unstable), which is then named as skipped, with the reason.

Every method that can run is fitted; their plant estimates are set side by
side (each coefficient ± σ, whether the method claims consistency on this
record, its time) in the notes and in ``results.json``
(``closedloop_candidates``).  The result is the first method in the order
indirect, direct Box–Jenkins, closed-loop IV, two-stage that ran and claims
consistency: the known controller adds the most information, the direct
approach is efficient, IV has no local minima, the two-stage method
carries its stage-1 error.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import numpy as np

from .._errors import ServoidError, ServoidWarning
from ..closedloop import fit_cliv, fit_direct_bj, fit_indirect_tf, fit_two_stage
from ..data import Experiment, ExperimentSpec
from ..estimate import Estimate
from ._arx import HORIZON
from ._closedloop_any import LOOP, broken, in_loop, known_loop
from ._examples import closed_loop
from ._lti import IdentificationResult, lti_result
from ._options import integer, optional, text
from ._registry import Method, Option

__all__ = ["CLOSEDLOOP_AUTO"]

#: The order of preference among the methods that claim consistency.
_PREFERENCE = ("indirect", "direct-bj", "cliv", "two-stage")


@dataclasses.dataclass(frozen=True)
class _Candidate:
    """One method's run on the record."""

    method: str
    estimate: Estimate | None
    seconds: float
    why: str = ""  # refused / skipped: the reason
    error: ServoidError | None = None  # the refusal

    @property
    def claims(self) -> bool:
        return self.estimate is not None and bool(self.estimate.options.get("consistent", True))

    def row(self) -> dict[str, Any]:
        est = self.estimate
        out: dict[str, Any] = {"method": self.method, "seconds": self.seconds,
                               "claims_consistency": self.claims, "why": self.why}
        if est is not None:
            out["parameters"] = dict(zip(est.names, np.asarray(est.parameters).tolist(),
                                         strict=True))
            out["std"] = dict(zip(est.names, np.asarray(est.std).tolist(), strict=True))
            out["broken_assumptions"] = list(est.options.get("broken_assumptions", []))
        return out

    def text(self) -> str:
        if self.estimate is None:
            return f"{self.method}: {self.why}"
        est = self.estimate
        values = ", ".join(f"{n} = {v:.5g} ± {s:.2g}" for n, v, s in
                           zip(est.names, est.parameters, est.std, strict=True))
        claim = "claims consistency" if self.claims else "not consistent here"
        return f"{self.method} ({claim}, {self.seconds:.2g} s): {values}"


class ClosedLoopChoice(IdentificationResult):
    """The chosen method's result, with every candidate in ``results.json``."""

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``, with the candidates side by side."""
        return {**super().to_dict(),
                "closedloop_candidates": self.estimate.options.get("candidates", [])}


def _run(spec: ExperimentSpec, options: Mapping[str, Any],
         truth: Mapping[str, float] | None) -> IdentificationResult:
    estimation, validations = spec.records()
    first = estimation if isinstance(estimation, Experiment) else estimation[0]
    nb, nf, nk, nc, nd = (options[k] for k in ("nb", "nf", "nk", "nc", "nd"))
    out = options["output"]
    has_r = len(first.names_of("r")) == 1
    loop = options["[loop]"]
    known = loop.get("controller") is not None
    plan: list[tuple[str, Callable[[], Estimate] | None, str]] = []
    if known and has_r:
        controller, feedback = known_loop(loop, first.dt)
        plan.append(("indirect", partial(fit_indirect_tf, estimation, controller, nb, nf, nk,
                                         feedback=feedback, output=out), ""))
    elif known:
        plan.append(("indirect", None, "skipped: the record has no reference r"))
    else:
        plan.append(("indirect", None,
                     "skipped: the controller is not known ([loop] controller)"))
    plan.append(("direct-bj", partial(fit_direct_bj, estimation, nb, nc, nd, nf, nk,
                                      output=out), ""))
    if has_r:
        plan.append(("cliv", partial(fit_cliv, estimation, nf, nb, nk, output=out), ""))
        plan.append(("two-stage", partial(fit_two_stage, estimation, nb, nf, nk, output=out),
                     ""))
    else:
        for name in ("cliv", "two-stage"):
            plan.append((name, None, "skipped: the record has no reference r"))
    candidates = [_attempt(name, fit, why) for name, fit, why in plan]
    chosen = next((c for m in _PREFERENCE for c in candidates if c.method == m and c.claims),
                  None) or next((c for c in candidates if c.estimate is not None), None)
    if chosen is None or chosen.estimate is None:
        raise next(c.error for c in candidates if c.error is not None)
    facts = (f"the loop's facts: reference {'recorded' if has_r else 'not recorded'}, "
             f"controller {'known' if known else 'unknown'}; methods run: "
             f"{', '.join(c.method for c in candidates if c.estimate is not None)}; chosen: "
             f"{chosen.method}" + ("" if chosen.claims else " (no method claims consistency: "
                                   "the first that ran)"))
    est = chosen.estimate
    est = dataclasses.replace(est, options={
        **est.options, "input": "u", "inputs": [first.names_of("u")[0]],
        "candidates": [c.row() for c in candidates], "chosen": chosen.method})
    in_the_loop = in_loop(est, estimation, loop)
    if in_the_loop[0] is not None:
        est = dataclasses.replace(est, options={**est.options, "validated_in_loop": True})
    notes = [facts, *[f"side by side: {c.text()}" for c in candidates], *broken(est),
             *in_the_loop[1]]
    title = f"plant by {chosen.method}, chosen by closedloop-auto"
    return lti_result(spec, "closedloop-auto", est, title, validations, options, truth=truth,
                      notes=notes, closed_loop=True, records=estimation,
                      how=f"the closed-loop methods the loop's facts allow, {chosen.method} "
                          "chosen", loop_model=in_the_loop[0], result_type=ClosedLoopChoice)


def _attempt(name: str, fit: Callable[[], Estimate] | None, why: str) -> _Candidate:
    if fit is None:
        return _Candidate(name, None, 0.0, why)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)  # its verdict is in its options
            est = fit()
    except ServoidError as exc:
        return _Candidate(name, None, time.perf_counter() - t0, f"refused: {exc}", exc)
    return _Candidate(name, est, time.perf_counter() - t0)


CLOSEDLOOP_AUTO = Method(
    name="closedloop-auto",
    summary="plant from a closed-loop record: the loop's known facts (reference, controller, "
            "stability) pick the closed-loop methods, run side by side, the most informative "
            "consistent one kept",
    options=(
        Option("output", None, optional(text()), "output channel when the data have several"),
        Option("nb", 2, integer(minimum=1), "B coefficients of the plant"),
        Option("nf", 2, integer(minimum=0), "order of F (plant poles)"),
        Option("nk", 1, integer(minimum=0), "plant delay [samples]"),
        Option("nc", 1, integer(minimum=0), "noise zeros of the direct Box–Jenkins fit"),
        Option("nd", 1, integer(minimum=0), "noise poles of the direct Box–Jenkins fit"),
        HORIZON,
    ),
    run=_run,
    tables=(LOOP, "validation"),
    example=partial(closed_loop, identify={"method": "closedloop-auto"}),
)
