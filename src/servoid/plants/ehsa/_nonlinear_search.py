"""The search behind :func:`refine_nonlinear_ehsa`: coordinates, probes, fit, covariance.

Private to :mod:`._nonlinear` (see its notes for the reasons): the
optimiser's coordinates (:class:`Coordinate`), the identifiability probe at
the start, bounded trust-region searches from one or several starts, the
central Jacobian at the optimum, and its white, robust or bootstrap
covariance from the shared :mod:`servoid.estimate._covariance`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._errors import ConvergenceError, ServoidWarning
from ..._lazy import optimize
from ..._warn import warn
from ...estimate import (
    bootstrap_covariance,
    draw_starts,
    least_squares_covariance,
    summarise_starts,
)
from ._nonlinear_model import UNITS, NonlinearEhsa

__all__ = [
    "Coordinate",
    "add_peaks",
    "bootstrap",
    "bound_notes",
    "covariance_of",
    "final_jacobian",
    "probe",
    "search",
    "summary_in_theta",
    "values_of",
]

_PROBE = 0.05  # [z] parameter move of the identifiability probe (5 %)
_STEP = 0.01  # [z] finite-difference step (see the notes of ._nonlinear)
_PENALTY = 1e3  # residual [m] of a trial whose simulation fails: 1 km, beyond any stroke
_COST_FLOOR = 1e-24  # costs within this multiple of Σy² are rounding (as fit_greybox)
_REASONS = {
    "K": "the output does not depend on the velocity gain",
    "omega_hp": "the hydraulic resonance is not excited",
    "delta_hp": "the hydraulic resonance is not excited",
    "F_c": "friction does not show in the position",
    "v_s_max": "the spool never reaches its rate limit",
    "x_s_max": "the spool never reaches its travel limit (no flow saturation)",
    "x_f_max": "the flapper never reaches the nozzles",
    "T_d": "the dead time does not show",
    "u_0": "the valve overlap does not show",
}

Simulate = Callable[[Mapping[str, float]], "NDArray[np.float64] | None"]


@dataclass(frozen=True)
class Coordinate:
    """One fitted parameter: start, bounds and the optimiser's coordinate."""

    name: str
    start: float
    lower: float
    upper: float
    log: bool
    scale: float  # θ = θ₀ + scale·z when not log

    def value(self, z: float) -> float:
        """θ at coordinate z."""
        return self.start * math.exp(z) if self.log else self.start + self.scale * z

    def z_bounds(self) -> tuple[float, float]:
        """The bounds in z (−inf for a log parameter bounded at 0)."""
        if self.log:
            lo = math.log(self.lower / self.start) if self.lower > 0 else -np.inf
            return lo, math.log(self.upper / self.start)
        return (self.lower - self.start) / self.scale, (self.upper - self.start) / self.scale

    def derivative(self, z: float) -> float:
        """dθ/dz."""
        return self.value(z) if self.log else self.scale




def values_of(coords: Sequence[Coordinate], z: NDArray[np.float64]) -> dict[str, float]:
    return {cd.name: cd.value(float(v)) for cd, v in zip(coords, z, strict=True)}


def probe(coords: Sequence[Coordinate], simulate: Simulate, y0: NDArray[np.float64],
           sigma: float) -> dict[str, str]:
    """Flag parameters the output does not move with at the start."""
    flags = {}
    for cd in coords:
        lo, hi = cd.z_bounds()
        moves = []
        for step in (_PROBE, -_PROBE):
            z = min(max(step, lo), hi)
            if z == 0.0:
                continue
            y = simulate({cd.name: cd.value(z)})
            if y is not None:
                moves.append(float(np.linalg.norm(y - y0)) / abs(z))
        if moves and sigma > max(moves):  # σ/‖∂y/∂z‖ > 1
            flags[cd.name] = (f"{_REASONS[cd.name]}: a ±{100 * _PROBE:g} % change moves the "
                              f"simulated position by {max(moves) * _PROBE / sigma:.2g}·σ over "
                              f"the whole record, less than the {_PROBE:g}·σ that would "
                              "fix it to ±100 %")
    return flags


def add_peaks(flags: dict[str, str], model: NonlinearEhsa,
               records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]]) -> None:
    """Say how far a flagged travel limit is from what the record reaches."""
    peak = {"x_s_max": 0.0, "x_f_max": 0.0}
    for r, y in records:
        sig = model.internals(r, y0=float(y[0]))
        peak["x_s_max"] = max(peak["x_s_max"], float(np.max(np.abs(sig["x_s"]))))
        peak["x_f_max"] = max(peak["x_f_max"], float(np.max(np.abs(sig["x_f"]))))
    for name, what in (("x_s_max", "spool"), ("x_f_max", "flapper")):
        if name in flags:
            limit = float(getattr(model.params, name))
            flags[name] += (f" (the {what} travels at most {1e6 * peak[name]:.3g} µm at the "
                            f"samples, {100 * peak[name] / limit:.3g} % of the limit "
                            f"{1e6 * limit:.3g} µm; a larger amplitude reaches it)")


def solve(coords: Sequence[Coordinate], simulate: Simulate, y: NDArray[np.float64],
           z_start: NDArray[np.float64], max_nfev: int | None) -> optimize.OptimizeResult:
    """One bounded trust-region search from z_start (forward differences, 1 %)."""
    lo = np.array([cd.z_bounds()[0] for cd in coords])
    hi = np.array([cd.z_bounds()[1] for cd in coords])
    cache: dict[bytes, NDArray[np.float64]] = {}

    def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
        key = z.tobytes()
        if key not in cache:
            yh = simulate(values_of(coords, z))
            cache.clear()
            cache[key] = np.full(y.size, _PENALTY) if yh is None else y - yh
        return cache[key]

    def jacobian(z: NDArray[np.float64]) -> NDArray[np.float64]:
        r0 = residuals(z)
        cols = []
        for k in range(z.size):
            h = _STEP if z[k] + _STEP <= hi[k] else -_STEP
            zk = z.copy()
            zk[k] += h
            yh = simulate(values_of(coords, zk))
            rk = np.full(y.size, _PENALTY) if yh is None else y - yh
            cols.append((rk - r0) / h)
        return np.column_stack(cols)

    inside = np.clip(z_start, np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf))
    return optimize.least_squares(
        residuals, inside, jac=jacobian, bounds=(lo, hi), method="trf", x_scale=1.0,
        ftol=1e-8, xtol=1e-6, gtol=1e-8,
        max_nfev=max_nfev if max_nfev is not None else 30 * (len(coords) + 1))


def failure(res: optimize.OptimizeResult, coords: Sequence[Coordinate]) -> str | None:
    if np.any(np.asarray(res.fun) == _PENALTY):
        return f"the simulation fails at the final point {values_of(coords, res.x)}"
    if res.status <= 0:
        return f"{res.message.strip()} after {res.nfev} evaluations (cost {res.cost:.4g})"
    return None


def search(
    coords: Sequence[Coordinate], simulate: Simulate, y: NDArray[np.float64],
    max_nfev: int | None, multistart: int, generator: np.random.Generator | None,
    sigma: float,
) -> tuple[NDArray[np.float64], dict[str, Any], Any]:
    """The given start and `multistart` random ones; the best, its report, the summary."""
    z0 = np.zeros(len(coords))
    starts = [z0]
    if multistart:
        assert generator is not None
        lo = np.array([cd.z_bounds()[0] for cd in coords])
        hi = np.array([cd.z_bounds()[1] for cd in coords])
        is_log = np.array([cd.log for cd in coords])
        starts += draw_starts(z0, lo, hi, is_log, multistart, generator)
    results: list[optimize.OptimizeResult | None] = []
    first_failure = ""
    for k, z_start in enumerate(starts):
        res = solve(coords, simulate, y, z_start, max_nfev)
        why = failure(res, coords)
        if k == 0 and why:
            first_failure = why
        results.append(None if why else res)
    if all(q is None for q in results):
        raise ConvergenceError(
            f"nonlinear EHSA refinement: the search did not converge from "
            f"{'any of the ' + str(len(starts)) + ' starts' if multistart else 'the start'} "
            f"({first_failure}); start closer (e.g. from the one-step fit), fit fewer "
            "parameters or raise max_nfev")
    costs = [2.0 * q.cost if q is not None else np.inf for q in results]
    best = results[int(np.argmin(costs))]
    assert best is not None
    summary = None
    if multistart:
        summary = (costs, [None if q is None else np.asarray(q.x) for q in results],
                   _COST_FLOOR * float(y @ y))
    report = {"nfev": int(best.nfev), "status": int(best.status),
              "message": str(best.message), "cost": float(best.cost),
              "optimality": float(best.optimality)}
    if first_failure:
        report["first_start_failed"] = first_failure
    return np.asarray(best.x, dtype=float), report, summary


def summary_in_theta(summary: Any, fit: Sequence[Coordinate], keep: Sequence[int]) -> Any:
    """The multistart summary with θ (kept parameters) instead of z."""
    if summary is None:
        return None
    costs, zs, floor = summary
    thetas = [None if z is None else np.array([fit[k].value(float(z[k])) for k in keep])
              for z in zs]
    return summarise_starts(costs, thetas, floor)


def final_jacobian(
    coords: Sequence[Coordinate], z: NDArray[np.float64], simulate: Simulate,
    y_hat: NDArray[np.float64], sigma: float,
) -> tuple[NDArray[np.float64], dict[str, str]]:
    """Central differences of ŷ in z (one-sided at a bound), and late flags."""
    cols, late = [], {}
    for k, cd in enumerate(coords):
        lo, hi = cd.z_bounds()
        sides = []
        for h in (min(_STEP, hi - z[k]), -min(_STEP, z[k] - lo)):
            if abs(h) < 1e-12:
                continue
            zk = z.copy()
            zk[k] += h
            yk = simulate(values_of(coords, zk))
            if yk is None:
                raise ConvergenceError(
                    f"the simulation fails next to the optimum when {cd.name} moves by "
                    f"{100 * h:.2g} %; the optimum sits on the edge of the physical region")
            sides.append((yk - y_hat) / h)
        col = sides[0] if len(sides) == 1 else 0.5 * (sides[0] + sides[1])
        norm = float(np.linalg.norm(col))
        if sigma / max(norm, 1e-300) > 1.0:
            late[cd.name] = (f"{_REASONS[cd.name]} at the fitted values (alone, the data fix it "
                             f"to no better than ±{100 * sigma / max(norm, 1e-300):.3g} %)")
        cols.append(col)
    jac = np.column_stack(cols) if cols else np.zeros((y_hat.size, 0))
    return jac, late


def covariance_of(kind: str, jac: NDArray[np.float64], resid: NDArray[np.float64],
                lengths: Sequence[int]) -> tuple[NDArray[np.float64] | None, int | None]:
    """Covariance of z from the Jacobian of ŷ; None when JᵀJ is singular."""
    n = jac.shape[1]
    if n == 0:
        return np.zeros((0, 0)), None
    cuts = np.cumsum(lengths)[:-1]
    res = least_squares_covariance("white" if kind == "bootstrap" else kind,
                                   [np.split(-jac, cuts)], [np.split(resid, cuts)],
                                   max(resid.size - n, 1))
    if res.singular:
        return None, None
    return res.covariance, res.ar_order


def bootstrap(
    fitted: Sequence[Coordinate], z_hat: NDArray[np.float64], values: Mapping[str, float],
    simulate: Simulate, y_hat: NDArray[np.float64], resid: NDArray[np.float64],
    lengths: Sequence[int], max_nfev: int | None, n_bootstrap: int,
    generator: np.random.Generator,
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Covariance of θ from refits on ``ŷ(θ̂) + ε*`` (sieve resamples)."""
    cuts = np.cumsum(lengths)[:-1]
    dof = max(resid.size - len(fitted), 1)

    def simulate_fitted(vals: Mapping[str, float]) -> NDArray[np.float64] | None:
        merged = dict(values)
        merged.update(vals)
        return simulate(merged)

    def refit(resampled: list[list[NDArray[np.float64]]]) -> NDArray[np.float64] | None:
        y_star = y_hat + np.concatenate(resampled[0])
        res = solve(fitted, simulate_fitted, y_star, z_hat, max_nfev)
        if failure(res, fitted):
            return None
        return np.array([cd.value(float(z)) for cd, z in zip(fitted, res.x, strict=True)])

    boot = bootstrap_covariance([np.split(resid, cuts)], dof, refit, n_bootstrap, generator)
    if boot.samples.shape[0] < 2:
        raise ConvergenceError(f"nonlinear EHSA refinement: only {boot.samples.shape[0]} of "
                               f"{n_bootstrap} bootstrap refits converged; use "
                               "covariance='robust'")
    if boot.failed > 0.1 * n_bootstrap:
        _warn(f"{boot.failed} of {n_bootstrap} bootstrap refits failed and were left out; the "
              "bootstrap covariance may understate the spread")
    lo, hi = np.percentile(boot.samples, [2.5, 97.5], axis=0)
    info = {"method": "ar-sieve", "resamples": int(n_bootstrap), "failed": int(boot.failed),
            "ar_orders": list(boot.ar_orders),
            "percentile_95": {cd.name: [float(a), float(b)]
                              for cd, a, b in zip(fitted, lo, hi, strict=True)}}
    return boot.covariance, info


def bound_notes(coords: Sequence[Coordinate], theta: NDArray[np.float64]) -> list[str]:
    notes = []
    for cd, v in zip(coords, theta, strict=True):
        for edge, label in ((cd.lower, "lower"), (cd.upper, "upper")):
            if abs(v - edge) <= 1e-6 * max(abs(edge), abs(cd.start), 1e-30):
                notes.append(f"{cd.name} = {v:.6g} {UNITS[cd.name]} sits on its {label} bound: "
                             "its interval ignores the bound; widen it or revisit the model")
    return notes


def _warn(message: str) -> None:
    warn(message, ServoidWarning)
