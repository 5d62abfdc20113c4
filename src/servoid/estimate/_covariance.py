"""Parameter covariance for coloured residuals: white and robust.

Prediction error, instrumental variables and refined IV all leave, to
first order, an error of the form

``θ̂ − θ₀ ≈ B⁻¹ Σ_t ζ(t) ε(t)``

with ζ(t) independent of the noise ε, so their covariance is the sandwich

``P = B⁻¹ · Z̄ᵀ R_ε Z̄ · B⁻ᵀ,   Z̄ᵀ R_ε Z̄ = Σ_τ r_ε(τ) Σ_t ζ(t) ζ(t−τ)ᵀ``

(Z̄ stacks the rows ζ(t)ᵀ):

* **prediction error** at the minimum of Σε², where ψ does not depend on
  the noise (output error, and the G part of Box–Jenkins, in open loop):
  ζ = ψ the gradient of the predictions and ``B = ΨᵀΨ`` (Ljung, *System
  Identification*, 2nd ed., §9.3; Söderström & Stoica, *System
  Identification*, 1989, ch. 7);
* **instrumental variables** ``θ̂ = (Σ ζφᵀ)⁻¹ Σ ζ y``: ζ the (prefiltered)
  instruments and ``B = M = Σ ζ φᵀ``, ε the (prefiltered) equation error
  (Söderström & Stoica, *Instrumental Variable Methods for System
  Identification*, 1983, §4.3, eq. 4.21 with its ``Σ_τ`` sum);
* **refined IV** (SRIVC): ζ the filtered instruments, which are the
  gradient of the simulated output, so in open loop ``B = Σ ζζᵀ`` exactly
  as for output error, and in closed loop ``B = M`` (Young, *Recursive
  Estimation and Time-Series Analysis*, 2nd ed., 2011, §7.3 and §8.2).
* **grey-box output error** (nonlinear least squares ``min Σ r(θ)²``
  with a simulated model, :func:`~servoid.estimate.fit_tf_greybox`,
  :func:`~servoid.estimate.fit_greybox`): ζ = the columns of the residual
  Jacobian J = ∂r/∂θ (the solver's finite differences) and ``B = JᵀJ``,
  the Gauss–Newton form of the Hessian at the minimum (Seber & Wild,
  *Nonlinear Regression*, 1989, §2.1 and §6.4 for correlated errors);
  :func:`least_squares_covariance`.

``"white"``
    ``r_ε(τ) = σ̂² δ(τ)``: ``P = σ̂² B⁻¹ Z̄ᵀZ̄ B⁻ᵀ`` (``σ̂² B⁻¹`` when ``B = Z̄ᵀZ̄``),
    the asymptotic covariance when the estimator's noise description is
    right, so its residuals are white (Ljung §9.3).
``"robust"``
    The sandwich with the residuals' own autocovariance.  An estimator
    without a noise model (output error, SRIVC, the basic IV) leaves the
    noise's colour in its residual, and the white formula then misstates
    the standard deviations: by up to ×2.4 for OE and ×4 for SRIVC on the
    coloured test records.  The sum runs over every lag of the record, with
    ``r̂_ε(τ)`` the sample autocovariance for |τ| <= p and its
    maximum-entropy (autoregressive) extension beyond: a Yule–Walker AR(p)
    model ``A_v(q) ε = η`` reproduces r̂_ε(0…p) exactly (Levinson–Durbin)
    and implies ``R_ε ≈ σ_η² A_v⁻¹A_v⁻ᵀ`` (with the AR process started from
    rest), so ``Z̄ᵀ R_ε Z̄ = σ_η² Z̃ᵀZ̃`` with ``Z̃ = Z̄/A_v(q)``: one Gram
    matrix of filtered signals, positive semidefinite by construction.
    The order p minimises AIC, ``N ln σ_p² + 2p`` over
    ``p <= min(10·log10 N, N − 1)``: AIC is asymptotically efficient for
    an AR(∞) noise such as the ARMA noise of a real sensor (Shibata 1980)
    — the autoregressive-sieve HAC estimator (Berk 1974; den Haan &
    Levin 1997).  With white residuals AIC picks p = 0 and the result is
    exactly the white formula.  σ_η² carries the same N/(N − d)
    degrees-of-freedom correction as ``σ̂² = Σε²/(N − d)``.
``"auto"``
    ``"robust"`` where the estimator has no noise model of its own (its
    residuals are coloured whenever the noise is), ``"white"`` where it
    has one (when that model is right its residuals are white and the
    white formula is the efficient one).  The premise that ζ is
    independent of the noise holds for the plant parameters of output
    error and IV, open loop or with instruments from the reference; it
    fails for the A, C and D of prediction error, whose ψ are filtered
    outputs and errors — coloured residuals there say the noise model is
    too simple, which is better fixed by raising its orders.

Several noise sources.  The channels of a multi-output fit carry noises
of their own colour and level, so :func:`grouped_sandwich_covariance`
fits one residual AR model per group (channel) and sums the meats,
``Σ_g σ_η,g²·N/(N − d)·Z̃_gᵀZ̃_g``; cross-channel correlation of the noise
is neglected there (the bootstrap keeps it, below).  Segments of one
channel share one model.  With one group and white residuals this is the
white formula exactly; with several groups and white residuals it is the
channel-wise heteroscedastic (White 1980) sandwich, which also corrects
wrong channel weights.

``"bootstrap"`` (grey-box fits): :func:`bootstrap_covariance` refits
``ŷ(θ̂) + ε*`` B times and takes the sample covariance of the refitted θ*.
ε* is an autoregressive-sieve resample of the residuals (Kreiss 1992;
Bühlmann, *Bernoulli* 3, 1997): the innovations ``η = A_v(q) ε`` of the
same AIC-chosen AR model, centred, inflated by ``√(N/(N − d))`` (the
fit shrinks residuals; Davison & Hinkley, *Bootstrap Methods*, 1997,
§6.2.3), drawn with replacement — at the same time indices in every
group, which keeps the contemporaneous correlation between channels —
and coloured again, ``ε* = η*/A_v(q)`` from rest.  AR order 0 gives the
classical residual bootstrap.  Refits see the model's nonlinearity and
the curvature of the cost beyond the linearisation, which the sandwich
cannot.  Why not a moving-block bootstrap of ε?  Blocks of length ℓ
lose the correlation across block joints: the variance is biased by
``−Σ_τ |τ| r_ε(τ) / (ℓ Σ_τ r_ε(τ))`` (Künsch, *Ann. Statist.* 17, 1989),
−9.5/ℓ for the AR(1) noise with pole 0.9 of the tests — −70 % at
Hall–Horowitz–Jing's ℓ ≈ N^(1/3) = 13 for N = 2000.

Why not a lag window?  A Bartlett (Newey–West) window truncated at M keeps
the estimate positive semidefinite but both truncates and tapers Σ_τ
r_ε(τ)·Σ_t ζζᵀ, whose terms decay only as the product of the noise's and
the plant's memories.  On 200 seeded records of the OE test rig (second-order
plant; noise (1 + 0.5q⁻¹)/(1 − 0.9q⁻¹), three other ARMA noises and white
noise; N = 500 and 2000), Bartlett windows with Newey–West's M = 4(N/100)^(2/9)
or with M = the first lag inside the ±2/√N band missed 95 % coverage by
up to 5 points (both over and under), while the AR extension stayed
within a point of the sandwich built from the true noise autocovariance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from .._lazy import signal as sps
from ._gram import _full_sums

if TYPE_CHECKING:
    from ._pem_predictor import Problem

__all__ = ["COVARIANCES", "GREYBOX_COVARIANCES", "BootstrapResult", "Covariance",
           "CovarianceResult", "GreyboxCovariance", "bootstrap_covariance", "filtered_gram",
           "grouped_sandwich_covariance", "least_squares_covariance", "parameter_covariance",
           "residual_ar", "resolve", "sandwich_covariance", "sieve_innovations"]

Covariance = Literal["auto", "white", "robust"]
COVARIANCES: tuple[str, ...] = ("auto", "white", "robust")
#: The grey-box fits refit, so they also offer the bootstrap.
GreyboxCovariance = Literal["auto", "white", "robust", "bootstrap"]
GREYBOX_COVARIANCES: tuple[str, ...] = ("auto", "white", "robust", "bootstrap")

#: Σ_segments Z̃ᵀZ̃ for an AR polynomial (``[1.0]``: the unfiltered Z̄ᵀZ̄).
GramFunction = Callable[[NDArray[np.float64]], NDArray[np.float64]]

#: Relative eigenvalue floor of the scaled ΨᵀΨ (singular-value floor of a
#: scaled M) below which a direction is not determined and the
#: pseudo-inverse drops it (about 5000 ε of double precision).
_RANK_TOL = 1e-12
#: The Levinson recursion stops when the prediction-error variance of the
#: residual falls below this fraction of its variance: a residual predicted to
#: 1e-13 of its RMS is predictable to rounding (e.g. a pure sinusoid).
_PREDICTABLE = 1e-26


@dataclass(frozen=True, slots=True)
class CovarianceResult:
    """A covariance, whether B was singular, and how it was made."""

    covariance: NDArray[np.float64]
    singular: bool
    kind: str  # "white" or "robust"
    ar_order: int | None  # order of the residual AR model (robust only; the largest of groups)
    ar_orders: tuple[int, ...] = ()  # per group (robust only)


@dataclass(frozen=True, slots=True)
class BootstrapResult:
    """Refitted parameters of a residual bootstrap and their covariance."""

    covariance: NDArray[np.float64]
    samples: NDArray[np.float64]  # (B_ok, d) refitted θ*
    failed: int  # refits that did not converge
    ar_orders: tuple[int, ...]  # the sieve's AR order per group


def resolve(kind: str, noise_model: bool) -> str:
    """The covariance used: ``"auto"`` resolved by the estimator.

    ``noise_model`` says whether the estimator models the noise itself
    (then ``"white"``), else ``"robust"`` (see the module notes).
    """
    if kind == "auto":
        return "white" if noise_model else "robust"
    return kind


def sandwich_covariance(
    kind: str,
    bread: NDArray[np.float64],
    sigma2: float,
    dof: int,
    residuals: Callable[[], Sequence[NDArray[np.float64]]],
    gram: GramFunction,
    *,
    gram_bread: bool = False,
) -> CovarianceResult:
    """White or robust covariance ``B⁻¹·Z̄ᵀR_εZ̄·B⁻ᵀ`` (kind resolved).

    Parameters
    ----------
    kind : {"white", "robust"}
        The resolved choice (:func:`resolve`).
    bread : ndarray, shape (d, d)
        B: ΨᵀΨ (prediction error, SRIVC in open loop) or ``M = Σ ζφᵀ`` (IV).
    sigma2 : float
        ``σ̂² = Σε²/dof``.
    dof : int
        Degrees of freedom N − d of σ̂².
    residuals : callable
        Returns the residual ε of each segment (only called for ``"robust"``).
    gram : callable
        Maps a monic AR polynomial A_v to ``Σ_segments Z̃ᵀZ̃``, ``Z̃ = Z̄/A_v(q)``;
        ``gram([1.0])`` is Z̄ᵀZ̄.
    gram_bread : bool
        B is Z̄ᵀZ̄ itself (ζ = ψ): the white formula is then ``σ̂² B⁻¹``
        and `gram` is not called for it.

    Returns
    -------
    CovarianceResult
        The covariance, whether B was singular (a pseudo-inverse was used),
        the kind and the residual AR order (None for ``"white"``).
    """
    return grouped_sandwich_covariance(kind, bread, sigma2, dof, [(residuals, gram)],
                                       gram_bread=gram_bread)


def grouped_sandwich_covariance(
    kind: str,
    bread: NDArray[np.float64],
    sigma2: float,
    dof: int,
    groups: Sequence[tuple[Callable[[], Sequence[NDArray[np.float64]]], GramFunction]],
    *,
    gram_bread: bool = False,
) -> CovarianceResult:
    """The sandwich with one residual AR model per noise group.

    Parameters
    ----------
    kind : {"white", "robust"}
        The resolved choice (:func:`resolve`).
    bread : ndarray, shape (d, d)
        B, as for :func:`sandwich_covariance`.
    sigma2 : float
        ``σ̂² = Σε²/dof`` over every group.
    dof : int
        Degrees of freedom N − d of σ̂² (N counts every group).
    groups : sequence of (residuals, gram)
        Per noise group (a channel): the callable returning its residual
        segments and its filtered-Gram function (see
        :func:`sandwich_covariance`); the Gram matrices of the groups sum
        to Z̄ᵀZ̄.
    gram_bread : bool
        B is Z̄ᵀZ̄ itself.

    Returns
    -------
    CovarianceResult
        ``ar_orders`` per group, ``ar_order`` their maximum (robust only).
    """
    inv, singular = _pinv_psd(bread) if gram_bread else _pinv(bread)
    if inv.size == 0:
        return CovarianceResult(np.zeros((0, 0)), singular, "white", None)
    if kind != "robust":
        if gram_bread:
            return CovarianceResult(_sym(sigma2 * inv), singular, kind, None)
        meat = sigma2 * sum(gram(np.ones(1)) for _, gram in groups)
        return CovarianceResult(_sym(inv @ meat @ inv.T), singular, kind, None)
    fitted = []
    n_all = 0
    for residuals, gram in groups:
        errors = list(residuals())
        n = sum(e.size for e in errors)
        ar, innovation = residual_ar(errors, n)
        fitted.append((ar, innovation, gram))
        n_all += n
    orders = tuple(ar.size - 1 for ar, _, _ in fitted)
    if len(fitted) == 1 and orders[0] == 0:
        # white residuals: exactly the white formula
        if gram_bread:
            return CovarianceResult(_sym(sigma2 * inv), singular, kind, 0, orders)
        meat = sigma2 * fitted[0][2](np.ones(1))
    else:
        # σ_η² is a Σ/n_g mean; N/(N − d) is the degrees-of-freedom correction of σ̂²
        meat = sum(innovation * n_all / dof * gram(ar) for ar, innovation, gram in fitted)
    return CovarianceResult(_sym(inv @ meat @ inv.T), singular, kind, max(orders), orders)


def least_squares_covariance(
    kind: str,
    jacobians: Sequence[Sequence[NDArray[np.float64]]],
    errors: Sequence[Sequence[NDArray[np.float64]]],
    dof: int,
) -> CovarianceResult:
    """White or robust covariance of a nonlinear least-squares fit.

    ``B = JᵀJ`` and ζ = the Jacobian columns (module notes): ``"white"``
    is ``σ̂²(JᵀJ)⁻¹`` with ``σ̂² = Σr²/dof``.

    Parameters
    ----------
    kind : {"white", "robust"}
        The resolved choice.
    jacobians : sequence of sequence of ndarray
        Per noise group, per segment: the rows ∂r(t)/∂θ, shape (N_s, d).
    errors : sequence of sequence of ndarray
        The residuals r in the same layout, shape (N_s,).
    dof : int
        N − d.

    Returns
    -------
    CovarianceResult
        ``singular``: JᵀJ is singular to the rank tolerance (a
        pseudo-inverse was used — the caller should refuse it).
    """
    bread = sum(filtered_gram(group, np.ones(1)) for group in jacobians)
    sigma2 = sum(float(e @ e) for group in errors for e in group) / dof
    groups = [(_constant(group_e), _gram_of(group_j))
              for group_j, group_e in zip(jacobians, errors, strict=True)]
    return grouped_sandwich_covariance(kind, bread, sigma2, dof, groups, gram_bread=True)


def sieve_innovations(
    errors: Sequence[Sequence[NDArray[np.float64]]], dof: int
) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Per group: the residual AR polynomial and its pooled innovations.

    The innovations ``η = A_v(q) ε`` (per segment, from rest) are centred
    and inflated by ``√(N/dof)`` (module notes, ``"bootstrap"``).
    """
    n_all = sum(e.size for group in errors for e in group)
    out = []
    for group in errors:
        ar, _ = residual_ar(group, sum(e.size for e in group))
        eta = np.concatenate([sps.lfilter(ar, [1.0], e) for e in group])
        out.append((ar, (eta - eta.mean()) * np.sqrt(n_all / dof)))
    return out


def bootstrap_covariance(
    errors: Sequence[Sequence[NDArray[np.float64]]],
    dof: int,
    refit: Callable[[list[list[NDArray[np.float64]]]], NDArray[np.float64] | None],
    n_bootstrap: int,
    rng: np.random.Generator,
) -> BootstrapResult:
    """Covariance of θ̂ from refits on sieve-resampled residuals.

    Parameters
    ----------
    errors : sequence of sequence of ndarray
        Residuals per noise group and segment (as fitted).
    dof : int
        N − d.
    refit : callable
        Takes resampled residuals in the same layout, refits on
        ``ŷ(θ̂) + ε*`` and returns θ*, or None when the refit fails.
    n_bootstrap : int
        Number of resamples B.
    rng : numpy.random.Generator
        Source of the resampling.

    Returns
    -------
    BootstrapResult
        Sample covariance (ddof 1) of the successful θ*, the samples, the
        failures and the AR order per group.
    """
    sieves = sieve_innovations(errors, dof)
    lengths = [[e.size for e in group] for group in errors]
    joint = all(lg == lengths[0] for lg in lengths)  # same time grid: draw jointly
    samples = []
    failed = 0
    for _ in range(n_bootstrap):
        draw = rng.integers(0, sieves[0][1].size, sieves[0][1].size) if joint else None
        resampled = []
        for (ar, eta), sizes in zip(sieves, lengths, strict=True):
            idx = draw if draw is not None else rng.integers(0, eta.size, eta.size)
            star = eta[idx]
            cuts = np.cumsum(sizes)[:-1]
            resampled.append([sps.lfilter([1.0], ar, part) for part in np.split(star, cuts)])
        theta = refit(resampled)
        if theta is None or not np.all(np.isfinite(theta)):
            failed += 1
        else:
            samples.append(np.asarray(theta, dtype=float))
    arr = np.array(samples) if samples else np.zeros((0, 0))
    d = arr.shape[1]
    cov = _sym(np.cov(arr, rowvar=False, ddof=1).reshape(d, d)) if len(samples) > 1 else \
        np.full((d, d), np.nan)
    return BootstrapResult(cov, arr, failed, tuple(ar.size - 1 for ar, _ in sieves))


def filtered_gram(instruments: Sequence[NDArray[np.float64]],
                  ar: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_segments Z̃ᵀZ̃ with Z̃ = Z/ar(q), filtered from rest.

    ``instruments`` holds one (N_k, d) matrix Z per segment, rows ζ(t)ᵀ.
    """
    d = instruments[0].shape[1]
    out = np.zeros((d, d))
    for z in instruments:
        zf = z if ar.size == 1 else sps.lfilter([1.0], ar, z, axis=0)
        out += zf.T @ zf
    return _sym(out)


def parameter_covariance(problem: Problem, theta: NDArray[np.float64],
                         h: NDArray[np.float64], sigma2: float, dof: int,
                         kind: str) -> CovarianceResult:
    """Prediction-error covariance of θ̂ (``kind`` resolved).

    ``h`` is ΨᵀΨ at θ (the Schur complement with estimated initial values),
    ``sigma2 = Σε²/dof``; the filtered Gram matrix comes from the
    predictor's lagged-product plan.
    """
    return sandwich_covariance(kind, h, sigma2, dof, lambda: problem.errors_at(theta),
                               lambda ar: problem.filtered_gram(theta, ar), gram_bread=True)


def residual_ar(errors: Sequence[NDArray[np.float64]],
                n: int) -> tuple[NDArray[np.float64], float]:
    """AR model ``A_v ε = η`` of the residuals by Yule–Walker and AIC.

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


def _autocovariance(errors: Sequence[NDArray[np.float64]],
                    max_lag: int) -> NDArray[np.float64]:
    """Σ_t ε(t) ε(t + τ), τ = 0…max_lag, summed over segments.

    Lags never cross segments.
    """
    keys = np.zeros((max_lag + 1, 3), dtype=np.int64)
    keys[:, 2] = np.arange(max_lag + 1)
    out = np.zeros(max_lag + 1)
    for e in errors:
        if e.size:
            _full_sums((np.ascontiguousarray(e, dtype=np.float64),), keys, out)
    return out


def _pinv_psd(h: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
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


def _pinv(m: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """M⁺ after row and column equilibration; whether M was singular."""
    n = m.shape[0]
    if n == 0:
        return np.zeros((0, 0)), False
    rows = np.sqrt(np.einsum("ij,ij->i", m, m))
    cols = np.sqrt(np.einsum("ij,ij->j", m, m))
    zero = ~(rows > 0) | ~(cols > 0)
    rows[~(rows > 0)] = 1.0
    cols[~(cols > 0)] = 1.0
    u, sv, vt = np.linalg.svd(m / np.outer(rows, cols))
    # singular values of M are those of Z̄ᵀΦ: compare them as eigenvalues of ΨᵀΨ above
    singular = bool(zero.any() or not sv[-1] > _RANK_TOL * sv[0])
    keep = sv > _RANK_TOL * max(float(sv[0]), 1e-300)
    inv = (vt[keep].T / sv[keep]) @ u[:, keep].T
    return inv / np.outer(cols, rows), singular


def _sym(m: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (m + m.T)


def _constant(
    errors: Sequence[NDArray[np.float64]],
) -> Callable[[], Sequence[NDArray[np.float64]]]:
    return lambda: errors


def _gram_of(instruments: Sequence[NDArray[np.float64]]) -> GramFunction:
    return lambda ar: filtered_gram(instruments, ar)
