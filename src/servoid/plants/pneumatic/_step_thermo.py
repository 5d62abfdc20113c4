"""Step S2: κ and R from the chamber equations (2.x) by SVF and RLS.

The chamber equations (2.1), (2.2) of [S2] (models-spec §2) in the
derivative-free form of spec §3.6, per chamber with V = V₀ ± A·x_k::

    d/dt (V p) = κR·T·ṁ − (κ − 1)·V̇·p

are linear in θ = (κR, κ − 1) (Type II).  Each product signal V·p, T·ṁ
and V̇·p is filtered by one state-variable filter F(s) and the filtered
equation ``sF[V p] = θ₁ F[T ṁ] − θ₂ F[V̇ p]`` of both chambers is stacked
and solved by RLS (λ = 1, the paper's estimator; its history shows the
convergence, [S2] Fig. 11) and by batch LS (the reported estimate; the
two agree to ~cond²/p₀).  κ = 1 + θ₂ and R = θ₁/(1 + θ₂) with their
std by the delta method.

V̇ = ±A·ẋ_k needs the piston velocity: the recorded ``v_k``
(``derivatives="measured"``) or, with ``"svf"``, the zero-phase
state-variable filter derivative of x_k (:func:`zero_phase_derivatives`).
The p·V̇ term must be excited: the paper adds a rectangular external force
to the closed-loop sine for it.  Windows of the filter touching a
saturated mass-flow sample (|ṁ| ≥ 98 % of the sensor range) are dropped.
With ``known.mdot_sensor_bandwidth`` the terms V·p and V̇·p pass the
mass-flow sensor's first-order lag before the SVF, as ṁ did in the sensor.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float
from ..._errors import DataError
from ...data import Experiment
from ...estimate import fit_rls, lstsq, state_variable_filter
from ._steps import (
    MDOT_LIMIT,
    Derivatives,
    KnownConstants,
    StepResult,
    channel,
    check_derivatives,
    check_known,
    check_positive,
    ls_estimate,
    mdot_sensor_lag,
    physical_estimate,
    pressures,
    spectral_covariance,
    temperature,
    window_all,
)

__all__ = ["identify_thermodynamics", "zero_phase_derivatives"]

_EQUATION = ("(2.x) in derivative-free form d/dt(V p) = κR·T·ṁ − (κ−1)·V̇·p per chamber, "
             "V = V₀ ± A x_k: V·p, T·ṁ and V̇·p filtered by one SVF, both chambers stacked, "
             "RLS (λ = 1) and batch LS for (κR, κ−1), delta method to κ, R")


def zero_phase_derivatives(
    x: NDArray[np.float64], dt: float, omega_f: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]:
    """Return G x, sG x, s²G x of the zero-phase filter G = F(−s)F(s).

    The signal is filtered forwards by the second-order SVF F(s) and the
    result backwards by the same filter, so the derivatives carry no lag
    (the magnitude is |F(jω)|², 1 − 2(ω/ω_f)² at low frequency).

    Parameters
    ----------
    x : ndarray, shape (N,)
        Signal.
    dt : float
        Sample period [s].
    omega_f : float
        Bandwidth of each pass [rad/s].

    Returns
    -------
    tuple
        (G x, sG x, s²G x, margin): the filtered signal and derivatives,
        and the number of samples at each end spoilt by the start-ups.
    """
    fwd = state_variable_filter(x, dt, omega_f, 2, initial="steady")
    back = state_variable_filter(fwd.derivative(0)[::-1].copy(), dt, omega_f, 2,
                                 initial="steady")
    vals = back.values[::-1]
    margin = 2 * fwd.first_valid
    return vals[:, 0].copy(), -vals[:, 1], vals[:, 2].copy(), margin


def identify_thermodynamics(
    record: Experiment,
    known: KnownConstants,
    *,
    derivatives: Derivatives = "svf",
    omega_f: float = 2 * math.pi * 30.0,
    velocity_omega_f: float = 2 * math.pi * 300.0,
    mdot_limit: float = MDOT_LIMIT,
    settle: float | None = None,
    name: str = "thermo",
) -> StepResult:
    """Identify κ and R from the chamber equations (step S2).

    Parameters
    ----------
    record : Experiment
        Closed-loop sine with a rectangular external force: channels
        ``x_k`` [m], ``p_I``, ``p_II`` [Pa], ``mdot_I``, ``mdot_II``
        [kg/s], optionally ``T_I``, ``T_II`` [K] (default T_S) and
        ``v_k`` [m/s] (needed with ``derivatives="measured"``).
    known : KnownConstants
        A_I, A_II, V_0I, V_0II (and T_S).
    derivatives : {"svf", "measured"}
        Source of ẋ_k: the recorded ``v_k``, or the zero-phase SVF of x_k.
    omega_f : float
        Bandwidth of the filter applied to the equation [rad/s].
    velocity_omega_f : float
        Bandwidth of the zero-phase velocity filter ("svf") [rad/s].
    mdot_limit : float
        Mass-flow sensor range [kg/s].
    settle : float, optional
        Filter start-up to discard [s] (default 12/ω_f).
    name : str
        Record name for the result.

    Returns
    -------
    StepResult
        ``kappa`` [-] and ``R`` [J/(kg·K)] with std (batch LS);
        ``extra`` holds the RLS final values and a decimated history.

    Raises
    ------
    DataError
        Missing channels, non-positive pressures, too few samples.
    IdentifiabilityError
        The p·V̇ term is not excited (the piston does not move).
    """
    known = check_known(known)
    check_derivatives(derivatives)
    omega_f = check_positive("omega_f", omega_f, "rad/s")
    velocity_omega_f = check_positive("velocity_omega_f", velocity_omega_f, "rad/s")
    if settle is not None:
        settle = as_float("settle", settle, nonneg=True, unit="s")
    step = "S2 (thermodynamics)"
    x_k = channel(record, "x_k", step)
    p_1, p_2 = pressures(record, step)
    m_1, m_2 = channel(record, "mdot_I", step), channel(record, "mdot_II", step)
    t_1, t_2 = temperature(record, "T_I", known), temperature(record, "T_II", known)
    margin = 0
    if derivatives == "measured":
        v_k = channel(record, "v_k", step)
    else:
        _, v_k, _, margin = zero_phase_derivatives(x_k, record.dt, velocity_omega_f)
    dt = record.dt
    settle = 12.0 / omega_f if settle is None else settle
    limit = check_positive("mdot_limit", mdot_limit, "kg/s") * 0.98
    window = math.ceil(12.0 / omega_f / dt)
    ys, phis, masks = [], [], []
    for vol0, area, p, m, temp in ((known.V_0I, known.A_I, p_1, m_1, t_1),
                                   (known.V_0II, -known.A_II, p_2, m_2, t_2)):
        vol = vol0 + area * x_k
        if np.any(vol <= 0.0):
            raise DataError(f"{step}: a chamber volume V₀ ± A x_k is <= 0; check x_k against "
                            "the known volumes")
        # ṁ is read through the sensor's lag H (if known): H(T ṁ) = T·H ṁ with T
        # constant over H's few samples, so the two other terms pass H too
        vp, lag_start = mdot_sensor_lag(vol * p, dt, known, step)
        dvp = mdot_sensor_lag(area * v_k * p, dt, known, step)[0]
        f_vp, f_tm, f_dvp = (
            state_variable_filter(sig, dt, omega_f, 1, initial="steady", settle=settle)
            for sig in (vp, temp * m, dvp))
        mask = np.zeros(record.n_samples, dtype=bool)
        mask[max(f_vp.first_valid + lag_start, margin):record.n_samples - margin] = True
        mask &= window_all(np.abs(m) < limit, window)
        ys.append(f_vp.derivative(1)[mask])
        phis.append(np.column_stack([f_tm.derivative(0)[mask], -f_dvp.derivative(0)[mask]]))
        masks.append(mask)
    y = np.concatenate(ys)
    phi = np.vstack(phis)
    if y.size < 20:
        raise DataError(f"{step}: only {y.size} usable samples after the filter start-up and "
                        "the saturated mass-flow windows; record longer or excite less")
    raw_names = ("kappa*R", "kappa-1")
    res = lstsq(phi, y, raw_names)
    rls = fit_rls(phi, y, forgetting=1.0, history=True, names=raw_names)
    # the residual is the sensors' noise through sF (its power far above the regressors'
    # band) and the chambers share the x_k, v_k noise: the covariance takes the residuals'
    # (cross-)spectra at the regressors' frequencies (Newey–West over 12/ω_f put R's σ at
    # 1.6× its seed-to-seed spread, the chambers' correlation 0.46 for 0.84)
    groups = []
    for m, y_c, phi_c in zip(masks, ys, phis, strict=True):
        resid = y_c - phi_c @ res.theta
        groups.append((phi_c, resid, np.flatnonzero(m)))
    raw = dataclasses.replace(ls_estimate(res, raw_names, ("J/(kg·K)", "-"), "ls"),
                              covariance=spectral_covariance(groups))
    t1, t2 = (float(v) for v in res.theta)
    kappa = 1.0 + t2
    if kappa <= 1.0:
        raise DataError(f"{step}: the fit gives κ = {kappa:g} <= 1; the p·V̇ term is not "
                        "excited enough (add the external force) or the data are inconsistent")
    jac = np.array([[0.0, 1.0], [1.0 / kappa, -t1 / kappa**2]])
    est = physical_estimate((kappa, t1 / kappa), jac, raw, ("kappa", "R"),
                            ("-", "J/(kg·K)"), "svf+ls",
                            {"omega_f": omega_f, "derivatives": derivatives,
                             "white_std": [float(v) for v in res.std],
                             "covariance": "LS, residual spectra at the regressors' frequencies "
                             "(both chambers), delta method"})
    hist = rls.history if rls.history is not None else np.empty((0, 2))
    stride = max(1, hist.shape[0] // 400)
    h_kappa = 1.0 + hist[::stride, 1]
    h_r = hist[::stride, 0] / np.where(h_kappa > 0, h_kappa, np.nan)
    rls_theta = rls.theta
    return StepResult(
        step="S2", title="thermodynamic constants κ, R", equation=_EQUATION, record=name,
        estimate=est, mask=masks[0] | masks[1], method="svf+rls/ls",
        extra={
            "theta": res.theta.tolist(),
            "rls_kappa": float(1.0 + rls_theta[1]),
            "rls_R": float(rls_theta[0] / (1.0 + rls_theta[1])),
            "rls_history_kappa": h_kappa,
            "rls_history_R": h_r,
            "rows_per_chamber": [int(m.sum()) for m in masks],
            "omega_f": omega_f,
        },
    )
