"""ARX order selection over a grid by information criteria or validation fit."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .._checks import as_int, type_error
from .._errors import DataError, check_option
from ..data import Experiment, ExperimentSet, check_experiment
from ..validate import fit_percent, simulate_from_data
from ._arx import ArxOrders, InputRole, fit_arx
from ._estimate import Estimate

__all__ = ["OrderCandidate", "OrderSelection", "select_arx_order"]

Criterion = Literal["aic", "fpe", "mdl", "fit"]


@dataclass(frozen=True)
class OrderCandidate:
    """Scores of one (na, nb, nk) on the common estimation rows.

    ``loss`` is V = RSS/N; ``aic`` = N ln V + 2d, ``fpe`` = V(1 + d/N)/(1 − d/N),
    ``mdl`` = N ln V + d ln N (Ljung, *System Identification*, 2nd ed., §16.4),
    with d parameters and N equations; ``fit`` is the simulation fit [%] on
    validation data (NaN without it).
    """

    na: int
    nb: int
    nk: int
    n_parameters: int
    loss: float
    aic: float
    fpe: float
    mdl: float
    fit: float

    def score(self, criterion: Criterion) -> float:
        """Value to minimise for ``criterion`` (negated fit)."""
        return -self.fit if criterion == "fit" else getattr(self, criterion)


@dataclass(frozen=True, eq=False)
class OrderSelection:
    """Every order candidate of a grid search and the chosen one."""

    candidates: tuple[OrderCandidate, ...]
    criterion: Criterion
    best: OrderCandidate
    estimate: Estimate

    def ranked(self) -> list[OrderCandidate]:
        """Candidates from best to worst by the criterion."""
        return sorted(self.candidates, key=lambda c: c.score(self.criterion))


def select_arx_order(
    data: Experiment | ExperimentSet,
    na: Iterable[int] = range(1, 6),
    nb: Iterable[int] = range(1, 6),
    nk: Iterable[int] = (1,),
    *,
    criterion: Criterion = "aic",
    validation: Experiment | None = None,
    input: InputRole = "u",
    output: str | None = None,
) -> OrderSelection:
    """Fit ARX over a grid of orders and pick the best by a criterion.

    All candidates are scored on the same equations (a common first sample,
    the longest lag in the grid), so their losses are comparable.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Estimation data (single-input for the grid search).
    na, nb, nk : iterable of int
        Orders to try.
    criterion : {"aic", "fpe", "mdl", "fit"}
        Information criterion on the estimation data, or simulation fit [%]
        on ``validation`` (required for ``"fit"``).
    validation : Experiment, optional
        Validation data; when given, every candidate's simulation fit is computed.
    input : {"u", "r"}
        Input role, as in :func:`fit_arx`.
    output : str, optional
        Output channel when there are several.
    """
    check_option("criterion", criterion, ("aic", "fpe", "mdl", "fit"))
    if criterion == "fit" and validation is None:
        raise DataError('criterion="fit" needs validation data: pass validation=<Experiment>')
    if validation is not None:
        check_experiment(validation, "validation")
    grid = list(itertools.product(*(_orders(name, value) for name, value in
                                    (("na", na), ("nb", nb), ("nk", nk)))))
    if not grid:
        raise DataError("the order grid is empty")
    start = max(ArxOrders(a, b, k, 1).max_lag for a, b, k in grid)
    candidates, fits = [], {}
    for a, b, k in grid:
        est = fit_arx(data, a, b, k, input=input, output=output, start=start)
        n, d = est.n_samples, est.parameters.size
        loss = est.noise_variance * est.dof / n
        log_v = math.log(loss) if loss > 0 else -np.inf
        fit = np.nan
        if validation is not None:
            fit = _validation_fit(est, validation, input)
        candidates.append(
            OrderCandidate(
                a, b, k, d, loss,
                aic=n * log_v + 2 * d,
                fpe=loss * (1 + d / n) / (1 - d / n),
                mdl=n * log_v + d * math.log(n),
                fit=fit,
            )
        )
        fits[(a, b, k)] = est
    best = min(candidates, key=lambda c: (c.score(criterion), c.n_parameters))
    return OrderSelection(tuple(candidates), criterion, best, fits[(best.na, best.nb, best.nk)])


def _orders(name: str, value: object) -> list[int]:
    """A grid of orders (a range, a list) as a list of integers."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
        raise type_error(name, value, "an iterable of integers, e.g. range(1, 6) or [2, 3]")
    return [as_int(f"{name} entry", v, minimum=0) for v in value]


def _validation_fit(est: Estimate, validation: Experiment, input: InputRole) -> float:
    y = validation[est.options["output"]]
    u = np.column_stack([validation[n] for n in est.options["inputs"]])
    y_sim, first = simulate_from_data(est.model, y, u)
    return float(fit_percent(y[first:], y_sim[first:]))
