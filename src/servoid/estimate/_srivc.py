"""Continuous-time transfer functions by refined instrumental variables.

:func:`fit_tf` estimates

    G(s) = (b_m s^m + … + b_1 s + b_0) / (s^n + a_1 s^{n−1} + … + a_n) · e^{−sτ}

from sampled data by the simplified refined instrumental variable method
for continuous-time models, SRIVC (Young & Jakeman, "Refined instrumental
variable methods of recursive time-series analysis, Part III:
extensions", Int. J. Control 31(4), 1980; Young, *Recursive Estimation and
Time-Series Analysis*, 2nd ed., Springer 2011), in its hybrid form
for sampled data (Garnier, Gilson & Young, "Direct identification of
continuous-time models from sampled data: issues, basic solutions and
relevance", ch. 1 of Garnier & Wang (eds.), *Identification of
Continuous-time Models from Sampled Data*, Springer 2008), and, for data
taken in a loop, its closed-loop variant CLSRIVC (Gilson, Garnier, Young &
Van den Hof, "Instrumental variable methods for closed-loop continuous-time
model identification", ch. 5 of the same book).

**Iteration.**  With the current estimate Â, B̂, every signal is filtered
by 1/Â(p) (p = d/dt): ``x_f^{(i)} = p^i/Â(p)·x``.  The filtered equation

    y_f^{(n)} = φ_fᵀθ + noise,   φ_f = [u_f^{(m)} … u_f, −y_f^{(n−1)} … −y_f]

is solved with the instruments ``φ̂_f = [u_f^{(m)} … u_f, −x̂_f^{(n−1)} … −x̂_f]``,
x̂ = B̂/Â·u the auxiliary model's noise-free output:
θ̂ ← (Σ φ̂_f φ_fᵀ)⁻¹ Σ φ̂_f y_f^{(n)}.  The instruments are exactly
the gradient of the simulated output with respect to θ, so a converged
SRIVC estimate satisfies Σ φ̂_f·(y − x̂) = 0: the stationarity condition of
the output-error criterion, which for white noise is the maximum-
likelihood estimate.

**Sampled data, exactly.**  Everything driven by the input (u_f, x̂ and
x̂_f, which are ``p^i·B̂/Â²·u``) is computed by exact discretisation for the
input's stated course between samples (:mod:`._hybrid`: staircase, straight
lines or a band-limited cubic) and its delay, fractional included.  The
measured output has no known course between samples, so it is split as
``y = x̂ + ε̂``: x̂ is filtered exactly and only the residual ε̂ by a
first-order hold.  Since ``Â(p)/Â(p)`` is the identity for that filter
too, ``y_f^{(n)} − φ_fᵀθ̂ = ε̂`` holds sample by sample when Â is the
current denominator, so the interpolation of y changes the path of the
iteration but not its fixed point: on noise-free data from a model in
the structure, θ is recovered to rounding and the tolerance.

**Closed loop.**  In a loop the input carries the noise back, and
instruments built from u correlate with it: with coloured noise the
open-loop estimate is biased.  With ``instrument="r"`` the instruments
are built from the reference instead, from the noise-free input
û = C/(1 + C·Ĝ)·r when the digital controller C is given (the loop
``u = C·(r − y)``, C discrete at the data's dt), otherwise from a
least-squares FIR estimate of the map r → u of order M (the projection
idea of Forssell & Ljung, "A projection method for closed-loop system
identification", IEEE TAC 45(11), 2000); the regressors stay the measured
u and y.

**Covariance.**  At the fixed point ``θ̂ − θ₀ ≈ B⁻¹ Σ_t φ̂_f(t) ε(t)``, ε
the output error, so the covariance is the instrumental-variable sandwich
``B⁻¹ [Σ_τ r_ε(τ) Σ_t φ̂_f(t) φ̂_f(t−τ)ᵀ] B⁻ᵀ`` (Söderström & Stoica,
*Instrumental Variable Methods for System Identification*, Springer 1983,
§4.3; Young 2011, §7.3), with ``B = Σ φ̂_f φ̂_fᵀ`` in open loop (the
instruments are the output-error gradient, so this is the output-error
covariance) and ``B = M = Σ φ̂_f φ_fᵀ`` in closed loop, where the
instruments are the noise-free part of the regressors only in the limit.
``covariance="white"`` takes ``r_ε(τ) = σ̂² δ(τ)``: ``σ̂²·(Σ φ̂_f φ̂_fᵀ)⁻¹``,
resp. ``σ̂²·M⁻¹(Σφ̂_fφ̂_fᵀ)M⁻ᵀ`` (Young 2011; Garnier, Gilson & Young 2008),
right only for white output noise.  SRIVC has no noise model, so with
coloured noise its estimate stays consistent but that formula is not its
covariance (×4 too small on the coloured test records); ``"robust"``, the
default, estimates r_ε from an AR model of the output error (order by AIC)
— the shared estimate of :mod:`servoid.estimate._covariance`, exactly
the white formula when the residuals look white.

**Scaling.**  Time is scaled internally by ω₀ [rad/s], the geometric mean
of the starting model's pole magnitudes, so that the filters' coefficients
are of order one for a servo at 10 rad/s or at 10⁴ rad/s; the results are
mapped back, b_j·ω₀^{n−j} and a_k·ω₀^k, covariance included.

**Start and safeguard.**  ``init`` or the least-squares state-variable
filter estimate (LSSVF, filter (p + λ)^{−n}) with the λ on a logarithmic
grid whose model simulates the output best (in closed loop: fitted from
the projected input û, the two-stage method).  Each SRIVC step is halved
while it raises a merit — the output-error cost in open loop, the
two-stage cost Σ(y − Ĝû)² by more than half in closed loop — and the
Gauss–Newton direction is tried when the SRIVC one fails; neither changes
the fixed point.  The filters start at rest: records should start with the
plant at rest (or the transient be short).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import (
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..models import TransferFunction
from ._channels import check_magnitude, check_not_constant
from ._channels import output_name as channel_output
from ._covariance import (
    COVARIANCES,
    Covariance,
    CovarianceResult,
    filtered_gram,
    resolve,
    sandwich_covariance,
)
from ._estimate import Estimate
from ._hybrid import HOLDS, Hold, filter_bank
from ._srivc_loop import fir_projection, loop_sensitivity, projection_order

__all__ = ["fit_tf"]

Intersample = Hold
InstrumentSource = Literal["u", "r"]

_INIT_GRID = 8  # λ values tried for the LSSVF start
_HALVINGS = 30  # step halvings before the step is given up


@dataclass(frozen=True)
class _Segment:
    u: NDArray[np.float64]
    y: NDArray[np.float64]
    r: NDArray[np.float64] | None
    u_hat: NDArray[np.float64] | None  # FIR projection of u on r (closed loop)


@dataclass(frozen=True)
class _Problem:
    segments: tuple[_Segment, ...]
    n: int
    m: int
    dt: float
    hold: Hold
    delay: float  # [samples]
    delay_s: float  # [s]
    closed_loop: bool
    controller: TransferFunction | None


@dataclass(frozen=True)
class _Pass:
    """Sums of one SRIVC pass at θ (scaled time)."""

    m_iv: NDArray[np.float64]  # Σ φ̂_f φ_fᵀ
    g_iv: NDArray[np.float64]  # Σ φ̂_f (y_f^{(n)} − φ_fᵀθ)
    s_zz: NDArray[np.float64]  # Σ φ̂_f φ̂_fᵀ
    residuals: tuple[NDArray[np.float64], ...]  # y − x̂ per segment
    instruments: tuple[NDArray[np.float64], ...]  # φ̂_f per segment, rows ζ(t)ᵀ
    merit: float  # Σ(y − x̂)² in open loop, Σ(y − Ĝû)² in closed loop


def fit_tf(
    data: Experiment | ExperimentSet,
    n_poles: int,
    n_zeros: int | None = None,
    *,
    delay: float = 0.0,
    intersample: Intersample = "zoh",
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    instrument: InstrumentSource | None = None,
    controller: TransferFunction | None = None,
    max_iter: int = 50,
    tol: float = 1e-8,
    init: TransferFunction | None = None,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit a continuous transfer function by SRIVC (or CLSRIVC).

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with one input channel of role `input`, one output and,
        for ``instrument="r"``, a reference channel (role ``"r"``).
    n_poles : int
        Number of poles n >= 1.
    n_zeros : int, optional
        Number of zeros m, 0 <= m <= n; default ``max(n − 1, 0)``.
    delay : float
        Known input delay τ [s], >= 0 and shorter than the record; need
        not be a whole number of samples.
    intersample : {"zoh", "foh", "bandlimited"}
        The logged input's course between samples: ``"zoh"`` a staircase
        (a DAC command), ``"foh"`` straight lines, ``"bandlimited"`` a
        smooth signal (cubic interpolation, error O((ω·dt)⁴)).
    input : {"u", "r"}
        Role of the input channel (``"r"`` fits the closed loop r → y as
        an open-loop transfer function).
    output : str, optional
        Output channel name when there are several.
    instrument : {None, "u", "r"}
        Source of the instruments: None or ``"u"`` for open-loop SRIVC,
        ``"r"`` for CLSRIVC on data from a loop ``u = C·(r − y)``.
    controller : TransferFunction, optional
        The loop's digital controller C, discrete at the data's dt
        (``instrument="r"`` only).  Without it the noise-free input is
        projected on r by a least-squares FIR filter.
    max_iter : int
        Most SRIVC iterations, >= 1.
    tol : float
        Convergence: relative change of the (time-scaled) parameters.
    init : TransferFunction, optional
        Continuous starting model with n poles and at most m zeros; by
        default the best LSSVF estimate on a grid of filter bandwidths.
    covariance : {"auto", "white", "robust"}
        ``"white"`` assumes white output noise; ``"robust"`` is the
        sandwich with the output error's own autocovariance, right for
        coloured noise; ``"auto"`` is ``"robust"`` (SRIVC has no noise
        model).  See the module notes.

    Returns
    -------
    Estimate
        ``model`` is the continuous :class:`~servoid.models.TransferFunction`
        with `delay`; ``parameters`` are ``b_m … b_0, a_1 … a_n`` as in the
        module formula (names ``"b2", "b1", "b0", "a1", "a2"`` for n = m = 2);
        ``covariance`` is the SRIVC covariance (module notes), and
        ``options["covariance"]`` says which (``"white"`` or ``"robust"``),
        ``options["covariance_ar_order"]`` the order of the residual AR
        model (None for ``"white"``);
        ``noise_variance`` the output-error variance; ``model_function``
        maps θ to the model.  ``method`` is ``"srivc"`` or ``"clsrivc"``.

    Raises
    ------
    DataError
        Orders out of range, a delay < 0 or not shorter than the record,
        too few samples, missing channels.
    OptionError
        An unknown `intersample`, `input` or `instrument`, or a controller
        without ``instrument="r"``.
    ModelError
        A controller that is not discrete at the data's dt, or an `init`
        of the wrong structure.
    IdentifiabilityError
        A constant input or reference, or singular normal equations.

    Warns
    -----
    ServoidWarning
        The iteration did not converge (``status`` says so, and
        ``options["converged"]`` is False), or the model is unstable.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.data import Experiment
    >>> from servoid.models import TransferFunction
    >>> g = TransferFunction([40.0], [1.0, 4.0, 40.0])
    >>> u = np.sign(np.sin(np.arange(2000) * 0.013))
    >>> exp = Experiment.from_arrays(0.01, u=u, y=g.simulate(u, dt=0.01))
    >>> est = fit_tf(exp, 2, 0)
    >>> [round(float(v), 6) for v in est.parameters]
    [40.0, 4.0, 40.0]
    """
    problem, n_par, units, output_name = _setup(
        data, n_poles, n_zeros, delay, intersample, input, output, instrument, controller
    )
    check_option("covariance", covariance, COVARIANCES)
    cov_kind = resolve(covariance, noise_model=False)
    max_iter = as_int("max_iter", max_iter, minimum=1)
    tol = as_float("tol", tol, positive=True)
    n, m = problem.n, problem.m
    if init is not None:
        theta_phys = _from_init(init, n, m)
        start = {"init": "given"}
    else:
        theta_phys, lam = _lssvf_start(problem)
        start = {"init": "lssvf", "init_filter": lam}
    omega0 = _time_scale(theta_phys, n, problem)
    scale = _scale_vector(n, m, omega0)
    theta = theta_phys / scale
    h = omega0 * problem.dt

    converged = False
    iterations = 0
    current = _srivc_pass(problem, theta, h, omega0)
    last_step = math.inf
    relax, previous = 1.0, None
    stalled = False
    for iterations in range(1, max_iter + 1):
        advanced = _advance(problem, theta, current, h, omega0, relax)
        if advanced is None:
            stalled = True  # no step improves the merit (reported as not converged)
            break
        new_theta, current, last_step = advanced
        step = new_theta - theta
        theta = new_theta
        if last_step <= tol:
            converged = True
            break
        if previous is not None and step @ previous < -0.5 * np.linalg.norm(step) * np.linalg.norm(
                previous):
            relax = max(relax / 2.0, 1.0 / 16.0)  # steps reverse: damp the oscillation
        previous = step
    final = current
    resid = final.residuals
    n_res = sum(e.size for e in resid)
    sse = float(sum(e @ e for e in resid))
    dof = max(n_res - n_par, 1)
    sigma2 = sse / dof
    cov_result = _covariance(final, sigma2, dof, problem.closed_loop, cov_kind)
    params = theta * scale
    cov = cov_result.covariance * np.outer(scale, scale)
    tau = problem.delay_s

    def model_function(th: NDArray[np.float64]) -> TransferFunction:
        return TransferFunction(th[: m + 1], np.concatenate([[1.0], th[m + 1 :]]), delay=tau)

    model = model_function(params)
    status = "ok"
    if not converged:
        why = ("no step reduced the merit" if stalled
               else f"last relative step {last_step:.3g}, tol = {tol:g}")
        status = f"not converged in {iterations} iterations ({why})"
        warn(
            f"fit_tf: SRIVC did not converge in {iterations} iterations ({why}); the estimate "
            "may be poor. Raise max_iter, check the orders and the delay, or start from init=",
            ServoidWarning,
        )
    if n and np.any(model.poles().real >= 0.0):
        warn(
            "fit_tf: the estimated model has a pole with Re >= 0; SRIVC filtered with its "
            "stabilised denominator, so suspect the orders, the delay or an integrating plant",
            ServoidWarning,
        )
    resid_all = np.concatenate(resid)

    def residual_function() -> NDArray[np.float64]:
        return resid_all

    return Estimate(
        model=model,
        parameters=params,
        names=_names(n, m),
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_res,
        method="clsrivc" if problem.closed_loop else "srivc",
        status=status,
        options={
            "n_poles": n,
            "n_zeros": m,
            "delay": tau,
            "intersample": problem.hold,
            "instrument": "r" if problem.closed_loop else "u",
            "controller": _controller_label(problem),
            "projection_order": _projection_order(problem) if problem.closed_loop else None,
            "iterations": iterations,
            "converged": converged,
            "input": input,
            "output": output_name,
            "time_scale": omega0,
            "segments": len(problem.segments),
            "covariance": cov_result.kind,
            "covariance_ar_order": cov_result.ar_order,
            **start,
        },
        units=units,
        residual_function=residual_function,
        model_function=model_function,
    )


# -- set-up --------------------------------------------------------------------------------
def _setup(
    data: Experiment | ExperimentSet,
    n_poles: object,
    n_zeros: object,
    delay: object,
    intersample: object,
    input: object,
    output: str | None,
    instrument: object,
    controller: object,
) -> tuple[_Problem, int, tuple[str, ...], str]:
    check_option("intersample", intersample, HOLDS)
    check_option("input", input, ("u", "r"))
    check_option("instrument", instrument, (None, "u", "r"))
    n = as_int("n_poles", n_poles, minimum=1)
    if n_zeros is None:
        m = n - 1
    else:
        m = as_int("n_zeros", n_zeros, minimum=0)
        if m > n:
            raise DataError(
                f"n_zeros = {m} > n_poles = {n}: a transfer function with more zeros than "
                "poles is improper (it differentiates the input); lower n_zeros or raise n_poles"
            )
    tau = as_float("delay", delay, nonneg=True, unit="s")
    closed = instrument == "r"
    if controller is not None and not closed:
        raise OptionError(
            "controller= builds closed-loop instruments and needs instrument='r'; pass "
            "instrument='r' (CLSRIVC) or drop the controller"
        )
    if closed and input != "u":
        raise OptionError("instrument='r' (closed loop) needs input='u', the plant input")
    segments = as_segments(data)
    dt = segments[0].dt
    ctl = _check_controller(controller, dt) if controller is not None else None
    n_par = n + m + 1
    output_name = channel_output(segments[0], output)
    parts = []
    for seg in segments:
        u = seg.signal(input)  # type: ignore[arg-type]
        if u.shape[1] != 1:
            raise DataError(f"fit_tf takes one {input!r} channel, got {u.shape[1]}")
        r = None
        if closed:
            rr = seg.signal("r")
            if rr.shape[1] != 1:
                raise DataError(f"instrument='r' takes one reference channel, got {rr.shape[1]}")
            r = np.ascontiguousarray(rr[:, 0])
        if tau >= (seg.n_samples - 1) * dt:
            raise DataError(
                f"delay = {tau:g} s is not shorter than the record ({(seg.n_samples - 1) * dt:g} s"
                f"{' in segment ' + repr(seg.name) if seg.name else ''}): no output sample "
                "depends on the input. Check the unit of the delay (seconds) or use a longer record"
            )
        parts.append((np.ascontiguousarray(u[:, 0], dtype=float),
                      np.ascontiguousarray(seg[output_name], dtype=float), r))
    n_total = sum(p[0].size for p in parts)
    need = max(4, 2 * n_par + 2)
    if min(p[0].size for p in parts) < 4 or n_total < need:
        raise DataError(
            f"fit_tf with {n} poles and {m} zeros ({n_par} parameters) needs at least {need} "
            f"samples (and 4 per segment), got {n_total}; use a longer record or lower orders"
        )
    check_magnitude(f"input {input!r}", [p[0] for p in parts])
    check_magnitude(f"output {output_name!r}", [p[1] for p in parts])
    check_not_constant(input, [p[0] for p in parts])  # type: ignore[arg-type]
    if closed:
        check_not_constant("r", [p[2] for p in parts])  # type: ignore[misc]
    problem = _Problem(
        segments=tuple(_Segment(u, y, r, None) for u, y, r in parts),
        n=n, m=m, dt=dt, hold=intersample,  # type: ignore[arg-type]
        delay=tau / dt, delay_s=tau, closed_loop=closed, controller=ctl,
    )
    if closed:  # the projection starts both routes and guards their steps
        problem = _with_projection(problem)
    y_unit = segments[0].unit(output_name)
    u_unit = segments[0].unit(segments[0].names_of(input)[0])  # type: ignore[arg-type]
    return problem, n_par, _units(n, m, y_unit, u_unit), output_name


def _check_controller(controller: object, dt: float) -> TransferFunction:
    if not isinstance(controller, TransferFunction):
        raise OptionTypeError(
            f"controller must be a discrete TransferFunction, got {type(controller).__name__}"
        )
    if controller.dt is None:
        raise ModelError(
            "controller must be the digital controller, discrete at the data's dt = "
            f"{dt:g} s; discretise it with c2d(controller, {dt:g})"
        )
    if not math.isclose(controller.dt, dt, rel_tol=1e-9):
        raise ModelError(
            f"controller.dt = {controller.dt:g} s differs from the data's dt = {dt:g} s; "
            "give the controller at the logging rate (c2d/d2c, or resample the data)"
        )
    return controller


def _from_init(init: object, n: int, m: int) -> NDArray[np.float64]:
    if not isinstance(init, TransferFunction):
        raise OptionTypeError(f"init must be a continuous TransferFunction, "
                              f"got {type(init).__name__}")
    if init.dt is not None or init.order != n or init.num.size > m + 1:
        raise ModelError(
            f"init must be continuous with {n} poles and at most {m} zeros, got dt = "
            f"{init.dt}, {init.order} poles, {init.num.size - 1} zeros"
        )
    num = np.concatenate([np.zeros(m + 1 - init.num.size), init.num])
    return np.concatenate([num, init.den[1:]])


def _names(n: int, m: int) -> tuple[str, ...]:
    return tuple([f"b{j}" for j in range(m, -1, -1)] + [f"a{k}" for k in range(1, n + 1)])


def _units(n: int, m: int, y_unit: str, u_unit: str) -> tuple[str, ...]:
    gain = f"{y_unit or 'y'}/{u_unit or 'u'}" if (y_unit or u_unit) else ""

    def per_s(k: int, base: str) -> str:
        if k == 0:
            return base
        tail = "s" if k == 1 else f"s^{k}"
        return f"{base}/{tail}" if base else f"1/{tail}"

    return tuple([per_s(n - j, gain) for j in range(m, -1, -1)]
                 + [per_s(k, "") for k in range(1, n + 1)])


def _controller_label(problem: _Problem) -> str | None:
    if not problem.closed_loop:
        return None
    return "given" if problem.controller is not None else "projected"


# -- starting values and time scale --------------------------------------------------------
def _lssvf_start(problem: _Problem) -> tuple[NDArray[np.float64], float]:
    """Best LSSVF estimate (by simulation error) over a grid of filter bandwidths [rad/s]."""
    n, m, dt = problem.n, problem.m, problem.dt
    longest = max(s.u.size for s in problem.segments) * dt
    lo, hi = 8.0 * math.pi / longest, 0.3 * math.pi / dt
    grid = np.geomspace(lo, hi, _INIT_GRID) if hi > lo else np.array([hi])
    best: tuple[float, NDArray[np.float64], float] | None = None
    den = np.poly(np.full(n, -1.0))
    num_u = _power_rows(m, n)
    num_y = np.eye(n + 1)
    for lam in grid:
        h = lam * dt
        rows, target = [], []
        for seg in problem.segments:
            uf = filter_bank(den, num_u, _start_input(problem, seg), h, problem.hold,
                             problem.delay)
            yf = filter_bank(den, num_y, seg.y, h, "foh")
            rows.append(np.hstack([uf, -yf[:, 1:]]))
            target.append(yf[:, 0])
        phi, tgt = np.vstack(rows), np.concatenate(target)
        norms = np.linalg.norm(phi, axis=0)
        if not np.all(norms > 0):
            continue
        sol, *_ = np.linalg.lstsq(phi / norms, tgt, rcond=None)
        theta = sol / norms * _scale_vector(n, m, lam)
        if not np.all(np.isfinite(theta)):
            continue
        a = _stable(np.concatenate([[1.0], theta[m + 1 :]]))
        theta = np.concatenate([theta[: m + 1], a[1:]])
        cost = _simulation_cost(problem, theta, lam)
        if np.isfinite(cost) and (best is None or cost < best[0]):
            best = (cost, theta, float(lam))
    if best is None:
        raise IdentifiabilityError(
            "fit_tf: no state-variable-filter start could be computed (singular regression); "
            "check that the input excites the output, or pass init="
        )
    return best[1], best[2]


def _simulation_cost(problem: _Problem, theta_phys: NDArray[np.float64], omega0: float) -> float:
    n, m = problem.n, problem.m
    th = theta_phys / _scale_vector(n, m, omega0)
    a = np.concatenate([[1.0], th[m + 1 :]])
    b = np.concatenate([np.zeros(n - m), th[: m + 1]])
    cost = 0.0
    with np.errstate(all="ignore"):
        for seg in problem.segments:
            x = filter_bank(a, b[None, :], _start_input(problem, seg), omega0 * problem.dt,
                            problem.hold, problem.delay)[:, 0]
            e = seg.y - x
            cost += float(e @ e)
    return cost


def _start_input(problem: _Problem, seg: _Segment) -> NDArray[np.float64]:
    """The input of the starting fit: u, or in closed loop its projection on r.

    In a loop, y = G·û + (G·ũ + v) with ũ the part of u the noise drives, which
    is uncorrelated with r: fitting y on û (the two-stage method of Van den
    Hof & Schrama, Automatica 29(6), 1993) starts from a consistent model
    where a fit on u would start from a biased one.
    """
    if problem.closed_loop:
        assert seg.u_hat is not None
        return seg.u_hat
    return seg.u


def _time_scale(theta_phys: NDArray[np.float64], n: int, problem: _Problem) -> float:
    """ω₀ [rad/s]: geometric mean of the pole magnitudes, within the data's band."""
    dt = problem.dt
    longest = max(s.u.size for s in problem.segments) * dt
    lo, hi = 2.0 * math.pi / longest, math.pi / dt
    mags = np.abs(np.roots(np.concatenate([[1.0], theta_phys[problem.m + 1 :]])))
    mags = mags[mags > 1e-12 * hi]
    w = float(np.exp(np.mean(np.log(mags)))) if mags.size else math.sqrt(lo * hi)
    return min(max(w, lo), hi)


def _scale_vector(n: int, m: int, omega0: float) -> NDArray[np.float64]:
    """θ_physical = θ_scaled · this: b_j·ω₀^{n−j}, a_k·ω₀^k."""
    return np.concatenate([
        omega0 ** (n - np.arange(m, -1, -1, dtype=float)),
        omega0 ** np.arange(1, n + 1, dtype=float),
    ])


def _stable(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Reflect roots with Re > 0 into the left half-plane (the prefilter must be stable)."""
    if a.size < 2:
        return a
    roots = np.roots(a)
    if np.all(roots.real <= 0.0):
        return a
    roots = np.where(roots.real > 0.0, -roots.real + 1j * roots.imag, roots)
    return np.real(np.poly(roots))


def _power_rows(k_max: int, q: int, poly: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Rows p^k·poly(p), k = k_max … 0, as descending coefficients of length q + 1."""
    base = np.ones(1) if poly is None else poly
    rows = np.zeros((k_max + 1, q + 1))
    for i, k in enumerate(range(k_max, -1, -1)):
        c = np.concatenate([base, np.zeros(k)])
        rows[i, q + 1 - c.size :] = c
    return rows


# -- the iteration ---------------------------------------------------------------------------
def _srivc_pass(problem: _Problem, theta: NDArray[np.float64], h: float,
                omega0: float) -> _Pass:
    n, m = problem.n, problem.m
    b = theta[: m + 1]
    a_f = _stable(np.concatenate([[1.0], theta[m + 1 :]]))
    den2 = np.polymul(a_f, a_f)
    q = 2 * n
    # u_f^{(k)} = p^k·Â/Â², k = m..0;  x̂_f^{(i)} = p^i·B̂/Â², i = n..0;  x̂ = B̂·Â/Â²
    rows = np.vstack([_power_rows(m, q, a_f), _power_rows(n, q, b),
                      _power_rows(0, q, np.polymul(a_f, b))])
    n_par = n + m + 1
    m_iv = np.zeros((n_par, n_par))
    g_iv = np.zeros(n_par)
    s_zz = np.zeros((n_par, n_par))
    residuals, instruments = [], []
    merit = 0.0
    eye = np.eye(n + 1)
    ctl_model = _instrument_model(problem, theta, a_f, omega0)
    for seg in problem.segments:
        out = filter_bank(den2, rows, seg.u, h, problem.hold, problem.delay)
        uf, xf, xhat = out[:, : m + 1], out[:, m + 1 : m + 2 + n], out[:, -1]
        eps = seg.y - xhat
        yf = xf + filter_bank(a_f, eye, eps, h, "foh")
        phi = np.hstack([uf, -yf[:, 1:]])
        resid = yf[:, 0] - phi @ theta
        if problem.closed_loop:
            source = _noise_free_input(problem, seg, ctl_model)
            z = filter_bank(den2, rows, source, h, problem.hold, problem.delay)
            zeta = np.hstack([z[:, : m + 1], -z[:, m + 2 : m + 2 + n]])
            assert seg.u_hat is not None
            two_stage = seg.y - (z[:, -1] if source is seg.u_hat else filter_bank(
                den2, rows[-1:], seg.u_hat, h, problem.hold, problem.delay)[:, 0])
            merit += float(two_stage @ two_stage)
        else:
            zeta = np.hstack([uf, -xf[:, 1:]])
            merit += float(eps @ eps)
        m_iv += zeta.T @ phi
        g_iv += zeta.T @ resid
        s_zz += zeta.T @ zeta
        residuals.append(eps)
        instruments.append(zeta)
    return _Pass(m_iv, g_iv, s_zz, tuple(residuals), tuple(instruments), merit)


def _advance(
    problem: _Problem, theta: NDArray[np.float64], current: _Pass, h: float, omega0: float,
    relax: float,
) -> tuple[NDArray[np.float64], _Pass, float] | None:
    """One safeguarded step: the SRIVC step, halved while it worsens the merit.

    The merit is the output-error cost in open loop (the SRIVC fixed point is
    its stationary point, and near it the step is a Gauss–Newton step) and the
    two-stage cost Σ(y − Ĝû)² in closed loop, where only a gross increase
    (50 %) is refused: the CLSRIVC fixed point is not that cost's minimum.  If
    the SRIVC direction fails, the Gauss–Newton direction (Σφ̂φ̂ᵀ)⁻¹Σφ̂ε is tried,
    which has the same fixed points.  `relax` (<= 1) shortens every step once
    the iteration oscillates.  Returns the new θ, its pass and the relative
    size of the undamped step (zero exactly at a fixed point).
    """
    slack = 1.5 if problem.closed_loop else 1.0 + 1e-9
    limit = current.merit * slack
    for matrix in (current.m_iv, current.s_zz):
        delta = _solve(matrix, current.g_iv, current.s_zz)
        size = float(np.linalg.norm(delta) / max(np.linalg.norm(theta), 1e-300))
        delta = relax * delta
        for halving in range(_HALVINGS):
            candidate = theta + delta
            if np.all(np.isfinite(candidate)):
                with np.errstate(all="ignore"):
                    trial = _srivc_pass(problem, candidate, h, omega0)
                if math.isfinite(trial.merit) and trial.merit <= limit:
                    return candidate, trial, size
            if size * relax * 2.0**-halving < 1e-15:
                break  # the step is at rounding level: the merit cannot decide any more
            delta = delta / 2.0
    return None


def _solve(m_iv: NDArray[np.float64], g: NDArray[np.float64],
           s_zz: NDArray[np.float64]) -> NDArray[np.float64]:
    d = np.sqrt(np.diag(s_zz))
    if not np.all(d > 0):
        raise IdentifiabilityError(
            "fit_tf: an instrument is identically zero (the input does not reach the output "
            "through the model); check the input, the delay and the orders"
        )
    scaled = m_iv / np.outer(d, d)
    if np.linalg.cond(scaled) > 1e12:
        raise IdentifiabilityError(
            "fit_tf: the instrumental-variable equations are singular (cond > 1e12): the orders "
            "are too high for the data (a pole cancels a zero) or the input excites too few "
            "frequencies. Lower n_poles/n_zeros or use a richer input"
        )
    return np.linalg.solve(scaled, g / d) / d


def _covariance(final: _Pass, sigma2: float, dof: int, closed_loop: bool,
                kind: str) -> CovarianceResult:
    """The SRIVC sandwich covariance in scaled time.

    ``B⁻¹·Σ_τ r̂_ε(τ)Σ_t φ̂_f(t)φ̂_f(t−τ)ᵀ·B⁻ᵀ`` (module notes): B is
    Σφ̂_fφ̂_fᵀ in open loop (φ̂_f is the output-error gradient) and M in
    closed loop; ε the output error y − x̂.
    """

    def gram(ar: NDArray[np.float64]) -> NDArray[np.float64]:
        return final.s_zz if ar.size == 1 else filtered_gram(final.instruments, ar)

    return sandwich_covariance(kind, final.m_iv if closed_loop else final.s_zz, sigma2, dof,
                               lambda: final.residuals, gram, gram_bread=not closed_loop)


# -- closed-loop instruments ---------------------------------------------------------------
def _instrument_model(problem: _Problem, theta: NDArray[np.float64], a_f: NDArray[np.float64],
                      omega0: float) -> TransferFunction | None:
    """The noise-free loop r → u with the current plant, if the controller is known."""
    if problem.controller is None:
        return None
    return loop_sensitivity(problem.controller, a_f, theta[: problem.m + 1],
                            omega0 * problem.dt, problem.delay)


def _noise_free_input(problem: _Problem, seg: _Segment,
                      sensitivity: TransferFunction | None) -> NDArray[np.float64]:
    if sensitivity is not None:
        assert seg.r is not None
        return np.asarray(sensitivity.simulate(seg.r), dtype=float)
    assert seg.u_hat is not None
    return seg.u_hat


def _projection_order(problem: _Problem) -> int:
    return projection_order(min(s.u.size for s in problem.segments))


def _with_projection(problem: _Problem) -> _Problem:
    """Add to each segment the LS FIR projection û of its input u on its reference r."""
    pairs = [(s.r, s.u) for s in problem.segments]
    projected = fir_projection(pairs, _projection_order(problem))  # type: ignore[arg-type]
    segments = tuple(_Segment(s.u, s.y, s.r, u_hat)
                     for s, u_hat in zip(problem.segments, projected, strict=True))
    return _Problem(segments, problem.n, problem.m, problem.dt, problem.hold, problem.delay,
                    problem.delay_s, problem.closed_loop, problem.controller)
