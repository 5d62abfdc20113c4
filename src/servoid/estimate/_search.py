"""Order and structure search over a grid, for any estimator.

Every candidate of the grid is fitted with the same estimator and scored
on the same equations: the estimator is asked to start its cost at the
longest lag of the whole grid (its ``start`` keyword), so the losses
V = mean ε² of all candidates sum over the same samples and the
information criteria compare like with like (Ljung, *System
Identification*, 2nd ed., §16.4):

* AIC = N ln V + 2d,  BIC = N ln V + d ln N,
* FPE = V (1 + d/N)/(1 − d/N),

with d parameters and N prediction errors.  ``criterion="fit"`` ranks by
the simulation fit [%] on a separate validation record instead.
"""

from __future__ import annotations

import inspect
import itertools
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int, as_mapping
from .._errors import DataError, OptionTypeError, ServoidError, ServoidWarning, check_option
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..validate import discrete_model, fit_percent, simulate_model
from ._estimate import Estimate

__all__ = ["StructureCandidate", "StructureSelection", "select_order"]

Criterion = Literal["aic", "bic", "fpe", "fit"]
_CRITERIA: tuple[Criterion, ...] = ("aic", "bic", "fpe", "fit")
#: Smallest meaningful value of each order (the lower edge of a grid is only an
#: edge above it): B needs one coefficient, everything else may be absent.
_FLOOR = {"nb": 1}


@dataclass(frozen=True)
class StructureCandidate:
    """Scores of one candidate of the grid.

    Attributes
    ----------
    orders : mapping of str to int
        The orders of this candidate (the grid's names).
    n_parameters : int
        d, the number of estimated parameters (0 when the fit failed).
    n_samples : int
        N, the number of prediction errors scored.
    loss : float
        V = mean squared prediction error over the common equations.
    aic, bic, fpe : float
        Information criteria (see the module notes); NaN when failed.
    fit : float
        Simulation fit [%] on the validation record, NaN without one.
    status : str
        ``"ok"``, the estimator's warnings, or ``"failed: <error>"``.
    """

    orders: Mapping[str, int]
    n_parameters: int
    n_samples: int
    loss: float
    aic: float
    bic: float
    fpe: float
    fit: float
    status: str = "ok"

    def __post_init__(self) -> None:
        as_mapping("orders", self.orders)
        object.__setattr__(self, "orders", MappingProxyType(dict(self.orders)))

    @property
    def failed(self) -> bool:
        """Whether the estimator raised for this candidate."""
        return self.status.startswith("failed")

    def score(self, criterion: Criterion) -> float:
        """Value to minimise for ``criterion`` (negated fit; inf when failed)."""
        value = -self.fit if criterion == "fit" else getattr(self, criterion)
        return float(value) if math.isfinite(value) else math.inf

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (NaN as None)."""
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        return {"orders": dict(self.orders), "n_parameters": self.n_parameters,
                "n_samples": self.n_samples, "loss": num(self.loss), "aic": num(self.aic),
                "bic": num(self.bic), "fpe": num(self.fpe), "fit": num(self.fit),
                "status": self.status}


@dataclass(frozen=True, eq=False)
class StructureSelection:
    """Every candidate of a structure search and the chosen one.

    Attributes
    ----------
    candidates : tuple of StructureCandidate
        All candidates in grid order, failed ones included.
    criterion : str
        The criterion that chose.
    best : StructureCandidate
        The chosen candidate.
    estimate : Estimate
        The chosen candidate's fit.
    edge : tuple of str
        Names of the orders whose chosen value sits on the edge of the grid
        (the largest value tried, or the smallest when a smaller one was
        possible): widen the grid there.
    first_sample : int
        The common first sample of the scored equations in each segment.
    """

    candidates: tuple[StructureCandidate, ...]
    criterion: Criterion
    best: StructureCandidate
    estimate: Estimate
    edge: tuple[str, ...] = ()
    first_sample: int = 0
    grid: Mapping[str, tuple[int, ...]] = field(default_factory=dict)

    def ranked(self) -> list[StructureCandidate]:
        """Candidates from best to worst (failed ones last)."""
        return sorted(self.candidates,
                      key=lambda c: (c.score(self.criterion), c.n_parameters))

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON: the ranking table and the choice."""
        return {"criterion": self.criterion, "chosen": dict(self.best.orders),
                "edge": list(self.edge), "first_sample": self.first_sample,
                "grid": {k: list(v) for k, v in self.grid.items()},
                "candidates": [c.to_dict() for c in self.ranked()]}


def select_order(
    fit: Callable[..., Estimate],
    data: Experiment | ExperimentSet,
    grid: Mapping[str, Sequence[int]],
    *,
    criterion: Criterion = "aic",
    validation: Experiment | None = None,
    **fixed: Any,
) -> StructureSelection:
    """Fit every structure of a grid and choose one by a criterion.

    Parameters
    ----------
    fit : callable
        An estimator such as :func:`fit_oe`, :func:`fit_armax`,
        :func:`fit_bj`, :func:`fit_iv` or :func:`fit_arx`, called as
        ``fit(data, **orders, **fixed)``.  If it takes ``start``, every
        candidate is scored from the grid's longest lag on (comparable
        equations); otherwise a polynomial model's own one-step residuals
        are scored from there.
    data : Experiment or ExperimentSet
        Estimation data.
    grid : mapping of str to sequence of int
        Order name → values to try, e.g. ``{"nb": [1, 2, 3], "nf": [1, 2, 3]}``;
        every combination is a candidate.
    criterion : {"aic", "bic", "fpe", "fit"}
        Information criterion on the estimation data, or simulation fit [%]
        on ``validation`` (required for ``"fit"``).
    validation : Experiment, optional
        Validation record; when given every candidate's simulation fit is computed.
    **fixed
        Further keywords for every call (``nk=1``, ``initial="estimate"``, ...).

    Returns
    -------
    StructureSelection
        All candidates (a failed fit is a row with its error), the chosen
        one, its estimate and the orders on the edge of the grid.

    Raises
    ------
    DataError
        An empty grid, ``criterion="fit"`` without validation data, or every
        candidate failed.
    OptionError
        An unknown criterion.
    """
    check_option("criterion", criterion, _CRITERIA)
    if not callable(fit):
        raise OptionTypeError(f"fit must be an estimator function such as fit_oe, got {fit!r}")
    if criterion == "fit" and validation is None:
        raise DataError('criterion="fit" needs a validation record: pass validation=<Experiment>')
    if validation is not None and not isinstance(validation, Experiment):
        raise OptionTypeError(
            f"validation must be an Experiment, got {type(validation).__name__}")
    values = _check_grid(grid, fixed)
    names = list(values)
    combos = [dict(zip(names, combo, strict=True))
              for combo in itertools.product(*(values[n] for n in names))]
    params = inspect.signature(fit).parameters
    takes_start = "start" in params or any(
        p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    defaults = {k: p.default for k, p in params.items()
                if p.default is not inspect.Parameter.empty}
    if "start" in fixed:
        first = as_int("start", fixed.pop("start"), minimum=0)
    else:
        first = max(_longest_lag({**defaults, **fixed, **c}) for c in combos)
    candidates: list[StructureCandidate] = []
    best_est: tuple[float, int, int, Estimate, list[str]] | None = None
    for k, orders in enumerate(combos):
        kwargs = {**fixed, **orders}
        if takes_start:
            kwargs["start"] = first
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                est = fit(data, **kwargs)
            except ServoidError as exc:
                candidates.append(_failed(orders, exc))
                continue
        notes = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
        cand = _score(est, orders, data, first, validation, takes_start, notes)
        candidates.append(cand)
        key = (cand.score(criterion), cand.n_parameters, k)
        if best_est is None or key < best_est[:3]:
            best_est = (*key, est, notes)
    if best_est is None:
        listed = "; ".join(f"{dict(c.orders)}: {c.status}" for c in candidates[:3])
        raise DataError(f"every candidate of the grid failed ({listed}). Check the data and "
                        "use lower orders")
    *_, k_best, estimate, notes = best_est
    for note in notes:  # the chosen fit's own warnings still reach the caller
        warn(note, ServoidWarning)
    best = candidates[k_best]
    return StructureSelection(tuple(candidates), criterion, best, estimate,
                              _edges(best.orders, values), first,
                              {n: tuple(v) for n, v in values.items()})


def _check_grid(grid: object, fixed: Mapping[str, Any]) -> dict[str, tuple[int, ...]]:
    if not isinstance(grid, Mapping) or not grid:
        raise DataError("grid must be a non-empty mapping of order name to values, e.g. "
                        '{"nb": [1, 2, 3], "nf": [1, 2, 3]}')
    out: dict[str, tuple[int, ...]] = {}
    for name, vals in grid.items():
        if not isinstance(name, str):
            raise OptionTypeError(f"grid names must be strings, got {name!r}")
        if name in fixed:
            raise DataError(f"{name} is both in the grid and fixed; give it in one place")
        if isinstance(vals, (str, bytes)) or not isinstance(vals, (Sequence, range, np.ndarray)):
            raise OptionTypeError(f"grid[{name!r}] must be a sequence of integers, got {vals!r}")
        items = tuple(as_int(f"grid[{name!r}]", v) for v in vals)
        if not items:
            raise DataError(f"grid[{name!r}] is empty; give at least one value")
        out[name] = tuple(dict.fromkeys(items))
    return out


def _longest_lag(orders: Mapping[str, Any]) -> int:
    def ints(v: Any) -> list[int]:
        if isinstance(v, (list, tuple, np.ndarray)):
            return [int(x) for x in v]
        return [int(v)] if isinstance(v, (int, np.integer)) and not isinstance(v, bool) else []
    lag = 0
    for name in ("na", "nc", "nd", "nf"):
        lag = max(lag, *ints(orders.get(name, 0)), 0)
    nb, nk = ints(orders.get("nb", 0)), ints(orders.get("nk", 0))
    if nb:
        if len(nk) != len(nb):  # one delay for every input
            nk = [max(nk, default=0)] * len(nb)
        lag = max(lag, *(b + k - 1 for b, k in zip(nb, nk, strict=True)))
    return lag


def _score(est: Estimate, orders: Mapping[str, int], data: Experiment | ExperimentSet,
           first: int, validation: Experiment | None, takes_start: bool,
           notes: list[str]) -> StructureCandidate:
    if takes_start:
        errors = est.residuals
    else:
        errors = _model_residuals(est, data, first)
        if errors is None:
            errors = est.residuals
            notes = ["scored on the estimator's own equations", *notes]
    status = "; ".join(notes) if notes else "ok"
    n = int(errors.size)
    d = int(est.parameters.size)
    loss = float(np.mean(errors**2)) if n else math.nan
    log_v = math.log(loss) if loss > 0 else -math.inf
    fit = _validation_fit(est, validation) if validation is not None else math.nan
    return StructureCandidate(
        orders, d, n, loss,
        aic=n * log_v + 2 * d,
        bic=n * log_v + d * math.log(max(n, 1)),
        fpe=loss * (1 + d / n) / (1 - d / n) if n > d else math.inf,
        fit=fit,
        status=status,
    )


def _model_residuals(est: Estimate, data: Experiment | ExperimentSet,
                     first: int) -> NDArray[np.float64] | None:
    model = est.model
    if not hasattr(model, "residuals") or "output" not in est.options:
        return None
    pieces = []
    for seg in as_segments(data):
        y = seg[est.options["output"]]
        u = np.column_stack([seg[n] for n in est.options["inputs"]])
        pieces.append(np.asarray(model.residuals(y, u if u.shape[1] > 1 else u[:, 0]))[first:])
    return np.concatenate(pieces)


def _validation_fit(est: Estimate, validation: Experiment) -> float:
    """Simulation fit [%] of the estimate on a validation record.

    The model is simulated as :func:`servoid.validate.validate` does (a
    continuous one discretised with its intersample behaviour, the initial
    state measured for ARX and fitted otherwise), so the search ranks
    candidates by the number the report then shows.
    """
    y = validation[est.options["output"]]
    u = np.column_stack([validation[n] for n in est.options["inputs"]])
    model = discrete_model(est, validation.dt)
    y_sim, start, _ = simulate_model(model, y, u if u.shape[1] > 1 else u[:, 0])
    return float(fit_percent(y[start:], y_sim[start:]))


def _failed(orders: Mapping[str, int], exc: ServoidError) -> StructureCandidate:
    nan = math.nan
    return StructureCandidate(orders, 0, 0, nan, nan, nan, nan, nan,
                              status=f"failed: {type(exc).__name__}: {exc}")


def _edges(chosen: Mapping[str, int], values: Mapping[str, tuple[int, ...]]) -> tuple[str, ...]:
    out = []
    for name, vals in values.items():
        if len(vals) < 2:
            continue
        v = chosen[name]
        if v == max(vals) or (v == min(vals) and v > _FLOOR.get(name, 0)):
            out.append(name)
    return tuple(out)
