"""The linear start of ``method = "pnlss"`` with ``linear = "auto"``: the linear model that
model choice picks (``method = "auto"``'s linear candidates, scored on their own hold-out),
as a discrete state space."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._errors import ConvergenceError, DataError, OptionError, ServoidError
from ..data import Experiment, ExperimentSet, ExperimentSpec

__all__ = ["AutoStart", "choose_linear", "discrete_ss"]


@dataclass(frozen=True)
class AutoStart:
    """The linear start of ``linear = "auto"``: model choice's linear model in state space.

    Attributes
    ----------
    model : StateSpace
        The chosen model, discrete at the records' dt (a continuous one by zero-order hold).
    label, reason : str
        The chosen candidate and why model choice chose it.
    samples : int
        The samples model choice saw (PNLSS's fitted part, never its held-out part).
    candidates : tuple of (str, float, str)
        Each linear candidate's label, held-out fit [%] and status.
    """

    model: Any
    label: str
    reason: str
    samples: int
    candidates: tuple[tuple[str, float, str], ...] = ()

    @property
    def text(self) -> str:
        """The start in words, for the model text."""
        return (f"{self.label}, chosen by model choice among the linear candidates on "
                f"{self.samples} samples: {self.reason}")

    def record(self) -> dict[str, Any]:
        """Plain data for ``results.json``."""
        return {"chosen": self.label, "reason": self.reason, "samples": self.samples,
                "n_states": int(self.model.n_states),
                "candidates": [{"label": c, "held_out_fit_percent": None if not
                                np.isfinite(f) else f, "status": st}
                               for c, f, st in self.candidates]}


def choose_linear(spec: ExperimentSpec, fit_on: Experiment | ExperimentSet,
                  options: Mapping[str, Any]) -> AutoStart:
    """Model choice's linear model on the records `fit_on` alone (its candidates scored on
    their own held-out part), as a discrete state space."""
    from ._choice import (
        Fold,
        _HeldSpec,
        auto_candidates,
        choice_method,
        declares_loop,
        folds_of,
        score_candidates,
        score_name,
    )
    from ._leaderboard import Fitted, _in_the_loop, fit_choice

    segments = (fit_on,) if isinstance(fit_on, Experiment) else tuple(fit_on)
    own = _HeldSpec(spec, Fold(fit_on, segments))  # records: the fitted part alone
    table = {"input": options["input"]}
    if options["output"] is not None:
        table["output"] = options["output"]
    choosing = choice_method({"method": "auto"}).parse(table)
    folds = folds_of(fit_on, int(choosing["folds"]), float(choosing["holdout"]))
    scores = score_candidates(own, auto_candidates(loop=declares_loop(spec)), choosing, folds)
    scores = _in_the_loop(spec, scores)
    converted: dict[int, Any] = {}

    def usable(fitted: Fitted) -> str:
        try:
            converted[id(fitted)] = discrete_ss(fitted.result.estimate.model, float(fit_on.dt))
        except ServoidError as exc:
            return str(exc)
        return ""

    chosen, reason, fits, passed = fit_choice(
        own, choosing, folds, scores, score_name(choosing), usable=usable)  # type: ignore[arg-type]
    if chosen is None:
        raise ConvergenceError(
            '[identify] linear = "auto": no linear candidate of model choice gave a '
            "stable model on the fitted part of the estimation data ("
            + "; ".join(f"{s.candidate.label}: {s.status}" for s in scores)
            + "".join(f"; {label}: {why}" for label, why in passed)
            + '); give linear = "n4sid" or "oe"')
    fitted = fits[id(chosen)]
    model = converted[id(fitted)]
    if fitted.kept:
        reason += f"; {fitted.kept}"
    if passed:
        reason += f" ({'; '.join(f'{label}: {why}' for label, why in passed)}: passed over)"
    n = sum(seg.n_samples for seg in segments)
    return AutoStart(model, chosen.candidate.label, reason, n,
                     tuple((s.candidate.label, float(s.mean), s.status) for s in scores))


def discrete_ss(model: Any, dt: float) -> Any:
    """A linear model as a discrete single-output state space at `dt`: a polynomial model's
    transfer function, a continuous model by zero-order hold."""
    from ..models import PolynomialModel, StateSpace, TransferFunction, c2d

    if isinstance(model, PolynomialModel):
        if model.n_inputs != 1:
            raise OptionError('[identify] linear = "auto" starts from a single-input '
                              'polynomial model; for several inputs use linear = "n4sid"')
        model = model.transfer_function(0)
    if not isinstance(model, (TransferFunction, StateSpace)):
        raise OptionError(f'[identify] linear = "auto": the chosen model '
                          f"({type(model).__name__}) is not a linear transfer function or "
                          'state space; use linear = "n4sid" or "oe"')
    if model.dt is None:
        model = c2d(model, dt, "zoh")
    elif abs(model.dt - dt) > 1e-9 * dt:
        raise DataError(f"the chosen linear model's dt = {model.dt:g} s is not the "
                        f"records' {dt:g} s")
    if isinstance(model, TransferFunction):
        if model.delay:  # a whole number of samples in a discrete model: z^-k, as states
            k = round(model.delay / dt)
            model = TransferFunction(model.num, np.concatenate([model.den, np.zeros(k)]),
                                     dt=dt)
        model = model.to_ss()
    return model

