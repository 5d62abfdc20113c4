"""Step S1: the servovalve (1) by state-variable filters and LS.

Equation (1) of [S2] (Hahn & Piepenbrink 1994; models-spec §2)::

    ẍ_v + 2ξ_v ω_v ẋ_v + ω_v² x_v = k_v ω_v² u

is Type I: linear in θ = (2ξ_vω_v, ω_v², k_vω_v²) but with unmeasured
derivatives.  Filtering u and x_v by the same state-variable filter F(s)
(spec §3.6) gives ``s²F x_v = −θ₁ sF x_v − θ₂ F x_v + θ₃ F u``, solved by
batch LS after the filter's start-up; the physical parameters follow by
the delta method: ω_v = √θ₂, ξ_v = θ₁/(2ω_v), k_v = θ₃/θ₂.

The regressors sF x_v and F x_v carry the spool sensor's noise, which biases
this equation-error LS (ξ_v −1.3σ at 25 dB, −4.7σ at 15 dB on the virtual
rig).  By default (``estimator="iv"``) the LS model is the start of an
instrumental-variable solution whose instruments are the same filtered
signals of the model's *simulated* output, driven by the command u (the DAQ
knows it: no noise), as in the simplified refined IV method; one more pass
with the IV model.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import scipy.signal as sps
from numpy.typing import NDArray

from ..._errors import DataError, check_option
from ...data import Experiment
from ...estimate import Hold, lstsq, state_variable_filter
from ._steps import (
    StepResult,
    channel,
    check_positive,
    ls_estimate,
    physical_estimate,
    spectral_covariance,
)

__all__ = ["identify_valve"]

_EQUATION = ("(1) ẍ_v + 2ξ_v ω_v ẋ_v + ω_v² x_v = k_v ω_v² u: u and x_v filtered by one "
             "state-variable filter F(s) = ω_f²/(s + ω_f)², IV regression of s²F x_v on "
             "(−sF x_v, −F x_v, F u) after the filter start-up (instruments from the LS "
             "model's simulated output), delta method to k_v, ξ_v, ω_v")


def identify_valve(
    record: Experiment,
    *,
    omega_f: float = 2 * math.pi * 300.0,
    u_hold: Hold = "zoh",
    settle: float | None = None,
    name: str = "valve",
    estimator: str = "iv",
) -> StepResult:
    """Identify k_v, ξ_v, ω_v of the servovalve (step S1).

    Parameters
    ----------
    record : Experiment
        Rectangular valve input test with channels ``u`` [V] and
        ``x_v`` [m] (spec §3.9 S1: ±5 V, 25 Hz; f_s ≥ 20·f_v).
    omega_f : float
        Filter bandwidth [rad/s], 1.5–3× ω_v (spec §3.6: 2π·300).
    u_hold : {"zoh", "cubic", "foh", "tustin"}
        Inter-sample course of u for the exact filter discretisation:
        "zoh" for a DAC-held rectangle (exact), "cubic" for a smooth
        analog record.
    settle : float, optional
        Filter start-up time to discard [s] (default 5/ω_f).
    name : str
        Record name for the result.
    estimator : {"iv", "ls"}
        "iv" (default): the LS estimate, then instrumental variables
        whose instruments are the filtered output of the LS model driven
        by the command u (noise-free: the DAQ knows it), re-simulated once
        with the IV estimate.  The LS regressors sF x_v, F x_v carry the
        spool sensor's noise and bias ξ_v low below ~30 dB; "ls": LS only.

    Returns
    -------
    StepResult
        ``k_v`` [m/V], ``xi_v`` [-], ``omega_v`` [rad/s] with std;
        ``extra["theta"]`` the raw (2ξω, ω², kω²).

    Raises
    ------
    DataError
        A missing channel, too short a record, or an estimate without
        physical meaning (ω_v² <= 0).
    IdentifiabilityError
        The input does not excite the valve (rank-deficient regression).
    """
    check_option("estimator", estimator, ("iv", "ls"))
    u = channel(record, "u", "S1 (valve)")
    x_v = channel(record, "x_v", "S1 (valve)")
    omega_f = check_positive("omega_f", omega_f, "rad/s")
    fu = state_variable_filter(u, record.dt, omega_f, 2, hold=u_hold, settle=settle)
    fx = state_variable_filter(x_v, record.dt, omega_f, 2, settle=settle)
    first = fx.first_valid
    if record.n_samples - first < 20:
        raise DataError(f"S1 (valve): the record has {record.n_samples} samples, the filter "
                        f"start-up alone takes {first}; record longer")
    phi = np.column_stack([-fx.derivative(1, valid=True), -fx.derivative(0, valid=True),
                           fu.derivative(0)[first:]])
    y = fx.derivative(2, valid=True)
    raw_names = ("2xi_v*omega_v", "omega_v^2", "k_v*omega_v^2")
    res = lstsq(phi, y, raw_names)
    method = "svf+ls"
    ls_values = _physical(res.theta)
    if estimator == "iv":
        res = _srivc_instruments(res, phi, y, fu.derivative(0), first, record.dt)
        method = "svf+iv"
    else:
        res = dataclasses.replace(res, covariance=spectral_covariance(
            [(phi, y - phi @ res.theta, np.arange(y.size))]))
    raw = ls_estimate(res, raw_names, ("1/s", "1/s²", "m/(V·s²)"), method)
    a1, a0, b0 = (float(v) for v in res.theta)
    if a0 <= 0.0:
        raise DataError(f"S1 (valve): the fit gives ω_v² = {a0:g} <= 0; the record does not "
                        "show a second-order spool response (check u, x_v and omega_f)")
    w = math.sqrt(a0)
    jac = np.array([
        [0.0, -b0 / a0**2, 1.0 / a0],  # k_v = b0/a0
        [1.0 / (2 * w), -a1 / (4 * a0 * w), 0.0],  # ξ_v = a1/(2√a0)
        [0.0, 1.0 / (2 * w), 0.0],  # ω_v = √a0
    ])
    est = physical_estimate(
        (b0 / a0, a1 / (2 * w), w), jac, raw, ("k_v", "xi_v", "omega_v"),
        ("m/V", "-", "rad/s"), method,
        {"omega_f": omega_f, "u_hold": u_hold, "first_valid": first, "estimator": estimator,
         "ls_values": ls_values},
    )
    mask = np.zeros(record.n_samples, dtype=bool)
    mask[first:] = True
    return StepResult(
        step="S1", title="servovalve k_v, ξ_v, ω_v", equation=_EQUATION, record=name,
        estimate=est, mask=mask, method=method,
        extra={"theta": res.theta.tolist(), "theta_std": res.std.tolist(),
               "omega_f": omega_f, "condition": float(res.condition)},
    )


def _srivc_instruments(res: Any, phi: NDArray[np.float64], y: NDArray[np.float64],
                       f_u: NDArray[np.float64], first: int, dt: float) -> Any:
    """IV re-estimate of (2ξω, ω², kω²) with simulated, noise-free instruments.

    The instruments are ``(−sF x̂, −F x̂, F u)`` with ``F x̂`` the model
    ``θ₃/(s² + θ₁ s + θ₂)`` driven by ``F u``: functions of the command
    alone, so uncorrelated with the spool sensor's noise in the regressors.
    Two passes (LS model, then the first IV model).  The covariance is the
    IV one, ``A⁻¹ S A⁻ᵀ`` with ``A = ZᵀΦ`` and S weighing the instruments
    by the residual's spectrum (:func:`spectral_covariance`): the residual
    is the spool sensor's noise through ``F(s)·A(s)``, mostly far above the
    instruments' band, and ``σ̂² ZᵀZ`` put the valve's σ at 2.3× (ξ_v) to
    2.2× (ω_v) their seed-to-seed spread.
    """
    theta = np.asarray(res.theta, dtype=float)
    t = np.arange(f_u.size) * dt
    z = phi
    for _ in range(2):
        a1, a0, b0 = (float(v) for v in theta)
        if a0 <= 0.0 or a1 <= 0.0:
            return res  # an unstable LS model simulates no instrument; keep LS
        sys_ = sps.StateSpace(np.array([[0.0, 1.0], [-a0, -a1]]), np.array([[0.0], [b0]]),
                              np.eye(2), np.zeros((2, 1)))
        states = sps.lsim(sys_, f_u, t)[2][first:]
        z = np.column_stack([-states[:, 1], -states[:, 0], f_u[first:]])
        a = z.T @ phi
        theta = np.linalg.solve(a, z.T @ y)
    resid = y - phi @ theta
    return dataclasses.replace(res, theta=theta, covariance=spectral_covariance(
        [(phi, resid, np.arange(y.size), z)]),
                               rss=float(resid @ resid))


def _physical(theta: NDArray[np.float64]) -> dict[str, float]:
    """(2ξω, ω², kω²) → k_v, ξ_v, ω_v (NaN where ω² <= 0)."""
    a1, a0, b0 = (float(v) for v in theta)
    if a0 <= 0.0:
        return {"k_v": math.nan, "xi_v": math.nan, "omega_v": math.nan}
    w = math.sqrt(a0)
    return {"k_v": b0 / a0, "xi_v": a1 / (2 * w), "omega_v": w}
