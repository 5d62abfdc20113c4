"""Frequency-domain maximum likelihood of s- and z-domain transfer functions.

The model on the lines ω_k is ``G(Ω_k, θ) = B(Ω_k)/A(Ω_k)·D(ω_k)``, with
``Ω = s = jω`` (continuous, A monic in its highest power) or ``Ω = z⁻¹ =
e^{−jωT}`` (discrete, ``A(0) = 1``), and the input delay ``D = e^{−jωτ}``
(continuous: τ given, or estimated as a parameter) or ``z^{−n_k}``
(discrete, n_k whole samples).  With a nonparametric estimate Ĝ_k whose
errors are independent, circular complex normal of variance σ²_k, the
negative log-likelihood is, up to a constant,

    V(θ) = Σ_k |G(Ω_k, θ) − Ĝ_k|² / σ²_k

(Pintelon & Schoukens, *System Identification: A Frequency Domain
Approach*, 2nd ed., 2012, ch. 9–10).  When σ²_k is itself estimated from
ν complex degrees of freedom (the LPM's q, the BLA's M − 1, the periodic
P − 1) the same cost is the *sample* maximum-likelihood (SML) cost; its
consequences are (P&S §10.3, with the weights' law χ²_{2ν}):

- each term ``|e_k|²/σ̂²_k`` is F(2, 2ν)-distributed: mean ν/(ν − 1),
  variance ν³/((ν − 1)²(ν − 2));
- the covariance ``½(JᵀJ)⁻¹`` of the normalised residuals underestimates
  the true one by ``(ν − 2)/ν``: it is multiplied by ``ν/(ν − 2)``.

The *cost-function test* (the validation verdict, P&S §11.3): at the
minimum, with L lines and n_θ free parameters, V is distributed as
``(L − n_θ/2)`` of those terms, matched to a scaled χ² (exactly ½χ²
with ``2L − n_θ`` degrees of freedom when σ² is known); the p-value is
the chance of a larger cost under the model.  A model that is too simple
leaves its systematic error in V and is rejected.

Lines of a local method (LPM/LRM) share windows, so their errors are
correlated over ``stride`` lines; the fit uses every ``stride``-th line,
whose errors are independent, so that the covariance and the cost test
hold (at the price of the lines in between).

The starting values come from the equation error ``B(Ω) − Ĝ·A(Ω)``,
linear in θ: ``"wls"`` — weighted linear least squares (Levy, weights
1/σ_k) iterated with the weights 1/(σ_k·|A(Ω_k)|) of the previous
denominator (Sanathanan–Koerner); ``"gtls"`` — the generalised total
least squares estimate (the equation error's covariance,
``σ²_k·|A(Ω_k)|²``, in the constraint: the smallest generalised
eigenvalue), consistent where Levy is biased; ``"btls"`` — GTLS
bootstrapped with the previous ``1/|A(Ω_k)|²`` (P&S §9.11); ``"auto"`` —
each, and the one of lowest V.  The minimum is then found by
Levenberg–Marquardt with the analytic Jacobian: ``∂G/∂b_i = Ω^i·D/A``,
``∂G/∂a = −G·Ω^·/A``, ``∂G/∂τ = −jω·G``.

For conditioning, s is divided by ω_s (the geometric mean of the lowest
and highest line) and the response by its median magnitude; θ and its
covariance are mapped back at the end.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import (
    ConvergenceError,
    DataError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from .._lazy import linalg, optimize, stats
from .._warn import warn
from ..models import TransferFunction
from ._measured import FrfMeasurement, VarianceKind, as_measurement

__all__ = ["Domain", "MlFit", "MlStart", "fit_ml", "select_ml_order"]

Domain = Literal["s", "z"]
MlStart = Literal["auto", "wls", "gtls", "btls"]
_DOMAINS: tuple[Domain, ...] = ("s", "z")
_STARTS: tuple[MlStart, ...] = ("auto", "wls", "gtls", "btls")
_SK_ITER = 20
_SK_TOL = 1e-9
_MAX_NFEV = 2000


@dataclass(frozen=True, eq=False)
class MlFit:
    """A transfer function fitted by frequency-domain ML.

    Attributes
    ----------
    model : TransferFunction
        The fitted model (its delay included).
    names : tuple of str
        Parameter names: ``b0 … b_m`` (numerator, coefficient of Ω^i),
        ``a1 … a_n`` (denominator; in s the coefficient of s^{n−k}, in z
        of z^{−k}), and ``tau`` [s] when the delay was estimated.
    parameters : ndarray
        Their values.
    covariance : ndarray
        Their covariance (SML-corrected when the variances were estimated).
    cost : float
        V at the minimum.
    expected_cost, cost_std : float
        Mean and standard deviation of V at the minimum under the model.
    p_value : float
        Chance of a cost above `cost` under the model (cost-function test).
    n_lines : int
        Lines fitted (independent ones).
    dof : float
        Complex degrees of freedom of the line variances (``inf``: known).
    domain : {"s", "z"}
        Continuous or discrete model.
    n_poles, n_zeros : int
        Orders (zeros: degree of B in Ω).
    start : str
        The starting estimate the minimum was reached from.
    measurement : FrfMeasurement
        The lines fitted.
    """

    model: TransferFunction
    names: tuple[str, ...]
    parameters: NDArray[np.float64]
    covariance: NDArray[np.float64]
    cost: float
    expected_cost: float
    cost_std: float
    p_value: float
    n_lines: int
    dof: float
    domain: Domain
    n_poles: int
    n_zeros: int
    start: str
    measurement: FrfMeasurement
    _scale: tuple[float, float, int] = (1.0, 1.0, 0)

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviation of each parameter."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def passes_cost_test(self, level: float = 0.05) -> bool:
        """True unless the cost is improbably high under the model at `level`."""
        return bool(self.p_value >= level)

    def model_at(self, parameters: NDArray[np.float64]) -> TransferFunction:
        """The model with other parameter values (same structure)."""
        return _model(np.asarray(parameters, dtype=float), self.domain, self.n_poles,
                      self.n_zeros, self.model.dt, self._scale[2], self.model.delay,
                      "tau" in self.names)

    def response(self, frequency: NDArray[np.float64]) -> NDArray[np.complex128]:
        """The model's response at `frequency` [Hz]."""
        return self.model.freqresp(2 * np.pi * np.asarray(frequency, dtype=float))

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "domain": self.domain, "n_poles": self.n_poles, "n_zeros": self.n_zeros,
            "start": self.start, "names": list(self.names),
            "parameters": [float(v) for v in self.parameters],
            "std": [float(v) for v in self.std],
            "covariance": [[float(v) for v in row] for row in self.covariance],
            "cost": float(self.cost), "expected_cost": float(self.expected_cost),
            "cost_std": float(self.cost_std), "p_value": float(self.p_value),
            "n_lines": self.n_lines, "dof": None if math.isinf(self.dof) else float(self.dof),
            "num": [float(v) for v in self.model.num], "den": [float(v) for v in self.model.den],
            "dt": self.model.dt, "delay": float(self.model.delay),
        }

    def __repr__(self) -> str:
        return (f"<MlFit {self.domain}: {self.n_poles} poles, {self.n_zeros} zeros, "
                f"V = {self.cost:.4g} (expected {self.expected_cost:.4g} ± "
                f"{self.cost_std:.2g}), p = {self.p_value:.2g}>")


def fit_ml(
    frf: FrfMeasurement,
    n_poles: int,
    n_zeros: int | None = None,
    *,
    domain: Domain = "s",
    delay: float | None = 0.0,
    delay_samples: int = 0,
    variance: VarianceKind = "total",
    start: MlStart = "auto",
    f_min: float | None = None,
    f_max: float | None = None,
) -> MlFit:
    """Fit a transfer function to an FRF by maximum likelihood.

    Parameters
    ----------
    frf : FrfMeasurement
        From :func:`estimate_lpm`, :func:`estimate_lrm` or :func:`estimate_bla`.
    n_poles : int
        Degree of A (>= 1).
    n_zeros : int, optional
        Degree of B in Ω; default ``n_poles − 1`` in s, ``n_poles`` in z.
    domain : {"s", "z"}
        Continuous (needs ``n_zeros <= n_poles``) or discrete at the
        record's dt.
    delay : float or None
        Continuous input delay τ [s], fixed; None estimates it (starting
        from 0).
    delay_samples : int
        Discrete input delay n_k [samples] (``domain="z"``).
    variance : {"total", "noise"}
        Which variance weights the lines (total: noise plus the
        stochastic nonlinear distortion of a BLA).
    start : {"auto", "wls", "gtls", "btls"}
        Starting estimate (module notes).
    f_min, f_max : float, optional
        Band of lines to fit [Hz].

    Returns
    -------
    MlFit

    Raises
    ------
    DataError
        Fewer lines than parameters, a line without a positive variance,
        a discrete fit of a measurement without dt.
    ConvergenceError
        No finite start.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.frequency import FrfMeasurement, fit_ml
    >>> f = np.linspace(0.1, 10, 50)
    >>> g = 10.0 / (1j * 2 * np.pi * f + 10.0)
    >>> frm = FrfMeasurement(f, g, np.full(50, 1e-6), np.full(50, 1e-6), None, np.inf,
    ...                      np.inf, 1, "periodic")
    >>> fit = fit_ml(frm, 1, 0)
    >>> [round(float(v), 6) for v in fit.parameters]
    [10.0, 10.0]
    """
    frm = as_measurement(frf)
    check_option("domain", domain, _DOMAINS)
    check_option("variance", variance, ("total", "noise"))
    check_option("start", start, _STARTS)
    n = as_int("n_poles", n_poles, minimum=1, maximum=40)
    default_m = n - 1 if domain == "s" else n
    m = default_m if n_zeros is None else as_int("n_zeros", n_zeros, minimum=0, maximum=40)
    if domain == "s" and m > n:
        raise DataError(f"a continuous model needs n_zeros <= n_poles = {n}, got {m}")
    nk = as_int("delay_samples", delay_samples, minimum=0)
    est_delay = delay is None
    tau = 0.0 if delay is None else as_float("delay", delay, nonneg=True, unit="s")
    if domain == "z":
        if frm.dt is None:
            raise DataError("a discrete (domain = \"z\") fit needs the measurement's sample "
                            "period; this FrfMeasurement has dt = None")
        if est_delay or tau:
            raise DataError("a discrete model takes its delay in whole samples: pass "
                            "delay_samples, not delay")
    if f_min is not None or f_max is not None:
        frm = frm.select(f_min, f_max)
    frm = frm.independent()
    var, dof = frm.variance_of(variance)
    if not np.all(np.isfinite(var) & (var > 0)):
        raise DataError("every line needs a positive, finite variance to weight the fit; "
                        f"{int(np.sum(~(np.isfinite(var) & (var > 0))))} line(s) have none "
                        "(noise-free data, or a line without excitation); restrict the band")
    n_theta = (m + 1) + n + int(est_delay)
    if 2 * frm.n_lines <= n_theta:
        raise DataError(f"{frm.n_lines} independent lines cannot fit {n_theta} parameters; "
                        "lower the orders or measure more lines")
    omega = frm.omega
    g_meas = np.asarray(frm.response)
    sigma = np.sqrt(var)
    if domain == "s":
        pos = omega[omega > 0]
        w_s = float(np.sqrt(pos.min() * pos.max())) if pos.size else 1.0
        x = 1j * omega / w_s
        fixed = np.exp(-1j * omega * tau)
    else:
        w_s = 1.0
        x = np.exp(-1j * omega * frm.dt)
        fixed = x**nk
    g_s = float(np.median(np.abs(g_meas))) or 1.0
    prob = _Problem(x, g_meas / g_s, sigma / g_s, fixed, domain, n, m, est_delay)
    starts = _starts(prob, start)
    if not starts:
        raise ConvergenceError("no starting estimate was finite: the lines do not determine "
                               f"a model of {n} poles and {m} zeros; lower the orders")
    best = None
    for name, theta0 in starts:
        sol = optimize.least_squares(prob.residual, theta0, jac=prob.jacobian, method="lm",
                                     x_scale="jac", max_nfev=_MAX_NFEV)
        cost = float(np.sum(sol.fun**2))
        if best is None or cost < best[1]:
            best = (name, cost, sol)
    assert best is not None
    name, cost, sol = best
    jac = prob.jacobian(sol.x)
    try:
        cov_s = 0.5 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov_s = np.full((n_theta, n_theta), np.nan)
    if math.isfinite(dof):
        if dof <= 2:
            warn(f"the line variances have {dof:g} degree(s) of freedom: the parameter "
                 "covariance is not finite (the SML needs > 2); measure more periods or "
                 "realisations", ServoidWarning)
            cov_s = cov_s * np.inf
        else:
            cov_s = cov_s * dof / (dof - 2.0)
    scale = _scale_vector(n, m, domain, w_s, g_s, est_delay)
    theta = sol.x * scale
    cov = cov_s * np.outer(scale, scale)
    mean, spread, p = cost_test(cost, frm.n_lines, n_theta, dof)
    names = tuple([f"b{i}" for i in range(m + 1)] + [f"a{k}" for k in range(1, n + 1)]
                  + (["tau"] if est_delay else []))
    model = _model(theta, domain, n, m, frm.dt, nk, tau, est_delay)
    return MlFit(model=model, names=names, parameters=theta, covariance=cov, cost=cost,
                 expected_cost=mean, cost_std=spread, p_value=p, n_lines=frm.n_lines, dof=dof,
                 domain=domain, n_poles=n, n_zeros=m, start=name, measurement=frm,
                 _scale=(w_s, g_s, nk))


def select_ml_order(
    frf: FrfMeasurement,
    orders: Sequence[tuple[int, int]],
    *,
    level: float = 0.05,
    **options: Any,
) -> tuple[MlFit, tuple[MlFit, ...]]:
    """The simplest order that passes the cost-function test.

    Parameters
    ----------
    frf : FrfMeasurement
        The measurement.
    orders : sequence of (n_poles, n_zeros)
        Candidates, simplest first.
    level : float
        Test level: a cost with p-value below it rejects the order.
    **options
        Passed to :func:`fit_ml`.

    Returns
    -------
    (MlFit, tuple of MlFit)
        The chosen fit (the first that passes, else the one of highest
        p-value) and every fit, in the order of `orders`.
    """
    level = as_float("level", level, positive=True)
    pairs = _orders(orders)
    fits = tuple(fit_ml(frf, p, z, **options) for p, z in pairs)
    for fit in fits:
        if fit.passes_cost_test(level):
            return fit, fits
    return max(fits, key=lambda f: f.p_value), fits


def _orders(orders: object) -> list[tuple[int, int]]:
    if isinstance(orders, (str, bytes)) or not isinstance(orders, Sequence) or not orders:
        raise OptionTypeError(f"orders must be a non-empty sequence of (n_poles, n_zeros) pairs, "
                              f"got {orders!r}")
    out = []
    for pair in orders:
        if isinstance(pair, (str, bytes)) or not isinstance(pair, Sequence) or len(pair) != 2:
            raise OptionTypeError(f"each order must be a pair (n_poles, n_zeros), got {pair!r}")
        out.append((as_int("n_poles", pair[0], minimum=1), as_int("n_zeros", pair[1],
                                                                   minimum=0)))
    return out


def cost_test(cost: float, n_lines: int, n_theta: int, dof: float) -> tuple[float, float, float]:
    """Mean, standard deviation and p-value of the ML cost at its minimum under the model."""
    terms = n_lines - 0.5 * n_theta
    if math.isinf(dof):
        mean, var = terms, terms
    elif dof > 2:
        mean = terms * dof / (dof - 1.0)
        var = terms * dof**3 / ((dof - 1.0) ** 2 * (dof - 2.0))
    else:
        return math.nan, math.nan, math.nan
    c = var / (2.0 * mean)  # V ≈ c·χ²_d with the same mean and variance (Satterthwaite)
    d = 2.0 * mean**2 / var
    return mean, math.sqrt(var), float(stats.chi2.sf(cost / c, d))


# -- the problem ---------------------------------------------------------------------------------
class _Problem:
    """Residuals and Jacobian of the scaled ML cost."""

    def __init__(self, x: NDArray[np.complex128], g: NDArray[np.complex128],
                 sigma: NDArray[np.float64], fixed: NDArray[np.complex128], domain: str, n: int,
                 m: int, est_delay: bool) -> None:
        self.x, self.g, self.sigma, self.fixed = x, g, sigma, fixed
        self.domain, self.n, self.m, self.est_delay = domain, n, m, est_delay
        self.pow_b = x[:, None] ** np.arange(m + 1)[None, :]
        if domain == "s":  # A = x^n + Σ α_k x^{n−k}
            self.pow_a = x[:, None] ** (n - np.arange(1, n + 1))[None, :]
            self.lead = x**n
        else:  # A = 1 + Σ α_k x^k
            self.pow_a = x[:, None] ** np.arange(1, n + 1)[None, :]
            self.lead = np.ones_like(x)

    def parts(self, theta: NDArray[np.float64]) -> tuple[Any, Any, Any, Any]:
        m, n = self.m, self.n
        b = self.pow_b @ theta[:m + 1]
        a = self.lead + self.pow_a @ theta[m + 1:m + 1 + n]
        d = self.fixed * (np.exp(-self.x * theta[-1]) if self.est_delay else 1.0)
        return b, a, d, b / a * d

    def residual(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        *_, gm = self.parts(theta)
        e = (gm - self.g) / self.sigma
        return np.concatenate([e.real, e.imag])

    def jacobian(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        _, a, d, gm = self.parts(theta)
        cols = [self.pow_b * (d / a)[:, None], -self.pow_a * (gm / a)[:, None]]
        if self.est_delay:
            cols.append((-self.x * gm)[:, None])
        j = np.concatenate(cols, axis=1) / self.sigma[:, None]
        return np.concatenate([j.real, j.imag])

    def cost(self, theta: NDArray[np.float64]) -> float:
        r = self.residual(theta)
        return float(r @ r) if np.all(np.isfinite(r)) else math.inf

    # -- linear starts (delay fixed at 0 in the estimated part) ---------------------------------
    def equation_columns(self) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """Columns of B − Ĝ·A over the full coefficient vector [β, α_lead, α_1..n]."""
        gd = self.g / self.fixed
        cols_b = self.pow_b
        cols_a = -gd[:, None] * np.concatenate([self.lead[:, None], self.pow_a], axis=1)
        return cols_b, cols_a

    def a_of(self, theta: NDArray[np.float64]) -> NDArray[np.complex128]:
        return self.lead + self.pow_a @ theta[self.m + 1:self.m + 1 + self.n]

    def with_delay(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([theta, [0.0]]) if self.est_delay else theta


def _starts(prob: _Problem, start: str) -> list[tuple[str, NDArray[np.float64]]]:
    out = []
    for name in (("wls", "gtls", "btls") if start == "auto" else (start,)):
        theta = _wls(prob) if name == "wls" else _gtls(prob, boot=name == "btls")
        if theta is not None:
            theta = prob.with_delay(theta)
            if math.isfinite(prob.cost(theta)):
                out.append((name, theta))
    if start == "auto" and out:
        out = [min(out, key=lambda item: prob.cost(item[1]))]
    return out


def _wls(prob: _Problem) -> NDArray[np.float64] | None:
    """Levy, then Sanathanan–Koerner iterations; the iterate of lowest V."""
    cols_b, cols_a = prob.equation_columns()
    lhs = np.concatenate([cols_b, cols_a[:, 1:]], axis=1)
    rhs = -cols_a[:, 0]
    w = 1.0 / (prob.sigma / np.abs(prob.fixed))
    best, best_cost = None, math.inf
    last = None
    for _ in range(_SK_ITER + 1):
        theta = _solve_real(lhs * w[:, None], rhs * w)
        if theta is None:
            break
        cost = prob.cost(prob.with_delay(theta))
        if cost < best_cost:
            best, best_cost = theta, cost
        if last is not None and _settled(theta, last):
            break
        last = theta
        a = np.abs(prob.a_of(theta))
        if not np.all(np.isfinite(a) & (a > 0)):
            break
        w = 1.0 / (prob.sigma / np.abs(prob.fixed) * a)
    return best


def _gtls(prob: _Problem, boot: bool) -> NDArray[np.float64] | None:
    """Generalised total least squares (bootstrapped: reweighted by the last 1/|A|²)."""
    cols_b, cols_a = prob.equation_columns()
    full = np.concatenate([cols_b, cols_a], axis=1)
    nb = cols_b.shape[1]
    sig = prob.sigma / np.abs(prob.fixed)
    # covariance of the equation error's columns: only the A columns carry Ĝ's noise
    pa = np.concatenate([prob.lead[:, None], prob.pow_a], axis=1)
    w = np.ones(full.shape[0])
    best, best_cost = None, math.inf
    for _ in range(_SK_ITER if boot else 1):
        wk = w / sig
        jr = _stack(full * wk[:, None])
        gram = jr.T @ jr
        ca = np.real((pa * w[:, None]).conj().T @ (pa * w[:, None]))
        cmat = np.zeros_like(gram)
        cmat[nb:, nb:] = ca
        try:
            _, vecs = linalg.eigh(cmat, gram)
        except (np.linalg.LinAlgError, ValueError):
            break
        v = vecs[:, -1]  # largest θᵀCθ/θᵀJᵀJθ: the smallest cost ratio
        lead = v[nb]
        if not (np.isfinite(lead) and abs(lead) > 0):
            break
        v = v / lead
        theta = np.concatenate([v[:nb], v[nb + 1:]])
        cost = prob.cost(prob.with_delay(theta))
        if cost < best_cost:
            best, best_cost = theta, cost
        if best is not None and theta is not best and _settled(theta, best):
            break
        a = np.abs(prob.a_of(theta))
        if not np.all(np.isfinite(a) & (a > 0)):
            break
        w = 1.0 / a
    return best


def _settled(theta: NDArray[np.float64], last: NDArray[np.float64]) -> bool:
    """The reweighted iteration has stopped moving."""
    return bool(np.max(np.abs(theta - last)) <= _SK_TOL * max(float(np.max(np.abs(theta))), 1.0))


def _stack(a: NDArray[np.complex128]) -> NDArray[np.float64]:
    return np.concatenate([a.real, a.imag])


def _solve_real(lhs: NDArray[np.complex128], rhs: NDArray[np.complex128],
                ) -> NDArray[np.float64] | None:
    a, b = _stack(lhs), np.concatenate([rhs.real, rhs.imag])
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return None
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    return sol if np.all(np.isfinite(sol)) else None


def _scale_vector(n: int, m: int, domain: str, w_s: float, g_s: float,
                  est_delay: bool) -> NDArray[np.float64]:
    """Physical parameter = scaled parameter × this."""
    if domain == "s":
        sb = g_s * w_s ** (n - np.arange(m + 1, dtype=float))
        sa = w_s ** np.arange(1, n + 1, dtype=float)
    else:
        sb = np.full(m + 1, g_s)
        sa = np.ones(n)
    parts = [sb, sa] + ([np.array([1.0 / w_s])] if est_delay else [])
    return np.concatenate(parts)


def _model(theta: NDArray[np.float64], domain: str, n: int, m: int, dt: float | None, nk: int,
           tau: float, est_delay: bool) -> TransferFunction:
    b, a = theta[:m + 1], theta[m + 1:m + 1 + n]
    if domain == "s":
        delay = float(theta[-1]) if est_delay else tau
        return TransferFunction(b[::-1], np.concatenate([[1.0], a]), delay=max(delay, 0.0))
    top = max(n, m + nk)
    den = np.concatenate([[1.0], a, np.zeros(top - n)])
    num = np.concatenate([np.zeros(nk), b, np.zeros(top - m - nk)])
    return TransferFunction(num, den, dt=dt)
