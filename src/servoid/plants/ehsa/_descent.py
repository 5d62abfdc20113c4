"""Loose Levenberg–Marquardt descents that rank the one-step fit's starts.

The one-step fit descends from a few grid starts to a loose tolerance only
to find which basin of the criterion is best; the fit proper (with its
covariance) then converges from the best basin with
:func:`~servoid.estimate.fit_tf_greybox`.  For these descents MINPACK's
``lmder`` (through :func:`scipy.optimize.least_squares`) costs more than the
criterion itself on a long record: its QR with column pivoting and its
careful norms pass over the residual vector some ten times per iteration.
With three parameters the normal equations are a 3×3 system, so this
Levenberg–Marquardt works on ``JᵀJ`` and ``Jᵀe`` alone.

Algorithm: Marquardt's scaling ``D = diag(JᵀJ)`` (Marquardt, J. SIAM 11(2),
1963), Nielsen's update of the damping from the gain ratio ρ (Nielsen, IMM
report 1999-05: μ ← μ·max(1/3, 1 − (2ρ − 1)³) on success, μ ← μ·ν, ν ← 2ν
on failure), the Jacobian by forward differences with the steps of
:func:`scipy.optimize.approx_derivative` (√ε·max(1, |z|)), and MINPACK's
stopping tests with its tolerances (``ftol`` on the actual and predicted
relative reductions, ``xtol`` on the scaled step, ``gtol`` on the scaled
gradient; Moré, LNM 630, 1978).  Evaluations of the Jacobian count towards
``max_nfev``, as in ``lmder`` with a finite-difference Jacobian.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__: list[str] = []

_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Descent:
    """Where a loose descent stopped."""

    x: NDArray[np.float64]
    cost: float  # ½‖e‖²
    nfev: int
    converged: bool


def descend(
    fun: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x0: NDArray[np.float64],
    *,
    ftol: float = 1e-6,
    xtol: float = 1e-6,
    gtol: float = 1e-8,
    max_nfev: int,
) -> Descent:
    """Minimise ½‖fun(x)‖² from `x0` by Levenberg–Marquardt (module docstring)."""
    x = np.array(x0, dtype=float)
    n = x.size
    e = fun(x)
    nfev = 1
    with np.errstate(over="ignore"):
        cost = 0.5 * float(e @ e)
    mu = -1.0  # set from the first JᵀJ
    nu = 2.0
    while nfev + n < max_nfev:
        jt = np.empty((n, e.size))  # the Jacobian's transpose: contiguous columns
        for j in range(n):
            h = math.sqrt(_EPS) * max(1.0, abs(x[j])) * (1.0 if x[j] >= 0 else -1.0)
            xh = x.copy()
            xh[j] += h
            h = xh[j] - x[j]  # the step actually taken
            np.subtract(fun(xh), e, out=jt[j])
            jt[j] /= h
        nfev += n
        a = jt @ jt.T
        g = jt @ e
        del jt  # n record-length columns: not held through the trial steps
        d = np.maximum(np.diag(a).copy(), 1e-300)
        if not np.all(np.isfinite(a)) or not np.all(np.isfinite(g)):
            return Descent(x, cost, nfev, False)
        if np.max(np.abs(g) / np.sqrt(d)) <= gtol * math.sqrt(2.0 * cost) or cost == 0.0:
            return Descent(x, cost, nfev, True)
        if mu < 0.0:
            mu = 1e-3  # relative to the diagonal (Marquardt's scaling)
        while True:
            try:
                step = np.linalg.solve(a + mu * np.diag(d), -g)
            except np.linalg.LinAlgError:
                mu *= nu
                nu *= 2.0
                continue
            predicted = -(float(g @ step) + 0.5 * float(step @ a @ step))
            x_new = x + step
            e_new = fun(x_new)
            nfev += 1
            with np.errstate(over="ignore"):  # a refused step may be far off
                cost_new = 0.5 * float(e_new @ e_new)
            actual = cost - cost_new
            rho = actual / predicted if predicted > 0.0 else -1.0
            scaled_step = math.sqrt(float(d @ step**2))
            scaled_x = math.sqrt(float(d @ x**2))
            if rho > 0.0 and math.isfinite(cost_new):
                x, e, cost = x_new, e_new, cost_new
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                if (abs(actual) <= ftol * (cost + actual) and predicted <= ftol * (cost + actual)
                        and rho <= 2.0):
                    return Descent(x, cost, nfev, True)
                if scaled_step <= xtol * scaled_x:
                    return Descent(x, cost, nfev, True)
                break
            if scaled_step <= xtol * scaled_x:  # the step shrank to nothing: at the minimum
                return Descent(x, cost, nfev, True)
            if nfev >= max_nfev:
                return Descent(x, cost, nfev, False)
            mu *= nu
            nu *= 2.0
    return Descent(x, cost, nfev, False)
