"""The damped Gauss–Newton search of the prediction-error methods.

From a stable start, Gauss–Newton steps on the exact gradient, damped
Levenberg–Marquardt style (λ·diag(ΨᵀΨ)) when a full step does not lower the
cost; a step that carries a root of F, C or D out of the unit circle is
first halved until it stays inside, else the root is reflected (see
:mod:`servoid.estimate._pem` for the whole method and its references).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._errors import ConvergenceError
from ._ls import damped_step
from ._pem_orders import PemOrders
from ._pem_predictor import Problem
from ._pem_start import stabilize

__all__ = ["ADVICE", "Search", "search"]

#: Damping increases (×10 each, from λ = 1e-4) tried before a step is given up.
_MAX_DAMPING = 15
#: Halvings of a Gauss–Newton step that leaves the stability region, tried before
#: the reflected step is taken.
_MAX_HALVINGS = 8
#: What a stalled search advises (the fit drops from it the settings already in use).
ADVICE = "multistart=5, initial='estimate', lower orders or detrended data"


@dataclass(frozen=True, eq=False)
class Search:
    """Where one descent ended: θ, its cost and ΨᵀΨ, and how it got there."""

    theta: NDArray[np.float64]
    cost: float
    h: NDArray[np.float64]
    iterations: int
    converged: bool
    reflected: int
    note: str


def search(problem: Problem, orders: PemOrders, theta: NDArray[np.float64], max_iter: int,
           tol: float, floor: float) -> Search:
    """Damped Gauss–Newton from θ (stable) to a local minimum of Σε²."""
    cost = problem.cost(theta)
    if not np.isfinite(cost):
        raise ConvergenceError(
            "the search diverged: the prediction errors overflow at the start. Rescale the data "
            "(calibrate to SI units, remove offsets with detrend), give a sensible init, or try "
            "multistart=5")
    h, g = problem.normal_equations(theta)
    lam, iterations, reflected, converged, note = 0.0, 0, 0, False, ""
    while True:
        step = damped_step(h, g, 0.0)
        predicted = float(g @ step)  # = ‖ΨΔ‖², twice the decrease of ½Σε² the step promises
        if not np.isfinite(predicted):
            raise ConvergenceError(
                "the search diverged: the gradient is not finite. Rescale the data, lower the "
                "orders, or try initial='estimate' or multistart=5")
        if predicted <= tol * cost or predicted <= floor:
            converged = True
            break
        if iterations >= max_iter:
            break
        lam_try = lam
        for _ in range(_MAX_DAMPING):
            delta = step if lam_try == 0.0 else damped_step(h, g, lam_try)
            trial, n_ref = stabilize(orders, theta + delta)
            trial_cost = problem.cost(trial)
            if lam_try == 0.0 and n_ref == 0:
                trial, trial_cost, n_ref = _line_search(problem, orders, theta, delta, cost,
                                                        predicted, trial, trial_cost)
            elif lam_try == 0.0:
                trial, trial_cost, n_ref = _inside_step(problem, orders, theta, delta,
                                                        trial, trial_cost, n_ref)
            if trial_cost < cost:
                break
            lam_try = max(10.0 * lam_try, 1e-4)
        else:
            if predicted <= 1e-4 * cost:
                converged, note = True, "stopped where no step lowers the cost further"
                break
            raise ConvergenceError(
                f"the search stalled after {iterations} steps: no damped step lowers the cost "
                f"although the predicted decrease is {predicted / cost:.2g} of it. Try "
                f"{ADVICE}")
        theta, cost = trial, trial_cost
        reflected += n_ref
        iterations += 1
        lam = 0.0 if lam_try <= 1e-3 else lam_try / 10.0
        h, g = problem.normal_equations(theta)
    return Search(theta, cost, h, iterations, converged, reflected, note)


def _line_search(problem: Problem, orders: PemOrders, theta: NDArray[np.float64],
                 delta: NDArray[np.float64], cost: float, predicted: float,
                 trial: NDArray[np.float64], trial_cost: float) -> tuple[NDArray[np.float64],
                                                                         float, int]:
    """One parabolic correction of the step length along a Gauss–Newton step.

    Along θ + αΔ the cost starts at c₀ with slope −2·gᵀΔ; with the cost c₁
    at α = 1 the parabola has its minimum at α* = gᵀΔ/(c₁ − c₀ + 2 gᵀΔ),
    which is 1 when the Gauss–Newton model is exact (small residuals).
    Large-residual problems (under-modelled structures) overshoot and
    zig-zag; one evaluation at α* removes most of it.
    """
    curvature = trial_cost - cost + 2.0 * predicted
    if not (np.isfinite(trial_cost) and curvature > 0):
        alpha = 0.25
    else:
        alpha = float(np.clip(predicted / curvature, 0.05, 2.0))
    if abs(alpha - 1.0) < 0.25:
        return trial, trial_cost, 0
    other, n_ref = stabilize(orders, theta + alpha * delta)
    other_cost = problem.cost(other)
    if other_cost < trial_cost:
        return other, other_cost, n_ref
    return trial, trial_cost, 0


def _inside_step(problem: Problem, orders: PemOrders, theta: NDArray[np.float64],
                 delta: NDArray[np.float64], trial: NDArray[np.float64], trial_cost: float,
                 n_ref: int) -> tuple[NDArray[np.float64], float, int]:
    """The Gauss–Newton direction shortened until F_i, C, D stay stable.

    A full step that carries a root of F, C or D across the unit circle is
    halved until none crosses (Ljung, *System Identification*, 2nd ed.,
    §10.2: the step length is reduced until the model is stable); the
    shortened step wins over the reflected one when it costs less.  Near a
    lightly damped pole the reflected full step is far off, and without
    this the search crawls on tiny damped steps (a 6th-order OE with poles
    at radius 0.98 stopped at max_iter; tests/estimate/test_pem_start.py).
    """
    alpha = 1.0
    for _ in range(_MAX_HALVINGS):
        alpha *= 0.5
        candidate = theta + alpha * delta
        if stabilize(orders, candidate)[1] == 0:
            other_cost = problem.cost(candidate)
            if other_cost < trial_cost:
                return candidate, other_cost, 0
            break
    return trial, trial_cost, n_ref
