"""Step S6 and grey-box refinement: simulate the full model on a record.

* :func:`simulate_record` runs :func:`~servoid.plants.pneumatic.simulate_pneumatic`
  on a record's own input — in closed loop from its reference ``x_ref``
  with the known (or reconstructed) :class:`PositionController`, else
  open loop from ``u`` — starting from the measured first sample.
* :func:`compare_record` is step S6 ([S2] §6.2, Figs 18–19): predicted
  vs measured p_I, p_II, ṁ_I, ṁ_II, x_k with the fit per channel.  The
  predicted flows are clipped to the sensor range before the comparison,
  since the measured ones cannot exceed it.
* :func:`refine_parameters` fits all identified parameters, or a subset
  with the rest fixed, by output error on measured outputs with the
  compiled simulator (:func:`~servoid.estimate.fit_greybox` with
  ``simulate=``, bounded trust-region, log-transformed positive
  parameters, channels weighted by their noise level), with the
  covariance chosen by ``covariance=`` (robust by default: one residual
  AR model per channel) and the identifiability checks of
  :func:`~servoid.estimate.check_identifiability`.  The Jacobian is
  differenced over 1e-4 of each parameter, not √ε: the simulator's
  outputs jump with its switching events (a stick–slip transition moving
  by a sample), and a √ε step left the noisy P4 refinement of (c_k, κ) 4 %
  off with a std 100× too small, its cost curvature 1e-6 of 2JᵀJ (the
  diagnostics' "not quadratic" flag); with 1e-4 it converges within
  1.4σ (c_k) and the curvature agrees within 25 %.  A trial point
  whose simulation fails (a pressure leaves (0, ∞), an invalid parameter
  set) returns NaN, which fit_greybox penalises; if the optimum itself
  diverges it raises :class:`~servoid.ConvergenceError` — never a silent
  number.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float, as_float_list, as_instance, as_int, as_mapping, as_str, as_str_list
from ..._errors import DataError, ModelError, OptionError
from ...data import Experiment
from ...estimate import Estimate, GreyboxCovariance, GreyboxParameter, fit_greybox, lstsq
from ...validate import fit_percent
from ._params import PneumaticParameters
from ._sim import PositionController, simulate_pneumatic
from ._steps import MDOT_LIMIT, channel, check_params, check_positive, check_record

__all__ = [
    "REFINABLE",
    "RecordComparison",
    "RefinementResult",
    "compare_record",
    "estimate_controller",
    "refine_parameters",
    "simulate_record",
]

#: Parameters the multi-step scheme identifies, in report order.
REFINABLE: tuple[str, ...] = ("k_v", "xi_v", "omega_v", "kappa", "R", "p_krit", "ad_1", "ad_2",
                              "ad_3", "ad_4", "v_krit", "d_k", "c_k", "F_haft")
UNITS: dict[str, str] = {"k_v": "m/V", "xi_v": "-", "omega_v": "rad/s", "kappa": "-",
                         "R": "J/(kg·K)", "p_krit": "-", "ad_1": "m", "ad_2": "m", "ad_3": "m",
                         "ad_4": "m", "v_krit": "m/s", "d_k": "N", "c_k": "N·s/m",
                         "F_haft": "N"}
_COMPARED = ("p_I", "p_II", "mdot_I", "mdot_II", "x_k")
_SIM_FIELD = {"p_I": "p_I", "p_II": "p_II", "mdot_I": "m_dot_I", "mdot_II": "m_dot_II",
              "x_k": "x_k", "x_v": "x_v"}
#: Relative difference step of the refinement's Jacobian: above the simulator's switching
#: jitter (measured on the P4 sine record: the x_k, p_I, p_II sensitivity to c_k is constant
#: from 1e-9 to 1e-5 relative and ×4.4 from 1e-4; to κ ×6 from 1e-5), below any physical scale.
_DIFF_STEP = 1e-4
_DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {"kappa": (1.01, 2.0), "p_krit": (0.0, 0.95),
                                                   "xi_v": (1e-3, 5.0)}


@dataclass(frozen=True, eq=False)
class RecordComparison:
    """Predicted vs measured channels of one record (step S6).

    Attributes
    ----------
    record : str
        Record name.
    t : ndarray, shape (N,)
        Time [s].
    measured, predicted : mapping of str to ndarray
        Channels by name (p_I, p_II, mdot_I, mdot_II, x_k).
    fit : mapping of str to float
        Fit 100(1 − ‖y − ŷ‖/‖y − ȳ‖) [%] per channel.
    closed_loop : bool
        Simulated in closed loop from the reference.
    controller : PositionController or None
        The controller used in closed loop.
    notes : tuple of str
        Remarks (e.g. a controller reconstructed from the record).
    """

    record: str
    t: NDArray[np.float64]
    measured: Mapping[str, NDArray[np.float64]]
    predicted: Mapping[str, NDArray[np.float64]]
    fit: Mapping[str, float]
    closed_loop: bool
    controller: PositionController | None
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (fit per channel, no time series)."""
        return {"record": self.record, "fit_percent": dict(self.fit),
                "closed_loop": self.closed_loop,
                "controller": None if self.controller is None else
                {"K_p": self.controller.K_p, "K_d": self.controller.K_d},
                "samples": int(self.t.size), "notes": list(self.notes)}


@dataclass(frozen=True, eq=False)
class RefinementResult:
    """Grey-box refinement of the assembled parameters.

    Attributes
    ----------
    estimate : Estimate
        Free parameters with covariance (greybox output error).
    parameters : PneumaticParameters
        The refined full set.
    start : PneumaticParameters
        The multi-step set the fit started from.
    free : tuple of str
        Parameters fitted; the others were fixed.
    outputs : tuple of str
        Channels in the criterion.
    noise_std : mapping of str to float
        Noise level per channel used as weight 1/σ.
    record : str
        Record fitted.
    """

    estimate: Estimate
    parameters: PneumaticParameters
    start: PneumaticParameters
    free: tuple[str, ...]
    outputs: tuple[str, ...]
    noise_std: Mapping[str, float]
    record: str
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {"record": self.record, "free": list(self.free), "outputs": list(self.outputs),
                "noise_std": dict(self.noise_std), "estimate": self.estimate.to_dict(),
                "start": {k: getattr(self.start, k) for k in self.free},
                "notes": list(self.notes)}


def estimate_controller(record: Experiment, u_max: float = 10.0) -> PositionController:
    """Reconstruct the PD gains u = K_p(x_ref − x_k) − K_d v_k by LS.

    Parameters
    ----------
    record : Experiment
        Closed-loop record with ``u``, ``x_ref``, ``x_k`` and ``v_k``.
    u_max : float
        Amplifier saturation [V]; saturated samples are left out.

    Returns
    -------
    PositionController
        The gains (negative estimates are clipped to 0).
    """
    check_record(record, "controller reconstruction")
    u_max = check_positive("u_max", u_max, "V")
    u = channel(record, "u", "controller reconstruction")
    e = channel(record, "x_ref", "controller reconstruction") - channel(
        record, "x_k", "controller reconstruction")
    v = channel(record, "v_k", "controller reconstruction")
    ok = np.abs(u) < 0.99 * u_max
    res = lstsq(np.column_stack([e[ok], -v[ok]]), u[ok], ("K_p", "K_d"))
    return PositionController(max(float(res.theta[0]), 0.0), max(float(res.theta[1]), 0.0))


def simulate_record(
    params: PneumaticParameters,
    record: Experiment,
    controller: PositionController | None = None,
) -> Any:
    """Simulate the full model on a record's own input.

    Parameters
    ----------
    params : PneumaticParameters
        Parameter set.
    record : Experiment
        A record with ``x_ref`` (closed loop, needs ``controller``) or
        ``u`` (open loop), and the measured first sample of ``x_v``,
        ``p_I``, ``p_II``, ``x_k`` (and ``v_k``) as the initial state.
    controller : PositionController, optional
        The loop's controller (closed-loop records).

    Returns
    -------
    PneumaticResponse
        The simulated response.
    """
    params = check_params(params)
    check_record(record, "S6")
    controller = _check_controller(controller)
    x0 = _initial_state(params, record)
    f_ext = record["f_ext"] if "f_ext" in record.names else None
    if "x_ref" in record.names:
        if controller is None:
            raise DataError(f"the record {record.name!r} is closed loop (x_ref): the "
                            "simulation needs the controller (K_p, K_d)")
        return simulate_pneumatic(params, None, record.dt, r=record["x_ref"], f_ext=f_ext,
                                  controller=controller, x0=x0)
    return simulate_pneumatic(params, channel(record, "u", "S6"), record.dt, f_ext=f_ext, x0=x0)


def compare_record(
    params: PneumaticParameters,
    record: Experiment,
    controller: PositionController | None = None,
    *,
    mdot_limit: float = MDOT_LIMIT,
    name: str = "validation",
) -> RecordComparison:
    """Simulate a record and compare it channel by channel (step S6).

    Parameters
    ----------
    params : PneumaticParameters
        Identified parameter set.
    record : Experiment
        Held-back record (see :func:`simulate_record`).
    controller : PositionController, optional
        Controller of a closed-loop record; None reconstructs it from
        the record's u, x_ref, x_k, v_k by LS (noted).
    mdot_limit : float
        Mass-flow sensor range [kg/s]; predicted flows are clipped to it.
    name : str
        Record name for the result.

    Returns
    -------
    RecordComparison
        Predicted vs measured channels and fit per channel.
    """
    params = check_params(params)
    check_record(record, "S6")
    controller = _check_controller(controller)
    mdot_limit = check_positive("mdot_limit", mdot_limit, "kg/s")
    name = as_str("name", name, empty=True)
    notes = []
    closed = "x_ref" in record.names
    if closed and controller is None:
        controller = estimate_controller(record, params.u_max)
        notes.append(f"controller reconstructed from the record by LS: K_p = "
                     f"{controller.K_p:.4g} V/m, K_d = {controller.K_d:.4g} V·s/m")
    sim = simulate_record(params, record, controller if closed else None)
    measured, predicted, fit = {}, {}, {}
    for ch in _COMPARED:
        if ch not in record.names:
            continue
        y_hat = np.asarray(getattr(sim, _SIM_FIELD[ch]), dtype=float)
        if ch.startswith("mdot"):
            y_hat = np.clip(y_hat, -mdot_limit, mdot_limit)
        measured[ch] = np.asarray(record[ch], dtype=float)
        predicted[ch] = y_hat
        fit[ch] = float(fit_percent(measured[ch], y_hat))
    return RecordComparison(name, record.time, measured, predicted, fit, closed,
                            controller if closed else None, tuple(notes))


def refine_parameters(
    record: Experiment,
    params: PneumaticParameters,
    *,
    free: Sequence[str] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    controller: PositionController | None = None,
    outputs: Sequence[str] = ("p_I", "p_II", "x_k"),
    noise_std: Mapping[str, float] | None = None,
    max_nfev: int | None = None,
    name: str = "",
    covariance: GreyboxCovariance = "auto",
    multistart: int = 0,
    n_bootstrap: int = 200,
    rng: np.random.Generator | int | None = None,
    diff_step: float | None = _DIFF_STEP,
) -> RefinementResult:
    """Refine identified parameters by output error on a record.

    Parameters
    ----------
    record : Experiment
        Estimation record (not the validation one) with the ``outputs``.
    params : PneumaticParameters
        Start values (the multi-step result).
    free : sequence of str, optional
        Parameters to fit (default all of :data:`REFINABLE` but the
        switching threshold v_krit, whose output derivative is zero or a
        jump); the rest stay fixed.
    bounds : mapping, optional
        ``{name: (lower, upper)}``; default [value/3, 3·value] (κ in
        (1.01, 2), p_krit in [0, 0.95]).
    controller : PositionController, optional
        Controller of a closed-loop record (None: reconstructed).
    outputs : sequence of str
        Measured channels in the criterion.
    noise_std : mapping, optional
        Noise std per channel; default estimated from the record's
        second differences (floored at 1e-4·std for noise-free data).
    max_nfev : int, optional
        Limit on simulations.
    name : str
        Record name for the result.
    covariance : {"auto", "white", "robust", "bootstrap"}
        Covariance of the refined parameters (:func:`~servoid.estimate.
        fit_greybox`): ``"robust"`` (= ``"auto"``) allows for coloured
        residuals per channel — model error in a simulated record is
        coloured; ``"bootstrap"`` refits `n_bootstrap` resampled records
        (each a full set of simulations: slow).  The estimate's
        ``options["covariance"]`` says which was used.
    multistart : int
        Extra random starts within the bounds, >= 0.
    n_bootstrap : int
        Refits for ``covariance="bootstrap"``.
    rng : numpy.random.Generator or int, optional
        Source of the random starts and resamples.
    diff_step : float or None
        Relative finite-difference step of the Jacobian (None: √ε).  The
        default 1e-4 steps over the simulator's switching (stick–slip,
        sample-grid events): its outputs jump when a parameter moves by
        1e-5…1e-4 relative, so a √ε step sees only the smooth part between
        jumps or, straddling one, a slope 1e3× too steep — either way a
        Jacobian that does not describe the cost (see the module notes).

    Returns
    -------
    RefinementResult
        Refined parameters with covariance and 95 % intervals;
        ``estimate.options["identifiability"]`` holds the diagnostics.

    Raises
    ------
    DataError
        A bound excludes the start value (naming the parameter), unknown
        parameter names, missing channels.
    ConvergenceError
        The simulation diverges at the start or at the optimum, or the
        solver fails.
    """
    params = check_params(params)
    check_record(record, "refinement")
    controller = _check_controller(controller)
    name = as_str("name", name, empty=True)
    outputs = as_str_list("outputs", outputs, min_length=1)
    if max_nfev is not None:
        max_nfev = as_int("max_nfev", max_nfev, minimum=1)
    if diff_step is not None:
        diff_step = as_float("diff_step", diff_step, positive=True)
    if noise_std is not None:
        noise_std = {o: as_float(f"noise_std[{o!r}]", v, positive=True)
                     for o, v in as_mapping("noise_std", noise_std).items()}
    # ẋ_krit is a switching threshold: the simulated output moves with it only when a sample
    # crosses it, so its finite-difference derivative is zero or a jump — not refinable by NLS
    free_t = (tuple(n for n in REFINABLE if n != "v_krit") if free is None
              else tuple(as_str_list("free", free)))
    unknown = sorted(set(free_t) - set(REFINABLE))
    if unknown or not free_t:
        raise OptionError(f"free must name parameters among {', '.join(REFINABLE)}; "
                          f"got unknown {', '.join(unknown) or '(none given)'}")
    bounds = {k: tuple(as_float_list(f"bounds[{k!r}]", v, length=2))
              for k, v in as_mapping("bounds", {} if bounds is None else bounds).items()}
    bad = sorted(set(bounds) - set(free_t))
    if bad:
        raise OptionError(f"bounds given for parameters that are not free: {', '.join(bad)}")
    plist = []
    for p in free_t:
        value = float(getattr(params, p))
        lo, hi = bounds.get(p, _DEFAULT_BOUNDS.get(p, (value / 3.0, value * 3.0)))
        if not lo < hi:
            raise DataError(f"bounds of {p} need lower < upper, got ({lo:g}, {hi:g})")
        if not lo <= value <= hi:
            raise DataError(f"the start value of {p} = {value:.6g} {UNITS[p]} lies outside its "
                            f"bounds [{lo:.6g}, {hi:.6g}]; widen the bounds or fix {p}")
        log = lo >= 0.0 and value > 0.0 and p not in ("kappa", "p_krit")
        plist.append(GreyboxParameter(p, value, lo, hi, UNITS[p], False,
                                      "log" if log else "none"))
    y = np.column_stack([channel(record, o, "refinement") for o in outputs])
    sigma = {o: float(noise_std[o]) if noise_std and o in noise_std else _noise_level(y[:, k])
             for k, o in enumerate(outputs)}
    notes = []
    if "x_ref" in record.names and controller is None:
        controller = estimate_controller(record, params.u_max)
        notes.append(f"controller reconstructed by LS: K_p = {controller.K_p:.4g}, "
                     f"K_d = {controller.K_d:.4g}")

    def simulate(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        try:
            trial = params.with_(**dict(zip(free_t, (float(v) for v in theta), strict=True)))
            sim = simulate_record(trial, record, controller)
        except ModelError:
            return np.full(y.shape, np.nan)  # fit_greybox penalises it
        return np.column_stack([getattr(sim, _SIM_FIELD[o]) for o in outputs])

    est = fit_greybox((record.time, np.zeros(record.n_samples), y), None, None, plist,
                      simulate=simulate, outputs=tuple(outputs),
                      noise_std=[sigma[o] for o in outputs], max_nfev=max_nfev,
                      covariance=covariance, multistart=multistart, n_bootstrap=n_bootstrap,
                      rng=rng, diff_step=diff_step)
    refined = params.with_(**{n: float(v) for n, v in zip(est.names, est.parameters,
                                                          strict=True)})
    return RefinementResult(est, refined, params, free_t, tuple(outputs), sigma,
                            name or record.name, tuple(notes))


# -- helpers --------------------------------------------------------------------------------


def _initial_state(params: PneumaticParameters, record: Experiment) -> NDArray[np.float64]:
    state = [float(channel(record, n, "S6")[0]) for n in ("x_v", "p_I", "p_II", "x_k")]
    v0 = float(record["v_k"][0]) if "v_k" in record.names else 0.0
    lim = params.stroke / 2.0
    x_k = min(max(state[3], -lim), lim)
    if state[1] <= 0.0 or state[2] <= 0.0:
        raise DataError(f"the record {record.name!r} starts with a pressure <= 0 Pa; absolute "
                        "pressures are needed")
    return np.array([state[0], 0.0, state[1], state[2], x_k, v0])


def _noise_level(y: NDArray[np.float64]) -> float:
    d2 = np.diff(y, 2)
    sigma = float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))
    floor = 1e-4 * float(np.std(y)) or 1e-12
    return max(sigma, floor)


def _check_controller(controller: object) -> PositionController | None:
    if controller is None:
        return None
    return as_instance("controller", controller, PositionController,
                       "a PositionController(K_p, K_d) or None")
