"""Streamed Gauss–Newton of the grey-box OE fit on long records.

No N × n Jacobian is formed.

The residual is ``r = y − G(q, θ) u`` with ``G = num/den`` from the user's
``model_fn``.  Read in q⁻¹ and divided by ``den[0]``, G is an OE model
``B/F`` with fixed orders, so the exact gradient of the simulation with
respect to its coefficients c = (b, f) is a lag table of two filtered
signals (:mod:`._oe_kernel`), and by the chain rule

    J_z = −Ψ_c · ∂c/∂z,   JᵀJ = Dᵀ (Ψ_cᵀΨ_c) D,   Jᵀr = −Dᵀ Ψ_cᵀ ε,

with D = ∂c/∂z a small (n_c × n) matrix from central differences of
``model_fn`` (the solver coordinates z are θ or log θ).  One compiled pass
per evaluation gives Ψ_cᵀΨ_c and Ψ_cᵀε; the N × n Jacobian of MINPACK and
its finite differences (n + 1 simulations per Jacobian) are never formed.
The step is Levenberg–Marquardt, damped by λ·diag(JᵀJ) when a full step
does not lower the cost, as in :func:`._pem._search`; the search stops
when a step would lower the cost by less than ``tol`` relative, or move z
by less than ``tol`` relative.

Memory: the record and O(n_c²); each evaluation allocates nothing of
length N (the residual vector is made once, at the optimum).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ._ls import damped_step
from ._oe_kernel import oe_errors, oe_gram, oe_gram_columns

__all__ = ["StreamResult", "stream_filtered_gram", "stream_least_squares", "stream_residuals"]

_ONE = np.ones(1)
_NONE = np.zeros(0)
_MAX_DAMPING = 15
#: Relative step of the central differences of the coefficient map (ε^(1/3)).
_DIFF_STEP = 6e-6


@dataclass
class StreamResult:
    """The ``OptimizeResult`` fields the grey-box fit reads."""

    x: NDArray[np.float64]
    cost: float  # ½ Σ r², as scipy reports it
    nfev: int
    status: int
    message: str
    optimality: float
    jtj: NDArray[np.float64]  # JᵀJ in z at x
    fun: NDArray[np.float64] = field(default_factory=lambda: _NONE)


class _Coefficients:
    """z ↦ the OE coefficients (b, f_1…f_nf) of model_fn."""

    def __init__(self, model_fn: Callable[[NDArray[np.float64]], object],
                 to_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]],
                 z0: NDArray[np.float64]) -> None:
        self.model_fn = model_fn
        self.to_theta = to_theta
        g = model_fn(to_theta(z0))
        self.nb = int(np.asarray(g.den).size)  # type: ignore[attr-defined]
        self.nf = self.nb - 1

    def __call__(self, z: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The coefficients at z; None where model_fn refuses z or changes its orders."""
        try:
            with np.errstate(all="ignore"):
                g = self.model_fn(self.to_theta(z))
        except (ValueError, ArithmeticError, RuntimeError):  # e.g. a ModelError there
            return None
        num = np.asarray(g.num, dtype=float)  # type: ignore[attr-defined]
        den = np.asarray(g.den, dtype=float)  # type: ignore[attr-defined]
        if den.size != self.nb or num.size > den.size or den[0] == 0 or not np.isfinite(den[0]):
            return None
        numq = np.concatenate([np.zeros(den.size - num.size), num]) / den[0]
        return np.concatenate([numq, den[1:] / den[0]])

    def jacobian(self, z: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """∂c/∂z by central differences (n_c × n)."""
        cols = []
        for k in range(z.size):
            h = _DIFF_STEP * max(abs(z[k]), 1.0)
            zp, zm = z.copy(), z.copy()
            zp[k] += h
            zm[k] -= h
            cp, cm = self(zp), self(zm)
            if cp is None or cm is None:
                return None
            cols.append((cp - cm) / (2.0 * h))
        return np.column_stack(cols)


class _Passes:
    """Cost and normal equations over the segments at coefficients c."""

    def __init__(self, records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 start: int, nb: int, nf: int) -> None:
        self.records = [(np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(y, dtype=float))
                        for u, y in records]
        self.start = start
        self.nb = np.array([nb], dtype=np.int64)
        self.nk = np.zeros(1, dtype=np.int64)
        self.nf = np.array([nf], dtype=np.int64)
        self.evaluations = 0

    def _mats(self, c: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        nb = int(self.nb[0])
        return c[:nb].reshape(1, -1).copy(), np.concatenate([[1.0], c[nb:]]).reshape(1, -1)

    def cost(self, c: NDArray[np.float64], ys: Sequence[NDArray[np.float64]] | None = None,
             out: list[NDArray[np.float64]] | None = None) -> float:
        """Σ r² (inf on overflow); ``out`` collects r per segment."""
        b, f = self._mats(c)
        self.evaluations += 1
        total = 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            for k, (u, y) in enumerate(self.records):
                yk = y if ys is None else np.ascontiguousarray(ys[k], dtype=float)
                buf = np.empty(yk.size) if out is not None else _NONE
                total += oe_errors(_ONE, b, self.nb, self.nk, f, self.nf, (u,), yk, self.start,
                                   buf)
                if out is not None:
                    out.append(buf[self.start:])
        return total if np.isfinite(total) else np.inf

    def gram(self, c: NDArray[np.float64],
             ys: Sequence[NDArray[np.float64]] | None = None) -> tuple[NDArray[np.float64],
                                                                      NDArray[np.float64]]:
        """Ψ_cᵀΨ_c and Ψ_cᵀε (ψ = ∂ŷ/∂c)."""
        b, f = self._mats(c)
        n = c.size
        h, g = np.zeros((n, n)), np.zeros(n)
        with np.errstate(over="ignore", invalid="ignore"):
            for k, (u, y) in enumerate(self.records):
                yk = y if ys is None else np.ascontiguousarray(ys[k], dtype=float)
                hs, gs = oe_gram(_ONE, b, self.nb, self.nk, f, self.nf, (u,), yk, self.start,
                                 _ONE)
                h += hs
                g += gs
        return h, g

    def filtered_gram(self, c: NDArray[np.float64], ar: NDArray[np.float64]) -> NDArray[np.float64]:
        """Σ_segments Ψ̃_cᵀΨ̃_c, each column filtered by 1/ar from ``start``."""
        b, f = self._mats(c)
        h = np.zeros((c.size, c.size))
        with np.errstate(over="ignore", invalid="ignore"):
            for u, y in self.records:
                h += oe_gram_columns(_ONE, b, self.nb, self.nk, f, self.nf, (u,), y, self.start,
                                     ar)
        return h


def stream_least_squares(
    model_fn: Callable[[NDArray[np.float64]], object],
    to_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    start: int,
    z0: NDArray[np.float64],
    tol: float,
    max_nfev: int,
    ys: Sequence[NDArray[np.float64]] | None = None,
) -> StreamResult:
    """Minimise Σ (y − G(q, θ(z)) u)² from z0 by damped Gauss–Newton."""
    coef = _Coefficients(model_fn, to_theta, z0)
    passes = _Passes(records, start, coef.nb, coef.nf)
    z = np.array(z0, dtype=float)

    def evaluate(zz: NDArray[np.float64]) -> tuple[float, NDArray[np.float64] | None]:
        try:
            c = coef(zz)
        except (ValueError, ArithmeticError, RuntimeError):
            return np.inf, None
        if c is None or not np.all(np.isfinite(c)):
            return np.inf, None
        return passes.cost(c, ys), c

    def normal(zz: NDArray[np.float64], c: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                          NDArray[np.float64]]:
        d = coef.jacobian(zz)
        if d is None:
            raise ArithmeticError("model_fn fails next to the current parameters")
        hc, gc = passes.gram(c, ys)
        return d.T @ hc @ d, d.T @ gc

    cost, c = evaluate(z)
    if not np.isfinite(cost) or c is None:
        return StreamResult(z, np.inf, passes.evaluations, -1,
                            "the simulation overflows at the start", np.inf, np.zeros((0, 0)))
    try:
        h, g = normal(z, c)
    except ArithmeticError as exc:
        return StreamResult(z, 0.5 * cost, passes.evaluations, -1, str(exc), np.inf,
                            np.zeros((0, 0)))
    lam, status, message = 0.0, 0, "the maximum number of function evaluations is exceeded"
    while passes.evaluations < max_nfev:
        step = damped_step(h, g, 0.0)
        predicted = float(g @ step)
        if not np.isfinite(predicted):
            status, message = -1, "the gradient is not finite"
            break
        if predicted <= tol * cost:
            # converged; the last full step still lowers the cost by up to that much: take it
            status, message = 2, "`ftol` termination condition is satisfied."
            trial_cost, trial_c = evaluate(z + step)
            if trial_cost < cost and trial_c is not None:
                try:
                    h, g = normal(z + step, trial_c)
                except ArithmeticError:  # model_fn fails next to it: stay where we are
                    break
                z, cost, c = z + step, trial_cost, trial_c
            break
        lam_try, accepted = lam, False
        for _ in range(_MAX_DAMPING):
            delta = step if lam_try == 0.0 else damped_step(h, g, lam_try)
            trial_cost, trial_c = evaluate(z + delta)
            if trial_cost < cost:
                accepted = True
                break
            lam_try = max(10.0 * lam_try, 1e-4)
            if passes.evaluations >= max_nfev:
                break
        if not accepted:
            if predicted <= 1e-4 * cost:
                status, message = 2, "`ftol` termination condition is satisfied."
            break
        z_new = z + delta
        small_step = float(np.linalg.norm(delta)) <= tol * (tol + float(np.linalg.norm(z)))
        z, cost, c = z_new, trial_cost, trial_c
        lam = 0.0 if lam_try <= 1e-3 else lam_try / 10.0
        assert c is not None
        try:
            h, g = normal(z, c)
        except ArithmeticError as exc:
            status, message = -1, str(exc)
            break
        if small_step:
            status, message = 3, "`xtol` termination condition is satisfied."
            break
    return StreamResult(z, 0.5 * cost, passes.evaluations, status, message,
                        float(np.max(np.abs(g))) if g.size else 0.0, h)


def stream_residuals(
    model_fn: Callable[[NDArray[np.float64]], object],
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    start: int,
    theta: NDArray[np.float64],
    ys: Sequence[NDArray[np.float64]] | None = None,
) -> list[NDArray[np.float64]]:
    """r(t), t >= start, per segment at θ (NaN on overflow)."""
    coef = _Coefficients(model_fn, _identity, theta)
    passes = _Passes(records, start, coef.nb, coef.nf)
    c = coef(theta)
    if c is None or not np.all(np.isfinite(c)):
        return [np.full(y.size - start, np.nan) for _, y in records]
    out: list[NDArray[np.float64]] = []
    passes.cost(c, ys, out)
    return out


def _identity(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    return theta


def stream_filtered_gram(
    model_fn: Callable[[NDArray[np.float64]], object],
    to_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    records: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    start: int,
    z: NDArray[np.float64],
    scale: NDArray[np.float64],
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """``ar ↦ J̃ᵀJ̃``: J's columns filtered by 1/ar (robust covariance).

    ``scale`` is dθ/dz per parameter (the Jacobian in θ is J_z / scale).
    """
    coef = _Coefficients(model_fn, to_theta, z)
    passes = _Passes(records, start, coef.nb, coef.nf)
    c = coef(z)
    d = coef.jacobian(z)
    assert c is not None and d is not None
    d = d / scale

    def gram(ar: NDArray[np.float64]) -> NDArray[np.float64]:
        hc = passes.filtered_gram(c, np.ascontiguousarray(ar, dtype=float))
        out = d.T @ hc @ d
        return 0.5 * (out + out.T)

    return gram
