"""``method = "oe" | "armax" | "bj"``: the prediction-error family from the experiment file."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any

from ..data import ExperimentSpec
from ..estimate import Estimate, fit_armax, fit_bj, fit_oe
from ._arx import HORIZON, OUTPUT, ROLE
from ._examples import open_loop
from ._lti import IdentificationResult, fit_or_search, lti_result, n_inputs, order_grid
from ._options import choice, integer, number, orders
from ._registry import Method, Option

__all__ = ["ARMAX", "BJ", "COVARIANCE", "OE", "SEARCH", "orders_text", "search_options"]

_LOWEST = {"na": 0, "nb": 1, "nc": 0, "nd": 0, "nf": 0, "nk": 0}
_ORDERS = {"oe": ("nb", "nf", "nk"), "armax": ("na", "nb", "nc", "nk"),
           "bj": ("nb", "nc", "nd", "nf", "nk")}
_FITS: dict[str, Callable[..., Estimate]] = {"oe": fit_oe, "armax": fit_armax, "bj": fit_bj}
_TITLES = {"oe": "OE", "armax": "ARMAX", "bj": "BJ"}
#: [identify] of each structure's example: a first-order noise model for its ARMA(1, 1) noise
_EXAMPLE: dict[str, dict[str, Any]] = {"oe": {}, "armax": {"nc": 1}, "bj": {"nc": 1, "nd": 1}}


COVARIANCE = Option(
    "covariance", "auto", choice(("auto", "white", "robust")),
    "parameter covariance: robust allows for coloured residuals (auto: robust where the model "
    "has no noise model of its own)")
SEARCH = (
    Option("multistart", 0, integer(minimum=0), "extra random stable starts; the best wins"),
    Option("seed", 0, integer(minimum=0), "seed of the random starts"),
    Option("max_iter", 100, integer(minimum=1), "most Gauss–Newton iterations per start"),
    Option("tol", 1e-9, number(positive=True), "relative cost decrease that ends the search"),
)


def search_options() -> tuple[Option, ...]:
    """The options every prediction-error method shares."""
    return (
        Option("initial", "estimate", choice(("zero", "estimate")),
               "initial conditions of the predictor: estimated (a record that does not start "
               "at rest) or zero"),
        *SEARCH,
        COVARIANCE,
        Option("criterion", "aic", choice(("aic", "bic", "mdl", "fpe", "fit")),
               "order-search criterion (bic = mdl; fit: simulation fit on the validation data)"),
    )


def run(structure: str, spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> IdentificationResult:
    """Fit the structure (or search its orders) and validate it."""
    estimation, validations = spec.records()
    keys = _ORDERS[structure]
    fixed, grid = order_grid(options, keys, n_inputs(estimation, options["input"]))
    settings = {"input": options["input"], "output": options["output"],
                "initial": options["initial"], "multistart": options["multistart"],
                "rng": options["seed"], "max_iter": options["max_iter"], "tol": options["tol"],
                "covariance": options["covariance"]}
    estimate, rows, edge = fit_or_search(_FITS[structure], estimation, validations[0], fixed,
                                         grid, options["criterion"], **settings)
    title = f"{_TITLES[structure]} ({orders_text(estimate.options, keys)})"
    return lti_result(spec, structure, estimate, title, validations, options, orders=rows,
                      criterion=options["criterion"] if grid else "", edge=edge, truth=truth,
                      estimation=estimation,
                      how="prediction error (Gauss–Newton on the exact gradient)",
                      direct=structure == "bj")  # BJ's own noise model: the direct approach


def orders_text(options: Mapping[str, Any], keys: Sequence[str]) -> str:
    """``nb = 2, nf = 2, nk = 1`` from an estimate's options."""
    parts = []
    for key in keys:
        value = options.get(key)
        if isinstance(value, (list, tuple)):
            value = value[0] if len(value) == 1 else list(value)
        parts.append(f"{key} = {value}")
    return ", ".join(parts)


def _method(structure: str, summary: str) -> Method:
    order_help = {
        "na": "order of A (poles shared by input and noise)",
        "nb": "B coefficients per input; a list is a grid (one input) or one value per input",
        "nc": "order of C (noise zeros)",
        "nd": "order of D (noise poles)",
        "nf": "order of F per input (poles of the input path); a list as for nb",
        "nk": "input delay per input [samples]; a list as for nb",
    }
    defaults = {"na": 2, "nb": 2, "nc": 2, "nd": 2, "nf": 2, "nk": 1}
    return Method(
        name=structure,
        summary=summary,
        options=(
            ROLE, OUTPUT,
            *(Option(k, defaults[k], orders(_LOWEST[k]), order_help[k])
              for k in _ORDERS[structure]),
            *search_options(),
            HORIZON,
        ),
        run=partial(run, structure),
        example=partial(open_loop, identify={"method": structure, **_EXAMPLE[structure]},
                        coloured=structure != "oe"),
    )


OE = _method("oe", "output-error model y = B/F u + e by prediction error (exact gradient), "
             "with covariance; the best simulation model")
ARMAX = _method("armax", "ARMAX model A y = B u + C e by prediction error, with covariance; "
                "a noise model sharing the plant's poles")
BJ = _method("bj", "Box–Jenkins model y = B/F u + C/D e by prediction error, with covariance; "
             "independent plant and noise models (also the direct method on closed-loop data)")
