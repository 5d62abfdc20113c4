"""Step S1: the servovalve (1) by state-variable filters and LS.

Equation (1) of [S2] (Hahn & Piepenbrink 1994; models-spec §2)::

    ẍ_v + 2ξ_v ω_v ẋ_v + ω_v² x_v = k_v ω_v² u

is Type I: linear in θ = (2ξ_vω_v, ω_v², k_vω_v²) but with unmeasured
derivatives.  Filtering u and x_v by the same state-variable filter F(s)
(spec §3.6) gives ``s²F x_v = −θ₁ sF x_v − θ₂ F x_v + θ₃ F u``, solved by
batch LS after the filter's start-up; the physical parameters follow by
the delta method: ω_v = √θ₂, ξ_v = θ₁/(2ω_v), k_v = θ₃/θ₂.
"""

from __future__ import annotations

import math

import numpy as np

from ..._errors import DataError
from ...data import Experiment
from ...estimate import Hold, lstsq, state_variable_filter
from ._steps import StepResult, channel, check_positive, ls_estimate, physical_estimate

__all__ = ["identify_valve"]

_EQUATION = ("(1) ẍ_v + 2ξ_v ω_v ẋ_v + ω_v² x_v = k_v ω_v² u: u and x_v filtered by one "
             "state-variable filter F(s) = ω_f²/(s + ω_f)², LS of s²F x_v on "
             "(−sF x_v, −F x_v, F u) after the filter start-up, delta method to k_v, ξ_v, ω_v")


def identify_valve(
    record: Experiment,
    *,
    omega_f: float = 2 * math.pi * 300.0,
    u_hold: Hold = "zoh",
    settle: float | None = None,
    name: str = "valve",
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
    raw = ls_estimate(res, raw_names, ("1/s", "1/s²", "m/(V·s²)"), "svf+ls")
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
        ("m/V", "-", "rad/s"), "svf+ls",
        {"omega_f": omega_f, "u_hold": u_hold, "first_valid": first},
    )
    mask = np.zeros(record.n_samples, dtype=bool)
    mask[first:] = True
    return StepResult(
        step="S1", title="servovalve k_v, ξ_v, ω_v", equation=_EQUATION, record=name,
        estimate=est, mask=mask, method="svf+ls",
        extra={"theta": res.theta.tolist(), "theta_std": res.std.tolist(),
               "omega_f": omega_f, "condition": float(res.condition)},
    )
