"""Parameter covariance of the prediction-error fits: white and robust.

At the minimum θ̂ of Σε² the estimate is, to first order,
``θ̂ − θ₀ ≈ (ΨᵀΨ)⁻¹ Ψᵀ ε`` with Ψ the gradient of the predictions, so

``P = (ΨᵀΨ)⁻¹ · Ψᵀ R_ε Ψ · (ΨᵀΨ)⁻¹,   Ψᵀ R_ε Ψ = Σ_τ r_ε(τ) Σ_t ψ(t) ψ(t−τ)ᵀ``

whenever ψ does not depend on the noise: output error, and the G part of
Box–Jenkins, in open loop (Ljung, *System Identification*, 2nd ed., §9.3;
Söderström & Stoica, *System Identification*, 1989, ch. 7).

``"white"``
    ``r_ε(τ) = σ̂² δ(τ)``: ``P = σ̂² (ΨᵀΨ)⁻¹``, the asymptotic covariance
    when the model's noise description is right, so the prediction
    errors are white (Ljung §9.3).
``"robust"``
    The sandwich with the residuals' own autocovariance.  An output-error
    fit does not model the noise: on a real rig its residual is coloured,
    and the white formula misstates the standard deviations (by up to
    ×2.4 on the coloured test record).  The sum runs over every lag of the
    record, with ``r̂_ε(τ)`` the sample autocovariance for |τ| <= p and its
    maximum-entropy (autoregressive) extension beyond: a Yule–Walker AR(p)
    model ``A_v(q) ε = η`` reproduces r̂_ε(0…p) exactly (Levinson–Durbin)
    and implies ``R_ε ≈ σ_η² A_v⁻¹A_v⁻ᵀ`` (with the AR process started from
    rest), so ``Ψᵀ R_ε Ψ = σ_η² Ψ̃ᵀΨ̃`` with ``Ψ̃ = Ψ/A_v(q)``: one Gram
    matrix of filtered signals, positive semidefinite by construction.
    The order p minimises AIC, ``N ln σ_p² + 2p`` over
    ``p <= min(10·log10 N, N − 1)``: AIC is asymptotically efficient for
    an AR(∞) noise such as the ARMA noise of a real sensor (Shibata 1980)
    — the autoregressive-sieve HAC estimator (Berk 1974; den Haan &
    Levin 1997).  With white residuals AIC picks p = 0 and the result is
    exactly the white formula.

Why not a lag window?  A Bartlett (Newey–West) window truncated at M keeps
the estimate positive semidefinite but both truncates and tapers Σ_τ
r_ε(τ)·Σ_t ψψᵀ, whose terms decay only as the product of the noise's and
the plant's memories.  On 200 seeded records of the test rig (second-order
plant; noise (1 + 0.5q⁻¹)/(1 − 0.9q⁻¹), three other ARMA noises and white
noise; N = 500 and 2000), Bartlett windows with Newey–West's M = 4(N/100)^(2/9)
or with M = the first lag inside the ±2/√N band missed 95 % coverage by
up to 5 points (both over and under), while the AR extension stayed
within a point of the sandwich built from the true noise autocovariance.

``"auto"`` is ``"robust"`` for output-error structures (na = nc = nd = 0:
no noise model, coloured residuals are the rule) and ``"white"`` for
structures with a noise model (when that model is right its residuals are
white and the white formula is the efficient one).  ``"robust"`` may be
asked for any structure; its premise that ψ is independent of the noise
holds for the B and F parameters in open loop but not for A, C and D,
whose ψ are filtered outputs and errors — coloured residuals there say
the noise model is too simple, which is better fixed by raising nc/nd.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ._gram import _full_sums
from ._pem_orders import PemOrders
from ._pem_predictor import Problem

__all__ = ["COVARIANCES", "Covariance", "CovarianceResult", "parameter_covariance",
           "residual_ar"]

Covariance = Literal["auto", "white", "robust"]
COVARIANCES: tuple[str, ...] = ("auto", "white", "robust")

#: Relative eigenvalue floor of the scaled ΨᵀΨ below which a direction is
#: not determined and the pseudo-inverse drops it (about 5000 ε of double precision).
_RANK_TOL = 1e-12
#: The Levinson recursion stops when the prediction-error variance of the
#: residual falls below this fraction of its variance: a residual predicted to
#: 1e-13 of its RMS is predictable to rounding (e.g. a pure sinusoid).
_PREDICTABLE = 1e-26


@dataclass(frozen=True, slots=True)
class CovarianceResult:
    """A covariance, whether ΨᵀΨ was singular, and how it was made."""

    covariance: NDArray[np.float64]
    singular: bool
    kind: str  # "white" or "robust"
    ar_order: int | None  # order of the residual AR model (robust only)


def resolve(kind: str, orders: PemOrders) -> str:
    """The covariance actually used: ``"auto"`` resolved by the structure."""
    if kind == "auto":
        output_error = orders.na == 0 and orders.nc == 0 and orders.nd == 0
        return "robust" if output_error else "white"
    return kind


def parameter_covariance(problem: Problem, theta: NDArray[np.float64],
                         h: NDArray[np.float64], sigma2: float, dof: int,
                         kind: str) -> CovarianceResult:
    """The white or robust covariance of θ̂ (``kind`` already resolved).

    ``h`` is ΨᵀΨ at θ (the Schur complement with estimated initial values),
    ``sigma2 = Σε²/dof``.
    """
    inv, singular = _pinv(h)
    if kind == "white" or inv.size == 0:
        return CovarianceResult(_sym(sigma2 * inv), singular, "white", None)
    errors = problem.errors_at(theta)
    n = sum(e.size for e in errors)
    ar, innovation = residual_ar(errors, n)
    if ar.size == 1:  # white residuals: the sandwich is σ̂²·H⁺HH⁺ = σ̂²·H⁺ exactly
        return CovarianceResult(_sym(sigma2 * inv), singular, "robust", 0)
    # the same N/(N − d) degrees-of-freedom correction as σ̂² = Σε²/(N − d)
    meat = innovation * n / dof * problem.filtered_gram(theta, ar)
    return CovarianceResult(_sym(inv @ meat @ inv), singular, "robust", ar.size - 1)


def residual_ar(errors: list[NDArray[np.float64]],
                n: int) -> tuple[NDArray[np.float64], float]:
    """AR model ``A_v ε = η`` of the pooled residuals by Yule–Walker and AIC.

    Returns the monic A_v (``[1.0]`` for white residuals) and the
    innovation variance σ_η² (biased, Σ/N normalisation).
    """
    max_order = int(min(10 * np.log10(max(n, 1)), n - 1))
    r = _autocovariance(errors, max(max_order, 0)) / n
    if not (np.isfinite(r).all() and r[0] > 0):
        return np.ones(1), float(r[0]) if np.isfinite(r[0]) else 0.0
    a = np.ones(1)
    err = float(r[0])
    best_a, best_err, best_aic = a, err, n * np.log(err)
    for p in range(1, max_order + 1):
        # Durbin–Levinson step (Brockwell & Davis, *Time Series*, 1991, §5.2): the
        # biased autocovariance is positive semidefinite, so |k| <= 1 and A_v is stable
        k = -(r[p] + a[1:] @ r[p - 1:0:-1]) / err
        ext = np.concatenate([a, [0.0]])
        a = ext + k * ext[::-1]
        err *= 1.0 - k * k
        if not err > _PREDICTABLE * r[0]:
            break
        aic = n * np.log(err) + 2 * p
        if aic < best_aic:
            best_a, best_err, best_aic = a, err, aic
    return best_a, float(best_err)


def _autocovariance(errors: list[NDArray[np.float64]], max_lag: int) -> NDArray[np.float64]:
    """Σ_segments Σ_t ε(t) ε(t + τ), τ = 0…max_lag (lags never cross segments)."""
    keys = np.zeros((max_lag + 1, 3), dtype=np.int64)
    keys[:, 2] = np.arange(max_lag + 1)
    out = np.zeros(max_lag + 1)
    for e in errors:
        if e.size:
            _full_sums((np.ascontiguousarray(e),), keys, out)
    return out


def _pinv(h: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """(ΨᵀΨ)⁺ after equilibration, and whether ΨᵀΨ was singular."""
    n = h.shape[0]
    if n == 0:
        return np.zeros((0, 0)), False
    s = np.sqrt(np.clip(np.diag(h), 0.0, None))
    zero = ~(s > 0)
    s[zero] = 1.0
    hs = h / np.outer(s, s)
    lam, vec = np.linalg.eigh(hs)
    singular = bool(zero.any() or not lam[0] > _RANK_TOL * lam[-1])
    keep = lam > _RANK_TOL * max(float(lam[-1]), 1e-300)
    inv = (vec[:, keep] / lam[keep]) @ vec[:, keep].T
    return inv / np.outer(s, s), singular


def _sym(m: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (m + m.T)
