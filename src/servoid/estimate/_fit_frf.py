"""Continuous transfer function fitted to a measured frequency response.

The model is ``G(s, θ) = B(s)/A(s)·e^{−sτ}`` with ``B(s) = b_m·s^m + … +
b_0`` and a monic ``A(s) = s^n + a_1·s^{n−1} + … + a_n`` (the names
:func:`~servoid.estimate.fit_tf` gives: ``b_i`` multiplies s^i, ``a_k``
multiplies s^{n−k}); the delay τ is known, not estimated.  The fit minimises the maximum-likelihood
criterion of a frequency response with independent, circular complex
errors of variance σ²_k on its lines

    V(θ) = Σ_k |G(jω_k, θ) − Ĝ_k|² / σ²_k

(Pintelon & Schoukens, *System Identification: A Frequency Domain
Approach*, 2nd ed., ch. 9), in three steps:

1. Levy: the equation error ``B(jω) − Ĝ·A(jω)``, linear in θ, by least
   squares with the weights 1/σ_k.
2. Sanathanan–Koerner: the same, reweighted by the previous ``1/|A(jω)|``
   until θ settles, which removes most of Levy's bias towards high
   frequencies.  The iterate with the lowest V starts step 3.  No pole
   is reflected: a response measured in closed loop may belong to an
   unstable plant, and a reflected start lands in a wrong minimum.
3. Levenberg–Marquardt on V with the analytic Jacobian
   ``∂G/∂b_i = (jω)^i/A``, and ``−G·(jω)^i/A`` for the coefficient of s^i
   in A.

Frequencies are divided by ω_s, the geometric mean of the lowest and
highest non-zero line, and the response by its median magnitude, so the
polynomial columns stay near 1 whether the lines lie at 1 or 1e4 rad/s;
θ and its covariance are mapped back at the end.

The covariance is ``(JᵀJ)⁻¹`` of the normalised residuals.  When the
line variances were themselves estimated from M averages (periods, or
Welch's equivalent segments), the weights are random and the covariance
grows by ``(M − 1)/(M − 3)`` (P&S §10.3, the sample maximum-likelihood
estimator), and the expected normalised cost is ``(M − 1)/(M − 2)``
rather than 1.  With ``weighting="relative"`` or ``"none"`` the scale of
the errors is unknown and the covariance is scaled by the residual
variance, as in ordinary least squares.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from .._lazy import optimize
from .._warn import warn
from ..models import FrequencyResponseData, TransferFunction
from ._estimate import Estimate

__all__ = ["FrfWeighting", "fit_frf"]

FrfWeighting = Literal["auto", "variance", "relative", "none"]
_WEIGHTINGS: tuple[FrfWeighting, ...] = ("auto", "variance", "relative", "none")
# variances from these estimators were estimated from n_averages averages (not known)
_ESTIMATED_VARIANCE = ("periodic", "welch", "welch-indirect")
_SK_MAX_ITER = 50
#: Most solver iterations accepted: scipy counts function calls in a C int.
_MAX_ITER = 1_000_000
_SK_TOL = 1e-10
# warn that the structure is rejected when the cost exceeds its expectation by this many std
_REJECT_SIGMAS = 6.0


def fit_frf(
    frd: FrequencyResponseData,
    n_poles: int,
    n_zeros: int | None = None,
    *,
    delay: float = 0.0,
    weighting: FrfWeighting = "auto",
    max_iter: int = 200,
    tol: float = 1e-10,
) -> Estimate:
    """Fit a continuous transfer function to a frequency response.

    Parameters
    ----------
    frd : FrequencyResponseData
        Measured response, e.g. from :func:`estimate_frf`.  Every line is
        fitted; restrict the band with :meth:`FrequencyResponseData.
        select`.  A response measured with a staircase (ZOH) input is
        that of the sampled system, which departs from G(jω) by the hold
        (half a sample of delay, aliasing near Nyquist): fit it well
        below Nyquist, or measure with a band-limited input.
    n_poles : int
        Number of poles n >= 1.
    n_zeros : int, optional
        Number of zeros m, 0 <= m <= n; default ``max(n − 1, 0)`` (as
        MATLAB's ``tfest``).
    delay : float
        Known input delay τ [s] >= 0, not estimated.  A non-zero delay
        needs :class:`~servoid.models.TransferFunction` to carry one.
    weighting : {"auto", "variance", "relative", "none"}
        Line weights: ``"variance"`` 1/σ²_k from the record's variance
        (maximum likelihood; covariance from the known noise level);
        ``"relative"`` 1/|Ĝ_k|² (a fit of log|G| and phase);
        ``"none"`` equal weights.  ``"auto"``: "variance" when the record
        has a positive one on every line (noise-free data has none), else
        "none".
    max_iter : int
        Limit on the Levenberg–Marquardt evaluations of the criterion.
    tol : float
        Relative tolerance on the cost, the step and the gradient, > 0.

    Returns
    -------
    Estimate
        ``model``: the continuous :class:`~servoid.models.TransferFunction`.
        ``parameters``: ``b_m … b_0, a_1 … a_n`` (descending powers of
        s, as ``num`` and ``den``; the names of :func:`fit_tf`), with
        their covariance.  Before version 0.2 the denominator was named
        by power, ``a_{n−1} … a_0``: ``est["a0"]`` still reads ``a_n``,
        with a ``DeprecationWarning`` (``options["former_names"]``).
        ``noise_variance``: the normalised cost ``V/(F − n_θ/2)`` over F
        lines (about 1 when the model explains the response within its
        variance; see the module notes).  ``n_samples``: 2F real
        residuals; ``residuals``: the normalised ones ``√2·(Re, Im)(G − Ĝ)/σ``
        (unit variance when the weights are the line variances).
        ``model_function`` rebuilds the model at any θ, so
        the covariance carries to poles, gains or a Bode band.

    Raises
    ------
    IdentifiabilityError
        Fewer lines than parameters, or the lines do not determine them.
    ConvergenceError
        The Levenberg–Marquardt search did not converge.

    Warns
    -----
    ServoidWarning
        The fitted model is unstable, the cost is far above what the line
        variances allow (the structure is rejected by the data), or the
        variances rest on fewer than 4 averages.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.models import FrequencyResponseData, TransferFunction
    >>> from servoid.estimate import fit_frf
    >>> g = TransferFunction([2.0e4], [1.0, 60.0, 1.0e4])
    >>> f = np.geomspace(1.0, 100.0, 40)
    >>> frd = FrequencyResponseData(f, g.freqresp(2 * np.pi * f))
    >>> est = fit_frf(frd, n_poles=2, n_zeros=0)
    >>> np.round(est.model.den, 6).tolist(), round(float(est.model.num[-1]), 4)
    ([1.0, 60.0, 10000.0], 20000.0)
    """
    if not isinstance(frd, FrequencyResponseData):
        raise OptionTypeError(f"frd must be a FrequencyResponseData, got {type(frd).__name__}")
    n = as_int("n_poles", n_poles, minimum=1, maximum=30)
    m = max(n - 1, 0) if n_zeros is None else as_int("n_zeros", n_zeros, minimum=0)
    if m > n:
        raise ModelError(f"n_zeros must be <= n_poles = {n} (a proper model), got {m}")
    tau = as_float("delay", delay, nonneg=True, unit="s")
    check_option("weighting", weighting, _WEIGHTINGS)
    iters = as_int("max_iter", max_iter, minimum=1)
    if iters > _MAX_ITER:
        raise DataError(f"max_iter must be <= {_MAX_ITER:,}, got {iters:,}")
    tol_ = as_float("tol", tol, positive=True)
    has_delay_field = "delay" in {f.name for f in fields(TransferFunction)}
    if tau > 0 and not has_delay_field:
        raise OptionError(
            "delay > 0 needs TransferFunction to carry a delay, which this version lacks; "
            "remove the known delay from the response first (multiply it by exp(+j·ω·τ)) and "
            "fit with delay=0"
        )
    chosen: FrfWeighting = weighting
    if weighting == "auto":
        usable = frd.variance is not None and bool(np.all(frd.variance > 0))
        chosen = "variance" if usable else "none"

    omega = frd.omega
    g_meas = frd.response * np.exp(1j * omega * tau) if tau > 0 else frd.response
    sigma = _line_sigma(frd, chosen, g_meas)
    n_lines = omega.size
    n_theta = m + 1 + n
    if 2 * n_lines <= n_theta:
        raise IdentifiabilityError(
            f"{n_theta} parameters (n_poles = {n}, n_zeros = {m}) need more than "
            f"{n_theta / 2:g} lines, the response has {n_lines}; measure more lines or lower "
            "the orders"
        )
    positive = omega[omega > 0]
    if positive.size == 0:
        raise IdentifiabilityError("the response has only the DC line; it cannot fix any pole")
    # The geometric mean by logs: the product of the extreme lines can overflow or underflow.
    w_s = math.exp(0.5 * (math.log(positive.min()) + math.log(positive.max())))
    if n * abs(math.log10(w_s)) > 300:
        raise DataError(
            f"the lines lie around {w_s / (2 * math.pi):.3g} Hz: the coefficients of an order-{n} "
            "model there (powers of ω up to ω^n) over- or underflow double precision; express "
            "the frequencies in another unit (kHz, MHz, mHz) or lower n_poles"
        )
    g_s = float(np.median(np.abs(g_meas)))
    if not g_s > 0:
        raise DataError("the response is zero on most lines; there is nothing to fit")
    problem = _Problem(1j * omega / w_s, g_meas / g_s, sigma / g_s, m, n)

    theta0, sk_iter = problem.start()
    res = optimize.least_squares(
        problem.residuals, theta0, jac=problem.jacobian, method="lm",
        xtol=tol_, ftol=tol_, gtol=tol_, max_nfev=iters, x_scale="jac",
    )
    if res.status <= 0 or not np.all(np.isfinite(res.x)):
        raise ConvergenceError(
            f"fit_frf: the Levenberg–Marquardt search did not converge ({res.message.strip()}, "
            f"{res.nfev} evaluations); raise max_iter, lower the orders, or narrow the band "
            "with frd.select"
        )
    theta_s = np.asarray(res.x, dtype=float)
    jac = problem.jacobian(theta_s)
    resid = problem.residuals(theta_s)
    cost = 0.5 * float(resid @ resid)  # V = Σ|G − Ĝ|²/σ²: residuals carry a factor √2
    dof = n_lines - n_theta / 2.0
    # fit_tf's names: a_k multiplies s^(n−k) (until 0.2 they were by power, a_(n−1) … a_0)
    names = tuple([f"b{i}" for i in range(m, -1, -1)] + [f"a{k}" for k in range(1, n + 1)])
    cov_s = _inverse_normal(jac, names)
    n_avg = frd.n_averages
    estimated = chosen == "variance" and frd.method in _ESTIMATED_VARIANCE
    if chosen == "variance":
        factor, expected = _variance_factors(estimated, n_avg)
        _check_cost(cost, dof, n_lines, n_theta, estimated, n_avg, expected)
    else:
        factor, expected = cost / dof, math.nan
    cov_s = cov_s * factor
    # back to unscaled coefficients: b_i = g_s·ω_s^{n−i}·b'_i, a_i = ω_s^{n−i}·a'_i
    powers = np.concatenate([np.arange(n - m, n + 1), np.arange(1, n + 1)]).astype(float)
    scale = np.power(w_s, powers) * np.concatenate([np.full(m + 1, g_s), np.ones(n)])
    theta = theta_s * scale
    cov = cov_s * np.outer(scale, scale)

    def model_function(th: NDArray[np.float64]) -> TransferFunction:
        th = np.asarray(th, dtype=float)
        den = np.concatenate([[1.0], th[m + 1:]])
        if has_delay_field and tau > 0:
            return TransferFunction(th[: m + 1], den, delay=tau)
        return TransferFunction(th[: m + 1], den)

    model = model_function(theta)
    if model.order and np.max(model.poles().real) >= 0:
        warn(
            f"fit_frf: the fitted model has a pole in the closed right half-plane (largest "
            f"real part {np.max(model.poles().real):.4g} rad/s); check the orders and the "
            "band, or whether the measured system is unstable in this loop",
            ServoidWarning,
        )
    unit = frd.unit
    units = tuple([_power_unit(unit, n - i) for i in range(m, -1, -1)]
                  + [_power_unit("", n - i) for i in range(n - 1, -1, -1)])

    def residual_function() -> NDArray[np.float64]:
        return resid

    return Estimate(
        model=model,
        parameters=theta,
        names=names,
        covariance=cov,
        noise_variance=cost / dof,
        n_samples=2 * n_lines,
        method="frf",
        status="ok",
        options={
            "n_poles": n,
            "n_zeros": m,
            "delay": tau,
            "weighting": chosen,
            "frd_method": frd.method,
            "n_lines": n_lines,
            "band_hz": [float(frd.frequency[0]), float(frd.frequency[-1])],
            "n_averages": n_avg,
            "omega_scale": w_s,
            "gain_scale": g_s,
            "sk_iterations": sk_iter,
            "nfev": int(res.nfev),
            "cost": cost,
            "expected_cost": None if math.isnan(expected) else expected * dof,
            "covariance_factor": factor,
            "message": str(res.message),
            "solver_status": int(res.status),
            "former_names": {"a0": f"a{n}"},  # readable until 0.2; est["a0"] warns
        },
        units=units,
        residual_function=residual_function,
        model_function=model_function,
    )


class _Problem:
    """Scaled lines and the model's residuals and Jacobian on them."""

    def __init__(self, s: NDArray[np.complex128], g: NDArray[np.complex128],
                 sigma: NDArray[np.float64], m: int, n: int) -> None:
        self.g, self.m, self.n = g, m, n
        self.weight = math.sqrt(2.0) / sigma  # Re and Im of each error then have unit variance
        powers = s[:, None] ** np.arange(n + 1)[None, :]
        self.num_cols = powers[:, m::-1]  # s^m … s^0
        self.den_cols = powers[:, n - 1::-1]  # s^{n−1} … s^0
        self.s_n = powers[:, n]

    def split(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.complex128],
                                                          NDArray[np.complex128]]:
        b = self.num_cols @ theta[: self.m + 1]
        a = self.s_n + self.den_cols @ theta[self.m + 1:]
        return b, a

    def residuals(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        b, a = self.split(theta)
        err = self.weight * (b / a - self.g)
        return np.concatenate([err.real, err.imag])

    def jacobian(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        b, a = self.split(theta)
        inv_a = self.weight / a
        d_num = self.num_cols * inv_a[:, None]
        d_den = -self.den_cols * (inv_a * b / a)[:, None]
        jac = np.hstack([d_num, d_den])
        return np.vstack([jac.real, jac.imag])

    def cost(self, theta: NDArray[np.float64]) -> float:
        r = self.residuals(theta)
        return float(r @ r) if np.all(np.isfinite(r)) else math.inf

    def start(self) -> tuple[NDArray[np.float64], int]:
        """Levy, then Sanathanan–Koerner; the iterate with the lowest cost."""
        base = np.hstack([self.num_cols, -self.g[:, None] * self.den_cols])
        rhs = self.g * self.s_n
        w = self.weight / math.sqrt(2.0)
        theta = _weighted_lstsq(base, rhs, w)
        best, best_cost, used = theta, self.cost(theta), 0
        for k in range(1, _SK_MAX_ITER + 1):
            _, a = self.split(theta)
            if not np.all(np.abs(a) > 0):
                break
            new = _weighted_lstsq(base, rhs, w / np.abs(a))
            change = np.max(np.abs(new - theta)) / max(np.max(np.abs(new)), 1e-300)
            theta, used = new, k
            c = self.cost(theta)
            if c < best_cost:
                best, best_cost = theta, c
            if change < _SK_TOL:
                break
        return best, used


def _weighted_lstsq(base: NDArray[np.complex128], rhs: NDArray[np.complex128],
                    w: NDArray[np.float64]) -> NDArray[np.float64]:
    rows = base * w[:, None]
    a = np.vstack([rows.real, rows.imag])
    b = np.concatenate([(rhs * w).real, (rhs * w).imag])
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0  # an all-zero column stays zero; lstsq gives it 0
    sol = np.linalg.lstsq(a / norms, b, rcond=None)[0]
    return np.asarray(sol / norms, dtype=float)


def _line_sigma(frd: FrequencyResponseData, weighting: FrfWeighting,
                g: NDArray[np.complex128]) -> NDArray[np.float64]:
    if weighting == "variance":
        if frd.variance is None:
            raise OptionError("weighting='variance' needs a response with a variance per line; "
                              "use weighting='relative' or 'none'")
        zero = frd.variance <= 0
        if np.any(zero):
            f0 = float(frd.frequency[np.flatnonzero(zero)[0]])
            raise DataError(
                f"{int(zero.sum())} line(s) have zero variance (the first at {f0:g} Hz), which "
                "would weigh them infinitely; add noise-level information or use "
                "weighting='relative'"
            )
        return np.sqrt(frd.variance)
    if weighting == "relative":
        mag = np.abs(g)
        if np.any(mag == 0):
            raise DataError("weighting='relative' needs |G| > 0 on every line; drop the zero "
                            "lines with frd.select or use weighting='none'")
        return mag
    return np.ones(g.size)


def _variance_factors(estimated: bool, n_avg: int) -> tuple[float, float]:
    """Covariance factor and expected cost per degree of freedom."""
    if not estimated:
        return 1.0, 1.0
    if n_avg <= 3:
        warn(
            f"fit_frf: the line variances rest on {n_avg} average(s); with fewer than 4 their "
            "weights are too uncertain for a covariance (it is left uncorrected). Record more "
            "periods or longer data",
            ServoidWarning,
        )
        return 1.0, math.nan if n_avg <= 2 else (n_avg - 1) / (n_avg - 2)
    return (n_avg - 1) / (n_avg - 3), (n_avg - 1) / (n_avg - 2)


def _check_cost(cost: float, dof: float, n_lines: int, n_theta: int, estimated: bool,
                n_avg: int, expected: float) -> None:
    if math.isnan(expected):
        return
    if estimated:
        d2 = 2.0 * (n_avg - 1)
        if d2 <= 4:
            return
        term_var = d2**3 / ((d2 - 2.0) ** 2 * (d2 - 4.0))  # variance of an F(2, d2) term
    else:
        term_var = 1.0  # |e|²/σ² of a circular complex normal error: Exp(1)
    spread = math.sqrt(n_lines * term_var)
    if cost > expected * dof + _REJECT_SIGMAS * spread:
        warn(
            f"fit_frf: the cost V = {cost:.4g} is far above the {expected * dof:.4g} ± "
            f"{spread:.2g} the line variances allow: the model structure is rejected by the "
            "data. Raise n_poles / n_zeros, narrow the band (frd.select), or check for a "
            "delay; the covariance understates the error",
            ServoidWarning,
        )


def _inverse_normal(jac: NDArray[np.float64], names: tuple[str, ...]) -> NDArray[np.float64]:
    # SVD of J rather than inverting JᵀJ: it squares nothing and exposes a rank loss
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    if s.size == 0 or s[-1] <= s[0] * np.finfo(float).eps * max(jac.shape) * 10:
        weak = names[int(np.argmax(np.abs(vt[-1])))] if s.size else "?"
        raise IdentifiabilityError(
            f"the response does not determine the parameters independently (weakest direction "
            f"mostly {weak!r}: a pole-zero pair cancels or an order is too high); lower "
            "n_poles / n_zeros"
        )
    return (vt.T / s**2) @ vt


def _power_unit(base: str, power: int) -> str:
    if power == 0:
        return base
    tail = "s" if power == 1 else f"s^{power}"
    return f"{base}/{tail}" if base else f"1/{tail}"
