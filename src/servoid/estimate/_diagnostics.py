"""Identifiability diagnostics of a least-squares fit: can the data pin θ down?

A covariance from ``(JᵀJ)⁻¹`` is only as good as three premises: the
columns of the Jacobian J = ∂r/∂θ are independent, the cost
``V(θ) = Σ r(θ)²`` is quadratic over the interval it claims, and the
search found the global minimum.  :func:`check_identifiability` tests each
and returns an :class:`Identifiability` record, warning
(:class:`~servoid.ServoidWarning`) when a premise fails:

**Correlation and conditioning.**  The parameter correlation
``ρ_ij = P_ij/(σ_i σ_j)`` of the reported covariance P, and the singular
values of the column-normalised Jacobian ``J_s = J·diag(1/‖J_k‖)`` —
normalising makes them independent of units and of log or linear
coordinates, and is within √n of the best diagonal scaling (van der
Sluis, *Numer. Math.* 14, 1969).  Its condition number is
``κ = s_max/s_min``.  Warned: a pair with ``|ρ_ij| > 0.999``, and a
near-null direction ``s_min² < 1 − 0.999``; ``s_min²`` is the smallest
eigenvalue of ``J_sᵀJ_s`` (unit diagonal), which for two parameters is
exactly ``1 − |ρ|`` of the white covariance, so both limits agree there,
while with more parameters the singular vector also catches a
combination of three or more that no pair shows.  The parameters named
are the largest components of that vector, holding 90 % of its weight.

**A floor on the standard deviation.**  With Gaussian noise of known
spectrum and every other parameter known, no unbiased estimator of θ_k
has a variance below the Hammersley–Chapman–Robbins bound (Hammersley
1950; Chapman & Robbins, *Ann. Math. Statist.* 22, 1951)

``var θ̂_k ≥ sup_h h² / (exp(Δ_k(h)) − 1),   Δ_k(h) = Σ_g ‖A_g(q) δŷ_g‖² / s_g²``

where ``δŷ = ŷ(θ̂ + h e_k) − ŷ(θ̂)`` is the change of the model output
(of the weighted residual) for a finite move h, and ``A_g``, ``s_g²`` the
whitening AR filter and innovation variance ``σ_η²·N/(N − d)`` of group g
(the same AR model as the robust covariance,
:func:`~servoid.estimate._covariance.residual_ar`).  As h → 0 it tends to
the Cramér–Rao bound ``σ_η² / ‖A ψ_k‖²`` — for white noise ``σ̂² /
(N · mean ψ_k²)``, the "σ/√(N·…)" of the record length and the
sensitivity ψ_k = ∂ŷ/∂θ_k — but it needs no derivative: it is evaluated
at ``h = ±max(σ_k, 10⁻⁴|θ_k|)`` (capped at |θ_k|/2), so a Jacobian
spoilt by a discontinuity (a threshold crossed inside the √ε
finite-difference step makes ∂ŷ/∂θ look huge and σ_k tiny) is checked
against the output's real change over a step 10⁴ times longer.  For a
smooth model ``σ_k ≥ floor_k`` holds by construction (with the others
unknown the variance can only grow); warned: ``σ_k < floor_k/2``.  The
white formula on coloured noise trips it (the noise at low frequency
is worth fewer independent samples than N).

**Smoothness.**  The curvature of the cost along each parameter by
finite differences over the same ±h, ``(V(θ̂+h e_k) − 2V(θ̂) +
V(θ̂−h e_k))/h²``, divided by its Gauss–Newton value ``2‖J_k‖²``; the
ratio differs from 1 by the residual-weighted second derivative of r
and by the change of J across ±h, both small when the model is linear in
θ_k over the interval (Seber & Wild, *Nonlinear Regression*, 1989,
§4.2).  Warned: a ratio outside [0.5, 2] — the quadratic model behind
the interval does not describe the cost over ±1σ (a discontinuity, a
kink, a bound of the simulation, strong nonlinearity).  Where the move
is not ±1σ — capped at |θ_k|/2 < σ_k, or raised to 10⁻⁴|θ_k| > σ_k (very
precise parameters, noise-free data, where a simulator with
parameter-dependent steps may jitter at that scale) — only a ratio
outside [0.01, 100] is warned: a Jacobian column spoilt by rounding in
the model or by a discontinuity inside the difference step, which no
smooth nonlinearity explains.

**Values.**  Warned: σ_k > |θ_k| (the interval contains 0: the data do
not determine θ_k).

**Several starts** (:func:`draw_starts`, :func:`summarise_starts`): the
fits can run the search from ``multistart`` random starts besides the
given one; the summary counts the starts that reached the best cost
(within 10⁻⁶ of it, as in :func:`~servoid.estimate.fit_pem`) and warns
when the given start stopped in a worse local minimum, and when another
minimum fits statistically as well (``ΔV < χ²₁(0.95)·σ̂²``, the
likelihood-ratio limit) at parameters outside the 99 % confidence
ellipsoid of the chosen one — then the data do not single out one
parameter set.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _warn
from .._checks import as_array, as_str_list, type_error
from .._errors import DataError, ServoidWarning
from .._lazy import stats
from ._covariance import residual_ar

__all__ = [
    "MAX_STARTS",
    "Identifiability",
    "IdentifiabilityFlag",
    "MultistartSummary",
    "check_identifiability",
    "draw_starts",
    "summarise_starts",
    "weakest_parameters",
]

#: |ρ_ij| above which two parameters are not separately identifiable (issue 9).
CORRELATION_LIMIT = 0.999
#: s_min² of the normalised Jacobian below which a direction is near-null: 1 − 0.999, the
#: same limit for two parameters (module notes).
NULL_LIMIT = 1.0 - CORRELATION_LIMIT
#: The named parameters of a near-null direction hold this share of its squared norm.
NULL_SHARE = 0.9
#: FD curvature / Gauss–Newton curvature outside this band: the cost is not quadratic over ±h.
CURVATURE_BAND = (0.5, 2.0)
#: Beyond this band the Jacobian column itself is wrong (rounding, a discontinuity): a
#: curvature off by 100 over a move of |θ_k|/2 is no smooth nonlinearity.
SPOILT_BAND = (1e-2, 1e2)
#: σ_k below this fraction of the floor is flagged (a smooth model has σ_k >= floor_k).
FLOOR_FACTOR = 0.5
#: The shortest finite move, relative to |θ_k|: 10⁴ times the solver's √ε difference step.
MIN_STEP = 1e-4
#: Two starts reached the same minimum when their costs agree to this relative amount.
SAME_MINIMUM = 1e-6
#: Most extra starts a multistart fit takes: each is a full fit, and a few dozen already
#: show whether the minimum is unique.
MAX_STARTS = 1000


@dataclass(frozen=True)
class IdentifiabilityFlag:
    """One failed check.

    Attributes
    ----------
    kind : str
        ``"correlated"``, ``"near_null"``, ``"std_exceeds_value"``,
        ``"std_below_floor"``, ``"not_smooth"``, ``"local_minimum"`` or
        ``"equivalent_minimum"``.
    parameters : tuple of str
        The parameters concerned.
    message : str
        The warning text.
    """

    kind: str
    parameters: tuple[str, ...]
    message: str


@dataclass(frozen=True)
class MultistartSummary:
    """Outcome of a search from several starts.

    Attributes
    ----------
    starts : int
        Starts run (the given one first).
    same_minimum : int
        Starts whose cost is within 1e-6 (relative) of the best.
    failed : int
        Starts that did not converge.
    best : int
        Index of the start whose result is used (0: the given start).
    costs : tuple of float or None
        Final cost Σr² per start (None: failed).
    parameters : tuple of tuple of float or None
        Final θ per start (None: failed).
    """

    starts: int
    same_minimum: int
    failed: int
    best: int
    costs: tuple[float | None, ...]
    parameters: tuple[tuple[float, ...] | None, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {"starts": self.starts, "same_minimum": self.same_minimum,
                "failed": self.failed, "best": self.best, "costs": list(self.costs),
                "parameters": [None if p is None else list(p) for p in self.parameters]}


@dataclass(frozen=True, eq=False)
class Identifiability:
    """Identifiability diagnostics of a fit (see the module notes).

    Attributes
    ----------
    names : tuple of str
        Parameter names.
    values : ndarray, shape (n,)
        The estimate θ̂.
    std : ndarray, shape (n,)
        Its reported standard deviations.
    correlation : ndarray, shape (n, n)
        Correlation matrix of the reported covariance (NaN where a std is 0).
    singular_values : ndarray, shape (n,)
        Of the column-normalised Jacobian, descending.
    weakest_direction : ndarray, shape (n,)
        Right singular vector of the smallest singular value (its largest
        component positive).
    curvature_ratio : ndarray, shape (n,)
        Finite-difference curvature of the cost over ±h_k divided by
        2‖J_k‖² (NaN: not evaluated, e.g. the simulation failed at a step).
    std_floor : ndarray, shape (n,)
        The Hammersley–Chapman–Robbins floor of each std (NaN: not evaluated).
    step : ndarray, shape (n,)
        The finite move h_k used by the last two checks.
    multistart : MultistartSummary or None
        The several-start summary, when the fit ran several starts.
    flags : tuple of IdentifiabilityFlag
        The checks that failed (each was also warned).
    """

    names: tuple[str, ...]
    values: NDArray[np.float64]
    std: NDArray[np.float64]
    correlation: NDArray[np.float64]
    singular_values: NDArray[np.float64]
    weakest_direction: NDArray[np.float64]
    curvature_ratio: NDArray[np.float64]
    std_floor: NDArray[np.float64]
    step: NDArray[np.float64]
    multistart: MultistartSummary | None = None
    flags: tuple[IdentifiabilityFlag, ...] = ()

    def __post_init__(self) -> None:
        for name in ("values", "std", "correlation", "singular_values", "weakest_direction",
                     "curvature_ratio", "std_floor", "step"):
            arr = np.array(as_array(name, getattr(self, name), finite=False), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def condition_number(self) -> float:
        """κ of the column-normalised Jacobian, s_max/s_min."""
        s = self.singular_values
        if s.size == 0:
            return 1.0
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")

    @property
    def is_identifiable(self) -> bool:
        """No check failed."""
        return not self.flags

    def flagged(self, kind: str) -> tuple[str, ...]:
        """Parameters named by the flags of one kind.

        Parameters
        ----------
        kind : str
            A flag kind (see :class:`IdentifiabilityFlag`).
        """
        return tuple(dict.fromkeys(p for f in self.flags if f.kind == kind
                                   for p in f.parameters))

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (NaN and inf as None)."""
        names = self.names
        return {
            "identifiable": self.is_identifiable,
            "condition_number": _num(self.condition_number),
            "singular_values": [_num(v) for v in self.singular_values],
            "weakest_direction": dict(zip(names, (_num(v) for v in self.weakest_direction),
                                          strict=True)),
            "correlation": [[_num(v) for v in row] for row in self.correlation],
            "std": dict(zip(names, (_num(v) for v in self.std), strict=True)),
            "std_floor": dict(zip(names, (_num(v) for v in self.std_floor), strict=True)),
            "curvature_ratio": dict(zip(names, (_num(v) for v in self.curvature_ratio),
                                        strict=True)),
            "step": dict(zip(names, (_num(v) for v in self.step), strict=True)),
            "multistart": None if self.multistart is None else self.multistart.to_dict(),
            "flags": [{"kind": f.kind, "parameters": list(f.parameters), "message": f.message}
                      for f in self.flags],
        }


def check_identifiability(
    residual_fn: Callable[[NDArray[np.float64]], ArrayLike],
    theta: ArrayLike,
    covariance: ArrayLike,
    names: Sequence[str],
    *,
    jacobian: ArrayLike | None = None,
    groups: Sequence[Sequence[int]] | None = None,
    multistart: MultistartSummary | None = None,
    warn: bool = True,
) -> Identifiability:
    """Check that a least-squares fit's parameters are identifiable.

    Parameters
    ----------
    residual_fn : callable
        ``residual_fn(theta) -> r``: the (weighted) residuals y − ŷ(θ)
        stacked, shape (N,); NaN where the model cannot be evaluated.
    theta : array_like, shape (n,)
        The estimate θ̂ (a minimum of Σr²).
    covariance : array_like, shape (n, n)
        Its reported covariance.
    names : sequence of str
        A name per parameter.
    jacobian : array_like, shape (N, n), optional
        ∂r/∂θ at θ̂; default central differences (2n evaluations).
    groups : sequence of sequence of int, optional
        How r is made of series: the lengths of consecutive segments,
        grouped by noise (e.g. ``[[n]]``, the default: one series;
        ``[[n1, n2]]``: two records of one channel; ``[[n], [n]]``: two
        channels).  Each group gets its own whitening AR model; lags never
        cross segments.
    multistart : MultistartSummary, optional
        Outcome of a several-start search, to be checked and kept.
    warn : bool
        Issue a :class:`~servoid.ServoidWarning` per failed check.

    Returns
    -------
    Identifiability
        The diagnostics and the flags (module notes).

    Raises
    ------
    DataError
        Shapes that do not agree, or a non-finite residual at θ̂.
    """
    if not callable(residual_fn):
        raise type_error("residual_fn", residual_fn, "a function theta -> residuals")
    theta = as_array("theta", theta).ravel()
    n = theta.size
    names = tuple(as_str_list("names", names))
    cov = as_array("covariance", covariance, finite=False)
    if len(names) != n or cov.shape != (n, n):
        raise DataError(f"theta has {n} entries; names has {len(names)} and covariance "
                        f"shape {cov.shape} (expected ({n}, {n}))")
    r0 = np.asarray(residual_fn(theta), dtype=float).ravel()
    if not np.all(np.isfinite(r0)):
        raise DataError("the residuals at theta are not all finite")
    layout = [[r0.size]] if groups is None else [[int(k) for k in g] for g in groups]
    if sum(sum(g) for g in layout) != r0.size:
        raise DataError(f"groups cover {sum(sum(g) for g in layout)} residuals, "
                        f"residual_fn returned {r0.size}")
    if jacobian is None:
        jac = _central_jacobian(residual_fn, theta, r0.size)
    else:
        jac = as_array("jacobian", jacobian)
        if jac.shape != (r0.size, n):
            raise DataError(f"jacobian must have shape {(r0.size, n)}, got {jac.shape}")
    return assess(residual_fn, theta, r0, jac, cov, names, layout, multistart, warn=warn)


def assess(
    residual_fn: Callable[[NDArray[np.float64]], ArrayLike],
    theta: NDArray[np.float64],
    r0: NDArray[np.float64],
    jac: NDArray[np.float64],
    cov: NDArray[np.float64],
    names: tuple[str, ...],
    layout: Sequence[Sequence[int]],
    multistart: MultistartSummary | None = None,
    *,
    warn: bool = True,
    covariance_kind: str = "",
) -> Identifiability:
    """The checks of :func:`check_identifiability`, inputs trusted.

    ``covariance_kind`` is the covariance the fit reported (``"white"``,
    ``"robust"``, ``"bootstrap"``): the flags' advice leaves it out.
    """
    n = theta.size
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov / np.outer(std, std)
    np.fill_diagonal(corr, np.where(std > 0, 1.0, np.nan))
    norms = np.sqrt(np.einsum("ij,ij->j", jac, jac))
    js = jac / np.where(norms > 0, norms, 1.0)
    _, sv, vt = np.linalg.svd(js, full_matrices=False)
    weakest = vt[-1] if n else np.zeros(0)
    if n and weakest[np.argmax(np.abs(weakest))] < 0:
        weakest = -weakest
    steps, ratio, floor = _finite_moves(residual_fn, theta, r0, norms, std, layout)
    flags = _flags(theta, std, corr, sv, weakest, ratio, floor, steps, names, covariance_kind)
    if multistart is not None:
        flags += _multistart_flags(multistart, theta, cov, float(r0 @ r0),
                                   max(r0.size - n, 1), names)
    if warn:
        for f in flags:
            _warn.warn(f.message, ServoidWarning)
    return Identifiability(names, theta, std, corr, sv, weakest, ratio, floor, steps,
                           multistart, tuple(flags))


def draw_starts(
    z0: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    is_log: NDArray[np.bool_],
    count: int,
    rng: np.random.Generator,
) -> list[NDArray[np.float64]]:
    """Random starts in the search coordinates z around z0.

    Per coordinate: uniform between finite bounds (log-uniform for a log
    parameter); else within a factor 3 of θ₀ (log parameters) or θ₀ ±
    50 % (±1 when θ₀ = 0); kept strictly inside the bounds.
    """
    out = []
    spread = np.where(is_log, np.log(3.0), 0.5 * np.where(z0 != 0, np.abs(z0), 2.0))
    bounded = np.isfinite(lower) & np.isfinite(upper)
    for _ in range(count):
        z = np.where(bounded, rng.uniform(np.where(bounded, lower, 0.0),
                                          np.where(bounded, upper, 1.0)),
                     z0 + spread * rng.uniform(-1.0, 1.0, z0.size))
        inside = np.clip(z, np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf))
        out.append(inside)
    return out


def weakest_parameters(jac: NDArray[np.float64], names: Sequence[str]) -> tuple[str, ...]:
    """Names in the weakest direction of the column-normalised Jacobian.

    The largest components holding 90 % of the squared norm (at least one).
    """
    norms = np.sqrt(np.einsum("ij,ij->j", jac, jac))
    _, _, vt = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), full_matrices=False)
    v = vt[-1]  # a zero column (a parameter without effect) makes it that unit vector
    order = np.argsort(-v**2)
    count = int(np.searchsorted(np.cumsum(v[order] ** 2), NULL_SHARE)) + 1
    return tuple(names[k] for k in order[:count])


def summarise_starts(
    costs: Sequence[float], thetas: Sequence[NDArray[np.float64] | None], floor: float
) -> MultistartSummary:
    """The :class:`MultistartSummary` of finished starts (cost inf: failed).

    ``floor`` is the cost below which two costs count as equal (the
    rounding floor of the data, e.g. ``N·(1e-12·rms y)²``).
    """
    c = np.asarray(costs, dtype=float)
    best = int(np.argmin(c))
    same = int(np.sum(np.isfinite(c) & (np.abs(c - c[best]) <= SAME_MINIMUM
                                        * max(c[best], floor))))
    return MultistartSummary(
        starts=c.size, same_minimum=same, failed=int(np.sum(~np.isfinite(c))), best=best,
        costs=tuple(float(v) if np.isfinite(v) else None for v in c),
        parameters=tuple(None if t is None or not np.isfinite(v) else
                         tuple(float(x) for x in t) for t, v in zip(thetas, c, strict=True)))


# -- helpers --------------------------------------------------------------------------------


def _central_jacobian(
    residual_fn: Callable[[NDArray[np.float64]], ArrayLike], theta: NDArray[np.float64],
    size: int,
) -> NDArray[np.float64]:
    jac = np.empty((size, theta.size))
    for k in range(theta.size):
        h = np.cbrt(np.finfo(float).eps) * max(abs(theta[k]), 1.0)  # central differences
        e = np.zeros(theta.size)
        e[k] = h
        plus = np.asarray(residual_fn(theta + e), dtype=float).ravel()
        minus = np.asarray(residual_fn(theta - e), dtype=float).ravel()
        jac[:, k] = (plus - minus) / (2.0 * h)
    return jac


def _finite_moves(
    residual_fn: Callable[[NDArray[np.float64]], ArrayLike],
    theta: NDArray[np.float64],
    r0: NDArray[np.float64],
    norms: NDArray[np.float64],
    std: NDArray[np.float64],
    layout: Sequence[Sequence[int]],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Steps h_k, curvature ratios and HCR floors from r(θ̂ ± h_k e_k)."""
    n = theta.size
    whiten = _whitening(r0, layout, n)
    v0 = float(r0 @ r0)
    steps = np.full(n, np.nan)
    ratio = np.full(n, np.nan)
    floor = np.full(n, np.nan)
    for k in range(n):
        h = max(std[k], MIN_STEP * abs(theta[k]))
        if theta[k] != 0.0:
            h = min(h, 0.5 * abs(theta[k]))
        if not (np.isfinite(h) and h > 0):
            continue
        steps[k] = h
        # each side reduced to ‖r‖² and its whitened distance from r0 at once: no residual of
        # the record's length is kept beyond the one in hand
        squares: list[float | None] = []
        bounds = []
        for sign in (1.0, -1.0):
            t = theta.copy()
            t[k] += sign * h
            try:
                with np.errstate(all="ignore"):
                    r = np.asarray(residual_fn(t), dtype=float).ravel()
            except (ValueError, ArithmeticError, RuntimeError):
                # the model refuses θ there (a bound, an unstable or invalid set): this side of
                # the check is not evaluated — the fit itself stands
                r = np.full(0, np.nan)
            if r.shape != r0.shape or not np.all(np.isfinite(r)):
                squares.append(None)
                continue
            squares.append(float(r @ r))
            with np.errstate(divide="ignore"):  # a step that moves nothing: no finite floor
                bounds.append(h**2 / _expm1(whiten(r0, r)))  # of r0 − r, formed chunk-wise
            del r
        if squares[0] is not None and squares[1] is not None and norms[k] > 0:
            curv = (squares[0] - 2.0 * v0 + squares[1]) / h**2
            ratio[k] = curv / (2.0 * norms[k] ** 2)
        if bounds:
            floor[k] = float(np.sqrt(max(bounds)))
    return steps, ratio, floor


def _whitening(
    r0: NDArray[np.float64], layout: Sequence[Sequence[int]], n_par: int
) -> Callable[[NDArray[np.float64], NDArray[np.float64]], float]:
    """``(x, y) ↦ Σ_g ‖A_g(q) δ_g‖²/s_g²``, δ = x − y, with each group's residual AR model."""
    n_all = r0.size
    dof_ratio = n_all / max(n_all - n_par, 1)  # σ_η² is a Σ/N mean: N/(N − d) as for σ̂²
    cuts: list[list[tuple[int, int]]] = []
    pos = 0
    for group in layout:
        cuts.append([])
        for size in group:
            cuts[-1].append((pos, pos + size))
            pos += size
    models = []
    for spans in cuts:
        ar, innovation = residual_ar([r0[a:b] for a, b in spans], sum(b - a for a, b in spans))
        models.append((spans, ar, innovation * dof_ratio))

    def information(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
        """The whitened energy of δ = x − y."""
        total = 0.0
        for spans, ar, s2 in models:
            if not s2 > 0:
                return float("inf")
            for a, b in spans:
                total += _fir_energy(ar, x[a:b], y[a:b]) / s2
        return total

    return information


def _fir_energy(ar: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64],
                chunk: int = 1 << 16) -> float:
    """‖ar(q)(x − y)‖², zero before the start, a chunk of samples at a time."""
    p = ar.size - 1
    total = 0.0
    for lo in range(0, x.size, chunk):
        hi = min(lo + chunk, x.size)
        part = x[max(lo - p, 0) : hi] - y[max(lo - p, 0) : hi]
        if p == 0:  # the AR model is monic: no filter
            total += float(part @ part)
            continue
        if lo < p:  # the start of the record: zeros before it, as the filter starts from rest
            part = np.concatenate([np.zeros(p - lo), part])
        w = np.convolve(part, ar, mode="valid")
        total += float(w @ w)
    return total


def _expm1(x: float) -> float:
    with np.errstate(over="ignore"):
        return float(np.expm1(x)) if x > 0 else 0.0


def _flags(
    theta: NDArray[np.float64],
    std: NDArray[np.float64],
    corr: NDArray[np.float64],
    sv: NDArray[np.float64],
    weakest: NDArray[np.float64],
    ratio: NDArray[np.float64],
    floor: NDArray[np.float64],
    step: NDArray[np.float64],
    names: tuple[str, ...],
    kind: str = "",
) -> list[IdentifiabilityFlag]:
    flags: list[IdentifiabilityFlag] = []
    n = theta.size
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)
             if np.isfinite(corr[i, j]) and abs(corr[i, j]) > CORRELATION_LIMIT]
    if pairs:
        text = ", ".join(f"{names[i]}–{names[j]} ({corr[i, j]:+.5f})" for i, j in pairs)
        flags.append(IdentifiabilityFlag(
            "correlated", tuple(dict.fromkeys(names[k] for p in pairs for k in p)),
            f"parameters not separately identifiable: correlation beyond ±{CORRELATION_LIMIT} "
            f"for {text}; the data fix a combination of them, not each — fix one, "
            "reparametrise, or give a record that separates their effects"))
    if n > 1 and sv[-1] ** 2 < NULL_LIMIT:
        order = np.argsort(-weakest**2)
        share = np.cumsum(weakest[order] ** 2)
        count = max(2, int(np.searchsorted(share, NULL_SHARE)) + 1)
        involved = tuple(names[k] for k in order[:count])
        if not any(set(involved) == {names[i], names[j]} for i, j in pairs):
            combo = " ".join(f"{weakest[k]:+.3f}·{names[k]}" for k in order[:count])
            flags.append(IdentifiabilityFlag(
                "near_null", involved,
                f"parameters {', '.join(involved)} are not separately identifiable: the "
                f"normalised sensitivities nearly cancel along {combo} (smallest singular "
                f"value {sv[-1]:.2g} of the column-normalised Jacobian, condition number "
                f"{sv[0] / max(sv[-1], 1e-300):.3g}); fix one or reparametrise"))
    big = [k for k in range(n) if np.isfinite(std[k]) and std[k] > abs(theta[k])]
    if big:
        text = ", ".join(f"{names[k]} = {theta[k]:.4g} ± {std[k]:.2g}" for k in big)
        flags.append(IdentifiabilityFlag(
            "std_exceeds_value", tuple(names[k] for k in big),
            f"standard deviation exceeds the value ({text}): the data do not determine "
            "these parameters; fix them or give a record that excites their effect"))
    low = [k for k in range(n) if np.isfinite(floor[k]) and std[k] < FLOOR_FACTOR * floor[k]]
    if low:
        text = ", ".join(f"{names[k]}: {std[k]:.3g} < {floor[k]:.3g}" for k in low)
        flags.append(IdentifiabilityFlag(
            "std_below_floor", tuple(names[k] for k in low),
            f"standard deviation below what the noise and record length allow ({text}, the "
            "Hammersley–Chapman–Robbins floor with the others known): the covariance "
            "understates the error — coloured noise under a white formula, or a Jacobian "
            "spoilt by a discontinuity; " + _floor_advice(kind)))
    # a move capped at |θ_k|/2 < σ_k or raised to 1e-4·|θ_k| > σ_k does not test the quadratic
    # model over ±1σ, so there only a disagreement no nonlinearity explains counts: a spoilt
    # Jacobian column
    bands = [CURVATURE_BAND if step[k] == std[k] else SPOILT_BAND for k in range(n)]
    rough = [k for k in range(n) if np.isfinite(ratio[k])
             and not bands[k][0] <= ratio[k] <= bands[k][1]]
    if rough:
        text = ", ".join(f"{names[k]} ({ratio[k]:.3g})" for k in rough)
        flags.append(IdentifiabilityFlag(
            "not_smooth", tuple(names[k] for k in rough),
            f"the cost is not quadratic over ±1σ: its finite-difference curvature differs "
            f"from 2JᵀJ by more than a factor 2 for {text} (ratio in parentheses); the "
            "interval from the Jacobian does not describe it — a discontinuity or threshold, "
            "rounding in the model that spoils the finite-difference Jacobian, or a strong "
            "nonlinearity; try covariance='bootstrap' or a smoother, better-scaled model"))
    return flags


def _floor_advice(kind: str) -> str:
    """What to try when a std is below its floor, without the covariance already in use."""
    others = [k for k in ("robust", "bootstrap") if k != kind]
    if kind == "bootstrap":
        return ("the bootstrap in use resamples a model with a discontinuity too: smooth the "
                "model or fix the parameter")
    return "use covariance=" + " or ".join(f"'{k}'" for k in others)


def _multistart_flags(
    summary: MultistartSummary, theta: NDArray[np.float64], cov: NDArray[np.float64],
    cost: float, dof: int, names: tuple[str, ...],
) -> list[IdentifiabilityFlag]:
    flags: list[IdentifiabilityFlag] = []
    sigma2 = cost / dof
    c0 = summary.costs[0]
    if summary.best != 0 and (c0 is None or c0 - cost > SAME_MINIMUM * cost):
        flags.append(IdentifiabilityFlag(
            "local_minimum", names,
            f"the search from the given start stopped "
            f"{'without converging' if c0 is None else f'in a local minimum (cost {c0:.6g})'}; "
            f"random start {summary.best} of {summary.starts - 1} reached cost {cost:.6g} and "
            "is the result — check the start values"))
    lr_limit = float(stats.chi2.ppf(0.95, 1)) * sigma2
    ellipsoid = float(stats.chi2.ppf(0.99, theta.size))
    inv = np.linalg.pinv(cov)
    others = []
    for k, (c, p) in enumerate(zip(summary.costs, summary.parameters, strict=True)):
        if k == summary.best or c is None or p is None or c - cost > lr_limit:
            continue
        d = np.asarray(p) - theta
        if float(d @ inv @ d) > ellipsoid:
            others.append((k, c, p))
    if others:
        k, c, p = others[0]
        text = ", ".join(f"{nm} = {v:.4g}" for nm, v in zip(names, p, strict=True))
        flags.append(IdentifiabilityFlag(
            "equivalent_minimum", names,
            f"{len(others)} other start(s) reached a different minimum that fits as well "
            f"(start {k}: cost {c:.6g} vs {cost:.6g}, within the likelihood-ratio limit; "
            f"{text}) outside the 99 % confidence region: the data do not single out one "
            "parameter set"))
    return flags


def _num(v: float) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None
