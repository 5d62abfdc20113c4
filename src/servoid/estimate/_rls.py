"""Recursive least squares with forgetting and covariance guarding (spec §3.7).

The update, per sample t with regressor φ and forgetting factor λ ≤ 1::

    L = P φ / (λ + φᵀ P φ)
    θ ← θ + L (y − φᵀ θ)
    P ← (P − L φᵀ P) / λ,   symmetric by construction

With λ = 1 and P₀ = p₀·I the final θ is the batch estimate regularised by
I/p₀: θ_N = (ΦᵀΦ + I/p₀)⁻¹ Φᵀy (from θ₀ = 0). It is the same estimator as
:func:`~servoid.estimate.lstsq` when the columns of Φ are scaled exactly as
the batch core scales them — to unit Euclidean norm over the whole record,
with the same zero-column and rank checks and the same ``names`` in the
messages. Then ΦᵀΦ has a unit diagonal, the prior's relative weight is
about 1/(p₀·λ_min), and RLS and batch LS agree to ~cond²/p₀ (spec P3). The
scaling needs the whole record, so this is an *offline* RLS (the use in the
servopneumatic study: time-varying estimates of κ, R and a record-long
check); pass ``normalise=False`` for raw regressors.

With λ < 1 the estimate weights sample t by λ^{N−t}: memory ≈ 1/(1 − λ)
samples, and after a parameter step the error decays like λ^k ≈
e^{−k(1−λ)}, i.e. with a time constant of 1/(1 − λ) samples.

**Covariance windup.** With λ < 1 and a regressor that stops exciting some
direction, P grows like λ^{−k} in that direction until the next burst of
excitation produces a huge gain. The guard caps trace(P) (default: its
initial value p₀·n in scaled units): ``"bound"`` rescales P onto the cap,
``"reset"`` restarts P at P₀; both count their interventions, and a
warning reports them. P stays exactly symmetric: each pair (i, j) is
updated once.

**Covariance of θ̂.** For white equation error of variance σ² the
exponentially weighted estimate has cov θ̂ = σ² H⁻¹ G H⁻¹ with
H = Σ λ^{N−1−t} φφᵀ and G = Σ λ^{2(N−1−t)} φφᵀ (for λ = 1: σ²(ΦᵀΦ)⁻¹, the
batch covariance). σ̂² = Σ w_t (y_t − φ_tᵀθ̂)² / (Σ w_t − n) with
w_t = λ^{N−1−t}, the residuals of the final estimate over its memory; for
λ = 1 that is the batch RSS/(N − n).

**Cost.** Two passes over the record and nothing of its size allocated
(:mod:`._rls_kernel`): one sums the n×n Gram matrix ΦᵀΦ (and, for λ < 1, H
and G) — the column norms, the rank test (its eigenvalues, as the batch
Gram route does) and the covariance come from it, never from a QR of Φ —
and one runs the recursion, compiled, in the units of θ (the normalisation
enters as P₀ = p₀·diag(1/‖φ_i‖²), so Φ is never scaled or copied). The
weighted residual sum of squares is the recursion's own cost
J_N = λJ_{N−1} + α_N·e_N (a priori times a posteriori error, a sum of
non-negative terms) minus the prior's share λ^N (θ̂ − θ₀)ᵀP₀⁻¹(θ̂ − θ₀); after
a guard event, which breaks that identity, a third pass sums it directly.
The parameter history is stored only with ``history=True`` and the residual
series only with ``residuals=True``; otherwise the first access of
``prior_residuals`` or ``posterior_residuals`` runs the recursion again.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ServoidWarning, check_option
from .._warn import warn
from ._estimate import Estimate
from ._ls import RANK_COND_LIMIT, _check_columns, _check_rows, _rank_error
from ._rls_kernel import GUARD_CODES, RlsPass, gram_pass, rls_pass, weighted_rss

__all__ = ["RecursiveLeastSquaresResult", "fit_rls"]

Guard = Literal["bound", "reset", "none"]
_GUARDS = ("bound", "reset", "none")

ResidualPair = tuple[NDArray[np.float64], NDArray[np.float64]]


@dataclass(frozen=True, eq=False)
class RecursiveLeastSquaresResult:
    """Outcome of a recursive least-squares run.

    Attributes
    ----------
    estimate : Estimate
        Final θ̂ with covariance (module notes), method ``"rls"``.
    history : ndarray, shape (N, n), or None
        θ_t after each sample, when asked for.
    trace_history : ndarray, shape (N,), or None
        trace(P_t) in scaled units after each sample, when asked for.
    final_p : ndarray, shape (n, n)
        P_N mapped back to the units of θ (≈ (ΦᵀΦ)⁻¹ for λ = 1).
    guard_events : int
        How often the covariance guard acted.
    residual_function : callable
        ``() -> (prior, posterior)`` residual series; called once, on first
        access of :attr:`prior_residuals` or :attr:`posterior_residuals`.
    """

    estimate: Estimate
    history: NDArray[np.float64] | None
    trace_history: NDArray[np.float64] | None
    final_p: NDArray[np.float64]
    guard_events: int
    residual_function: Callable[[], ResidualPair] = field(repr=False)

    @property
    def theta(self) -> NDArray[np.float64]:
        """Final parameter vector θ_N."""
        return self.estimate.parameters

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of the final θ̂."""
        return self.estimate.covariance

    @property
    def prior_residuals(self) -> NDArray[np.float64]:
        """A priori errors y_t − φ_tᵀθ_{t−1} (the innovations), shape (N,)."""
        return self._residuals[0]

    @property
    def posterior_residuals(self) -> NDArray[np.float64]:
        """A posteriori errors y_t − φ_tᵀθ_t, shape (N,)."""
        return self._residuals[1]

    @cached_property
    def _residuals(self) -> ResidualPair:
        return self.residual_function()


def fit_rls(
    phi: ArrayLike,
    y: ArrayLike,
    *,
    forgetting: float = 1.0,
    p0: float = 1e8,
    theta0: ArrayLike | None = None,
    normalise: bool = True,
    history: bool = False,
    residuals: bool = False,
    guard: Guard = "bound",
    max_trace: float | None = None,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
) -> RecursiveLeastSquaresResult:
    """Estimate θ in y = φᵀθ + e recursively, sample by sample.

    Parameters
    ----------
    phi : array_like, shape (N, n)
        Regressors, one row per sample.
    y : array_like, shape (N,)
        Left-hand side.
    forgetting : float
        Forgetting factor λ in (0, 1]: 1 for constant parameters,
        0.98–0.999 to track (memory ≈ 1/(1 − λ) samples).
    p0 : float
        Initial covariance P₀ = p0·I, in scaled units when ``normalise``
        (10⁶–10⁸: a vague prior).
    theta0 : array_like, shape (n,), optional
        Initial parameters in the units of θ (default 0).
    normalise : bool
        Scale the columns of Φ to unit norm, as the batch core does.
    history : bool
        Keep θ_t and trace(P_t) for every sample (N·(n + 1) values).
    residuals : bool
        Store the a priori and a posteriori errors during the pass (2·N
        values). Otherwise they are not kept, and the first access of
        ``prior_residuals`` or ``posterior_residuals`` runs the recursion
        again to produce them (the same numbers).
    guard : {"bound", "reset", "none"}
        Covariance-windup guard when trace(P) exceeds ``max_trace``.
    max_trace : float, optional
        Cap on trace(P) in scaled units (default p0·n, its initial value).
    names : sequence of str, optional
        A name per parameter (default ``theta0``, ``theta1``, ...).
    units : sequence of str, optional
        A unit per parameter.

    Returns
    -------
    RecursiveLeastSquaresResult
        Final estimate, residuals, optional history and guard count.

    Raises
    ------
    DataError
        Shapes, non-finite data, too few rows, λ outside (0, 1], p0 ≤ 0.
    IdentifiabilityError
        A zero column, or Φ rank deficient over the whole record.

    Warns
    -----
    ServoidWarning
        When the guard acted (poor excitation under forgetting), or when
        the final memory window does not excite every parameter.

    Notes
    -----
    Memory: about 0 N × 8 bytes beyond the record (Φ and y): O(n²).

    Time is linear in N: about 20 ms for N = 10⁶ and n = 4 on one core of
    the reference machine, 2–3 ms of it the Gram pass
    (``benchmarks/bench_scaling.py``, which checks the memory line). Peak memory
    beyond the inputs is O(n²) — nothing of the record's size — plus
    8·N·(n + 1) bytes with ``history`` and 16·N bytes with ``residuals``
    (and a float64 copy of ``phi`` or ``y`` if they are not float64
    arrays already). ``estimate.residuals`` (y − Φθ̂, computed on first
    access) costs 8·N bytes more.
    """
    check_option("guard", guard, _GUARDS)
    phi_a = as_array("phi", phi, finite=False)
    y_a = as_array("y", y, finite=False)
    if phi_a.ndim != 2 or y_a.ndim != 1 or phi_a.shape[0] != y_a.shape[0]:
        raise DataError(f"need phi (N, n) and y (N,), got {phi_a.shape} and {y_a.shape}")
    # a NaN or inf makes the sum non-finite (so does overflow, beyond ~1e300): only then look
    if not np.isfinite(np.add.reduce(y_a)) and not np.all(np.isfinite(y_a)):
        raise DataError("phi and y must be finite; cut or fill the gaps first")
    n_rows, n = phi_a.shape
    names_t = tuple(names) if names is not None else tuple(f"theta{k}" for k in range(n))
    if len(names_t) != n:
        raise DataError(f"names needs one entry per column ({n}), got {len(names_t)}")
    units_t = tuple(units) if units is not None else ("",) * n
    if len(units_t) != n:
        raise DataError(f"units needs one entry per column ({n}), got {len(units_t)}")
    lam = float(forgetting)
    if not 0 < lam <= 1:
        raise DataError(f"forgetting must lie in (0, 1], got {forgetting}")
    if not (np.isfinite(p0) and p0 > 0):
        raise DataError(f"p0 must be > 0, got {p0}")
    _check_rows(n_rows, n)
    gram, h_weighted, g_weighted = gram_pass(phi_a, lam)
    norms = _column_norms(gram, phi_a)
    _check_columns(norms, names_t)
    # the batch core's rank test on the whole record: a direction never excited cannot be
    # estimated recursively either (eigenvalues of the unit-diagonal Gram matrix, as
    # solve_gram; it resolves cond(Φ) up to ~1e7, below the 6.7e7 limit only roughly)
    unit_gram = gram / np.outer(norms, norms)
    eig, vec = np.linalg.eigh(unit_gram)
    condition = float(np.sqrt(eig[-1] / eig[0])) if eig[0] > 0 else np.inf
    if condition > RANK_COND_LIMIT:
        raise _rank_error(condition, names_t)
    if theta0 is None:
        th0 = np.zeros(n)
    else:
        th0 = np.asarray(theta0, dtype=float).ravel()
        if th0.size != n or not np.all(np.isfinite(th0)):
            raise DataError(f"theta0 must be {n} finite values, got {th0.tolist()}")
    cap = float(max_trace) if max_trace is not None else p0 * n
    if not (np.isfinite(cap) and cap > 0):
        raise DataError(f"max_trace must be > 0, got {max_trace}")

    # P₀ = p₀·I on the unit-norm columns is P₀ = p₀·diag(1/‖φ_i‖²) on the raw ones
    scale2 = norms**2 if normalise else np.ones(n)
    p0_diag = p0 / scale2
    settings = (th0, p0_diag, scale2, lam, cap, GUARD_CODES[guard])

    def run(keep_residuals: bool, keep_history: bool) -> tuple[RlsPass, _Series]:
        series = _Series(
            np.empty(n_rows if keep_residuals else 0),
            np.empty(n_rows if keep_residuals else 0),
            np.empty((n_rows if keep_history else 0, n)),
            np.empty(n_rows if keep_history else 0),
        )
        return rls_pass(phi_a, y_a, *settings, *series), series

    result, series = run(residuals, history)
    theta, events = result.theta, result.events
    n_eff = float(n_rows) if lam == 1.0 else -np.expm1(n_rows * np.log(lam)) / (1.0 - lam)
    if events == 0:
        prior_share = lam**n_rows * float(scale2 @ (theta - th0) ** 2) / p0
        rss = max(result.cost - prior_share, 0.0)
    else:  # a guard event breaks J_N's identity: sum the weighted residuals directly
        rss = weighted_rss(phi_a, y_a, theta, lam)
    sigma2 = rss / max(n_eff - n, 1.0)
    if h_weighted is None:
        cov = sigma2 * (vec / eig) @ vec.T / np.outer(norms, norms)
    else:
        cov = sigma2 * _sandwich(h_weighted, g_weighted, np.sqrt(scale2), names_t)
    if events:
        warn(
            f"rls: the covariance guard ({guard!r}) acted {events} times: trace(P) exceeded "
            f"{cap:.3g} — covariance windup from poor excitation under forgetting = {lam}; "
            "excite the system continuously or raise forgetting",
            ServoidWarning,
        )
    estimate = Estimate(
        model=None,
        parameters=theta,
        names=names_t,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_rows,
        method="rls",
        status="ok",
        options={
            "forgetting": lam,
            "memory_samples": None if lam == 1 else 1.0 / (1.0 - lam),
            "p0": float(p0),
            "normalise": bool(normalise),
            "guard": guard,
            "max_trace": cap,
            "guard_events": int(events),
            "condition": condition,
        },
        units=units_t,
        residual_function=lambda: y_a - phi_a @ theta,
    )
    if residuals:
        stored = (series.prior, series.post)

        def residual_function() -> ResidualPair:
            return stored

    else:

        def residual_function() -> ResidualPair:
            again = run(True, False)[1]  # the same recursion, this time keeping them
            return again.prior, again.post

    return RecursiveLeastSquaresResult(
        estimate=estimate,
        history=series.hist if history else None,
        trace_history=series.traces if history else None,
        final_p=result.p,
        guard_events=int(events),
        residual_function=residual_function,
    )


class _Series(NamedTuple):
    """Per-sample outputs of a pass (length 0 when not kept)."""

    prior: NDArray[np.float64]
    post: NDArray[np.float64]
    hist: NDArray[np.float64]
    traces: NDArray[np.float64]


def _column_norms(gram: NDArray[np.float64], phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """‖φ_i‖ from the Gram diagonal, which is not finite when Φ is not (or too large)."""
    diag = np.diag(gram)
    if not np.all(np.isfinite(diag)):
        if not np.all(np.isfinite(phi)):
            raise DataError("phi and y must be finite; cut or fill the gaps first")
        raise DataError(
            f"phi reaches {float(np.max(np.abs(phi))):.3g}: its squares overflow double "
            "precision; rescale the regressors"
        )
    return np.sqrt(diag)


def _sandwich(
    h: NDArray[np.float64],
    g: NDArray[np.float64],
    scale: NDArray[np.float64],
    names: tuple[str, ...],
) -> NDArray[np.float64]:
    """H⁻¹ G H⁻¹ (times σ² by the caller), from the weighted Gram matrices of the pass."""
    # excitation of the final window, judged in the record's scaled units as before
    s2 = np.linalg.eigvalsh(h / np.outer(scale, scale))
    if not s2[0] > s2[-1] / RANK_COND_LIMIT**2:
        warn(
            "rls: the final memory window (~1/(1 − forgetting) samples) does not excite every "
            f"parameter ({', '.join(names)}); the covariance is unreliable",
            ServoidWarning,
        )
    # invert on the window's own unit diagonal: a column the window barely sees (weights
    # λ^k of samples long gone) then costs no precision in the others
    d = np.sqrt(np.diag(h))
    if not np.all(d > 0):
        return np.full(h.shape, np.inf)
    w, v = np.linalg.eigh(h / np.outer(d, d))
    if not w[0] > 0:
        return np.full(h.shape, np.inf)
    hinv = (v / w) @ v.T
    return hinv @ (g / np.outer(d, d)) @ hinv / np.outer(d, d)
