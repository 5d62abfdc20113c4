"""``method = "arx"``: ARX by least squares, orders given or searched."""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from typing import Any

from ..data import ExperimentSpec
from ..estimate import OrderSelection, fit_arx, select_arx_order
from ._examples import open_loop
from ._lti import IdentificationResult, OrderRow, lti_result, n_inputs, on_edge, order_grid
from ._options import choice, integer, optional, orders, text
from ._registry import Method, Option

__all__ = ["HORIZON", "METHOD", "OUTPUT", "ROLE"]

_LOWEST = {"na": 0, "nb": 1, "nk": 0}

ROLE = Option("input", "u", choice(("u", "r")),
              'role of the input channel(s): "u" (plant input) or "r" (reference, closed loop)')
OUTPUT = Option("output", None, optional(text()), "output channel when the data have several")
HORIZON = Option("horizon", 5, integer(minimum=1),
                 "k of the k-step prediction fit on validation data [samples]")


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> IdentificationResult:
    """Fit ARX (or search its orders) and validate it."""
    estimation, validations = spec.records()
    fixed, grid = order_grid(options, ("na", "nb", "nk"), n_inputs(estimation, options["input"]))
    rows: tuple[OrderRow, ...] = ()
    edge: list[str] = []
    if grid:
        full = {k: grid.get(k, [fixed.get(k)]) for k in ("na", "nb", "nk")}
        selection = select_arx_order(
            estimation, full["na"], full["nb"], full["nk"],
            criterion="mdl" if options["criterion"] == "bic" else options["criterion"],
            validation=validations[0], input=options["input"], output=options["output"])
        estimate = selection.estimate
        rows = _rows(selection)
        edge = on_edge({k: getattr(selection.best, k) for k in grid}, grid, _LOWEST)
    else:
        estimate = fit_arx(estimation, fixed["na"], fixed["nb"], fixed["nk"],
                           input=options["input"], output=options["output"])
    o = estimate.options
    title = f"ARX (na = {o['na']}, nb = {_short(o['nb'])}, nk = {_short(o['nk'])})"
    return lti_result(spec, "arx", estimate, title, validations, options, orders=rows,
                      criterion=options["criterion"] if grid else "", edge=edge, truth=truth,
                      estimation=estimation, how="linear least squares")


def _rows(selection: OrderSelection) -> tuple[OrderRow, ...]:
    return tuple(
        OrderRow({"na": c.na, "nb": c.nb, "nk": c.nk}, c.n_parameters, c.loss,
                 {"aic": c.aic, "fpe": c.fpe, "mdl": c.mdl}, c.fit)
        for c in selection.ranked())


def _short(values: list[int]) -> str:
    return str(values[0]) if len(values) == 1 else str(list(values))


METHOD = Method(
    name="arx",
    summary="ARX model A y = B u + e by least squares, with covariance; orders given or "
            "searched over a grid",
    options=(
        ROLE,
        OUTPUT,
        Option("na", 2, orders(0), "number of poles (A coefficients); a list is a grid"),
        Option("nb", 2, orders(1), "B coefficients per input; a list is a grid (one input) "
               "or one value per input"),
        Option("nk", 1, orders(0), "input delay per input [samples]; a list as for nb"),
        Option("criterion", "aic", choice(("aic", "bic", "mdl", "fpe", "fit")),
               "order-search criterion (bic = mdl; fit: simulation fit on the validation data)"),
        HORIZON,
    ),
    run=run,
    example=partial(open_loop, identify={"method": "arx"}),
)
