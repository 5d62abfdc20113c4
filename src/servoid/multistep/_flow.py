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
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, IdentifiabilityError, ServoidWarning
from ..actuators import psi_ellipse, psi_max
from ..data import Experiment
from ..estimate import Estimate, fit_separable, lstsq
from ._common import (
    MDOT_LIMIT,
    KnownConstants,
    StepResult,
    channel,
    check_known,
    check_positive,
    pressures,
    temperature,
)

__all__ = ["EDGES", "identify_critical_pressure", "identify_flow"]

#: Edge number → (chamber, spool sign, description).
EDGES: dict[int, tuple[str, int, str]] = {
    1: ("I", -1, "chamber I → exhaust"),
    2: ("I", +1, "supply → chamber I"),
    3: ("II", -1, "supply → chamber II"),
    4: ("II", +1, "chamber II → exhaust"),
}
_SATURATION_MARGIN = 0.98
_EQ_S3 = ("(3.1), (3.2) with κ, R from S2 and p_krit from S0 inserted: samples split by "
          "sgn x_v and chamber, one LS per edge of ṁ on π|x_v|ψ(π)p_up√(2/(R T_up)) → a_i d_i; "
          "samples with a saturated ṁ sensor excluded")
_EQ_S0 = ("(3.1), (3.2) Type IV in b = p_krit: separable LS, outer grid over b (step 0.01) "
          "and Brent refinement, inner LS of the four edge coefficients (Type II for fixed b)")


@dataclass(frozen=True)
class _EdgeData:
    """Samples of one edge: index, measured flow and the ψ ingredients."""

    edge: int
    index: NDArray[np.intp]
    mdot: NDArray[np.float64]
    area: NDArray[np.float64]  # π|x_v| [m]·(a d) gives the orifice area
    p_up: NDArray[np.float64]
    p_down: NDArray[np.float64]
    c_flow: NDArray[np.float64]  # √(2/(R T_up)) at R = 1
    sign: float  # +1 flow into the chamber (supply edge), −1 out of it

    def regressor(self, b: float, kappa: float, R: float) -> NDArray[np.float64]:
        """ṁ/(a d) for critical ratio b."""
        forward = self.p_up >= self.p_down
        hi = np.where(forward, self.p_up, self.p_down)
        lo = np.where(forward, self.p_down, self.p_up)
        psi = psi_ellipse(lo / hi, b, kappa)
        mag = self.area * psi * hi * self.c_flow / math.sqrt(R)
        return self.sign * np.where(forward, mag, -mag)


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
    edges, notes, mask = _edge_data(record, known, mdot_limit, x_v_min, min_samples, "S0 (p_krit)")
    lo, hi = (float(v) for v in bounds)
    step = check_positive("step", step, "")
    grid = np.arange(lo, hi + 0.5 * step, step)
    grid = grid[grid <= hi + 1e-12]
    kappa, R = 1.4, 287.0  # placeholders: the profile over b does not depend on them
    mdot = np.concatenate([e.mdot for e in edges])
    offsets = np.cumsum([0] + [e.mdot.size for e in edges])

    def build(b: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        phi = np.zeros((mdot.size, len(edges)))
        for j, e in enumerate(edges):
            phi[offsets[j]:offsets[j + 1], j] = e.regressor(b, kappa, R)
        return phi, mdot

    labels = tuple(f"c_{e.edge}" for e in edges)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        est = fit_separable(build, (lo, hi), grid=grid, method="grid+golden", names=labels,
                            beta_name="p_krit", units=("m",) * len(edges), beta_unit="-")
    for w in caught:
        notes.append(f"S0 (p_krit): {w.message}")
        warnings.warn(str(w.message), ServoidWarning, stacklevel=2)
    return StepResult(
        step="S0 p_krit", title="critical pressure ratio p_krit of the flow function",
        equation=_EQ_S0, record=name, estimate=est, mask=mask, method="separable_ls",
        notes=tuple(notes),
        extra={"grid": est.options["grid"], "grid_rss": est.options["grid_rss"],
               "edges": [e.edge for e in edges], "placeholder_kappa": kappa,
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
    mdot_limit: float = MDOT_LIMIT,
    x_v_min: float = 0.0,
    min_samples: int = 50,
    name: str = "flow",
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
    mdot_limit : float
        Mass-flow sensor range [kg/s]; saturated samples are excluded.
    x_v_min : float
        Exclude samples with |x_v| at or below this [m].
    min_samples : int
        Fewest unsaturated samples an edge needs.
    name : str
        Record name for the result.

    Returns
    -------
    StepResult
        ``ad_1`` … ``ad_4`` [m] for the identifiable edges.

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
    if not 0.0 <= p_krit < 1.0:
        raise DataError(f"p_krit must lie in [0, 1), got {p_krit:g}")
    edges, notes, mask = _edge_data(record, known, mdot_limit, x_v_min, min_samples, "S3 (flow)")
    values, stds, names = [], [], []
    rss, rows = 0.0, 0
    dlog_psi = (math.log(psi_max(kappa + 1e-6)) - math.log(psi_max(kappa - 1e-6))) / 2e-6
    per_edge = {}
    for e in edges:
        phi = e.regressor(p_krit, kappa, R)[:, None]
        res = lstsq(phi, e.mdot, (f"ad_{e.edge}",))
        ad = float(res.theta[0])
        # ad ∝ √R/ψ_max(κ) for the measured lumped coefficient: delta method
        var = float(res.covariance[0, 0]) + (ad / (2 * R) * R_std) ** 2 + (
            ad * dlog_psi * kappa_std) ** 2
        values.append(ad)
        stds.append(math.sqrt(var))
        names.append(f"ad_{e.edge}")
        rss += res.rss
        rows += res.n_rows
        per_edge[f"ad_{e.edge}"] = {"samples": int(res.n_rows), "ls_std": float(res.std[0]),
                                    "rms_residual": math.sqrt(res.rss / res.n_rows)}
    est = Estimate(
        model=None, parameters=np.array(values), names=tuple(names),
        covariance=np.diag(np.square(stds)), noise_variance=rss / max(rows - len(values), 1),
        n_samples=rows, method="ls", units=("m",) * len(values),
        options={"kappa": kappa, "R": R, "p_krit": p_krit, "mdot_limit": mdot_limit,
                 "covariance": "per-edge LS, κ and R std propagated (delta method)"},
    )
    return StepResult(
        step="S3", title="flow coefficients a_i d_i of the valve edges", equation=_EQ_S3,
        record=name, estimate=est, mask=mask, method="ls", notes=tuple(notes),
        extra={"edges": per_edge},
    )


# -- helpers --------------------------------------------------------------------------------


def _edge_data(
    record: Experiment, known: KnownConstants, mdot_limit: float, x_v_min: float,
    min_samples: int, step: str,
) -> tuple[list[_EdgeData], list[str], NDArray[np.bool_]]:
    x_v = channel(record, "x_v", step)
    p_1, p_2 = pressures(record, step)
    flows = {"I": channel(record, "mdot_I", step), "II": channel(record, "mdot_II", step)}
    temps = {"I": temperature(record, "T_I", known), "II": temperature(record, "T_II", known)}
    press = {"I": p_1, "II": p_2}
    limit = check_positive("mdot_limit", mdot_limit, "kg/s") * _SATURATION_MARGIN
    notes: list[str] = []
    for chamber, m in flows.items():
        share = float(np.mean(np.abs(m) >= limit))
        if share > 0.5:
            msg = (f"{step}: the mass-flow channel mdot_{chamber} is saturated (|ṁ| >= "
                   f"{limit * 1e3:.3g} g/s) on {100 * share:.0f} % of the record; those samples "
                   "are excluded — reduce the excitation so |ṁ| stays within the sensor range")
            warnings.warn(msg, ServoidWarning, stacklevel=3)
            notes.append(msg)
    edges: list[_EdgeData] = []
    missing: dict[int, str] = {}
    mask = np.zeros(record.n_samples, dtype=bool)
    big = np.abs(x_v) > x_v_min
    for edge, (chamber, sign, _) in EDGES.items():
        side = big & (np.sign(x_v) == sign)
        ok = side & (np.abs(flows[chamber]) < limit)
        n_side, n_ok = int(side.sum()), int(ok.sum())
        if n_ok < min_samples:
            word = "positive" if sign > 0 else "negative"
            if n_side < min_samples:
                missing[edge] = (f"spool never {word}" if n_side == 0 else
                                 f"spool {word} on only {n_side} samples")
            else:
                missing[edge] = (f"ṁ_{chamber} saturated on {n_side - n_ok} of the {n_side} "
                                 f"samples with x_v {word}")
            continue
        idx = np.flatnonzero(ok)
        mask[idx] = True
        supply = edge in (2, 3)
        p_ch = press[chamber][idx]
        t_up = np.full(idx.size, known.T_S) if supply else temps[chamber][idx]
        edges.append(_EdgeData(
            edge=edge, index=idx, mdot=flows[chamber][idx], area=math.pi * np.abs(x_v[idx]),
            p_up=np.full(idx.size, known.p_S) if supply else p_ch,
            p_down=p_ch if supply else np.full(idx.size, known.p_R),
            c_flow=np.sqrt(2.0 / t_up), sign=1.0 if supply else -1.0,
        ))
    if missing:
        reasons: dict[str, list[int]] = {}
        for edge, why in missing.items():
            reasons.setdefault(why, []).append(edge)
        text = "; ".join(
            f"{why}: edge{'s' if len(es) > 1 else ''} "
            f"{' and '.join(str(e) for e in es)} unidentifiable" for why, es in reasons.items())
        msg = f"{step}: {text} (need at least {min_samples} unsaturated samples per edge)"
        if not edges:
            raise IdentifiabilityError(msg)
        warnings.warn(msg, ServoidWarning, stacklevel=3)
        notes.append(msg)
    return edges, notes, mask
