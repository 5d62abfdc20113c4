"""Validation of a model on data: :class:`ValidationReport` and :func:`validate`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from .._checks import type_error
from .._errors import DataError, check_option
from ..data import Experiment
from ._metrics import fit_percent, nrmse, relative_error, rmse, vaf
from ._residuals import ResidualAnalysis, residual_analysis

__all__ = ["ValidationReport", "simulate_from_data", "validate"]


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Plain-data result of validating a model on one experiment.

    Simulation metrics compare the measured output with the model simulated
    from the input alone (from sample ``first`` on, with the samples before
    it used as initial conditions); prediction metrics use the k-step-ahead
    predictor from sample ``prediction_first`` on (for an ARX model
    ``first + horizon − 1``, where its FIR predictor needs no sample before
    the record); residual tests use one-step prediction errors.
    """

    output: str
    time: NDArray[np.float64]
    measured: NDArray[np.float64]
    simulated: NDArray[np.float64]
    predicted: NDArray[np.float64]
    first: int
    fit_percent: float
    nrmse: float
    rmse: float
    vaf: float
    relative_error: float
    horizon: int
    prediction_fit_percent: float
    residuals: ResidualAnalysis
    experiment: str = ""
    prediction_first: int = 0

    def summary(self) -> dict[str, Any]:
        """Scalars and residual tests as plain data (no time series)."""
        return {
            "experiment": self.experiment,
            "output": self.output,
            "n_samples": int(self.measured.size - self.first),
            "fit_percent": self.fit_percent,
            "nrmse": self.nrmse,
            "rmse": self.rmse,
            "vaf": self.vaf,
            "relative_error_percent": self.relative_error,
            "prediction_horizon": self.horizon,
            "prediction_fit_percent": self.prediction_fit_percent,
            "prediction_first": self.prediction_first,
            "residuals": self.residuals.to_dict(),
        }

    def __str__(self) -> str:
        r = self.residuals
        return (
            f"validation on {self.measured.size - self.first} samples of {self.output!r}: "
            f"fit {self.fit_percent:.2f} %, NRMSE {self.nrmse:.4f}, RMSE {self.rmse:.4g}, "
            f"VAF {self.vaf:.2f} %, {self.horizon}-step prediction fit "
            f"{self.prediction_fit_percent:.2f} %; residuals "
            f"{'white' if r.is_white else 'NOT white'} (p = {r.whiteness_pvalue:.3g}), "
            f"{'independent of' if r.is_independent else 'CORRELATED with'} the input"
        )


def validate(
    model: Any,
    experiment: Experiment,
    *,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    horizon: int = 5,
    max_lag: int = 25,
    confidence: float = 0.99,
) -> ValidationReport:
    """Validate a discrete model on an experiment.

    Parameters
    ----------
    model : PolynomialModel
        A discrete model with ``simulate``, ``predict`` and ``residuals``.
    experiment : Experiment
        Validation data (not used for fitting).
    input : {"u", "r"}
        Role that drives the model.
    output : str, optional
        Output channel when there are several.
    horizon : int
        k of the k-step-ahead prediction fit.
    max_lag : int
        Largest lag of the residual correlations [samples].
    confidence : float
        Level of the correlation bands and verdicts.
    """
    check_option("input", input, ("u", "r"))
    if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)):
        raise type_error("horizon", horizon, "an integer (samples)")
    if horizon < 1:
        raise DataError(f"horizon must be >= 1 sample, got {horizon}")
    dt = getattr(model, "dt", None)
    if dt is not None and not np.isclose(dt, experiment.dt, rtol=1e-9, atol=0.0):
        raise DataError(
            f"the model has dt = {dt} s but the experiment {experiment.dt} s; "
            "resample the data or discretise the model at the data rate"
        )
    outputs = experiment.names_of("y") if output is None else (output,)
    if len(outputs) != 1:
        experiment.signal("y")
        raise DataError(f"several outputs ({', '.join(outputs)}): pass output=<name>")
    y = experiment[outputs[0]]
    u = experiment.signal(input)
    y_sim, first = simulate_from_data(model, y, u)
    y_pred = np.asarray(model.predict(y, u, horizon=horizon), dtype=float)
    eps = np.asarray(model.residuals(y, u), dtype=float)
    ys, ss = y[first:], y_sim[first:]
    # The k-step predictor takes unknown samples before the record as zero. For an ARX
    # model it is an FIR in y and u reaching back k − 1 + first samples, so from there on
    # it is exact, as the simulation is from `first` on (measured initial conditions).
    p0 = min(first + horizon - 1, len(y) - 2) if first > 0 else 0
    return ValidationReport(
        output=outputs[0],
        time=experiment.time,
        measured=y,
        simulated=y_sim,
        predicted=y_pred,
        first=first,
        fit_percent=float(fit_percent(ys, ss)),
        nrmse=float(nrmse(ys, ss)),
        rmse=float(rmse(ys, ss)),
        vaf=float(vaf(ys, ss)),
        relative_error=float(relative_error(ys, ss)),
        horizon=horizon,
        prediction_fit_percent=float(fit_percent(y[p0:], y_pred[p0:])),
        residuals=residual_analysis(eps[first:], u[first:], max_lag, confidence),
        experiment=experiment.name,
        prediction_first=p0,
    )


def simulate_from_data(
    model: Any, y: NDArray[np.float64], u: NDArray[np.float64]
) -> tuple[NDArray[np.float64], int]:
    """Simulate from the input and measured initial conditions.

    For an ARX-type model (A y = Σ B_i u_i) the first ``m`` = longest-lag
    samples of y and u set the initial state exactly, so the simulation has
    no start-up transient; other models start from rest (``first`` = 0).

    Returns
    -------
    y_sim : ndarray, shape (N,)
        Simulated output; equals the measurement before ``first``.
    first : int
        First simulated sample.
    """
    u = np.asarray(u, dtype=float).reshape(len(y), -1)
    if _is_arx(model):
        a = np.asarray(model.a)
        v = np.zeros(len(y))
        m = a.size - 1
        for b, k, col in zip(model.b, model.nk, u.T, strict=True):
            bk = np.concatenate([np.zeros(k), b])
            v += sps.lfilter(bk, [1.0], col)
            m = max(m, bk.size - 1)
        if m == 0:
            return v, 0
        if m >= len(y) - 1:
            raise DataError(f"validation needs more than {m + 1} samples, got {len(y)}")
        zi = sps.lfiltic([1.0], a, y[m - 1 :: -1][: a.size - 1]) if a.size > 1 else None
        y_sim = np.array(y, dtype=float)
        if zi is None:
            y_sim[m:] = v[m:]
        else:
            y_sim[m:] = sps.lfilter([1.0], a, v[m:], zi=zi)[0]
        return y_sim, m
    return np.asarray(model.simulate(u if u.shape[1] > 1 else u[:, 0]), dtype=float), 0


def _is_arx(model: Any) -> bool:
    if not all(hasattr(model, n) for n in ("a", "b", "nk", "f", "c", "d")):
        return False
    trivial = [np.asarray(model.c), np.asarray(model.d), *map(np.asarray, model.f)]
    return all(p.size == 1 for p in trivial)
