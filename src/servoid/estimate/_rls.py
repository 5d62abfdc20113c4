"""Recursive least squares with forgetting and covariance guarding (spec §3.7).

The update, per sample t with regressor φ and forgetting factor λ ≤ 1::

    L = P φ / (λ + φᵀ P φ)
    θ ← θ + L (y − φᵀ θ)
    P ← (P − L φᵀ P) / λ,   then symmetrised

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
warning reports them. P is symmetrised after every update.

**Covariance of θ̂.** For white equation error of variance σ² the
exponentially weighted estimate has cov θ̂ = σ² H⁻¹ G H⁻¹ with
H = Σ λ^{N−t} φφᵀ and G = Σ λ^{2(N−t)} φφᵀ (for λ = 1: σ²(ΦᵀΦ)⁻¹, the batch
covariance). σ̂² = Σ w_t (y_t − φ_tᵀθ̂)² / (Σ w_t − n) with w_t = λ^{N−t}, the
residuals of the final estimate over its memory; for λ = 1 that is the
batch RSS/(N − n).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import linalg

from .._errors import DataError, ServoidWarning, check_option
from ._estimate import Estimate
from ._ls import RANK_COND_LIMIT, _check_columns, _check_rows, _rank_error, _triangular_condition

__all__ = ["RecursiveLeastSquaresResult", "fit_rls"]

Guard = Literal["bound", "reset", "none"]
_GUARDS = ("bound", "reset", "none")


@dataclass(frozen=True, eq=False)
class RecursiveLeastSquaresResult:
    """Outcome of a recursive least-squares run.

    Attributes
    ----------
    estimate : Estimate
        Final θ̂ with covariance (module notes), method ``"rls"``.
    prior_residuals : ndarray, shape (N,)
        A priori errors y_t − φ_tᵀθ_{t−1} (the innovations).
    posterior_residuals : ndarray, shape (N,)
        A posteriori errors y_t − φ_tᵀθ_t.
    history : ndarray, shape (N, n), or None
        θ_t after each sample, when asked for.
    trace_history : ndarray, shape (N,), or None
        trace(P_t) in scaled units after each sample, when asked for.
    final_p : ndarray, shape (n, n)
        P_N mapped back to the units of θ (≈ (ΦᵀΦ)⁻¹ for λ = 1).
    guard_events : int
        How often the covariance guard acted.
    """

    estimate: Estimate
    prior_residuals: NDArray[np.float64]
    posterior_residuals: NDArray[np.float64]
    history: NDArray[np.float64] | None
    trace_history: NDArray[np.float64] | None
    final_p: NDArray[np.float64]
    guard_events: int

    @property
    def theta(self) -> NDArray[np.float64]:
        """Final parameter vector θ_N."""
        return self.estimate.parameters

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of the final θ̂."""
        return self.estimate.covariance


def fit_rls(
    phi: ArrayLike,
    y: ArrayLike,
    *,
    forgetting: float = 1.0,
    p0: float = 1e8,
    theta0: ArrayLike | None = None,
    normalise: bool = True,
    history: bool = False,
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
        Keep θ_t and trace(P_t) for every sample.
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
    """
    check_option("guard", guard, _GUARDS)
    phi_a = np.asarray(phi, dtype=float)
    y_a = np.asarray(y, dtype=float)
    if phi_a.ndim != 2 or y_a.ndim != 1 or phi_a.shape[0] != y_a.shape[0]:
        raise DataError(f"need phi (N, n) and y (N,), got {phi_a.shape} and {y_a.shape}")
    if not (np.all(np.isfinite(phi_a)) and np.all(np.isfinite(y_a))):
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
    norms = np.sqrt(np.einsum("ij,ij->j", phi_a, phi_a))
    _check_columns(norms, names_t)
    scale = norms if normalise else np.ones(n)
    phi_s = np.ascontiguousarray(phi_a / scale)
    # the batch core's rank test on the whole record: a direction never excited cannot be
    # estimated recursively either
    r = linalg.qr(phi_a / norms, mode="r", check_finite=False)[0][:n, :n]
    condition = _triangular_condition(r)
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

    theta_s, p_s, prior, post, hist, traces, events = _rls_loop(
        phi_s, y_a, th0 * scale, p0, lam, cap, _GUARDS.index(guard), history
    )
    theta = theta_s / scale
    weights = lam ** np.arange(n_rows - 1, -1, -1, dtype=float)
    resid = y_a - phi_a @ theta
    n_eff = float(weights.sum())
    sigma2 = float(weights @ resid**2) / max(n_eff - n, 1.0)
    cov = _sandwich(phi_s, weights, sigma2, names_t) / np.outer(scale, scale)
    if events:
        warnings.warn(
            f"rls: the covariance guard ({guard!r}) acted {events} times: trace(P) exceeded "
            f"{cap:.3g} — covariance windup from poor excitation under forgetting = {lam}; "
            "excite the system continuously or raise forgetting",
            ServoidWarning,
            stacklevel=2,
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
        residual_function=lambda: resid,
    )
    return RecursiveLeastSquaresResult(
        estimate=estimate,
        prior_residuals=prior,
        posterior_residuals=post,
        history=hist / scale if history else None,
        trace_history=traces if history else None,
        final_p=p_s / np.outer(scale, scale),
        guard_events=int(events),
    )


def _sandwich(
    phi_s: NDArray[np.float64], w: NDArray[np.float64], sigma2: float, names: tuple[str, ...]
) -> NDArray[np.float64]:
    # H = Σ w φφᵀ = RᵀR from the QR of √w·Φ (squares nothing), H⁻¹ = R⁻¹R⁻ᵀ
    sw = np.sqrt(w)
    r = linalg.qr(phi_s * sw[:, None], mode="r", check_finite=False)[0][: phi_s.shape[1]]
    r = np.triu(r)
    s = np.linalg.svd(r, compute_uv=False)
    if s[-1] <= s[0] / RANK_COND_LIMIT:
        warnings.warn(
            "rls: the final memory window (~1/(1 − forgetting) samples) does not excite every "
            f"parameter ({', '.join(names)}); the covariance is unreliable",
            ServoidWarning,
            stacklevel=3,
        )
    rinv = linalg.solve_triangular(r, np.eye(r.shape[0]))
    hinv = rinv @ rinv.T
    if np.all(w == 1.0):
        return sigma2 * hinv
    g = (phi_s * w[:, None]).T @ (phi_s * w[:, None])
    return sigma2 * (hinv @ g @ hinv)


@numba.njit(cache=True, nogil=True)
def _rls_loop(phi, y, theta0, p0, lam, cap, guard, keep):  # type: ignore[no-untyped-def]  # pragma: no cover
    n_rows, n = phi.shape
    theta = theta0.copy()
    p = np.eye(n) * p0
    prior = np.empty(n_rows)
    post = np.empty(n_rows)
    hist = np.empty((n_rows if keep else 0, n))
    traces = np.empty(n_rows if keep else 0)
    pphi = np.empty(n)
    gain = np.empty(n)
    events = 0
    for t in range(n_rows):
        f = phi[t]
        denom = lam
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += p[i, j] * f[j]
            pphi[i] = acc
            denom += f[i] * acc
        err = y[t]
        for i in range(n):
            err -= f[i] * theta[i]
        prior[t] = err
        for i in range(n):
            gain[i] = pphi[i] / denom
            theta[i] += gain[i] * err
        # P ← (P − L (Pφ)ᵀ)/λ, symmetrised: φᵀP = (Pφ)ᵀ for symmetric P
        tr = 0.0
        for i in range(n):
            for j in range(i, n):
                v = 0.5 * ((p[i, j] - gain[i] * pphi[j]) + (p[j, i] - gain[j] * pphi[i])) / lam
                p[i, j] = v
                p[j, i] = v
            tr += p[i, i]
        if guard != 2 and tr > cap:
            events += 1
            if guard == 0:
                p *= cap / tr
            else:
                p[:, :] = 0.0
                for i in range(n):
                    p[i, i] = p0
            tr = 0.0
            for i in range(n):
                tr += p[i, i]
        e2 = y[t]
        for i in range(n):
            e2 -= f[i] * theta[i]
        post[t] = e2
        if keep:
            hist[t] = theta
            traces[t] = tr
    return theta, p, prior, post, hist, traces, events
