"""A user's grey-box ODE fitted by simulation error, and replayed on new records.

:func:`fit_ode` fits the free parameters and the chosen initial states of
an :class:`~servoid.estimate._ode.OdeSystem` to one record with
:func:`~servoid.estimate.fit_greybox` (bounded least squares on the
simulation error, multistart, covariance options and the identifiability
checks), passing it the system's own simulator.  Initial states to
estimate are extra parameters named ``"<state>(0)"``, bounded by the
state's clamp.

The result's model is an :class:`OdeModel`: frozen, it holds the system,
every parameter value and ``dt``, and implements
:class:`servoid.validate.Replayable` — ``replay(y, u)`` simulates a new
record from its input, with the initial states that were estimated refitted
to that record (a small bounded least squares over those states only; the
parameters stay fixed), so :func:`servoid.validate.validate` and the
workflows' ``[validation] file`` treat it as any other model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_float, type_error
from .._errors import ChannelError, DataError, ModelError, check_option
from .._lazy import optimize
from ..data import Experiment
from ._estimate import Estimate
from ._greybox import GreyboxParameter, fit_greybox
from ._ode import OdeSystem

__all__ = ["OdeModel", "fit_ode", "initial_name"]

#: residual of a diverged replay trial: finite, so the solver rejects the step
_PENALTY = 1e50
_INITIALS = ("auto", "estimate", "zero", "measured")


@dataclass(frozen=True, eq=False)
class OdeModel:
    """A fitted grey-box ODE: the system, its parameters and ``dt``.

    Attributes
    ----------
    system : OdeSystem
        The user's functions with their integrator.
    names : tuple of str
        Every model parameter (free and fixed), in the order ``p`` holds them.
    theta : ndarray
        Their values.
    states : tuple of str
        State names.
    x0 : ndarray
        Initial state of the estimation record (estimated entries fitted).
    estimated : tuple of int
        States whose initial value is refitted on each record by ``replay``.
    dt : float
        Sample period [s].
    substeps : int
        RK4 steps per sample.
    """

    system: OdeSystem
    names: tuple[str, ...]
    theta: NDArray[np.float64]
    states: tuple[str, ...]
    x0: NDArray[np.float64]
    estimated: tuple[int, ...]
    dt: float
    substeps: int = 1

    @property
    def has_noise_model(self) -> bool:
        """False: the predictor is the simulation (output error)."""
        return False

    def __getitem__(self, name: str) -> float:
        if name not in self.names:
            raise ChannelError(f"no parameter {name!r}; the model has {', '.join(self.names)}")
        return float(self.theta[self.names.index(name)])

    def simulate(self, u: Any, x0: Any = None) -> NDArray[np.float64]:
        """Output from ``x0`` (default the fitted one) under ``u``.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_inputs)
            Input, held between samples.
        x0 : array_like, optional
            Initial state (n_states,).

        Returns
        -------
        ndarray, shape (N,) or (N, n_outputs)
            The output (NaN after a divergence).
        """
        uu = self._inputs(u)
        start = self.x0 if x0 is None else as_array("x0", x0, ndim=1)
        if start.size != len(self.states):
            raise DataError(f"x0 needs {len(self.states)} values ({', '.join(self.states)}), "
                            f"got {start.size}")
        ys = self.system.simulate(start, uu, self.theta, self.dt, self.substeps)
        return ys[:, 0] if ys.shape[1] == 1 else ys

    def replay(self, y: Any, u: Any, *, initial: str = "auto") -> tuple[
            NDArray[np.float64], int, str]:
        """Free run on a new record, its initial states refitted.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output, used only for the initial states.
        u : array_like, shape (N,) or (N, n_inputs)
            Input.
        initial : {"auto", "estimate", "zero", "measured"}
            ``"auto"``/``"estimate"``: the states estimated in the fit are
            refitted to this record (bounded by their clamps), the others
            keep the declared initial state; ``"zero"``: the declared
            initial state with the estimation record's fitted values, no
            refit.  ``"measured"`` is refused (an ARX rule).

        Returns
        -------
        y_sim : ndarray, shape (N,)
            Simulated output.
        first : int
            First sample the metrics use (0).
        initial : str
            The rule applied (``"estimate"`` or ``"zero"``).
        """
        check_option("initial", initial, _INITIALS)
        if initial == "measured":
            raise ModelError('initial="measured" sets the state from past samples, which only '
                             'an ARX model allows; use initial="estimate" for this model')
        y_arr = as_array("y", y, ndim=1, min_size=2)
        uu = self._inputs(u)
        if uu.shape[0] != y_arr.size:
            raise DataError(f"u has {uu.shape[0]} samples and y {y_arr.size}; give the same "
                            "record's input and output")
        if self.system.n_outputs != 1:
            raise ModelError("the model has several outputs; replay validates one")
        x0 = self.x0.copy()
        if initial == "zero" or not self.estimated:
            return self.system.simulate(x0, uu, self.theta, self.dt, self.substeps)[:, 0], 0, \
                "zero" if initial == "zero" or not self.estimated else "estimate"
        idx = list(self.estimated)
        lo = self.system.state_lower[idx]
        hi = self.system.state_upper[idx]

        def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
            x = x0.copy()
            x[idx] = z
            with np.errstate(all="ignore"):
                r = self.system.simulate(x, uu, self.theta, self.dt, self.substeps)[:, 0] - y_arr
            r[~np.isfinite(r)] = _PENALTY
            return r

        start = np.clip(x0[idx], np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf))
        res = optimize.least_squares(residuals, start, bounds=(lo, hi), x_scale="jac",
                                     xtol=1e-10, ftol=1e-10, gtol=1e-10)
        x0[idx] = res.x
        y_sim = self.system.simulate(x0, uu, self.theta, self.dt, self.substeps)[:, 0]
        return y_sim, 0, "estimate"

    def to_dict(self) -> dict[str, Any]:
        """The model as plain data (the functions by name)."""
        return {"type": "greybox_ode", "model": self.system.source, "dt": self.dt,
                "substeps": self.substeps, "states": list(self.states),
                "parameters": dict(zip(self.names, self.theta.tolist(), strict=True)),
                "initial_state": dict(zip(self.states, self.x0.tolist(), strict=True)),
                "estimate_initial": [self.states[i] for i in self.estimated],
                "compiled": self.system.compiled}

    def _inputs(self, u: Any) -> NDArray[np.float64]:
        uu = as_array("u", u)
        uu = uu[:, None] if uu.ndim == 1 else uu
        if uu.ndim != 2 or uu.shape[1] != self.system.n_inputs:
            raise DataError(f"u must have shape (N, {self.system.n_inputs}) (one column per "
                            f"input of the model), got {uu.shape}")
        return uu


def initial_name(state: str) -> str:
    """The parameter name of a state's estimated initial value."""
    return f"{state}(0)"


def fit_ode(
    data: Experiment,
    system: OdeSystem,
    parameters: Sequence[GreyboxParameter],
    *,
    states: Sequence[str],
    output: str,
    x0: Any,
    estimate_initial: Sequence[str] = (),
    substeps: int = 1,
    covariance: str = "auto",
    multistart: int = 0,
    tol: float = 1e-10,
    max_nfev: int | None = None,
    rng: Any = None,
) -> Estimate:
    """Fit a user's ODE system to one record by simulation error.

    Parameters
    ----------
    data : Experiment
        The record: its "u" channels drive the model, ``output`` is fitted.
    system : OdeSystem
        From :func:`~servoid.estimate._ode.make_system`.
    parameters : sequence of GreyboxParameter
        The model's parameters, in the order ``p`` holds them.
    states : sequence of str
        State names.
    output : str
        The measured output channel.
    x0 : array_like
        Initial state (start values of the estimated entries).
    estimate_initial : sequence of str
        States whose initial value is estimated.
    substeps : int
        RK4 steps per sample.
    covariance : {"auto", "white", "robust", "bootstrap"}
        As :func:`~servoid.estimate.fit_greybox`.
    multistart : int
        Extra random starts.
    tol : float
        Solver tolerance.
    max_nfev : int, optional
        Most solver evaluations (default 100·(n_free + 1)).
    rng : Generator or int, optional
        Random starts and resamples.

    Returns
    -------
    Estimate
        ``model`` is an :class:`OdeModel`; the options add ``inputs``,
        ``output``, ``states``, ``compiled`` and ``integrator_note``.
    """
    if not isinstance(data, Experiment):
        raise type_error("data", data, "an Experiment")
    if not isinstance(system, OdeSystem):
        raise type_error("system", system, "an OdeSystem")
    states = tuple(states)
    x_start = as_array("x0", x0, ndim=1).copy()
    if x_start.size != len(states) or system.n_states != len(states):
        raise DataError(f"x0 needs {len(states)} values ({', '.join(states)}), got "
                        f"{x_start.size}")
    dt = as_float("dt", data.dt, positive=True, unit="s")
    u = data.u if data.u is not None else np.zeros((data.n_samples, 0))
    u = np.ascontiguousarray(np.asarray(u, dtype=float).reshape(data.n_samples, -1))
    params = list(parameters)
    n_model = len(params)
    idx = []
    for name in estimate_initial:
        if name not in states:
            raise DataError(f"estimate_initial names {name!r}, which is not a state; the states "
                            f"are {', '.join(states)}")
        k = states.index(name)
        idx.append(k)
        lo, hi = float(system.state_lower[k]), float(system.state_upper[k])
        params.append(GreyboxParameter(initial_name(name), float(np.clip(x_start[k], lo, hi)),
                                       lo, hi))
    x_base = np.clip(x_start, system.state_lower, system.state_upper)

    def split(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        x = x_base.copy()
        x[idx] = theta[n_model:]
        return theta[:n_model], x

    def simulate(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        p, x = split(theta)
        return system.simulate(x, u, p, dt, substeps)

    est = fit_greybox(data, None, None, params, simulate=simulate, outputs=[output],
                      substeps=substeps, covariance=covariance,  # type: ignore[arg-type]
                      multistart=multistart, tol=tol, max_nfev=max_nfev, rng=rng)
    theta_all = np.asarray(est.model.theta, dtype=float)
    p_fit, x_fit = split(theta_all)
    p_fit = p_fit.copy()
    p_fit.setflags(write=False)
    x_fit.setflags(write=False)
    model = OdeModel(system, tuple(p.name for p in params[:n_model]), p_fit, states, x_fit,
                     tuple(idx), dt, substeps)
    options = {**est.options, "input": "u", "inputs": list(data.names_of("u")),
               "output": output, "states": list(states), "integrator": "rk4",
               "compiled": system.compiled, "integrator_note": system.note,
               "model": system.source}
    return dataclasses.replace(est, model=model, options=options)
