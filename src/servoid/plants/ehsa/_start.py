"""Starting values for the one-step fit that need no other estimator.

The one-step criterion has local minima in ω_hp (a resonance the model
places on the wrong side of the excited band fits the low frequencies
almost as well), so it is started from several points and the best
optimum is kept (:func:`servoid.plants.ehsa.fit_one_step`).  The points
come from the data alone:

1. The closed loop ``c·G/(1 + F·G)`` of the reduced plant behaves below
   its resonance like ``(c/F)·a/(s + a)`` with ``a = F·K`` (spec §1.1,
   Eq. 11 without the s³ and s² terms).  A one-dimensional search of the
   output error of that first-order loop over log a gives K₀ = a/F.
2. With K₀, a coarse grid over ω_hp (log-spaced from a/4, below which the
   loop would be unstable for any δ ≤ 2, to the grid's upper end) and
   δ_hp ∈ {0.1, 0.3, 1, 3} is scored by the output error of the Tustin
   closed loop (cheap, and its warp is immaterial for ranking).
3. The best-scoring points with ω_hp at least a factor 1.5 apart start
   the fits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..._lazy import optimize
from ...models import TransferFunction
from ._kernels import first_order_cost, tustin_costs
from ._loop import FeedbackLoop, tustin, tustin_coefficients

__all__: list[str] = []

_DELTAS = (0.1, 0.3, 1.0, 3.0)
_N_OMEGA = 16
_DISTINCT = 1.5  # ω ratio between two starts


def grid_starts(
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    loop: FeedbackLoop,
    dt: float,
    omega_max: float,
    n_starts: int,
) -> list[NDArray[np.float64]]:
    """Return up to `n_starts` reduced starts (K, ω_hp, δ_hp), best first."""
    f0 = _static_feedback(loop)
    n_total = sum(r.size for r, _ in records)
    a_lo = 2.0 * math.pi / (n_total * dt)
    a_hi = math.pi / dt
    a = _first_order_rate(records, loop.c / f0, dt, a_lo, a_hi)
    k0 = a / f0
    w_lo = min(max(a / 4.0, a_lo), 0.5 * omega_max)
    omegas = np.geomspace(w_lo, omega_max, _N_OMEGA)
    grid = [np.array([k0, w, d]) for w in omegas for d in _DELTAS
            if not (loop.is_static and f0 * k0 >= 2.0 * d * w)]  # Routh: FK < 2δω
    costs = _costs(records, [_tustin_loop(theta, loop, dt) for theta in grid])
    scored = [(cost, theta) for cost, theta in zip(costs, grid, strict=True)
              if math.isfinite(cost)]
    if not scored:  # nothing stable on the grid: a resonance far above the band
        return [np.array([k0, omega_max, 1.0])]
    scored.sort(key=lambda item: item[0])
    chosen: list[NDArray[np.float64]] = []
    for _, theta in scored:
        if all(max(theta[1] / c[1], c[1] / theta[1]) >= _DISTINCT for c in chosen):
            chosen.append(theta)
        if len(chosen) == n_starts:
            break
    return chosen


def _static_feedback(loop: FeedbackLoop) -> float:
    f = loop.F
    gain = f.dc_gain() if isinstance(f, TransferFunction) else float(f)
    return float(gain)


def _first_order_rate(
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    gain: float, dt: float, a_lo: float, a_hi: float,
) -> float:
    """Bandwidth a [rad/s] of the first-order loop gain·a/(s + a) fitting y best."""

    pairs = [(np.ascontiguousarray(r, dtype=float), np.ascontiguousarray(y, dtype=float))
             for r, y in records]

    def cost(log_a: float) -> float:
        p = math.exp(-math.exp(log_a) * dt)  # ZOH image: y(k) = p·y(k−1) + gain·(1 − p)·r(k−1)
        return sum(first_order_cost(p, gain * (1.0 - p), r, y) for r, y in pairs)

    # bounded Brent on a log grid's best cell: the cost is smooth and unimodal there
    grid = np.linspace(math.log(a_lo), math.log(a_hi), 24)
    values = [cost(g) for g in grid]
    i = int(np.argmin(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = optimize.minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-3})
    return float(math.exp(res.x))


def _tustin_loop(theta: NDArray[np.float64], loop: FeedbackLoop,
                 dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(b, a)`` of the Tustin closed loop at θ, b as long as a (lfilter's form), a monic."""
    k, w, d = theta
    kw2 = k * w * w
    if loop.is_static:
        f = float(loop.F)  # type: ignore[arg-type]
        num, den = tustin_coefficients([loop.c * kw2], [1.0, 2.0 * d * w, w * w, f * kw2], dt)
    else:
        model = loop.close(tustin(TransferFunction([kw2], [1.0, 2.0 * d * w, w * w, 0.0]), dt))
        num, den = np.asarray(model.num, float), np.asarray(model.den, float)
    num = np.concatenate([np.zeros(den.size - num.size), num])
    return num / den[0], den / den[0]


def _costs(records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
           models: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]]) -> list[float]:
    """Output error Σ (y − model·r)² of each ``(b, a)`` over the records (inf if not finite)."""
    if not models:
        return []
    width = max(a.size for _, a in models)
    nums = np.zeros((len(models), width))
    dens = np.zeros((len(models), width))
    for i, (b, a) in enumerate(models):
        nums[i, : b.size] = b  # trailing zeros: the same filter
        dens[i, : a.size] = a
    total = np.zeros(len(models))
    with np.errstate(all="ignore"):
        for r, y in records:
            total += tustin_costs(nums, dens, np.ascontiguousarray(r, dtype=float),
                                  np.ascontiguousarray(y, dtype=float))
    return [float(c) if math.isfinite(c) else math.inf for c in total]
