"""Whether a covariance describes its estimate: the covariance one σ away.

The intervals of every closed-loop estimator here are those of its
linearised (delta-method) covariance P(θ̂), evaluated at the estimate.
They hold when P barely changes over the region they describe.  A record
that carries little information about part of the dynamics (a slow
reference through a fast loop leaves the fast poles almost unseen) makes
the criterion far from quadratic there: P(θ) then changes by a factor
within one standard deviation of θ̂, the estimate lands where the
curvature happens to be large, and it reports intervals several times too
narrow (Bates & Watts, *Nonlinear Regression Analysis*, 1988, ch. 7;
the parameter-effects curvature).

:func:`interval_check` re-evaluates the covariance one standard
deviation either side of θ̂ along the direction the covariance leaves
least determined (the leading eigenvector of the correlation matrix) and
reports when a standard deviation changes by more than ×1.4 (or the
model stops being one the method can evaluate, e.g. its closed loop
turns unstable).  The bound is where the interval stops being a 95 %
one: a reported σ that is 1.4 times too small (or large) turns the
±1.96σ interval into a ±1.4σ (±2.7σ) one of the true spread, a coverage
of 84 % (99.3 %), outside 90–98 %.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from .._errors import ServoidError

__all__ = ["LINEARITY_RATIO", "interval_check", "is_noise_free"]

#: Largest change (×) of a standard deviation one σ from the estimate that keeps the
#: ±1.96σ interval's coverage inside 90–98 % (1.96/1.4 → 84 %, 1.96·1.4 → 99.3 %).
LINEARITY_RATIO = 1.4
#: Residual power, relative to the output's, below which a fit is exact (round-off level).
_EXACT = 1e-16
#: Share of the weak direction a coefficient must carry to be named in the message.
_NAMED = 0.3


def interval_check(
    theta: NDArray[np.float64],
    covariance: NDArray[np.float64],
    covariance_at: Callable[[NDArray[np.float64]], NDArray[np.float64] | None],
    names: Sequence[str],
    also: Sequence[tuple[str, NDArray[np.float64]]] = (),
) -> tuple[float, str | None]:
    """The largest change of a standard deviation one σ from θ̂, and a verdict.

    Parameters
    ----------
    theta : ndarray
        The estimate θ̂.
    covariance : ndarray
        Its covariance P(θ̂).
    covariance_at : callable
        P(θ) by the same formula at another θ, or None where the method
        cannot evaluate its model (an unstable simulation).
    names : sequence of str
        The coefficients' names.
    also : sequence of (str, ndarray)
        Other consistent estimates of the same θ (named, e.g. "the
        closed-loop IV estimate"): P must not change there either, since
        the interval claims to hold them.

    Returns
    -------
    ratio : float
        ``max_i max(σ_i(θ)/σ_i(θ̂), σ_i(θ̂)/σ_i(θ))`` over θ = θ̂ ± d (inf
        where P cannot be evaluated).
    verdict : str or None
        Why the intervals do not hold, or None when the ratio is within
        :data:`LINEARITY_RATIO`.
    """
    theta = np.asarray(theta, dtype=float)
    sd = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    if theta.size == 0 or not np.all(np.isfinite(sd)) or np.any(sd <= 0.0):
        return 1.0, None
    corr = covariance / np.outer(sd, sd)
    eig, vec = np.linalg.eigh(0.5 * (corr + corr.T))
    lead = vec[:, -1]
    step = sd * lead * np.sqrt(max(float(eig[-1]), 0.0))
    ratio, where = 1.0, ""
    points = [("", theta + step), ("", theta - step)] + [(n, np.asarray(p)) for n, p in also]
    for label, point in points:
        here = _ratio(covariance_at, point, sd)
        if here > ratio:
            ratio, where = here, label
    if ratio <= LINEARITY_RATIO:
        return ratio, None
    weak = [n for n, v in zip(names, lead, strict=True) if abs(v) >= _NAMED * np.max(np.abs(lead))]
    change = ("the model there cannot be simulated (its loop turns unstable)" if np.isinf(ratio)
              else f"a standard deviation changes ×{ratio:.2g}")
    place = (f"at {where}" if where else
             f"one standard deviation from the estimate along ({', '.join(weak)})")
    return ratio, (
        f"the record carries too little information about part of the dynamics for the "
        f"linearised intervals: {place}, {change} (more than ×{LINEARITY_RATIO} turns a 95 % interval "
        "into one below 84 % or above 99 %), so the reported intervals are not 95 % ones. "
        "Excite the loop at the plant's own speed (a shorter reference bit, a richer "
        "reference), record longer, or fit lower orders"
    )



def _ratio(
    covariance_at: Callable[[NDArray[np.float64]], NDArray[np.float64] | None],
    point: NDArray[np.float64],
    sd: NDArray[np.float64],
) -> float:
    """Largest change (×) of a standard deviation at `point` (inf where P fails)."""
    try:
        with np.errstate(all="ignore"):
            other = covariance_at(point)
    except (ServoidError, np.linalg.LinAlgError, FloatingPointError, ValueError):
        return np.inf
    if other is None:
        return np.inf
    var = np.diag(np.asarray(other, dtype=float))
    if not np.all(np.isfinite(var)) or np.any(var <= 0.0):
        return np.inf
    s = np.sqrt(var)
    return max(float(np.max(s / sd)), float(np.max(sd / s)))


def is_noise_free(residuals: Sequence[NDArray[np.float64]],
                  outputs: Sequence[NDArray[np.float64]]) -> bool:
    """Whether the residuals are at round-off level: the covariance is then ~0 and not checked."""
    power = sum(float(e @ e) for e in residuals)
    return power <= _EXACT * max(sum(float(y @ y) for y in outputs), 1e-300)
