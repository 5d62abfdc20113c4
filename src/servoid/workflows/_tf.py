"""``method = "tf"``: a continuous transfer function by refined instrumental variables."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import partial
from typing import Any

from ..data import Experiment, ExperimentSet, ExperimentSpec
from ..estimate import Estimate, fit_tf
from ._arx import HORIZON, OUTPUT
from ._closedloop_any import LOOP, known_loop
from ._examples import open_loop
from ._lti import IdentificationResult, fit_or_search, lti_result, n_inputs, order_grid
from ._options import choice, integer, number, optional, orders
from ._pem import COVARIANCE
from ._registry import Method, Option

__all__ = ["TF"]


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> IdentificationResult:
    """Fit a continuous transfer function (or search its orders) and validate it."""
    estimation, validations = spec.records()
    closed = options["instrument"] == "r"
    # [loop] is read (and checked) when the reference is the instrument and it names a controller
    controller = known_loop(options["[loop]"], estimation.dt)[0] \
        if "[loop]" in options else None
    settings = {"delay": options["delay"], "intersample": options["intersample"],
                "output": options["output"], "max_iter": options["max_iter"],
                "tol": options["tol"], "covariance": options["covariance"]}
    if closed:
        settings.update(instrument="r", controller=controller)
    fixed, grid = order_grid(options, ("n_poles", "n_zeros"), n_inputs(estimation, "u"))
    fit = partial(_fit, estimation_input=_input_name(estimation))
    if fixed.get("n_zeros", 0) is None:
        fixed.pop("n_zeros")  # the estimator's default, n_poles − 1
    estimate, rows, edge = fit_or_search(fit, estimation, validations[0], fixed, grid,
                                         options["criterion"], **settings)
    o = estimate.options
    title = (f"continuous transfer function ({o['n_poles']} poles, {o['n_zeros']} zeros"
             + (f", delay {o['delay']:g} s" if o["delay"] else "") + f", {o['intersample']})")
    return lti_result(spec, "tf", estimate, title, validations, options, orders=rows,
                      criterion=options["criterion"] if grid else "", edge=edge, truth=truth,
                      estimation=estimation, closed_loop=closed,
                      how="refined instrumental variables (SRIVC)")


def _fit(data: Experiment | ExperimentSet, n_poles: int, n_zeros: int | None = None, *,
         estimation_input: str, delay: float, intersample: str, output: str | None,
         max_iter: int, tol: float, covariance: str, instrument: str | None = None,
         controller: Any = None) -> Estimate:
    # explicit keywords: select_order passes `start` only to estimators that take it
    est = fit_tf(data, n_poles, n_zeros, delay=delay, intersample=intersample, output=output,
                 max_iter=max_iter, tol=tol, instrument=instrument, controller=controller,
                 covariance=covariance)
    # the registry's results name the input channel and its role like every other method
    return dataclasses.replace(est, options={**est.options, "input": "u",
                                             "inputs": [estimation_input]})


def _input_name(data: Experiment | ExperimentSet) -> str:
    first = data if isinstance(data, Experiment) else data[0]
    names = first.names_of("u")
    return names[0] if len(names) == 1 else "u"


TF = Method(
    name="tf",
    summary="continuous transfer function (poles, zeros, input delay) by refined instrumental "
            "variables (SRIVC; CLSRIVC with the reference as instrument), with gain, ω_n, ζ ± σ",
    options=(
        OUTPUT,
        Option("n_poles", 2, orders(1), "number of poles; a list is a grid"),
        Option("n_zeros", None, lambda v, w, n: None if v is None else orders(0)(v, w, n),
               "number of zeros (default n_poles − 1); a list is a grid"),
        Option("delay", 0.0, number(nonneg=True, unit="s"), "input delay [s]"),
        Option("intersample", "zoh", choice(("zoh", "foh", "bandlimited")),
               "the logged input between samples: a DAC staircase (zoh) or smooth"),
        Option("instrument", None, optional(choice(("r",))),
               "\"r\": closed loop, the reference as instrument ([loop] controller if known)"),
        Option("max_iter", 50, integer(minimum=1), "most refined-IV iterations"),
        Option("tol", 1e-8, number(positive=True), "relative change that ends the iterations"),
        COVARIANCE,
        Option("criterion", "aic", choice(("aic", "bic", "mdl", "fpe", "fit")),
               "order-search criterion (bic = mdl; fit: simulation fit on the validation data)"),
        HORIZON,
    ),
    run=run,
    tables=(dataclasses.replace(
        LOOP, when=lambda options, table: options["instrument"] == "r" and "controller" in table,
        when_text='instrument = "r" and it names a controller (else CLSRIVC without one)'),
        "validation"),
    example=partial(open_loop, identify={"method": "tf"}),
)
