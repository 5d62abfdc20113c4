"""Simulating any identified model on a record: discretisation and initial state.

A fair comparison of a model with a measurement (MATLAB's ``compare``)
simulates it from the input alone, at the record's sample rate, from the
initial state that best explains the start of the record — otherwise a
slow model is judged by its start-up transient, not its dynamics.

- A continuous model is discretised at the record's ``dt`` with the hold
  that matches the logged input: ``"zoh"`` for a staircase (a DAC), ``"foh"``
  (also ``"bandlimited"``) for a smooth input.
- ``initial="estimate"``: the free responses of the model's n states are
  fitted to the record by linear least squares together with the forced
  response (the output is linear in the initial state).
- ``initial="measured"``: an ARX model takes its initial conditions from
  the first measured samples, which are then excluded from the metrics.
- ``initial="zero"``: from rest; ``transient`` samples may be excluded.
"""

from __future__ import annotations

from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_float, type_error
from .._errors import DataError, ModelError, check_option

__all__ = ["INITIALS", "INTERSAMPLES", "Initial", "Intersample", "Replayable", "discrete_model",
           "has_noise_model", "is_arx", "is_replayable", "simulate_model"]

Initial = Literal["auto", "estimate", "zero", "measured"]
Intersample = Literal["zoh", "foh", "bandlimited"]
INITIALS: tuple[Initial, ...] = ("auto", "estimate", "zero", "measured")
#: Fraction of its peak below which an impulse response has died out (free responses).
_DECAYED = 1e-20
INTERSAMPLES: tuple[Intersample, ...] = ("zoh", "foh", "bandlimited")


@runtime_checkable
class Replayable(Protocol):
    """A model that brings its own free run (nonlinear, grey-box).

    Linear models are discretised and simulated here; a model of any other
    kind (NARX, block-oriented, a grey-box ODE) brings its own free run.
    ``validate``, ``compare`` and the workflows' validation records then
    treat it as they treat a linear model.
    """

    dt: float

    def replay(self, y: NDArray[np.float64], u: NDArray[np.float64], *,
               initial: Initial = "auto") -> tuple[NDArray[np.float64], int, str]:
        """Free-run simulation on input ``u`` (N,) or (N, n_inputs).

        ``y`` (N,) is the measured output, used only for the initial state.
        Returns the simulated output (N,), the first sample the metrics
        use, and the initial-state rule applied.
        """


def is_replayable(model: Any) -> bool:
    """Return True for a model with its own free run (``replay``)."""
    return callable(getattr(model, "replay", None)) and hasattr(model, "dt")


def discrete_model(model: Any, dt: float, intersample: Intersample = "zoh") -> Any:
    """Return ``model`` as a discrete model at ``dt``.

    Parameters
    ----------
    model : PolynomialModel, TransferFunction, StateSpace or Estimate
        An identified model (an Estimate's model is used, with its
        ``intersample`` option when it was fitted in continuous time), or
        a python-control / scipy.signal system.
    dt : float
        Sample period of the record [s].
    intersample : {"zoh", "foh", "bandlimited"}
        Hold used to discretise a continuous model.

    Returns
    -------
    PolynomialModel, TransferFunction or StateSpace
        Discrete at ``dt``.
    """
    from ..models import PolynomialModel, StateSpace, TransferFunction, c2d

    check_option("intersample", intersample, INTERSAMPLES)
    dt = as_float("dt", dt, positive=True, unit="s")
    if hasattr(model, "model") and hasattr(model, "covariance"):  # an Estimate
        intersample = model.options.get("intersample", intersample)
        model = model.model
    if not isinstance(model, (PolynomialModel, TransferFunction, StateSpace)):
        from ..models import as_lti  # python-control, scipy.signal, an InnovationModel

        model = as_lti(model)
    if model.dt is None:
        method = "zoh" if intersample == "zoh" else "foh"
        return c2d(model, dt, method)
    if not np.isclose(model.dt, dt, rtol=1e-9, atol=0.0):
        raise DataError(
            f"the model has dt = {model.dt} s but the experiment {dt} s; "
            "resample the data or discretise the model at the data rate"
        )
    return model


def is_arx(model: Any) -> bool:
    """Return True for a polynomial model with only A and B."""
    if not all(hasattr(model, n) for n in ("a", "b", "nk", "f", "c", "d")):
        return False
    trivial = [np.asarray(model.c), np.asarray(model.d), *map(np.asarray, model.f)]
    return all(p.size == 1 for p in trivial)


def has_noise_model(model: Any) -> bool:
    """Return True unless the one-step predictor is the simulation (H = 1)."""
    if is_replayable(model):
        return bool(getattr(model, "has_noise_model", False))
    if not hasattr(model, "c"):  # transfer functions and state space: output error
        return False
    return any(np.asarray(p).size > 1 for p in (model.a, model.c, model.d))


def simulate_model(
    model: Any,
    y: NDArray[np.float64],
    u: NDArray[np.float64],
    *,
    initial: Initial = "auto",
    transient: int = 0,
) -> tuple[NDArray[np.float64], int, str]:
    """Simulate a discrete model from a chosen initial state.

    Parameters
    ----------
    model : PolynomialModel, TransferFunction or StateSpace
        Discrete, at the record's rate (see :func:`discrete_model`); one output.
    y : ndarray, shape (N,)
        Measured output (used only for the initial state).
    u : ndarray, shape (N,) or (N, n_inputs)
        Input.
    initial : {"auto", "estimate", "zero", "measured"}
        ``"auto"``: measured for an ARX model, else estimated.
    transient : int
        Samples at the start excluded from the metrics [samples] (added
        to those a measured initial condition uses).

    Returns
    -------
    y_sim : ndarray, shape (N,)
        Simulated output (equal to the measurement before ``first`` for
        measured initial conditions).
    first : int
        First sample the metrics use.
    initial : str
        The initial-state rule applied.
    """
    from ._report import simulate_from_data

    check_option("initial", initial, INITIALS)
    if not callable(getattr(model, "simulate", None)) or not hasattr(model, "dt"):
        raise type_error("model", model, "a discrete PolynomialModel, TransferFunction or "
                         "StateSpace (see discrete_model)")
    y, u = check_signals(y, u)
    if isinstance(transient, bool) or not isinstance(transient, (int, np.integer)):
        raise type_error("transient", transient, "an integer number of samples")
    if not 0 <= transient < y.size - 2:
        raise DataError(f"transient must lie in [0, {y.size - 3}] samples for {y.size} samples, "
                        f"got {transient}")
    if initial == "auto":
        initial = "measured" if is_arx(model) else "estimate"
    if initial == "measured":
        if not is_arx(model):
            raise ModelError('initial="measured" sets the state from past samples, which only an '
                             'ARX model allows; use initial="estimate" for this model')
        y_sim, first = simulate_from_data(model, y, u)
        return y_sim, first + int(transient), "measured"
    uu = u if u.ndim == 1 or u.shape[1] > 1 else u[:, 0]
    forced = np.asarray(model.simulate(uu), dtype=float)
    if forced.ndim != 1:
        raise ModelError("the model has several outputs; validate one output at a time")
    if initial == "zero":
        return forced, int(transient), "zero"
    free = _free_responses(model, y.size)
    if free.shape[1] == 0:
        return forced, int(transient), "estimate"
    rows = free.shape[0]  # the free responses vanish (below 1e-20 of their peak) after these
    if not (np.all(np.isfinite(free)) and np.all(np.isfinite(forced[:rows]))):
        # an unstable model's run leaves the floats: no initial state can be fitted to it,
        # and the caller names the divergence from the run itself
        return forced, int(transient), "zero"
    try:
        x0, *_ = np.linalg.lstsq(free, y[:rows] - forced[:rows], rcond=None)
    except np.linalg.LinAlgError:  # free responses too far apart in scale to solve for x(0)
        return forced, int(transient), "zero"
    if not forced.flags.writeable:  # a model may hand out a read-only result
        forced = forced.copy()
    forced[:rows] += free @ x0
    return forced, int(transient), "estimate"


def check_signals(y: object, u: object) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``y`` (N,) and ``u`` (N,) or (N, n_inputs) as float arrays, shapes checked."""
    y_arr = as_array("y", y, ndim=1, min_size=2, finite=False)
    u_arr = as_array("u", u, finite=False)
    if u_arr.ndim not in (1, 2) or u_arr.shape[0] != y_arr.size:
        raise DataError(f"u must have shape ({y_arr.size},) or ({y_arr.size}, n_inputs) to match "
                        f"y, got {u_arr.shape}")
    return y_arr, u_arr


def _free_responses(model: Any, n: int) -> NDArray[np.float64]:
    """Return (T, n_states) independent free responses of the model's output.

    For a transfer function or polynomial model the free responses are the
    lags 0…n−1 of the impulse response h of 1/den (the state ``zi = e_j`` of
    ``lfilter``'s transposed direct form starts h at lag j).  They are cut
    at T <= N samples once h has stayed below 1e-20 of its peak for n
    samples: the rows after T would change neither the least-squares fit
    nor the simulation in double precision, and a stable model then costs
    O(T·n) instead of an N × n matrix.  A state-space model keeps all N rows.
    """
    from ..models import StateSpace

    if isinstance(model, StateSpace):
        states = model.n_states
        zero = np.zeros((n, model.n_inputs))
        cols = [np.asarray(model.simulate(zero, x0=np.eye(states)[j]), dtype=float)
                for j in range(states)]
        return np.column_stack(cols) if cols else np.empty((n, 0))
    from ._kernels import decay_length, impulse

    den = _denominator(model)
    order = den.size - 1
    if order == 0:
        return np.empty((n, 0))
    den = np.ascontiguousarray(den / den[0])  # lfilter normalises by a[0]; zi is taken as is
    rows = int(decay_length(den, n, _DECAYED))
    h = impulse(den, rows)
    free = np.zeros((rows, order))
    for j in range(order):
        free[j:, j] = h[: rows - j]
    return free


def _denominator(model: Any) -> NDArray[np.float64]:
    """Return the simulation's denominator in q⁻¹ (its n coefficients give n states)."""
    if hasattr(model, "_common_denominator"):  # PolynomialModel: A·ΠF_i
        den = model._common_denominator()[0]
    else:  # discrete TransferFunction in z: same coefficients read in q⁻¹
        den = np.asarray(model.den, dtype=float)
    return np.asarray(den, dtype=float)
