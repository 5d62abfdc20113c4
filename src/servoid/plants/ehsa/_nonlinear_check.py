"""Validate a refined nonlinear EHSA, and the workflow's refine step.

* :func:`validate_nonlinear_ehsa` simulates the refined model on a
  held-back record from its reference and returns the same
  :class:`~servoid.validate.ValidationReport` the linear approaches get
  (fit, NRMSE, residual whiteness and independence of the reference), so
  reports and tests compare them on equal terms.  An output-error model
  predicts by simulating: its k-step prediction is the simulation.
* :func:`refine_after_linear` is what the ``[identify] method =
  "closedloop"`` workflow calls when ``refine = true``: the refinement
  started from a linear closed-loop result, and both validated on the
  same record (:class:`NonlinearRefinement`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._checks import as_float, as_instance, as_int, type_error
from ..._errors import DataError, ServoidWarning
from ..._warn import warn
from ...closedloop import output_name, reference_name
from ...data import Experiment, ExperimentSet
from ...estimate import Estimate
from ...validate import (
    ValidationReport,
    fit_percent,
    nrmse,
    relative_error,
    residual_analysis,
    rmse,
    vaf,
    validate,
)
from ._loop import FeedbackLoop
from ._nonlinear import NONLINEAR_DEFAULTS, refine_nonlinear_ehsa
from ._nonlinear_model import NonlinearEhsa
from ._params import SET_B, EhsaParameters
from ._result import ClosedLoopResult

__all__ = ["NonlinearRefinement", "refine_after_linear", "validate_nonlinear_ehsa"]


@dataclass(frozen=True, eq=False)
class NonlinearRefinement:
    """The nonlinear refinement of a linear closed-loop result.

    Parameters
    ----------
    estimate : Estimate
        The refined parameters (:func:`refine_nonlinear_ehsa`).
    start : ClosedLoopResult
        The linear result it started from.
    validation : ValidationReport
        The refined nonlinear model on the held-back record.
    linear_validation : ValidationReport
        The linear result on the same record (its closed loop from r).
    """

    estimate: Estimate
    start: ClosedLoopResult
    validation: ValidationReport
    linear_validation: ValidationReport

    @property
    def model(self) -> NonlinearEhsa:
        """The refined model."""
        model: NonlinearEhsa = self.estimate.model
        return model

    @property
    def improves(self) -> bool:
        """True when the refined model validates better than the linear one."""
        return self.validation.fit_percent > self.linear_validation.fit_percent

    def notes(self) -> list[str]:
        """Return what the refinement flagged, in plain words."""
        out = [f"{k}: not identifiable — {v}" for k, v in
               self.estimate.options.get("not_identifiable", {}).items()]
        out += [w for w in self.estimate.options.get("warnings", [])]
        if not self.improves:
            out.append(
                f"the nonlinear model validates no better than the linear {self.start.approach} "
                f"result ({self.validation.fit_percent:.2f} % vs "
                f"{self.linear_validation.fit_percent:.2f} %)")
        return out

    def to_dict(self, level: float = 0.95) -> dict[str, Any]:
        """Plain data for JSON.

        Parameters
        ----------
        level : float
            Confidence level of the parameter intervals.
        """
        return {"estimate": self.estimate.to_dict(level), "start_approach": self.start.approach,
                "validation": self.validation.summary(),
                "linear_validation": self.linear_validation.summary(),
                "improves": self.improves, "notes": self.notes()}

    def __str__(self) -> str:
        lines = ["nonlinear EHSA refinement (closed-loop output error, compiled simulator)",
                 str(self.estimate)]
        for name, reason in self.estimate.options.get("not_identifiable", {}).items():
            lines.append(f"  {name}: NOT IDENTIFIABLE — {reason}")
        lines.append(f"  validation fit: nonlinear {self.validation.fit_percent:.2f} %, linear "
                     f"{self.start.approach} {self.linear_validation.fit_percent:.2f} %")
        lines += [f"  ! {w}" for w in self.estimate.options.get("warnings", [])]
        return "\n".join(lines)


def validate_nonlinear_ehsa(
    model: NonlinearEhsa | Estimate,
    experiment: Experiment,
    *,
    reference: str | None = None,
    output: str | None = None,
    preceding: Experiment | None = None,
    max_lag: int = 25,
    confidence: float = 0.99,
    transient: int = 0,
) -> ValidationReport:
    """Validate a nonlinear EHSA on a record it was not fitted to.

    Parameters
    ----------
    model : NonlinearEhsa or Estimate
        The model, or the estimate of :func:`refine_nonlinear_ehsa`.
    experiment : Experiment
        Held-back record with the reference r and the position [m], at
        the model's sample period.  Without `preceding` the simulation
        starts at rest at its first measured position.
    reference : str, optional
        Channel that drives the model [m]; default the reference (role
        ``"r"``).  An estimate's own choice is used when it is one.
    output : str, optional
        Position channel when there are several outputs.
    preceding : Experiment, optional
        The record just before `experiment` in the same run (e.g. the
        estimation half): the simulation runs through it from rest, so the
        validation starts from the state the model has reached there
        rather than from rest (a record cut from a run starts in motion).
    max_lag : int
        Largest lag of the residual correlations [samples].
    confidence : float
        Level of the correlation bands and verdicts.
    transient : int
        Samples at the start left out of the metrics (a record cut from a
        longer run starts in motion, not at rest) [samples].

    Returns
    -------
    ValidationReport
        Fit, errors and residual tests; prediction = simulation.

    Raises
    ------
    DataError
        A record at another sample period, no reference, or a transient
        that leaves too few samples.
    """
    expected = "a NonlinearEhsa or its Estimate (from refine_nonlinear_ehsa)"
    if isinstance(model, Estimate):
        if not isinstance(model.model, NonlinearEhsa):
            raise type_error("model", model.model, expected)
        as_instance("experiment", experiment, Experiment,
                    "an Experiment (servoid.Experiment.from_arrays)")
        if reference is None and model.options.get("reference") in experiment.names:
            reference = model.options["reference"]
        model = model.model
    as_instance("model", model, NonlinearEhsa, expected)
    as_instance("experiment", experiment, Experiment,
                "an Experiment (servoid.Experiment.from_arrays)")
    if not np.isclose(experiment.dt, model.dt, rtol=1e-9, atol=0.0):
        raise DataError(f"the model has dt = {model.dt} s but the record {experiment.dt} s")
    transient = as_int("transient", transient, minimum=0,
                       maximum=max(experiment.n_samples - 3, 0))
    max_lag = as_int("max_lag", max_lag, minimum=1)
    confidence = as_float("confidence", confidence)
    if not 0.0 < confidence < 1.0:
        raise DataError(f"confidence must lie in (0, 1), got {confidence:g}")
    ref = reference_name(experiment, "validate_nonlinear_ehsa") if reference is None else \
        experiment.channel(reference).name
    out = output_name(experiment, output)
    r, y = experiment[ref], experiment[out]
    if preceding is None:
        y_sim = model.simulate(r, y0=float(y[0]))
    else:
        if not isinstance(preceding, Experiment):
            raise type_error("preceding", preceding, "an Experiment (the record just before) "
                             "or None")
        if not np.isclose(preceding.dt, experiment.dt, rtol=1e-9, atol=0.0):
            raise DataError(f"preceding has dt = {preceding.dt} s, the record {experiment.dt} s")
        r_prev, y_prev = preceding[ref], preceding[out]
        run = model.simulate(np.concatenate([r_prev, r]), y0=float(y_prev[0]))
        y_sim = run[r_prev.size:]
    k = int(transient)
    ys, ss = y[k:], y_sim[k:]
    eps = y - y_sim
    fit = float(fit_percent(ys, ss))
    return ValidationReport(
        output=out, time=experiment.time, measured=y, simulated=y_sim, predicted=y_sim,
        first=k, fit_percent=fit, nrmse=float(nrmse(ys, ss)), rmse=float(rmse(ys, ss)),
        vaf=float(vaf(ys, ss)), relative_error=float(relative_error(ys, ss)), horizon=1,
        prediction_fit_percent=fit,
        residuals=residual_analysis(eps[k:], r[k:], max_lag, confidence),
        experiment=experiment.name, prediction_first=k,
        initial="rest" if preceding is None else "run through the preceding record",
        unit=experiment.unit(out), noise_model=False)


def refine_after_linear(
    estimation: Experiment | ExperimentSet,
    validation: Experiment,
    loop: FeedbackLoop,
    result: ClosedLoopResult,
    *,
    parameters: Sequence[str] = NONLINEAR_DEFAULTS,
    nominal: EhsaParameters = SET_B,
    **options: Any,
) -> NonlinearRefinement:
    """Refine a linear closed-loop result into the nonlinear EHSA.

    Parameters
    ----------
    estimation : Experiment or ExperimentSet
        The records the linear result was fitted to.
    validation : Experiment
        The held-back record.  When it continues the (single) estimation
        record — a run split in halves, ``validation.t0`` at the end of
        `estimation` — the nonlinear model is run through the estimation
        half into it (:func:`validate_nonlinear_ehsa`, `preceding`); the
        linear result is validated as the workflow does, with its initial
        state fitted.
    loop : FeedbackLoop
        The known loop gains.
    result : ClosedLoopResult
        The linear result (one-step, two-step or direct with a loop): its
        K, ω_hp, δ_hp start the refinement.
    parameters : sequence of str
        Parameters to refine (:func:`refine_nonlinear_ehsa`).
    nominal : EhsaParameters
        Physical parameters of everything not refined.
    **options
        Further keywords of :func:`refine_nonlinear_ehsa` (side
        channels, bounds, intersample, covariance, ...).

    Returns
    -------
    NonlinearRefinement
        The refined estimate and both validations on `validation`.

    Warns
    -----
    ServoidWarning
        What :func:`refine_nonlinear_ehsa` flags, and a refined model that
        validates no better than the linear one.
    """
    as_instance("result", result, ClosedLoopResult,
                "a ClosedLoopResult (from identify_closed_loop, fit_one_step, ...)")
    as_instance("validation", validation, Experiment,
                "an Experiment (the held-back record)")
    if result.closed_loop is None:
        raise DataError(f"the {result.approach} result has no closed loop to start from; "
                        "refine a one-step or two-step result")
    est = refine_nonlinear_ehsa(estimation, loop, result, parameters, nominal=nominal,
                                **options)
    refined = validate_nonlinear_ehsa(est, validation, output=est.options["output"],
                                      preceding=_preceding(estimation, validation))
    linear = validate(result.closed_loop.to_polynomial("oe"), validation, input="r",
                      output=est.options["output"])
    out = NonlinearRefinement(est, result, refined, linear)
    if not out.improves:
        warn(out.notes()[-1], ServoidWarning)
    return out


def _preceding(estimation: Experiment | ExperimentSet, validation: Experiment) -> Experiment | None:
    """The estimation record when the validation record continues it (one run, split)."""
    if not isinstance(estimation, Experiment) or not np.isclose(estimation.dt, validation.dt,
                                                                rtol=1e-9, atol=0.0):
        return None
    end = estimation.t0 + estimation.n_samples * estimation.dt
    if abs(validation.t0 - end) > 1e-6 * estimation.dt or estimation.names != validation.names:
        return None
    return estimation
