"""Validation of a model on data: :class:`ValidationReport` and :func:`validate`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_float, as_int, type_error
from .._errors import DataError, ModelError, SimulationDivergedError, check_option
from ..data import Experiment, check_experiment
from ._metrics import fit_of_moments, fit_percent, metric_set
from ._nonlinearity import NonlinearityTests, nonlinearity_tests
from ._residuals import ResidualAnalysis, analyse_residuals
from ._simulate import (
    INITIALS,
    Initial,
    Intersample,
    check_signals,
    discrete_model,
    has_noise_model,
    is_arx,
    is_replayable,
    simulate_model,
)

__all__ = ["ValidationReport", "simulate_from_data", "validate"]

#: Lags of the residual correlations unless asked: at most a quarter of the residuals
#: (autocorrelations beyond N/4 lags rest on too few products; Box & Jenkins).
_DEFAULT_MAX_LAG = 25
#: Fewest residuals the default tests run on: N/4 >= 5 lags, and the 99 % band
#: 2.58/sqrt(N) below 0.6; fewer leave a whiteness verdict with nothing to rest on.
_MIN_RESIDUALS = 20


class _TimeSlot:
    """The ``time`` field: an array, or built from the experiment on first read.

    :func:`validate` passes the experiment's :attr:`~servoid.data.Experiment.time`
    as a zero-argument callable: building an N-sample time axis cost ~4 ms of a
    20 ms validation at N = 1e6, for a field only plots and exports read.
    """

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:  # class access: tells dataclass the field has no default
            raise AttributeError("time")
        value = obj.__dict__["_time"]
        if callable(value):
            value = value()
            obj.__dict__["_time"] = value
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        # reached only from __init__ (object.__setattr__); the frozen dataclass's
        # __setattr__ refuses assignments from outside first
        obj.__dict__["_time"] = value


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Plain-data result of validating a model on one experiment.

    Simulation metrics compare the measured output with the model simulated
    from the input alone, from sample ``first`` on: the samples before it
    either set the initial conditions (``initial = "measured"``, ARX) or
    are a start-up transient the user chose to exclude; with
    ``initial = "estimate"`` the initial state is fitted to the record
    (MATLAB's ``compare``).  Prediction metrics use the k-step-ahead
    predictor from sample ``prediction_first`` on; residual tests use
    one-step prediction errors (for a model without a noise model, the
    simulation error).
    """

    output: str
    time: NDArray[np.float64] = _TimeSlot()  # type: ignore[assignment]
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
    initial: str = "measured"
    clipped: int = 0
    unit: str = ""
    noise_model: bool = True
    nonlinearity: NonlinearityTests | None = None

    def __getstate__(self) -> dict[str, Any]:
        # pickle the time axis itself, not the callable that builds it
        state = dict(self.__dict__)
        state["_time"] = self.time
        return state

    def notes(self) -> tuple[str, ...]:
        """Verdicts in plain words: what the data say about the model."""
        out = []
        r = self.residuals
        if self.fit_percent < 0:
            out.append(
                f"the simulation fit on {self.experiment or 'the validation data'} is "
                f"{self.fit_percent:.1f} % (negative): the model predicts the output worse "
                "than its mean value; the model structure is rejected by the data"
            )
        if not r.is_independent:
            out.append(
                f"the residuals correlate with the input (p = {r.independence_pvalue:.3g}): the "
                "model structure is rejected by the data; the dynamics from the input are not "
                "captured (try other orders or delays), or the data were taken in closed loop"
            )
        if not r.is_white and not self.noise_model:
            out.append(
                f"the residuals are coloured (Ljung–Box p = {r.whiteness_pvalue:.3g}); an "
                "output-error model describes the dynamics, not the noise, so this alone does "
                "not reject it (the input–residual and higher-order tests judge the dynamics); "
                "BJ adds a noise "
                "model when the noise itself matters"
            )
        elif not r.is_white:
            out.append(
                f"the residuals are not white (Ljung–Box p = {r.whiteness_pvalue:.3g}): the "
                "noise model is rejected by the data; parameter intervals that assume white "
                "residuals are too narrow — a noise model (ARMAX, BJ) or a higher order helps"
            )
        nl = self.nonlinearity
        if nl is not None and nl.detected:
            out.append(
                f"the residuals correlate with nonlinear functions of the input ({nl.strongest} "
                f"p = {nl.pvalues[nl.strongest]:.3g}; Billings–Voon higher-order tests, combined "
                f"p = {nl.pvalue:.3g}): the model leaves a nonlinearity unexplained — a "
                "block-oriented model (wiener, hammerstein) or a NARX may capture it"
            )
        if self.clipped:
            out.append(f"{self.clipped} simulated samples were clipped to the declared limits of "
                       f"{self.output!r}")
        return tuple(out)

    def summary(self) -> dict[str, Any]:
        """Scalars and residual tests as plain data (no time series)."""
        return {
            "experiment": self.experiment,
            "output": self.output,
            "unit": self.unit,
            "n_samples": int(self.measured.size - self.first),
            "first": self.first,
            "initial": self.initial,
            "fit_percent": self.fit_percent,
            "nrmse": self.nrmse,
            "rmse": self.rmse,
            "vaf": self.vaf,
            "relative_error_percent": self.relative_error,
            "prediction_horizon": self.horizon,
            "prediction_fit_percent": self.prediction_fit_percent,
            "prediction_first": self.prediction_first,
            "clipped": self.clipped,
            "residuals": self.residuals.to_dict(),
            "nonlinearity": None if self.nonlinearity is None else self.nonlinearity.to_dict(),
            "notes": list(self.notes()),
        }

    def __repr__(self) -> str:
        return (f"<ValidationReport {self.output!r}: fit {self.fit_percent:.2f} %, residuals "
                f"{'white' if self.residuals.is_white else 'not white'}>")

    def _repr_html_(self) -> str:
        from .._display import html_block

        r = self.residuals
        rows = [("simulation fit", f"{self.fit_percent:.2f} %"),
                (f"{self.horizon}-step prediction fit", f"{self.prediction_fit_percent:.2f} %"),
                ("NRMSE", f"{self.nrmse:.4g}"), ("VAF", f"{self.vaf:.2f} %"),
                ("residual whiteness", f"{'white' if r.is_white else 'NOT white'} "
                                       f"(p = {r.whiteness_pvalue:.3g})"),
                ("input–residual independence",
                 f"{'independent' if r.is_independent else 'CORRELATED'} "
                 f"(p = {r.independence_pvalue:.3g})")]
        nl = self.nonlinearity
        if nl is not None and nl.tested:
            verdict = "NONLINEARITY LEFT" if nl.detected else "none left"
            rows.append(("higher-order (nonlinearity) tests", f"{verdict} (p = {nl.pvalue:.3g})"))
        return html_block(f"validation of {self.output}"
                          + (f" on {self.experiment}" if self.experiment else ""),
                          [("samples", str(self.measured.size - self.first))],
                          ("metric", "value"), rows, note=" ".join(self.notes()))

    def plot(self) -> Any:
        """Plot measured, simulated and predicted output, the error and a zoom.

        Returns
        -------
        matplotlib.figure.Figure
            A figure made by pyplot: Jupyter shows it inline (once, also as a
            cell's value), and in a script ``plt.show()`` or ``plt.savefig()``
            acts on it. Close it with ``plt.close(fig)`` when done.
        """
        from .._pyplot import pyplot_figure
        from ._figures import validation_figure

        return validation_figure(self, new=pyplot_figure)

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
    max_lag: int | None = None,
    confidence: float = 0.99,
    initial: Initial = "auto",
    transient: int = 0,
    intersample: Intersample = "zoh",
    limits: tuple[float, float] | None = None,
    closed_loop: bool = False,
) -> ValidationReport:
    """Validate a model on an experiment it was not fitted to.

    Parameters
    ----------
    model : PolynomialModel, TransferFunction, StateSpace or Estimate
        Discrete at the experiment's rate, or continuous (discretised with
        `intersample`); an Estimate's model is used with its options.
    experiment : Experiment
        Validation data (not used for fitting).
    input : {"u", "r"}
        Role that drives the model.
    output : str, optional
        Output channel when there are several; a state-space model with
        several outputs is validated on the matching row.
    horizon : int
        k of the k-step-ahead prediction fit.
    max_lag : int, optional
        Largest lag of the residual correlations [samples].  Default 25,
        capped at a quarter of the residuals; a record that leaves fewer
        than 20 residuals is refused unless `max_lag` is given.
    confidence : float
        Level of the correlation bands and verdicts.
    initial : {"auto", "estimate", "zero", "measured"}
        Initial state of the simulation: fitted to the record
        (``"estimate"``), from rest, or (ARX) from the first samples;
        ``"auto"`` takes measured for ARX and estimated otherwise.
    transient : int
        Samples at the start excluded from the metrics [samples].
    intersample : {"zoh", "foh", "bandlimited"}
        Hold for a continuous model.
    limits : (float, float), optional
        Declared range of the output sensor [output unit]: the simulation
        and prediction are clipped to it as the measurement was.
    closed_loop : bool
        The record was taken in closed loop: residuals are tested for
        independence of past inputs only (the loop correlates the rest).

    Returns
    -------
    ValidationReport
        Metrics, residual tests and the signals.

    Notes
    -----
    Memory: about 3 N × 8 bytes beyond the record: the simulated and
    predicted outputs the report keeps and the residuals (the residual
    tests centre them block by block; the report's time axis is built
    when it is first read, 1 N × 8 bytes more).  Time is linear in N
    (compiled filters; the estimated initial state is fitted on the
    samples where the free response has not died out; the fit metrics'
    sums come from the pass that makes the simulation): about 15–17 ms
    at N = 10⁶ on the reference machine, 17–20 ms on one thread
    (``benchmarks/bench_scaling.py``).
    """
    check_experiment(experiment, "experiment")
    check_option("input", input, ("u", "r"))
    # residual_analysis checks these too, but only after the simulation: refuse them first.
    if max_lag is not None:
        max_lag = as_int("max_lag", max_lag, minimum=1)
    confidence = as_float("confidence", confidence)
    if not 0.0 < confidence < 1.0:
        raise DataError(f"confidence must lie in (0, 1), e.g. 0.99, got {confidence}")
    closed_loop = as_bool("closed_loop", closed_loop)
    if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)):
        raise type_error("horizon", horizon, "an integer (samples)")
    if horizon < 1:
        raise DataError(f"horizon must be >= 1 sample, got {horizon}")
    outputs = experiment.names_of("y") if output is None else (output,)
    if len(outputs) != 1:
        experiment.signal("y")
        raise DataError(f"several outputs ({', '.join(outputs)}): pass output=<name>")
    if hasattr(model, "model") and hasattr(model, "covariance") and is_replayable(model.model):
        model = model.model  # an Estimate of a nonlinear or grey-box model
    replayable = is_replayable(model)
    if replayable:
        check_option("initial", initial, INITIALS)
        if not np.isclose(model.dt, experiment.dt, rtol=1e-9, atol=0.0):
            raise DataError(f"the model has dt = {model.dt} s but the experiment "
                            f"{experiment.dt} s; resample the data to the model's rate")
    else:
        model = _one_output(discrete_model(model, experiment.dt, intersample), experiment,
                            outputs[0])
    # ARX: the simulation, the prediction and the residuals from one compiled pass
    is_fused = (not replayable and isinstance(initial, str) and initial in ("auto", "measured")
                and is_arx(model) and has_noise_model(model))
    y = experiment[outputs[0]]
    inputs = experiment.names_of(input)
    # one input: a view of its channel shaped (N, 1) as signal() stacks it, without the copy
    u = experiment[inputs[0]][:, None] if len(inputs) == 1 else experiment.signal(input)
    if horizon >= y.size:
        raise DataError(
            f"horizon = {horizon} samples is not shorter than the {y.size}-sample validation "
            "record; a k-step prediction needs k below the record length (a few samples is usual)"
        )
    moments = stats = None  # the fit metrics' moments and the residual stats, when a pass has them
    if replayable:
        y_sim, first, initial_used = model.replay(y, u, initial=initial)
        y_sim = np.asarray(y_sim, dtype=float)
        first += int(transient)
        if y_sim.shape != y.shape or not 0 <= first < y.size - 2:
            raise ModelError(f"{type(model).__name__}.replay returned {y_sim.shape} samples "
                             f"from sample {first} for a {y.size}-sample record")
    elif is_fused:
        # the simulation, the k-step prediction and the residuals in one compiled pass
        skip = _transient(transient, y.size)
        y_sim, first, y_pred, eps, stats, moments = _arx_outputs(model, y, u, horizon, skip)
        first += skip
        initial_used = "measured"
    else:
        y_sim, first, initial_used = simulate_model(model, y, u, initial=initial,
                                                    transient=transient)
    if not has_noise_model(model):  # output error: every predictor is the simulation
        # the residuals, their sum and range and the metrics' moments in one pass
        moments, stats, e_run = _output_error_pass(y, y_sim, first)
    # finite means of y and y − y_sim from `first` on: the run is finite there
    if moments is None or not np.all(np.isfinite(moments[0, 1:3])):
        _check_finite_run(y_sim, first, model, experiment)
    if max_lag is None:
        max_lag = _default_max_lag(y.size, first, experiment.name)
    if has_noise_model(model):
        if not is_fused:
            y_pred = np.asarray(model.predict(y, u, horizon=horizon), dtype=float)
            eps = np.asarray(model.residuals(y, u), dtype=float)
        p0 = _prediction_start(first, horizon, y.size)
        e_run = eps[first:]
    else:  # output error: the predictor is the simulation, with its initial state
        y_pred, p0 = y_sim, first
    clipped = 0
    if limits is not None:
        lo, hi = _limits(limits)
        clipped = int(np.count_nonzero((y_sim[first:] < lo) | (y_sim[first:] > hi)))
        y_sim, y_pred = np.clip(y_sim, lo, hi), np.clip(y_pred, lo, hi)
        moments = None  # of the unclipped outputs
    ys, ss = y[first:], y_sim[first:]
    metrics = metric_set(ys, ss, None if moments is None else moments[0])  # the five at once
    # output error: the predictor is the simulation, from the same sample — the same fit
    same = y_pred is y_sim and p0 == first
    if same:
        prediction_fit = metrics["fit_percent"]
    elif moments is not None and moments.shape[0] > 1:
        prediction_fit = fit_of_moments(y[p0:], y_pred[p0:], moments[1])
    else:
        prediction_fit = float(fit_percent(y[p0:], y_pred[p0:]))
    return ValidationReport(
        output=outputs[0],
        time=_time_of(experiment),
        measured=y,
        simulated=y_sim,
        predicted=y_pred,
        first=first,
        fit_percent=metrics["fit_percent"],
        nrmse=metrics["nrmse"],
        rmse=metrics["rmse"],
        vaf=metrics["vaf"],
        relative_error=metrics["relative_error"],
        horizon=horizon,
        prediction_fit_percent=prediction_fit,
        residuals=analyse_residuals(e_run, u[first:], max_lag, confidence, closed_loop, stats),
        nonlinearity=_nonlinearity(e_run, u[first:], max_lag, confidence, closed_loop),
        experiment=experiment.name,
        prediction_first=p0,
        initial=initial_used,
        clipped=clipped,
        unit=experiment.unit(outputs[0]),
        noise_model=has_noise_model(model),
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
    y, u = check_signals(y, u)
    u = u.reshape(len(y), -1)
    if is_arx(model):
        from ._kernels import arx_from_data

        a = np.ascontiguousarray(model.a, dtype=float)
        bks = [np.concatenate([np.zeros(k), b]) for b, k in zip(model.b, model.nk, strict=True)]
        m = max(a.size - 1, *(bk.size - 1 for bk in bks))
        if m and m >= len(y) - 1:
            raise DataError(f"validation needs more than {m + 1} samples, got {len(y)}")
        from ..models import filter_into

        # y_sim = Σ B_i u_i, then in place A y_sim = that, with y(0…m−1) the initial conditions
        y_sim = np.empty(len(y))
        for i, bk in enumerate(bks):
            filter_into(bk, np.ones(1), u[:, i], y_sim, i > 0)
        arx_from_data(a, np.ascontiguousarray(y, dtype=float), m, y_sim)
        return y_sim, m
    return np.asarray(model.simulate(u if u.shape[1] > 1 else u[:, 0]), dtype=float), 0


def _arx_outputs(
    model: Any, y: NDArray[np.float64], u: NDArray[np.float64], horizon: int, first: int = 0
) -> tuple[NDArray[np.float64], int, NDArray[np.float64], NDArray[np.float64],
           NDArray[np.float64], NDArray[np.float64]]:
    """Simulation, k-step prediction and residuals of an ARX model, one pass.

    The same values as :func:`simulate_from_data`, ``model.predict(y, u,
    horizon)`` and ``model.residuals(y, u)`` (the same filters, summed in
    the same order), from one compiled pass over the record instead of
    six filter passes and their checks.

    Returns
    -------
    y_sim, m, y_pred, eps
        As :func:`simulate_from_data` returns them, then the prediction
        and the residuals.
    stats : ndarray, shape (1 + n_inputs, 3)
        Sum, min and max of ``eps[first + m:]`` and of each input there
        (``first``: samples skipped beyond the m initial conditions), for
        the residual tests.
    moments : ndarray, shape (2, MOMENTS)
        The fit metrics' moments of (y, y_sim) from ``first + m`` on and of
        (y, y_pred) from where the prediction is exact
        (:func:`_prediction_start`).
    """
    from ..models import all_finite
    from ._kernels import MOMENTS, arx_pass

    y, u = check_signals(y, u)
    u = u.reshape(len(y), -1)
    y = np.ascontiguousarray(y, dtype=float)
    a = np.ascontiguousarray(model.a, dtype=float)
    bks = [np.concatenate([np.zeros(k), b]) for b, k in zip(model.b, model.nk, strict=True)]
    m = max(a.size - 1, *(bk.size - 1 for bk in bks))
    if m and m >= len(y) - 1:
        raise DataError(f"validation needs more than {m + 1} samples, got {len(y)}")
    first += m
    r1, _ = model._predictor_filters(1)
    rk, terms = model._predictor_filters(int(horizon))
    n_in = len(bks)
    b_rows = np.zeros((n_in, max(bk.size for bk in bks)))
    p_rows = np.zeros((n_in, max(num.size for num, _ in terms)))
    for i, (bk, (num, _)) in enumerate(zip(bks, terms, strict=True)):
        b_rows[i, : bk.size] = bk  # trailing zero taps add exact zeros
        p_rows[i, : num.size] = num
    y_sim, y_pred, eps = np.empty(len(y)), np.empty(len(y)), np.empty(len(y))
    stats = np.zeros((1 + n_in, 3))
    stats[:, 1], stats[:, 2] = np.inf, -np.inf
    moments = np.zeros((2, MOMENTS))
    arx_pass(a, b_rows, np.ascontiguousarray(r1), np.ascontiguousarray(rk), p_rows, y,
             np.ascontiguousarray(u.T, dtype=float), m, y_sim, y_pred, eps, first, stats,
             _prediction_start(first, horizon, len(y)), moments)
    # y[first:] is finite when the mean of y there is (the moments' first mean); only then
    # does the check need no pass of its own beyond the first samples
    if not (np.isfinite(moments[0, 1]) and all_finite(y[:first])) and not all_finite(y):
        raise DataError("y must be finite")
    return y_sim, m, y_pred, eps, stats, moments


def _nonlinearity(e: NDArray[np.float64], u: NDArray[np.float64], max_lag: int,
                  confidence: float, closed_loop: bool) -> NonlinearityTests | None:
    """The higher-order tests, or None where the residuals are too few for them."""
    if u.size == 0 or e.size < 4 * max_lag + 10:
        return None
    try:
        return nonlinearity_tests(e, u, max_lag, confidence, closed_loop)
    except DataError:
        return None


def _prediction_start(first: int, horizon: int, n: int) -> int:
    """First sample of the k-step prediction the prediction fit is taken from.

    The k-step predictor takes unknown samples before the record as zero.
    For an ARX model it is an FIR in y and u reaching back k − 1 + first
    samples, so from there on it is exact, as the simulation is from
    ``first`` on (measured initial conditions).
    """
    return min(first + horizon - 1, n - 2) if first > 0 else 0


def _output_error_pass(
    y: NDArray[np.float64], y_sim: NDArray[np.float64], first: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Moments (one row), residual stats (one row) and residuals from ``first`` on."""
    from ._kernels import MOMENTS, error_pass

    y = np.ascontiguousarray(y, dtype=float)
    y_sim = np.ascontiguousarray(y_sim, dtype=float)
    moments = np.zeros((1, MOMENTS))
    stats = np.array([[0.0, np.inf, -np.inf]])
    e_run = np.empty(y.size - first)
    error_pass(y, y_sim, first, e_run, moments[0], stats)
    return moments, stats, e_run


def _transient(transient: Any, n: int) -> int:
    """``transient`` checked as :func:`simulate_model` checks it."""
    if isinstance(transient, bool) or not isinstance(transient, (int, np.integer)):
        raise type_error("transient", transient, "an integer number of samples")
    if not 0 <= transient < n - 2:
        raise DataError(f"transient must lie in [0, {n - 3}] samples for {n} samples, "
                        f"got {transient}")
    return int(transient)


def _time_of(experiment: Experiment) -> Any:
    """``experiment.time``, built when the report's ``time`` is first read."""
    return lambda: experiment.time


def _check_finite_run(y_sim: NDArray[np.float64], first: int, model: Any,
                      experiment: Experiment) -> None:
    """Refuse, by its own error, a simulation that diverged on the record."""
    from ..models import all_finite

    run = y_sim[first:]
    if run.flags.c_contiguous and all_finite(run):  # one pass, no boolean temporary
        return
    bad = np.flatnonzero(~np.isfinite(run))
    if bad.size:
        k = first + int(bad[0])
        label = f" {experiment.name!r}" if experiment.name else ""
        raise SimulationDivergedError(
            f"the free run of the {type(model).__name__} diverges on the validation "
            f"record{label} at sample {k} (t = {k * experiment.dt:.6g} s): the model is unstable "
            "in simulation there, whatever its one-step fit; try a lower order or degree, or "
            "validate on a record within the estimation data's range", k)


def _default_max_lag(n: int, first: int, name: str) -> int:
    """25 lags, or a quarter of the residuals; refuse too few residuals for any test."""
    residuals = n - first
    if residuals < _MIN_RESIDUALS:
        label = f" {name!r}" if name else ""
        skipped = (f" after the first {first} sample(s), which set the initial conditions or "
                   "are excluded as a transient" if first else "")
        raise DataError(
            f"the {n}-sample validation record{label} leaves {residuals} residual(s){skipped}: "
            f"too few for the residual tests, which need at least {_MIN_RESIDUALS}; validate "
            "on a longer record, or pass a small max_lag to test these few (from an experiment "
            "file: record a longer test, give the validation part more samples with [split] "
            "fraction or index, or name a [validation] file)"
        )
    return min(_DEFAULT_MAX_LAG, residuals // 4)


def _one_output(model: Any, experiment: Experiment, output: str) -> Any:
    """The row of a multi-output state-space model that matches ``output``."""
    n_out = getattr(model, "n_outputs", 1)
    if n_out == 1:
        return model
    names = experiment.names_of("y")
    if len(names) != n_out:
        raise DataError(f"the model has {n_out} outputs but the experiment {len(names)} "
                        f"({', '.join(names)}); give the experiment the model's outputs in order")
    k = names.index(output)
    return type(model)(model.A, model.B, model.C[k : k + 1], model.D[k : k + 1], model.dt)


def _limits(limits: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in limits)
    except (TypeError, ValueError):
        raise type_error("limits", limits, "a pair (low, high) of numbers") from None
    if not lo < hi:
        raise DataError(f"limits must be (low, high) with low < high, got {limits!r}")
    return lo, hi
