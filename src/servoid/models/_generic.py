"""One door for every model: frequency response, Bode data and simulation.

servoid's estimators return polynomial models, transfer functions, state
space, innovation models or an :class:`~servoid.estimate.Estimate` of one;
users bring python-control and scipy.signal systems.  :func:`as_lti` turns
any of them into a servoid :class:`TransferFunction`, :class:`StateSpace` or
:class:`PolynomialModel`, and :func:`freqresp`, :func:`bode` and
:func:`simulate` work on that, so none of them asks which kind it was given.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_int, type_error
from .._errors import DataError, ModelError
from ._frd import FrequencyResponseData
from ._polynomial import PolynomialModel
from ._statespace import StateSpace
from ._transfer import TransferFunction

__all__ = ["as_lti", "bode", "freqresp", "simulate"]

Lti = TransferFunction | StateSpace | PolynomialModel
_POINTS = 400
_KINDS = ("a TransferFunction, StateSpace, PolynomialModel, an Estimate of one, or a "
          "python-control / scipy.signal system")


def as_lti(model: Any) -> Lti:
    """Return any linear model as a servoid LTI model.

    Parameters
    ----------
    model : model, Estimate or foreign system
        A servoid TransferFunction, StateSpace or PolynomialModel; an
        Estimate or an InnovationModel of one (its ``model``); a
        python-control or scipy.signal system.

    Returns
    -------
    TransferFunction, StateSpace or PolynomialModel
        The same model; foreign systems are converted.

    Raises
    ------
    ModelError
        For a measured response or a nonlinear model, with what to do.
    """
    for _ in range(3):  # Estimate → InnovationModel → StateSpace at most
        if isinstance(model, (TransferFunction, StateSpace, PolynomialModel)):
            return model
        if isinstance(model, FrequencyResponseData):
            raise ModelError("a measured frequency response has no dynamics to simulate or "
                             "evaluate between its lines; fit a model to it first "
                             "(servoid.estimate.fit_frf)")
        if callable(getattr(model, "replay", None)):
            raise ModelError(f"{type(model).__name__} is a nonlinear model: it has no transfer "
                             "function; simulate it with its own simulate()/replay() or "
                             "servoid.validate.validate")
        inner = getattr(model, "model", None)
        if inner is None:
            break
        model = inner
    module = type(model).__module__.split(".")[0]
    if module == "control":
        from ._interop import from_control

        return from_control(model)
    if module == "scipy":
        from ._interop import from_scipy

        return from_scipy(model)
    raise type_error("model", model, _KINDS)


def freqresp(model: Any, omega: ArrayLike, *, input: int = 0,
             output: int = 0) -> NDArray[np.complex128]:
    """Return G(jω) (or G(e^{jω·dt})) of any linear model.

    Parameters
    ----------
    model : model, Estimate or foreign system
        See :func:`as_lti`.
    omega : array_like, shape (N,)
        Angular frequencies [rad/s].
    input, output : int
        Channel of a multi-input or multi-output model.

    Returns
    -------
    ndarray of complex, shape (N,)
        The response from `input` to `output`.
    """
    lti = as_lti(model)
    w = as_array("omega", omega).ravel()
    i = as_int("input", input, minimum=0)
    o = as_int("output", output, minimum=0)
    if isinstance(lti, PolynomialModel):
        if i >= lti.n_inputs:
            raise DataError(f"input = {i} but the model has {lti.n_inputs} input(s)")
        lti = lti.transfer_function(i)
        i = 0
    if isinstance(lti, StateSpace):
        if i >= lti.n_inputs or o >= lti.n_outputs:
            raise DataError(f"input = {i}, output = {o} but the model has {lti.n_inputs} "
                            f"input(s) and {lti.n_outputs} output(s)")
        g = np.asarray(lti.freqresp(w))
        return np.asarray(g if g.ndim == 1 else g[:, o, i], dtype=np.complex128)
    if i or o:
        raise DataError("a TransferFunction has one input and one output: use input = 0, "
                        "output = 0")
    return np.asarray(lti.freqresp(w), dtype=np.complex128).ravel()


def bode(model: Any, frequency: ArrayLike | None = None, *, input: int = 0,
         output: int = 0) -> FrequencyResponseData:
    """Return any linear model's frequency response, ready to plot.

    Parameters
    ----------
    model : model, Estimate or foreign system
        See :func:`as_lti`; a :class:`FrequencyResponseData` is returned
        as it is.
    frequency : array_like, optional
        Frequencies [Hz], >= 0 and increasing.  Default: 400 points,
        logarithmic, from a decade below the slowest pole or zero to a
        decade above the fastest (a discrete model stops at its Nyquist
        frequency).
    input, output : int
        Channel of a multi-input or multi-output model.

    Returns
    -------
    FrequencyResponseData
        ``frequency`` [Hz], complex ``response``, ``magnitude_db`` and
        ``phase_deg``; ``method = "model"``.  For ±σ bands of an Estimate
        use :func:`servoid.estimate.frequency_band`.

    Examples
    --------
    >>> from servoid.models import TransferFunction, bode
    >>> b = bode(TransferFunction([10.0], [1.0, 10.0]), [0.0, 10.0 / (2 * 3.141592653589793)])
    >>> [round(x, 2) for x in b.magnitude_db]
    [0.0, -3.01]
    """
    if isinstance(model, FrequencyResponseData):
        return model
    lti = as_lti(model)
    nyquist = None if lti.dt is None else 0.5 / lti.dt
    if frequency is None:
        f = _default_grid(lti, nyquist)
    else:
        f = as_array("frequency", frequency).ravel()
        if f.size == 0 or np.any(f < 0) or np.any(np.diff(f) <= 0):
            raise DataError("frequency must be >= 0 Hz and strictly increasing")
        if nyquist is not None and f[-1] > nyquist * (1 + 1e-9):
            raise DataError(f"frequency reaches {f[-1]:g} Hz, above the model's Nyquist "
                            f"frequency {nyquist:g} Hz (dt = {lti.dt} s)")
    with np.errstate(divide="ignore", invalid="ignore"):
        g = freqresp(lti, 2 * np.pi * f, input=input, output=output)
    if not np.all(np.isfinite(g)):
        raise ModelError("the response is infinite at some of these frequencies (a pole on the "
                         "axis, such as an integrator at 0 Hz); leave those frequencies out")
    return FrequencyResponseData(f, g, dt=lti.dt, method="model")


def simulate(model: Any, u: ArrayLike, *, dt: float | None = None,
             x0: ArrayLike | None = None) -> NDArray[np.float64]:
    """Return any model's output for input ``u``, from rest or ``x0``.

    Parameters
    ----------
    model : model, Estimate or foreign system
        See :func:`as_lti`; a nonlinear model with its own
        ``simulate(u)`` (NARX, block-oriented) is simulated by it.
    u : array_like, shape (N,) or (N, n_inputs)
        Input samples.
    dt : float, optional
        Sample period [s]: required for a continuous model (discretised
        with a zero-order hold, exact for a staircase input), equal to the
        model's for a discrete one.
    x0 : array_like, optional
        Initial state of a state-space model; zero by default.

    Returns
    -------
    ndarray, shape (N,) or (N, n_outputs)
        The simulated output.
    """
    if dt is not None:
        dt = as_float("dt", dt, positive=True, unit="s")
    if callable(getattr(model, "replay", None)) and callable(getattr(model, "simulate", None)):
        if x0 is not None:
            raise ModelError(f"x0 is for state-space models; {type(model).__name__} takes its "
                             "initial conditions in its own simulate()")
        return np.asarray(model.simulate(as_array("u", u)), dtype=float)
    lti = as_lti(model)
    if lti.dt is None and dt is None:
        raise DataError("the model is continuous: pass dt, the sample period of u [s]")
    if lti.dt is not None and dt is not None and not np.isclose(lti.dt, dt, rtol=1e-9):
        raise DataError(f"the model is discrete with dt = {lti.dt} s, not {dt} s; convert it "
                        "with d2c/c2d first")
    if isinstance(lti, StateSpace):
        return lti.simulate(u, x0=x0, dt=dt if lti.dt is None else None)
    if x0 is not None:
        raise ModelError("x0 is for state-space models; convert with to_ss() first, or use "
                         "PolynomialModel.simulate(u, y_init=…, u_init=…)")
    if isinstance(lti, PolynomialModel):
        return lti.simulate(u)
    return lti.simulate(u, dt=dt if lti.dt is None else None)


def _default_grid(lti: Lti, nyquist: float | None) -> NDArray[np.float64]:
    tf = lti.transfer_function(0) if isinstance(lti, PolynomialModel) else lti
    roots = np.concatenate([np.asarray(tf.poles()).ravel(),
                            np.asarray(tf.zeros()).ravel() if hasattr(tf, "zeros") else []])
    if lti.dt is not None:  # map z-plane roots to s-plane for their frequencies
        roots = roots[np.abs(roots) > 1e-12]
        roots = np.log(roots.astype(complex)) / lti.dt
    w = np.abs(roots[np.isfinite(roots)])
    w = w[w > 1e-9]
    lo, hi = (w.min() / 10, w.max() * 10) if w.size else (0.1, 1000.0)
    f_lo, f_hi = lo / (2 * np.pi), hi / (2 * np.pi)
    if nyquist is not None:
        f_hi = nyquist
        f_lo = min(f_lo, nyquist / 1000)
    f_lo = max(f_lo, f_hi * 1e-6)
    return np.logspace(np.log10(f_lo), np.log10(f_hi), _POINTS)
