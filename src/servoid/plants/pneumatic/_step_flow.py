"""Steps S0 (p_krit) and S3 (a_i d_i): the valve mass flows (3.x).

Equations (3.1), (3.2) of [S2] (models-spec §2), edges 1 I → exhaust,
2 supply → I, 3 supply → II, 4 II → exhaust, zero overlap::

    x_v > 0:  ṁ_I  =  a₂d₂·π x_v ψ_b(p_I/p_S) p_S √(2/(R T_S))
              ṁ_II = −a₄d₄·π x_v ψ_b(p_R/p_II) p_II √(2/(R T_II))
    x_v < 0:  ṁ_I  = −a₁d₁·π|x_v| ψ_b(p_R/p_I) p_I √(2/(R T_I))
              ṁ_II =  a₃d₃·π|x_v| ψ_b(p_II/p_S) p_S √(2/(R T_S))

with ψ_b the ellipse flow function of critical ratio b = p_krit (a
reversed pressure drop reverses the flow, as in the simulator).  For
fixed κ, R and b each line is linear in its a_i d_i (Type II); b enters
nonlinearly (Type IV), so step S0 finds it by separable least squares
(outer search over b, inner LS for the four edge coefficients, spec §3.8).

Why S0 can precede S2.  κ enters ψ_b only through the factor ψ_max(κ)
and R only through √(2/R): both scale every edge's regressor and are
absorbed by the edge coefficients.  The residual-sum profile over b is
therefore the same for any κ, R, and S0 runs with placeholders; S3 then
re-fits the edges with κ, R from S2 and b from S0.

Samples where the mass-flow sensor is saturated (|ṁ| ≥ 0.98·limit, the
paper's hot-wire sensor reads at most 4 g/s) are excluded, as are
samples with |x_v| <= ``x_v_min``.

Sensor dynamics.  The equations are static in x_v and p, but the hot-wire
reads ṁ through a first-order lag (1 kHz in [S2]).  Regressing the lagged
ṁ on unlagged regressors biases the profile over b strongly (p_krit 0.48
instead of 0.25 on the virtual rig, noise-free): the error is largest where
x_v moves fast.  With ``known.mdot_sensor_bandwidth`` given, every regressor
passes the same lag before the LS ("filter both sides identically"); the
two edges of a chamber then overlap for a few samples after each spool
zero crossing and share one LS per chamber.

Noisy regressors.  The regressors are built from the measured x_v, p_I,
p_II: their noise is errors in variables, which least squares does not
average out.  The profile over b is flat (σ(p_krit) ≈ 8 % at 30 dB), so the
small attenuation it causes moves b far: on the virtual rig LS gives p_krit
+1.7σ at 30 dB and +3.3σ at 25 dB (ad_2, ad_3 follow it, −2 %).  Both steps
therefore solve by instrumental variables (``estimator="iv"``, the default):
the instrument of a row is the same regressor (for S0 the whole Jacobian
row, ∂/∂b included) averaged over the samples ``iv_delay`` (2 ms) before and
after it.  Their noise is that of other samples, uncorrelated with the
row's once the delay exceeds the sensors' noise correlation (the anti-alias
filter's impulse response, < 1 ms at 2 kHz), while the flow test's slow
signals keep them correlated with the row's regressor.  S0 starts from the
separable LS and solves the moment equations ``Σ z_t r_t(b, c) = 0`` by
Gauss–Newton with the instruments held, rebuilt once at the solution; S3 is
linear IV per chamber.  Covariances are the IV ones with Newey–West
(``H⁻¹SH⁻ᵀ``, H = ZᵀJ).  The LS estimate is kept in
``options["ls_values"]``: the difference is the bias the noise put in it.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float, as_float_list, as_int
from ..._errors import DataError, IdentifiabilityError, ServoidWarning, check_option
from ..._warn import warn
from ...data import Experiment
from ...estimate import Estimate, fit_separable, lstsq
from ._flow import psi_ellipse, psi_max
from ._steps import (
    MDOT_LIMIT,
    KnownConstants,
    StepResult,
    channel,
    check_known,
    check_positive,
    hac_covariance,
    mdot_sensor_lag,
    newey_west_lags,
    pressures,
    propagate,
    temperature,
)

__all__ = ["EDGES", "IV_DELAY", "identify_critical_pressure", "identify_flow"]

#: Default delay of the flow steps' instruments [s]: beyond the rig's noise correlation
#: (a 2 kHz 4th-order anti-alias filter: its impulse response is below 1 % after ~1 ms),
#: well inside the flow test's signal correlation (a 1 Hz closed-loop sine).
IV_DELAY = 2e-3
_ESTIMATORS = ("iv", "ls")

#: Edge number → (chamber, spool sign, description).
EDGES: dict[int, tuple[str, int, str]] = {
    1: ("I", -1, "chamber I → exhaust"),
    2: ("I", +1, "supply → chamber I"),
    3: ("II", -1, "supply → chamber II"),
    4: ("II", +1, "chamber II → exhaust"),
}
_SATURATION_MARGIN = 0.98
_EQ_S3 = ("(3.1), (3.2) with κ, R from S2 and p_krit from S0 inserted: samples split by "
          "sgn x_v and chamber, IV regression of ṁ on π|x_v|ψ(π)p_up√(2/(R T_up)) per edge "
          "(per chamber when the regressors pass the ṁ sensor's known lag; instruments: the "
          "regressors ±2 ms away) → a_i d_i; samples with a saturated ṁ sensor excluded")
_EQ_S0 = ("(3.1), (3.2) Type IV in b = p_krit: separable LS, outer grid over b (step 0.01) "
          "and Brent refinement, inner LS of the four edge coefficients (Type II for fixed b); "
          "from there instrumental variables in (b, a_i d_i), instruments the Jacobian rows "
          "±2 ms away")


@dataclass(frozen=True)
class _ChamberData:
    """One chamber's flow equation: its identifiable edges and regression rows.

    The regressors are built on the whole record (an edge contributes where
    the spool opens it, 0 elsewhere) and pass the mass-flow sensor's lag, if
    known, before the rows are taken: with a lag the two edges of a chamber
    overlap for a few samples after each spool zero crossing, so they share
    one LS; without it their columns have disjoint rows and the LS splits
    into one per edge, as in [S2].
    """

    chamber: str
    edges: tuple[int, ...]
    rows: NDArray[np.intp]
    mdot: NDArray[np.float64]  # measured ṁ at the rows
    area: dict[int, NDArray[np.float64]]  # π|x_v| where the edge is open, else 0 [m]
    p_ch: NDArray[np.float64]
    t_ch: NDArray[np.float64]
    p_S: float
    p_R: float
    T_S: float
    open_rows: dict[int, NDArray[np.bool_]]  # per edge: rows at which it is open
    lag: Callable[[NDArray[np.float64]], NDArray[np.float64]]

    def regressors(self, b: float, kappa: float, R: float) -> NDArray[np.float64]:
        """Columns ṁ/(a_i d_i) of the chamber's edges at the rows."""
        return self.columns(b, kappa, R)[self.rows]

    def instruments(self, b: float, kappa: float, R: float, delay: int) -> NDArray[np.float64]:
        """The columns ``delay`` samples before and after each row, averaged.

        Built from the same measured signals, but their noise is that of
        other samples: with `delay` beyond the noise's correlation length
        they are uncorrelated with the regressors' noise at the row while
        the slow signal keeps them correlated with its value there.
        """
        cols = self.columns(b, kappa, R)
        return 0.5 * (cols[self.rows - delay] + cols[self.rows + delay])

    def columns(self, b: float, kappa: float, R: float) -> NDArray[np.float64]:
        """Columns ṁ/(a_i d_i) of the chamber's edges on the whole record."""
        cols = []
        for edge in self.edges:
            supply = edge in (2, 3)
            n = self.p_ch.size
            p_up: NDArray[np.float64]
            p_down: NDArray[np.float64]
            c_flow: NDArray[np.float64]
            if supply:  # flow into the chamber; a reversed drop reverses it
                p_up, p_down = np.full(n, self.p_S), self.p_ch
                c_flow = np.full(n, math.sqrt(2.0 / self.T_S))
            else:
                p_up, p_down, c_flow = self.p_ch, np.full(n, self.p_R), np.sqrt(2.0 / self.t_ch)
            forward = p_up >= p_down
            hi = np.where(forward, p_up, p_down)
            lo = np.where(forward, p_down, p_up)
            psi = psi_ellipse(lo / hi, b, kappa)
            mag = self.area[edge] * psi * hi * c_flow / math.sqrt(R)
            col = np.where(forward, mag, -mag) * (1.0 if supply else -1.0)
            cols.append(self.lag(col))
        return np.column_stack(cols)


def identify_critical_pressure(
    record: Experiment,
    known: KnownConstants,
    *,
    bounds: tuple[float, float] = (0.1, 0.6),
    step: float = 0.01,
    mdot_limit: float = MDOT_LIMIT,
    x_v_min: float = 0.0,
    min_samples: int = 50,
    name: str = "flow",
    estimator: str = "iv",
    iv_delay: float = IV_DELAY,
) -> StepResult:
    """Find p_krit by separable LS on the flow equations (step S0).

    Parameters
    ----------
    record : Experiment
        Flow test with ``x_v`` [m], ``p_I``, ``p_II`` [Pa], ``mdot_I``,
        ``mdot_II`` [kg/s] and optionally ``T_I``, ``T_II`` [K].
    known : KnownConstants
        Supply and exhaust pressure, supply temperature.
    bounds : (float, float)
        Search interval of b (spec: [0.1, 0.6]).
    step : float
        Grid step of the outer search (spec: 0.01); Brent refines the
        best cell.
    mdot_limit : float
        Range of the mass-flow sensors [kg/s]; samples at or above 98 %
        of it are treated as saturated and excluded.
    x_v_min : float
        Exclude samples with |x_v| at or below this [m].
    min_samples : int
        Fewest samples an edge needs to take part.
    name : str
        Record name for the result.
    estimator : {"iv", "ls"}
        "iv" (default): the separable LS is the start of an
        instrumental-variable solution of the same equations (module
        notes, "Noisy regressors"), which removes the errors-in-variables
        bias of the measured x_v, p_I, p_II; "ls": the LS estimate.
    iv_delay : float
        Delay of the instruments [s], longer than the correlation time of
        the sensors' noise (the anti-alias filter's impulse response);
        default 2 ms.

    Returns
    -------
    StepResult
        ``p_krit`` [-] with std (joint covariance of the separable fit)
        and the lumped edge coefficients ``c_i = a_i d_i ψ_max(1.4)/√287``
        (scale placeholders; module notes); ``extra`` holds the grid
        and its residual sums.

    Raises
    ------
    IdentifiabilityError
        No edge has enough unsaturated samples, or the profile is flat.
    """
    known = check_known(known)
    lo, hi = as_float_list("bounds", bounds, length=2)
    if not 0.0 <= lo < hi <= 1.0:
        raise DataError(f"bounds must be (low, high) with 0 <= low < high <= 1 (p_krit is a "
                        f"pressure ratio), got ({lo:g}, {hi:g})")
    step = check_positive("step", step, "")
    check_option("estimator", estimator, _ESTIMATORS)
    delay = _delay_samples(iv_delay, record.dt)
    chambers, notes, mask = _chamber_data(record, known, mdot_limit, x_v_min, min_samples,
                                          "S0 (p_krit)", delay)
    grid = np.arange(lo, hi + 0.5 * step, step)
    grid = grid[grid <= hi + 1e-12]
    kappa, R = 1.4, 287.0  # placeholders: the profile over b does not depend on them
    mdot = np.concatenate([c.mdot for c in chambers])
    edges = [e for c in chambers for e in c.edges]
    row0 = np.cumsum([0] + [c.rows.size for c in chambers])
    col0 = np.cumsum([0] + [len(c.edges) for c in chambers])

    def build(b: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        phi = np.zeros((mdot.size, len(edges)))
        for j, c in enumerate(chambers):
            phi[row0[j]:row0[j + 1], col0[j]:col0[j + 1]] = c.regressors(b, kappa, R)
        return phi, mdot

    labels = tuple(f"c_{e}" for e in edges)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        est = fit_separable(build, (lo, hi), grid=grid, method="grid+golden", names=labels,
                            beta_name="p_krit", units=("m",) * len(edges), beta_unit="-")
    for w in caught:
        notes.append(f"S0 (p_krit): {w.message}")
        warn(str(w.message), ServoidWarning)
    # the joint covariance σ̂²(JᵀJ)⁻¹ takes white residuals; the rig's ṁ noise passed the
    # anti-alias filter: Newey–West on the same Jacobian J = [∂r/∂b, Φ(b)]
    b_hat, coef = float(est["p_krit"]), np.asarray(est.parameters[1:], dtype=float)
    h = float(est.options["difference_step"])
    ls_b = b_hat
    iv_info: dict[str, Any] = {"estimator": "ls"}
    if estimator == "iv":
        iv = _separable_iv(chambers, b_hat, coef, (lo, hi), h, delay, kappa, R)
        if iv is None:
            msg = ("S0 (p_krit): the instrumental-variable solution did not converge; p_krit "
                   "is the LS estimate, which noisy x_v, p_I, p_II bias upward below ~40 dB")
            warn(msg, ServoidWarning)
            notes.append(msg)
        else:
            b_hat, coef, cov, iv_info = iv
    if iv_info["estimator"] == "ls":
        phi, y = build(b_hat)
        jac = np.column_stack([(build(b_hat + h)[0] - build(b_hat - h)[0]) @ coef / (2.0 * h),
                               phi])
        resid = y - phi @ coef
        cov = hac_covariance([(jac[row0[j]:row0[j + 1]], resid[row0[j]:row0[j + 1]], c.rows)
                              for j, c in enumerate(chambers)], newey_west_lags(y.size))
    est = dataclasses.replace(est, parameters=np.r_[b_hat, coef], covariance=cov, options={
        **est.options, "white_covariance": est.covariance.tolist(), "ls_p_krit": ls_b,
        "ls_values": {"p_krit": ls_b},
        **iv_info,
        "covariance": ("joint Jacobian [∂r/∂b, Φ], Newey–West (coloured residuals)"
                       + (f", instruments delayed ±{delay:g} samples"
                          if iv_info["estimator"] == "iv" else ""))})
    return StepResult(
        step="S0 p_krit", title="critical pressure ratio p_krit of the flow function",
        equation=_EQ_S0, record=name, estimate=est, mask=mask, method="separable_ls",
        notes=tuple(notes),
        extra={"grid": est.options["grid"], "grid_rss": est.options["grid_rss"],
               "edges": edges, "placeholder_kappa": kappa,
               "placeholder_R": R},
    )


def identify_flow(
    record: Experiment,
    known: KnownConstants,
    *,
    kappa: float,
    R: float,
    p_krit: float,
    kappa_std: float = 0.0,
    R_std: float = 0.0,
    p_krit_std: float = 0.0,
    mdot_limit: float = MDOT_LIMIT,
    x_v_min: float = 0.0,
    min_samples: int = 50,
    name: str = "flow",
    estimator: str = "iv",
    iv_delay: float = IV_DELAY,
) -> StepResult:
    """Identify the edge coefficients a_i d_i (step S3).

    Parameters
    ----------
    record : Experiment
        Flow test (closed-loop sine with |ṁ| within the sensor range)
        with ``x_v``, ``p_I``, ``p_II``, ``mdot_I``, ``mdot_II`` and
        optionally ``T_I``, ``T_II``.
    known : KnownConstants
        Supply and exhaust pressure, supply temperature.
    kappa : float
        Isentropic exponent from S2 [-].
    R : float
        Gas constant from S2 [J/(kg·K)].
    p_krit : float
        Critical pressure ratio from S0 [-].
    kappa_std : float
        Std of κ, propagated into the edges' std (delta method).
    R_std : float
        Std of R, propagated likewise.
    p_krit_std : float
        Std of p_krit, propagated likewise (∂(a_i d_i)/∂p_krit by
        re-solving at p_krit ± 0.001).
    mdot_limit : float
        Mass-flow sensor range [kg/s]; saturated samples are excluded.
    x_v_min : float
        Exclude samples with |x_v| at or below this [m].
    min_samples : int
        Fewest unsaturated samples an edge needs.
    name : str
        Record name for the result.
    estimator : {"iv", "ls"}
        "iv" (default): instrumental variables, the regressors ±`iv_delay`
        away as instruments (module notes); "ls": least squares.
    iv_delay : float
        Delay of the instruments [s]; default 2 ms.

    Returns
    -------
    StepResult
        ``ad_1`` … ``ad_4`` [m] for the identifiable edges.  The covariance
        is the LS one robust to coloured residuals (Newey–West) plus the
        inserted κ, R and p_krit uncertainties (delta method).

    Raises
    ------
    IdentifiabilityError
        No edge is identifiable.

    Warns
    -----
    ServoidWarning
        Some edges are unidentifiable (the message names them and says
        why), or the flow sensor is saturated on most of the record.
    """
    known = check_known(known)
    kappa = check_positive("kappa", kappa, "")
    R = check_positive("R", R, "J/(kg·K)")
    p_krit = as_float("p_krit", p_krit)
    kappa_std = as_float("kappa_std", kappa_std, nonneg=True)
    R_std = as_float("R_std", R_std, nonneg=True, unit="J/(kg·K)")
    if not 0.0 <= p_krit < 1.0:
        raise DataError(f"p_krit must lie in [0, 1), got {p_krit:g}")
    check_option("estimator", estimator, _ESTIMATORS)
    delay = _delay_samples(iv_delay, record.dt)
    chambers, notes, mask = _chamber_data(record, known, mdot_limit, x_v_min, min_samples,
                                          "S3 (flow)", delay)
    p_krit_std = as_float("p_krit_std", p_krit_std, nonneg=True)
    use_iv = estimator == "iv"
    ls_theta: dict[str, float] = {}

    def fit(b: float) -> list[Any]:
        out = []
        for c in chambers:
            names_c = tuple(f"ad_{e}" for e in c.edges)
            phi = c.regressors(b, kappa, R)
            res = lstsq(phi, c.mdot, names_c)
            ls_theta.update(zip(names_c, (float(v) for v in res.theta), strict=True))
            if use_iv:
                z = c.instruments(b, kappa, R, delay)
                theta = np.linalg.solve(z.T @ phi, z.T @ c.mdot)
                rss_iv = float(np.sum((c.mdot - phi @ theta) ** 2))
                res = dataclasses.replace(res, theta=theta, rss=rss_iv)
            out.append(res)
        return out

    fits = fit(p_krit)
    ls_values = dict(ls_theta)
    values: list[float] = []
    names: list[str] = []
    groups = []
    rss, rows = 0.0, 0
    per_edge = {}
    for c, res in zip(chambers, fits, strict=True):
        ad = np.asarray(res.theta, dtype=float)
        phi = c.regressors(p_krit, kappa, R)
        resid = c.mdot - phi @ ad
        groups.append([(phi, resid, c.rows, c.instruments(p_krit, kappa, R, delay))
                       if use_iv else (phi, resid, c.rows)])
        values += ad.tolist()
        names += [f"ad_{e}" for e in c.edges]
        rss += res.rss
        rows += res.n_rows
        for k, e in enumerate(c.edges):
            on = c.open_rows[e]
            per_edge[f"ad_{e}"] = {"samples": int(on.sum()), "ls_std": float(res.std[k]),
                                   "rms_residual": math.sqrt(float(np.mean(resid[on] ** 2)))}
    # per-chamber LS, block diagonal; residuals coloured by the anti-alias filter and the
    # sensor lag: Newey–West covariance
    lags = newey_west_lags(rows)
    cov = np.zeros((len(values), len(values)))
    at = 0
    for group in groups:
        block = hac_covariance(group, lags)
        cov[at:at + block.shape[0], at:at + block.shape[0]] = block
        at += block.shape[0]
    ls_var = np.diag(cov).copy()
    # ad ∝ √R/ψ_max(κ) for the measured lumped coefficients: delta method, fully
    # correlated across the edges (one κ, one R inserted into all of them)
    dlog_psi = (math.log(psi_max(kappa + 1e-6)) - math.log(psi_max(kappa - 1e-6))) / 2e-6
    g = np.array(values) * math.sqrt((R_std / (2 * R)) ** 2 + (dlog_psi * kappa_std) ** 2)
    cov += np.outer(g, g)
    # p_krit (S0) enters the regressors nonlinearly: re-solve at p_krit ± h
    h = min(1e-3, 0.5 * min(p_krit, 1.0 - p_krit)) if p_krit > 0.0 else 1e-3

    def solve(_: int, delta: float) -> NDArray[np.float64]:
        return np.concatenate([np.asarray(r.theta, dtype=float) for r in fit(p_krit + delta)])

    cov, grads = propagate(cov, solve, [(p_krit_std, h)])
    for k, n in enumerate(names):
        per_edge[n].update({"hac_std": math.sqrt(ls_var[k]),
                            "d_dp_krit": float(grads[0][k])})
    est = Estimate(
        model=None, parameters=np.array(values), names=tuple(names),
        covariance=cov, noise_variance=rss / max(rows - len(values), 1),
        n_samples=rows, method="ls", units=("m",) * len(values),
        options={"kappa": kappa, "R": R, "p_krit": p_krit, "mdot_limit": mdot_limit,
                 "mdot_sensor_bandwidth": known.mdot_sensor_bandwidth,
                 "p_krit_std": p_krit_std, "hac_lags": lags, "estimator": estimator,
                 "ls_values": ls_values,
                 "iv_delay_samples": delay,
                 "covariance": f"per-chamber {'IV' if use_iv else 'LS'} (Newey–West, coloured "
                               "residuals); the std of κ, R and p_krit propagated (delta "
                               "method)"},
    )
    return StepResult(
        step="S3", title="flow coefficients a_i d_i of the valve edges", equation=_EQ_S3,
        record=name, estimate=est, mask=mask, method="iv" if use_iv else "ls",
        notes=tuple(notes), extra={"edges": per_edge},
    )


# -- helpers --------------------------------------------------------------------------------


def _chamber_data(
    record: Experiment, known: KnownConstants, mdot_limit: float, x_v_min: float,
    min_samples: int, step: str, delay: int = 0,
) -> tuple[list[_ChamberData], list[str], NDArray[np.bool_]]:
    x_v_min = as_float("x_v_min", x_v_min, nonneg=True)
    min_samples = as_int("min_samples", min_samples, minimum=1)
    x_v = channel(record, "x_v", step)
    p_1, p_2 = pressures(record, step)
    flows = {"I": channel(record, "mdot_I", step), "II": channel(record, "mdot_II", step)}
    temps = {"I": temperature(record, "T_I", known), "II": temperature(record, "T_II", known)}
    press = {"I": p_1, "II": p_2}
    limit = check_positive("mdot_limit", mdot_limit, "kg/s") * _SATURATION_MARGIN
    start = mdot_sensor_lag(np.zeros(record.n_samples), record.dt, known, step)[1]

    def lag(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return mdot_sensor_lag(x, record.dt, known, step)[0]

    notes: list[str] = []
    for chamber, m in flows.items():
        share = float(np.mean(np.abs(m) >= limit))
        if share > 0.5:
            msg = (f"{step}: the mass-flow channel mdot_{chamber} is saturated (|ṁ| >= "
                   f"{limit * 1e3:.3g} g/s) on {100 * share:.0f} % of the record; those samples "
                   "are excluded — reduce the excitation so |ṁ| stays within the sensor range")
            warn(msg, ServoidWarning)
            notes.append(msg)
    missing: dict[int, str] = {}
    mask = np.zeros(record.n_samples, dtype=bool)
    big = np.abs(x_v) > x_v_min
    big[:max(start, delay)] = False  # the sensor-lag filter's start-up; the instruments
    if delay:
        big[-delay:] = False
    chambers: list[_ChamberData] = []
    for chamber in ("I", "II"):
        # a saturated reading is clipped after the sensor's lag: every other sample is a
        # valid reading of the lagged flow, whatever its neighbours
        ok = big & (np.abs(flows[chamber]) < limit)
        found: list[int] = []
        for edge, (ch, sign, _) in EDGES.items():
            if ch != chamber:
                continue
            side = big & (np.sign(x_v) == sign)
            n_side, n_ok = int(side.sum()), int((side & ok).sum())
            if n_ok >= min_samples:
                found.append(edge)
                continue
            word = "positive" if sign > 0 else "negative"
            if n_side < min_samples:
                missing[edge] = (f"spool never {word}" if n_side == 0 else
                                 f"spool {word} on only {n_side} samples")
            else:
                missing[edge] = (f"ṁ_{chamber} saturated on {n_side - n_ok} of the {n_side} "
                                 f"samples with x_v {word}")
        if not found:
            continue
        # rows: where a kept edge is open (an unidentifiable edge's rows carry its flow)
        keep = np.zeros(record.n_samples, dtype=bool)
        for edge in found:
            keep |= np.sign(x_v) == EDGES[edge][1]
        idx = np.flatnonzero(ok & keep)
        mask[idx] = True
        chambers.append(_ChamberData(
            chamber=chamber, edges=tuple(found), rows=idx, mdot=flows[chamber][idx],
            area={e: math.pi * np.abs(x_v) * (np.sign(x_v) == EDGES[e][1]) for e in found},
            p_ch=press[chamber], t_ch=temps[chamber], p_S=known.p_S, p_R=known.p_R,
            T_S=known.T_S,
            open_rows={e: np.sign(x_v[idx]) == EDGES[e][1] for e in found}, lag=lag,
        ))
    if missing:
        reasons: dict[str, list[int]] = {}
        for edge, why in missing.items():
            reasons.setdefault(why, []).append(edge)
        text = "; ".join(
            f"{why}: edge{'s' if len(es) > 1 else ''} "
            f"{' and '.join(str(e) for e in es)} unidentifiable" for why, es in reasons.items())
        msg = f"{step}: {text} (need at least {min_samples} unsaturated samples per edge)"
        if not chambers:
            raise IdentifiabilityError(msg)
        warn(msg, ServoidWarning)
        notes.append(msg)
    return chambers, notes, mask


def _delay_samples(iv_delay: float, dt: float) -> int:
    delay = check_positive("iv_delay", iv_delay, "s")
    return max(1, round(delay / dt))


def _separable_iv(
    chambers: list[_ChamberData], b: float, coef: NDArray[np.float64],
    bounds: tuple[float, float], h: float, delay: int, kappa: float, R: float,
) -> tuple[float, NDArray[np.float64], NDArray[np.float64], dict[str, Any]] | None:
    """Instrumental-variable solution of the flow equations in θ = (b, c).

    Gauss–Newton on the moment equations ``Σ z_t r_t(θ) = 0`` from the
    separable LS estimate, with z_t the model's Jacobian row averaged over
    the samples ``delay`` before and after t.  Returns None when it does
    not converge or leaves `bounds`.
    """
    ncol = sum(len(c.edges) for c in chambers)
    col0 = np.cumsum([0] + [len(c.edges) for c in chambers])

    def system(b: float, coef: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        jac, inst, resid, index = [], [], [], []
        for j, c in enumerate(chambers):
            cols = c.columns(b, kappa, R)
            cj = coef[col0[j]:col0[j + 1]]
            dcol = (c.columns(b + h, kappa, R) - c.columns(b - h, kappa, R)) @ cj / (2.0 * h)
            full = np.zeros((cols.shape[0], 1 + ncol))
            full[:, 0] = dcol
            full[:, 1 + col0[j]:1 + col0[j + 1]] = cols
            jac.append(full[c.rows])
            inst.append(0.5 * (full[c.rows - delay] + full[c.rows + delay]))
            resid.append(c.mdot - cols[c.rows] @ cj)
            index.append(c.rows)
        return tuple(jac), tuple(inst), tuple(resid), tuple(index)

    theta = np.r_[b, coef]
    iterations = 0
    # the instruments are held for a pass (Gauss–Newton is then exact for the moment
    # equations) and rebuilt at the pass's solution for the next
    for _pass in range(2):
        inst = system(float(theta[0]), theta[1:])[1]
        for _ in range(30):
            iterations += 1
            jac, _, resid, _ = system(float(theta[0]), theta[1:])
            a = sum(z.T @ j for z, j in zip(inst, jac, strict=True))
            g = sum(z.T @ r for z, r in zip(inst, resid, strict=True))
            try:
                delta = np.linalg.solve(a, g)
            except np.linalg.LinAlgError:
                return None
            theta = theta + delta
            if not bounds[0] <= theta[0] <= bounds[1] or not np.all(np.isfinite(theta)):
                return None
            if abs(delta[0]) < 1e-6 and np.all(np.abs(delta[1:]) <= 1e-7 * np.abs(theta[1:])):
                break
        else:
            return None
    jac, _, resid, index = system(float(theta[0]), theta[1:])
    n = sum(r.size for r in resid)
    cov = hac_covariance(list(zip(jac, resid, index, inst, strict=True)), newey_west_lags(n))
    return float(theta[0]), theta[1:], cov, {"estimator": "iv", "iv_iterations": iterations,
                                               "iv_delay_samples": delay}
