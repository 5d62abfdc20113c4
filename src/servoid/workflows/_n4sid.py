"""``method = "n4sid"``: subspace identification, optionally refined by output error."""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from typing import Any

from .._checks import as_int_list, as_str, type_error
from .._errors import DataError, OptionError
from ..data import ExperimentSpec
from ..estimate import fit_n4sid, fit_oe, to_polynomial
from ._examples import open_loop
from ._lti import IdentificationResult, lti_result
from ._options import HORIZON, ROLE, boolean, choice, integer, optional
from ._pem import SEARCH
from ._registry import Method, Option

__all__ = ["N4SID"]


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> IdentificationResult:
    """Fit a state-space model by subspace projection and validate it."""
    estimation, validations = spec.records()
    subspace = fit_n4sid(estimation, options["order"], weighting=options["weighting"],
                         horizon=options["horizon_blocks"], input=options["input"],
                         output=options["output"], feedthrough=options["feedthrough"],
                         max_order=options["max_order"])
    o = subspace.options
    title = (f"state space by {o['weighting'].upper()} (order {o['order']}, horizons "
             f"{o['horizon'][0]}/{o['horizon'][1]})")
    notes: list[str] = []
    estimate = subspace
    used = [k for k, default in _REFINE_DEFAULTS.items() if options[k] != default]
    if used and not options["refine"]:
        raise OptionError(f"[identify] {', '.join(used)} set the output-error refinement; "
                          "add refine = true, or remove them")
    if options["refine"]:
        if len(o["outputs"]) > 1:
            raise DataError("[identify] refine = true refines a single-output model by output "
                            "error; with several outputs leave refine = false")
        start = to_polynomial(subspace.model, "oe")
        estimate = fit_oe(estimation, list(start.nb), list(start.nf), list(start.nk),
                          input=options["input"], output=o["outputs"][0], init=start,
                          initial=options["initial"], multistart=options["multistart"],
                          rng=options["seed"], max_iter=options["max_iter"], tol=options["tol"])
        title = f"OE refined from {title}"
        notes.append(f"the subspace model (order {o['order']}) started an output-error fit; "
                     "the parameters and intervals are the output-error ones")
    return lti_result(spec, "n4sid", estimate, title, validations, options,
                      singular_values=o["singular_values"], truth=truth, notes=notes,
                      estimation=estimation, how="subspace projection")


#: The refinement's settings at their defaults (set without refine = true: refused).
_REFINE_DEFAULTS = {"initial": "estimate", **{o.name: o.default for o in SEARCH}}


def _outputs(value: Any, where: str, name: str) -> str | list[str]:
    if isinstance(value, (list, tuple)):
        if not value:
            raise DataError(f"{where} {name} must name at least one output channel")
        return [as_str(f"{name}[{i}]", v, where=where) for i, v in enumerate(value)]
    if not isinstance(value, str):
        raise type_error(name, value, "a channel name or a list of names", where=where)
    return as_str(name, value, where=where)


def _horizon(value: Any, where: str, name: str) -> int | tuple[int, int]:
    if isinstance(value, (list, tuple)):
        past, future = as_int_list(name, value, length=2, minimum=1, where=where)
        return past, future
    return integer(minimum=1)(value, where, name)


N4SID = Method(
    name="n4sid",
    summary="state-space model by subspace projection (MOESP, CVA, N4SID), SISO or MIMO, "
            "order from the singular values; optionally refined by output error",
    options=(
        ROLE,
        Option("output", None, optional(_outputs),
               "output channel or list (default: every y channel)"),
        Option("order", None, optional(integer(minimum=1)),
               "model order (default: chosen from the singular values)"),
        Option("max_order", None, optional(integer(minimum=1)),
               "largest order the singular-value rule may choose"),
        Option("weighting", "moesp", choice(("moesp", "cva", "n4sid")), "subspace weighting"),
        Option("horizon_blocks", None, optional(_horizon),
               "past/future block rows: an integer or [past, future] (default: from the data)"),
        Option("feedthrough", False, boolean(), "estimate a direct term D"),
        Option("refine", False, boolean(),
               "refine a single-output model by output error from the subspace estimate"),
        Option("initial", "estimate", choice(("zero", "estimate")),
               "with refine: initial conditions of the output-error predictor"),
        *SEARCH,
        HORIZON,
    ),
    run=run,
    multi_output=True,
    example=partial(open_loop, identify={"method": "n4sid"}),
)
