"""Two-step indirect and direct approaches built on ARX (spec §1.5, §3.3–3.4)."""

from __future__ import annotations

import dataclasses
import warnings
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float
from ..._errors import DataError, ModelError, OptionError, ServoidWarning, check_option
from ..._lazy import signal as sps
from ...closedloop import check_name
from ...data import Experiment, ExperimentSet, as_segments
from ...estimate import fit_arx, fit_tf_greybox
from ...models import TransferFunction
from ._loop import PARAMETER_NAMES, PARAMETER_UNITS, FeedbackLoop, plant_of_theta, tustin
from ._onestep import _check_loop, _check_theta0, _require_reference, greybox_result
from ._physical import anchors_of, to_continuous, two_step_result, values_of
from ._result import ClosedLoopResult

__all__ = ["fit_direct", "fit_indirect"]

Estimator = Literal["arx", "oe"]
InputSource = Literal["auto", "measured", "loop"]


def fit_indirect(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop,
    na: int = 3,
    nb: int = 4,
    nk: int = 0,
    *,
    output: str | None = None,
    prefilter: float | None = None,
    integrator_tol: float = 0.1,
    cancel_tol: float | None = None,
    step: float = 0.01,
) -> ClosedLoopResult:
    """Identify the plant in its loop by the two-step indirect method.

    Step 1 fits the closed loop ``H = B/A`` from (r, y) by ARX; step 2
    solves ``G0 = B/(c·A − F·B)`` (a dynamic F is Tustin-discretised at
    the data dt), maps it to s by the Tustin d2c and factorises it into K,
    ω_hp and δ_hp (spec §3.4). Their covariance is the ARX covariance
    propagated by the delta method.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the reference r and the output y.
    loop : FeedbackLoop
        Known forward gain c and feedback F.
    na, nb, nk : int
        ARX orders of the closed loop; the Tustin image of the reduced
        EHSA loop needs (3, 4, 0) (3 + deg F poles for a dynamic F).
    output : str, optional
        Output channel name when there are several.
    prefilter : float, optional
        Cut-off [Hz] of a zero-phase 4th-order Butterworth low-pass applied
        to r and y alike before the ARX fit (H is unchanged). It removes
        the out-of-band output noise that biases ARX strongly (spec §3.4
        warning); the covariance then assumes white residuals and is
        optimistic. Put it at the upper edge of the excitation band.
    integrator_tol : float
        |s₀| [rad/s] beyond which (and beyond 3σ) the integrator is flagged.
    cancel_tol : float, optional
        Relative distance under which a zero cancels a pole of G0(s);
        default 1e-3 for a dynamic F (its poles cancel), none otherwise.
    step : float
        Delta-method step [standard deviations along each principal axis].

    Returns
    -------
    ClosedLoopResult
        ``approach = "indirect"``; ``source`` is the closed-loop ARX fit.

    Raises
    ------
    DataError
        No reference channel, or too few samples for the orders.
    """
    _check_loop(loop)
    _require_reference(data, "indirect")
    _check_positive("step", step)
    integrator_tol = as_float("integrator_tol", integrator_tol, nonneg=True)
    if cancel_tol is not None:
        cancel_tol = as_float("cancel_tol", cancel_tol, nonneg=True)
    dt = as_segments(data)[0].dt
    if prefilter is not None:
        data = _lowpass(data, prefilter, output)
    with warnings.catch_warnings():
        # fit_arx's hint about open-loop drift misleads here; the pole report explains instead
        warnings.filterwarnings("ignore", "the estimated model is unstable", ServoidWarning)
        arx = fit_arx(data, na, nb, nk, input="r", output=output)
    if prefilter is not None:
        arx = dataclasses.replace(arx, options={**arx.options, "prefilter_hz": prefilter})

    def plant_of(theta: NDArray[np.float64]) -> TransferFunction:
        if loop.is_static:  # B/(c·A − F·B) from the arrays: one TransferFunction, not three
            a, b = _arx_arrays(theta, na, nk)
            den = loop.c * a - float(loop.F) * b  # type: ignore[arg-type]
            if not np.any(den):
                raise ModelError("c·A − F·B vanishes identically: the closed loop equals c/F")
            return TransferFunction(b, den, dt, "tustin")
        return loop.plant_from(_arx_tf(theta, na, nk, dt))

    if cancel_tol is None and not loop.is_static:
        cancel_tol = 1e-3
    return two_step_result(
        "indirect", arx, _arx_tf(arx.parameters, na, nk, dt), plant_of, loop,
        integrator_tol=integrator_tol, cancel_tol=cancel_tol, step=step,
    )


def fit_direct(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop | None = None,
    na: int = 3,
    nb: int = 4,
    nk: int = 0,
    *,
    estimator: Estimator = "arx",
    input_source: InputSource = "auto",
    theta0: NDArray[np.float64] | None = None,
    output: str | None = None,
    integrator_tol: float = 0.1,
    step: float = 0.01,
) -> ClosedLoopResult:
    """Identify the plant from its own input u and output y.

    u is the measured plant input, or ``u = c·r − F·y`` formed from the
    reference and the known loop. ARX (or the grey-box OE on the reduced
    model) then fits G0 directly; d2c and factorisation follow spec §3.4.
    Under feedback the noise reaches u, so the direct OE is biased unless
    the noise model is right; ARX is consistent for equation-error noise.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with y and either u or r.
    loop : FeedbackLoop, optional
        Known loop; needed to form u from r and to report the closed loop.
    na, nb, nk : int
        ARX orders of the plant (estimator "arx"; also the OE start).
    estimator : {"arx", "oe"}
        ARX, or output error on ``Tustin(G_simple(θ))`` started from ARX.
    input_source : {"auto", "measured", "loop"}
        Take the measured u, form it from the loop, or ``"auto"``: the
        measured u if there is one.
    theta0 : array_like, optional
        OE start (K, ω_hp, δ_hp); default the ARX estimate.
    output : str, optional
        Output channel name when there are several.
    integrator_tol : float
        |s₀| [rad/s] beyond which (and beyond 3σ) the integrator is flagged.
    step : float
        Delta-method step [standard deviations along each principal axis].

    Returns
    -------
    ClosedLoopResult
        ``approach = "direct"``; ``closed_loop`` and ``loop`` are None
        without a loop.
    """
    check_option("estimator", estimator, ("arx", "oe"))
    check_option("input_source", input_source, ("auto", "measured", "loop"))
    if loop is not None:
        _check_loop(loop)
    _check_positive("step", step)
    integrator_tol = as_float("integrator_tol", integrator_tol, nonneg=True)
    output = check_name("output", output)
    plant_data = _plant_data(data, loop, input_source, output)
    dt = as_segments(data)[0].dt
    with warnings.catch_warnings():
        # an integrating plant is "unstable" to fit_arx; the pole report judges it
        warnings.filterwarnings("ignore", "the estimated model is unstable", ServoidWarning)
        arx = fit_arx(plant_data, na, nb, nk, input="u", output=output)

    def plant_of(theta: NDArray[np.float64]) -> TransferFunction:
        return _arx_tf(theta, na, nk, dt)

    def close(plant: TransferFunction) -> TransferFunction | None:
        return None if loop is None else loop.close(plant)

    if estimator == "arx":
        plant = plant_of(arx.parameters)
        return two_step_result(
            "direct", arx, close(plant), plant_of, loop, integrator_tol=integrator_tol,
            cancel_tol=None, step=step,
        )
    if theta0 is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = two_step_result(
                "direct", arx, close(plant_of(arx.parameters)), plant_of, loop,
                integrator_tol=integrator_tol, cancel_tol=None, step=step,
            )
        theta0 = start.estimate.parameters
    theta = _check_theta0(theta0)

    def model_fn(t: NDArray[np.float64]) -> TransferFunction:
        return tustin(plant_of_theta(t), dt)

    est = fit_tf_greybox(
        plant_data, model_fn, theta, PARAMETER_NAMES, PARAMETER_UNITS, input="u", output=output,
        transform=("log", "log", "none"), method_name="direct",
    )
    return greybox_result("direct", est, loop, dt, close(est.model), integrator_tol)


def _plant_data(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop | None,
    source: InputSource,
    output: str | None,
) -> Experiment | ExperimentSet:
    segments = as_segments(data)
    has_u = bool(segments[0].names_of("u"))
    if source == "measured" or (source == "auto" and has_u):
        if not has_u:
            segments[0].signal("u")  # a DataError naming what exists
        return data
    if loop is None:
        raise DataError(
            "the direct approach needs the plant input u: the experiment has no 'u' channel, "
            "so pass loop=FeedbackLoop(c, F) to form u = c·r − F·y from the reference"
        )
    formed = []
    for seg in segments:
        if not seg.names_of("r"):
            seg.signal("r")
        outputs = seg.names_of("y")
        if not outputs:
            seg.signal("y")
        y_name = output or outputs[0]
        y = seg[y_name]
        u = loop.plant_input(seg.signal("r")[:, 0], y, seg.dt)
        formed.append(
            Experiment.from_arrays(seg.dt, u=u, y=y, names={"y": y_name}, t0=seg.t0,
                                   name=seg.name)
        )
    return formed[0] if isinstance(data, Experiment) else ExperimentSet(tuple(formed))


def indirect_theta(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop,
    output: str | None,
    prefilter: float | None,
) -> NDArray[np.float64]:
    """Return (K, ω, δ) of ARX(3, 4, 0) + indirect, without covariance or report."""
    if prefilter is not None:
        data = _lowpass(data, prefilter, output)
    dt = as_segments(data)[0].dt
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arx = fit_arx(data, 3, 4, 0, input="r", output=output)
    plant_c = to_continuous(loop.plant_from(_arx_tf(arx.parameters, 3, 0, dt)))
    anchors = anchors_of(plant_c, None if loop.is_static else 1e-3)
    return values_of(plant_c, anchors)[:3]


def _lowpass(
    data: Experiment | ExperimentSet, cutoff: float, output: str | None
) -> Experiment | ExperimentSet:
    segments = as_segments(data)
    nyquist = 0.5 / segments[0].dt
    cutoff = as_float("prefilter", cutoff, finite=False)
    if not 0.0 < cutoff < nyquist:
        raise OptionError(f"prefilter must lie in (0, {nyquist:g}) Hz (Nyquist), got {cutoff!r}")
    sos = sps.butter(4, cutoff, fs=2.0 * nyquist, output="sos")
    out = []
    for seg in segments:
        outputs = seg.names_of("y")
        if not outputs:
            seg.signal("y")
        y_name = output or outputs[0]
        r_f = sps.sosfiltfilt(sos, seg.signal("r")[:, 0])
        y_f = sps.sosfiltfilt(sos, seg[y_name])
        out.append(Experiment.from_arrays(seg.dt, r=r_f, y=y_f, names={"y": y_name},
                                          t0=seg.t0, name=seg.name))
    return out[0] if isinstance(data, Experiment) else ExperimentSet(tuple(out))


def _arx_tf(theta: NDArray[np.float64], na: int, nk: int, dt: float) -> TransferFunction:
    """Return ``B(q⁻¹)/A(q⁻¹)`` as a z-domain transfer function (Tustin-tagged)."""
    az, bz = _arx_arrays(theta, na, nk)
    return TransferFunction(bz, az, dt, "tustin")


def _arx_arrays(theta: NDArray[np.float64], na: int,
                nk: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``A`` and ``B`` of an ARX θ padded to one length (descending powers of z)."""
    a = np.concatenate([[1.0], theta[:na]])
    b = np.concatenate([np.zeros(nk), theta[na:]])
    n = max(a.size, b.size)
    return (np.concatenate([a, np.zeros(n - a.size)]),
            np.concatenate([b, np.zeros(n - b.size)]))


def _check_positive(name: str, value: float) -> None:
    if not as_float(name, value, finite=False) > 0:
        raise OptionError(f"{name} must be > 0, got {value!r}")
