"""Starting values of the block models, read off the data.

- **Hammerstein.** A shape linear in its parameters (polynomial,
  piecewise linear) starts from Bai's two-stage method: an ARX model on
  the basis expansion of u, whose B-coefficient matrix is split into the
  linear block and the static curve by its best rank-one approximation
  (E.-W. Bai, "An optimal two-stage identification algorithm for
  Hammerstein–Wiener nonlinear systems", Automatica 34(3), 1998,
  333–338).  Any other shape starts from a small grid on its parameters
  (breakpoints at quantiles of u, exponents, centres): an ARX model on
  f(u) for each, the one whose simulation fits best wins.
- **Wiener.** Two candidates for the linear block's output x: the best
  linear approximation (an ARX model from u to y), and — for even shapes
  such as |x|, whose best linear approximation vanishes — the dominant
  direction of a second-order Volterra kernel fitted by least squares
  (for y = g(h∗u) with g even the quadratic kernel is rank one, ∝ h hᵀ).
  For each, a static fit of y against x (with a scale for the linear
  block when the shape has none) from a grid of starts; the best wins.
- **Hammerstein–Wiener.** f from its data start, then the Wiener start on
  f(u).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._lazy import optimize
from .._lazy import signal as sps
from ._block_linear import LinearBlock, arx_fit, stable
from ._static import StaticNonlinearity

__all__ = ["Start", "hammerstein_start", "wiener_start"]

Pairs = list[tuple[NDArray[np.float64], NDArray[np.float64]]]
#: Samples used for the quadratic (Volterra) regression: enough for a start.
_VOLTERRA_SAMPLES = 20000


class Start:
    """A start: static parameters, discrete (b, f), output offset, cost."""

    def __init__(self, theta: NDArray[np.float64], b: NDArray[np.float64],
                 f: NDArray[np.float64], offset: float, cost: float, scale: float = 1.0) -> None:
        self.theta, self.b, self.f, self.offset, self.cost, self.scale = (
            theta, b, f, offset, cost, scale)


def hammerstein_start(shape: StaticNonlinearity, from_data: bool, pairs: Pairs,
                      lin: LinearBlock, offset: bool) -> Start:
    """The best start of f and G for y = G f(u) (+ offset)."""
    na, nb, nk = _arx_orders(lin)
    u_all = np.concatenate([u for u, _ in pairs])
    basis = shape._basis(u_all) if from_data else None
    starts: list[Start] = []
    if basis is not None:
        starts.append(_bai(shape, pairs, na, nb, nk, offset))
    else:
        thetas = [*shape._starts(u_all), shape.parameters] if from_data else [shape.parameters]
        for theta in thetas:
            vy = [(shape._f(u, theta), y) for u, y in pairs]
            a, b, d = arx_fit(vy, na, nb, nk, offset)
            a = stable(a)
            starts.append(Start(theta, b, a, _offset(d, a), _cost(vy, b, a, nk, _offset(d, a))))
    best = min(starts, key=lambda s: s.cost)
    if lin.unit_gain and basis is not None:  # linear in θ: move the gain into the curve
        k = best.b.sum() / best.f.sum()
        if np.isfinite(k) and k != 0:
            best.b, best.theta = best.b / k, best.theta * k
    return best


def wiener_start(shape: StaticNonlinearity, from_data: bool, pairs: Pairs, lin: LinearBlock,
                 offset: bool) -> Start:
    """The best start of G and g for y = g(G v) (+ offset), pairs of (v, y)."""
    na, nb, nk = _arx_orders(lin)
    candidates = []
    a, b, _ = arx_fit([(v, y - y.mean()) for v, y in pairs], na, nb, nk, True)
    candidates.append((b, stable(a)))
    volterra = _volterra(pairs, na, nb, nk)
    if volterra is not None:
        candidates.append(volterra)
    y_all = np.concatenate([y for _, y in pairs])
    best: Start | None = None
    for b, f in candidates:
        if not np.any(b):
            continue
        gain = b.sum() / f.sum()
        if lin.unit_gain and np.isfinite(gain) and abs(gain) > 1e-12:
            b = b / gain
        x_all = np.concatenate([sps.lfilter(np.concatenate([np.zeros(nk), b]), f, v)
                                for v, _ in pairs])
        if not np.all(np.isfinite(x_all)) or np.std(x_all) == 0:
            continue
        theta, scale, d, cost = static_fit(shape, from_data, x_all, y_all, offset)
        if best is None or cost < best.cost:
            best = Start(theta, b, f, d, cost, scale)
    if best is None:  # nothing moved x: start from the shape as it is
        b = np.zeros(nb)
        b[0] = 1.0
        return Start(shape.parameters, b, np.concatenate([[1.0], np.zeros(na)]), 0.0, np.inf)
    if not shape.free_scale and not lin.unit_gain:
        best.b = best.b * best.scale
        best.scale = 1.0
    return best


def static_fit(shape: StaticNonlinearity, from_data: bool, x: NDArray[np.float64],
               y: NDArray[np.float64], offset: bool) -> tuple[NDArray[np.float64], float,
                                                               float, float]:
    """Fit y ≈ g(s·x; θ) (+ d): θ, the scale s (1 for a free-scale shape), d and the cost."""
    basis = shape._basis(x)
    if basis is not None and shape.free_scale:  # linear: one least-squares solve
        cols = np.column_stack([basis, np.ones(x.size)]) if offset else basis
        coef, *_ = np.linalg.lstsq(cols, y, rcond=None)
        theta = coef[: basis.shape[1]]
        d = float(coef[-1]) if offset else 0.0
        r = y - cols @ coef
        return theta, 1.0, d, float(r @ r)
    scaled = not shape.free_scale
    s0 = np.std(y) / np.std(x) if scaled else 1.0
    lo, hi = shape.bounds
    starts: list[NDArray[np.float64]] = []
    for sign in ((1.0, -1.0) if scaled else (1.0,)):
        for factor in ((0.5, 1.0, 2.0) if scaled else (1.0,)):
            s = sign * factor * s0
            thetas = [*shape._starts(s * x), shape.parameters] if from_data else [
                shape.parameters]
            for theta in thetas:
                theta = np.clip(theta, lo, hi)
                d = float(np.mean(y - shape._f(s * x, theta))) if offset else 0.0
                starts.append(np.concatenate([[s] if scaled else [], theta, [d] if offset else []]))
    p_lo = np.concatenate([[-np.inf] if scaled else [], lo, [-np.inf] if offset else []])
    p_hi = np.concatenate([[np.inf] if scaled else [], hi, [np.inf] if offset else []])
    n_theta = shape.parameters.size

    def split(p: NDArray[np.float64]) -> tuple[float, NDArray[np.float64], float]:
        s = float(p[0]) if scaled else 1.0
        theta = p[int(scaled): int(scaled) + n_theta]
        return s, theta, float(p[-1]) if offset else 0.0

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        s, theta, d = split(p)
        r = y - shape._f(s * x, theta) - d
        return np.where(np.isfinite(r), r, 1e10)

    costs = [float(np.sum(residual(p) ** 2)) for p in starts]
    order = np.argsort(costs)[:3]
    best_p, best_cost = starts[int(order[0])], costs[int(order[0])]
    for k in order:
        res = optimize.least_squares(residual, starts[int(k)], bounds=(p_lo, p_hi),
                                     method="trf", max_nfev=60)
        cost = 2.0 * float(res.cost)
        if cost < best_cost:
            best_p, best_cost = res.x, cost
    s, theta, d = split(best_p)
    return np.asarray(theta, dtype=float), s, d, best_cost


# -- private ---------------------------------------------------------------------------------


def _arx_orders(lin: LinearBlock) -> tuple[int, int, int]:
    """ARX orders that stand for the linear block in the start."""
    if lin.kind == "oe":
        return lin.nf, lin.nb, lin.nk
    return lin.n_poles, lin.n_poles, 1  # a zero-order hold: n numerator terms after one delay


def _offset(d: float, a: NDArray[np.float64]) -> float:
    """Output offset of an ARX equation constant d: d/A(1)."""
    return d / a.sum() if a.sum() != 0 else 0.0


def _cost(pairs: Pairs, b: NDArray[np.float64], f: NDArray[np.float64], nk: int,
          d: float) -> float:
    num = np.concatenate([np.zeros(nk), b])
    total = 0.0
    for v, y in pairs:
        r = y - sps.lfilter(num, f, v) - d
        total += float(r @ r) if np.all(np.isfinite(r)) else np.inf
    return total


def _bai(shape: StaticNonlinearity, pairs: Pairs, na: int, nb: int, nk: int,
         offset: bool) -> Start:
    """ARX on the basis expansion, split by the best rank-one approximation (Bai 1998)."""
    rows, rhs = [], []
    p = shape.parameters.size
    lag = max(na, nk + nb - 1)
    for u, y in pairs:
        basis = shape._basis(u)
        n = y.size
        cols = [-y[lag - i: n - i] for i in range(1, na + 1)]
        for k in range(p):
            cols += [basis[lag - nk - j: n - nk - j, k] for j in range(nb)]
        if offset:
            cols.append(np.ones(n - lag))
        rows.append(np.column_stack(cols))
        rhs.append(y[lag:])
    coef, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    a = stable(np.concatenate([[1.0], coef[:na]]))
    theta_b = coef[na: na + p * nb].reshape(p, nb).T  # (nb, p): B coefficient per basis term
    left, sv, right = np.linalg.svd(theta_b, full_matrices=False)
    b = left[:, 0] * sv[0]
    theta = right[0]
    d = _offset(float(coef[-1]), a) if offset else 0.0
    vy = [(shape._f(u, theta), y) for u, y in pairs]
    return Start(theta, b, a, d, _cost(vy, b, a, nk, d))


def _volterra(pairs: Pairs, na: int, nb: int, nk: int) -> tuple[Any, Any] | None:
    """The linear block from the rank-one second-order Volterra kernel, or None."""
    length = int(min(20, max(8, 3 * (na + nb))))
    rows, rhs = [], []
    budget = _VOLTERRA_SAMPLES
    for v, y in pairs:
        n = min(y.size, budget)
        budget -= n
        if n <= length + nk + 10:
            continue
        lag = nk + length - 1
        lagged = np.column_stack([v[lag - nk - i: n - nk - i] for i in range(length)])
        iu = np.triu_indices(length)
        quad = lagged[:, iu[0]] * lagged[:, iu[1]]
        rows.append(np.column_stack([quad, lagged, np.ones(n - lag)]))
        rhs.append(y[lag:n])
        if budget <= 0:
            break
    if not rows:
        return None
    phi = np.vstack(rows)
    if phi.shape[0] < 2 * phi.shape[1]:
        return None
    coef, *_ = np.linalg.lstsq(phi, np.concatenate(rhs), rcond=None)
    iu = np.triu_indices(length)
    q = np.zeros((length, length))
    q[iu] = coef[: iu[0].size]
    q = 0.5 * (q + q.T)  # off-diagonal terms appear once in the regression, twice in hᵀQh
    values, vectors = np.linalg.eigh(q)
    k = int(np.argmax(np.abs(values)))
    h = vectors[:, k] * np.sqrt(abs(values[k]))
    targets = [(v, sps.lfilter(np.concatenate([np.zeros(nk), h]), [1.0], v)) for v, _ in pairs]
    a, b, _ = arx_fit(targets, na, nb, nk, False)
    return b, stable(a)

