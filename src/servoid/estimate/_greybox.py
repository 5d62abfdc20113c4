"""Grey-box output-error fit of a nonlinear ODE model ẋ = f(t, x, u, θ).

The user states the physics: a right-hand side ``rhs(t, x, u, theta)``, an
initial state, an output map ``output(x, u, theta)`` and a parameter list
with bounds and a fixed/free flag. The criterion is

    V(θ) = Σ_j Σ_t ( w_j · (y_j(t) − ŷ_j(t, θ)) )²

over the measured output channels j, with w_j = 1/σ_j when the channel
noise levels are given. It follows :func:`~servoid.estimate.fit_tf_greybox`:
bounded trust-region reflective least squares (:func:`scipy.optimize.
least_squares`) in transformed coordinates (``"log"``: θ > 0, relative
steps), a finite, huge residual for a trial point whose simulation diverges
(so the step is rejected instead of crashing the solver), several starts
on request, and a covariance from the solver's Jacobian J at the optimum
(free parameters only): σ̂²(JᵀJ)⁻¹ with σ̂² = V/(N·p − n_free)
(``"white"``), the sandwich with one residual AR model per channel
(``"robust"``, the default) or the spread of refits on resampled
residuals (``"bootstrap"``) — see :mod:`servoid.estimate._covariance`.
With w_j = 1/σ_j the expected σ̂² is 1, so its value checks the stated
noise levels.  The identifiability checks of
:mod:`servoid.estimate._diagnostics` run on every fit.

Simulation: fixed-step RK4 on the data's time grid with ``substeps`` steps
per sample, the input held (``"zoh"``) or interpolated linearly
(``"foh"``) between samples; or :func:`scipy.integrate.solve_ivp`; or a
user ``simulate(theta) -> (N, p)`` callable (a compiled simulator).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_generator, as_int, as_str, type_error
from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from .._lazy import integrate, optimize
from .._warn import warn
from ..data import Experiment
from ..integrate import keep, rk4_step
from ._covariance import (
    GREYBOX_COVARIANCES,
    CovarianceResult,
    GreyboxCovariance,
    bootstrap_covariance,
    least_squares_covariance,
    resolve,
)
from ._diagnostics import (
    MAX_STARTS,
    assess,
    draw_starts,
    summarise_starts,
    weakest_parameters,
)
from ._estimate import Estimate
from ._tf_greybox import _bootstrap_options, _bootstrap_result

__all__ = ["GreyboxModel", "GreyboxParameter", "fit_greybox"]

Rhs = Callable[[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]], ArrayLike]
OutputMap = Callable[[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]], ArrayLike]
Simulator = Callable[[NDArray[np.float64]], ArrayLike]
Transform = Literal["none", "log"]
Integrator = Literal["rk4", "solve_ivp"]
Hold = Literal["zoh", "foh"]
Solver = Literal["trf", "dogbox", "lm"]

#: residual for a diverged trial simulation: finite, so the solver rejects the step
_PENALTY = 1e50
#: Costs within this multiple of Σ(w·y)² are rounding: two starts there are at one minimum.
_COST_FLOOR = 1e-24


@dataclass(frozen=True)
class GreyboxParameter:
    """One physical parameter of a grey-box model.

    Attributes
    ----------
    name : str
        Parameter name.
    value : float
        Start value (or the value used when ``fixed``).
    lower, upper : float
        Bounds (±inf for none); the start must lie inside.
    unit : str
        Unit, e.g. "kg".
    fixed : bool
        Keep the value; do not estimate.
    transform : {"none", "log"}
        Optimise θ or log θ (θ > 0, relative steps).
    """

    name: str
    value: float
    lower: float = -np.inf
    upper: float = np.inf
    unit: str = ""
    fixed: bool = False
    transform: Transform = "none"

    def __post_init__(self) -> None:
        as_str("name", self.name)
        where = f"parameter {self.name!r}:"
        for field_name in ("value", "lower", "upper"):
            object.__setattr__(self, field_name, as_float(
                field_name, getattr(self, field_name), finite=False, where=where))
        as_str("unit", self.unit, empty=True, where=where)
        if not isinstance(self.fixed, (bool, np.bool_)):
            raise type_error("fixed", self.fixed, "true or false", where=where)


@dataclass(frozen=True, eq=False)
class GreyboxModel:
    """A grey-box ODE model with all its parameter values.

    Attributes
    ----------
    names : tuple of str
        All parameter names, free and fixed, in the order ``rhs`` sees them.
    theta : ndarray
        All parameter values.
    free : tuple of bool
        Which parameters were estimated.
    simulate_theta : callable
        ``simulate_theta(theta) -> (N, p)`` on the estimation record.
    """

    names: tuple[str, ...]
    theta: NDArray[np.float64]
    free: tuple[bool, ...]
    simulate_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]]

    def simulate(self) -> NDArray[np.float64]:
        """Outputs at the fitted θ on the estimation record, (N, p)."""
        return self.simulate_theta(self.theta)

    def __getitem__(self, name: str) -> float:
        return float(self.theta[self.names.index(name)])


def fit_greybox(
    data: Experiment | tuple[ArrayLike, ArrayLike, ArrayLike],
    rhs: Rhs | None,
    x0: ArrayLike | Callable[[NDArray[np.float64]], ArrayLike] | None,
    parameters: Sequence[GreyboxParameter | tuple[Any, ...]],
    *,
    output: OutputMap | Sequence[int] | None = None,
    simulate: Simulator | None = None,
    outputs: Sequence[str] | None = None,
    noise_std: ArrayLike | None = None,
    weights: ArrayLike | None = None,
    integrator: Integrator = "rk4",
    substeps: int = 1,
    hold: Hold = "zoh",
    ivp_options: Mapping[str, Any] | None = None,
    start: int = 0,
    method: Solver = "trf",
    max_nfev: int | None = None,
    tol: float = 1e-10,
    diff_step: float | None = None,
    covariance: GreyboxCovariance = "auto",
    multistart: int = 0,
    n_bootstrap: int = 200,
    rng: np.random.Generator | int | None = None,
) -> Estimate:
    """Fit physical parameters of an ODE model by output error.

    Parameters
    ----------
    data : Experiment or (t, u, y)
        The record: an Experiment (inputs = its "u" channels, none allowed;
        outputs = ``outputs`` or its "y" channels), or arrays t (N,) [s],
        u (N,) / (N, m) and y (N,) / (N, p).
    rhs : callable or None
        ``rhs(t, x, u, theta) -> dx/dt`` with x (nx,), u (m,) and theta all
        parameters in list order. None when ``simulate`` is given.
    x0 : array_like, callable or None
        Initial state (nx,), or ``x0(theta)`` to let it depend on the
        parameters (e.g. estimate an initial condition as a parameter).
    parameters : sequence of GreyboxParameter or tuples
        Tuples read ``(name, value, lower, upper, unit, fixed)``, trailing
        fields optional.
    output : callable or sequence of int, optional
        ``output(x, u, theta) -> y`` vectorised over samples (x (N, nx),
        u (N, m), returns (N, p)), or the indices of the measured states.
        Default: every state is measured.
    simulate : callable, optional
        ``simulate(theta) -> (N, p)`` outputs on the record's grid, replacing
        rhs/x0/output (for a compiled simulator).
    outputs : sequence of str, optional
        Experiment channels to fit (any role), default its "y" channels.
    noise_std : array_like, optional
        Noise std per output channel; sets the weights to 1/σ_j.
    weights : array_like, optional
        Weight per output channel (exclusive with ``noise_std``). Default 1
        for one channel; with several, 1/std(y_j) so that channels in
        different units count alike — pass noise levels when known.
    integrator : {"rk4", "solve_ivp"}
        Fixed-step RK4 on the sample grid, or scipy's adaptive solver.
    substeps : int
        RK4 steps per sample period (≥ 1).
    hold : {"zoh", "foh"}
        Input between samples: held, or linear to the next sample.
    ivp_options : mapping, optional
        Keywords for solve_ivp (default method "RK45", rtol 1e-8, atol 1e-10).
    start : int
        First sample in the criterion (earlier samples let transients of a
        wrong x0 die out).
    method : {"trf", "dogbox", "lm"}
        least_squares method; "lm" refuses finite bounds.
    max_nfev : int, optional
        Limit on simulations (default 100·(n_free + 1)).
    tol : float
        Relative tolerance on cost, step and gradient.
    diff_step : float, optional
        Relative finite-difference step of the Jacobian. Default √ε for
        RK4 and a compiled simulator (smooth in θ); √rtol for solve_ivp,
        whose step-size control makes the output jitter at the rtol level
        as θ moves — a √ε step would differentiate that jitter.
    covariance : {"auto", "white", "robust", "bootstrap"}
        ``"white"`` σ̂²(JᵀJ)⁻¹; ``"robust"`` the sandwich with one
        residual AR model per output channel (coloured noise, and channel
        noise levels other than the weights say); ``"bootstrap"`` the
        spread of `n_bootstrap` refits on sieve-resampled residuals (drawn
        at the same instants in every channel); ``"auto"`` is ``"robust"``.
        See :mod:`servoid.estimate._covariance`.
    multistart : int
        Extra random starts, >= 0 (uniform between finite bounds, log-
        uniform for log parameters; else within a factor 3 or ±50 % of the
        start); the lowest cost wins.
    n_bootstrap : int
        Refits for ``covariance="bootstrap"``, >= 2.
    rng : numpy.random.Generator or int, optional
        Source of the random starts and resamples.

    Returns
    -------
    Estimate
        Free parameters with the chosen covariance; ``model`` is a
        :class:`GreyboxModel` with all values; ``options`` hold the fixed
        values, weights, per-channel residual RMS, the solver report,
        ``covariance`` (``"white"``, ``"robust"`` or ``"bootstrap"``),
        ``covariance_ar_order`` (largest residual AR order; per channel in
        ``covariance_ar_orders``), ``bootstrap`` and ``multistart`` when
        used, and ``identifiability``
        (:meth:`~servoid.estimate.Identifiability.to_dict`).

    Raises
    ------
    DataError
        Start outside the bounds (naming the parameter), bad shapes or
        settings, or no free parameter.
    ConvergenceError
        The simulation diverges at the start or at the optimum, or the
        solver stops without meeting its tolerances.
    IdentifiabilityError
        The Jacobian at the optimum is rank deficient (to 1e-6 of its
        column-normalised singular values); the message names the
        parameters.

    Warns
    -----
    ServoidWarning
        A parameter ends on one of its bounds; an identifiability check
        fails (:func:`~servoid.estimate.check_identifiability`).
    """
    check_option("integrator", integrator, ("rk4", "solve_ivp"))
    check_option("covariance", covariance, GREYBOX_COVARIANCES)
    multistart = as_int("multistart", multistart, minimum=0)
    if multistart > MAX_STARTS:  # each start is a full fit
        raise DataError(f"multistart must be <= {MAX_STARTS} extra starts, got {multistart}")
    n_bootstrap = as_int("n_bootstrap", n_bootstrap, minimum=2)
    kind = resolve(covariance, noise_model=False)
    generator = as_generator(rng) if multistart or kind == "bootstrap" else None
    check_option("hold", hold, ("zoh", "foh"))
    check_option("method", method, ("trf", "dogbox", "lm"))
    if isinstance(parameters, (str, bytes, GreyboxParameter)) or not isinstance(
            parameters, Sequence):
        raise type_error("parameters", parameters,
                         "a list of GreyboxParameter or (name, value, ...) tuples")
    if rhs is not None and not callable(rhs):
        raise type_error("rhs", rhs, "a function rhs(t, x, u, theta) or None")
    params = [_as_parameter(p) for p in parameters]
    names = tuple(p.name for p in params)
    if len(set(names)) != len(names):
        raise DataError(f"parameter names must be unique, got {names}")
    theta_all = np.array([p.value for p in params], dtype=float)
    for p in params:
        _check_parameter(p)
    free = np.array([not p.fixed for p in params])
    if not free.any():
        raise DataError("every parameter is fixed: nothing to estimate")
    fidx = np.flatnonzero(free)
    is_log = np.array([params[k].transform == "log" for k in fidx])
    lo = np.array([params[k].lower for k in fidx])
    hi = np.array([params[k].upper for k in fidx])
    if method == "lm" and (np.isfinite(lo).any() or np.isfinite(hi).any()):
        raise DataError("method='lm' does not take bounds; use 'trf' or drop the bounds")

    t, u, y, out_names = _record(data, outputs)
    n_samples, n_out = y.shape
    if not isinstance(start, (int, np.integer)) or not 0 <= start < n_samples - 1:
        raise DataError(f"start must be an integer in [0, {n_samples - 2}], got {start}")
    w = _weights(noise_std, weights, y[start:], n_out)
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise DataError(f"substeps must be an integer >= 1, got {substeps}")

    if simulate is not None:
        if rhs is not None:
            raise DataError("give either rhs (with x0) or simulate, not both")
        sim_fn = simulate
    else:
        if rhs is None or x0 is None:
            raise DataError("rhs and x0 are needed unless simulate is given")
        sim_fn = _make_simulator(rhs, x0, output, t, u, integrator, substeps, hold, ivp_options)

    def simulate_all(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            out = np.asarray(sim_fn(theta), dtype=float)
        if out.ndim == 1:
            out = out[:, None]
        if out.shape != (n_samples, n_out):
            raise DataError(
                f"the model gives outputs of shape {out.shape}; the data have {(n_samples, n_out)}"
            )
        return out

    def to_theta(z: NDArray[np.float64]) -> NDArray[np.float64]:
        th = theta_all.copy()
        th[fidx] = np.where(is_log, np.exp(np.where(is_log, z, 0.0)), z)
        return th

    def raw_residuals(theta: NDArray[np.float64],
                      y_data: NDArray[np.float64] = y) -> NDArray[np.float64]:
        r = ((y_data - simulate_all(theta))[start:] * w).ravel(order="F")
        r[~np.isfinite(r)] = np.nan
        return r

    def residuals_for(y_data: NDArray[np.float64]) -> Callable[[NDArray[np.float64]],
                                                               NDArray[np.float64]]:
        def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
            r = raw_residuals(to_theta(z), y_data)
            r[np.isnan(r)] = _PENALTY
            return r

        return residuals

    z0 = np.where(is_log, np.log(np.where(is_log, theta_all[fidx], 1.0)), theta_all[fidx])
    zlo, zhi = lo.copy(), hi.copy()
    with np.errstate(divide="ignore"):  # log 0 = −inf: no lower bound on log θ
        zlo[is_log] = np.log(np.maximum(lo[is_log], 0.0))
        zhi[is_log] = np.log(hi[is_log])
    r0 = residuals_for(y)(z0)
    if np.any(r0 == _PENALTY):
        raise ConvergenceError(
            "the simulation diverges (non-finite output) at the start values "
            f"{dict(zip(names, theta_all.tolist(), strict=True))}; start from a stable model"
        )
    n_free = int(fidx.size)
    free_names = tuple(names[k] for k in fidx)
    n_res = r0.size
    if n_res <= n_free:
        raise DataError(f"{n_free} free parameters need more than {n_free} residuals, got {n_res}")
    if diff_step is None and integrator == "solve_ivp" and simulate is None:
        rtol = float(dict(ivp_options or {}).get("rtol", 1e-8))
        diff_step = max(float(np.sqrt(np.finfo(float).eps)), float(np.sqrt(rtol)))

    def solve(z_start: NDArray[np.float64],
              y_data: NDArray[np.float64] = y) -> optimize.OptimizeResult:
        inside = np.clip(z_start, np.nextafter(zlo, np.inf), np.nextafter(zhi, -np.inf))
        return optimize.least_squares(
            residuals_for(y_data),
            inside,
            method=method,
            bounds=(zlo, zhi) if method != "lm" else (-np.inf, np.inf),
            x_scale="jac",
            diff_step=diff_step,
            xtol=tol,
            ftol=tol,
            gtol=tol,
            max_nfev=max_nfev if max_nfev is not None else 100 * (n_free + 1),
        )

    starts = [z0]
    if multistart:
        assert generator is not None
        starts += draw_starts(z0, zlo, zhi, is_log, multistart, generator)
    results: list[optimize.OptimizeResult | None] = []
    first_failure: ConvergenceError | None = None
    for k, z_start in enumerate(starts):
        res = solve(z_start)
        failure = _failure(res, to_theta, names)
        if failure is not None and not multistart:
            raise failure
        results.append(None if failure is not None else res)
        if k == 0:
            first_failure = failure
    if all(q is None for q in results):
        raise ConvergenceError(f"greybox: every one of the {len(starts)} starts failed; the "
                               f"first: {first_failure}")
    costs = [2.0 * q.cost if q is not None else np.inf for q in results]
    res = results[int(np.argmin(costs))]
    assert res is not None
    theta = to_theta(res.x)
    r = np.asarray(res.fun)
    jac = np.asarray(res.jac)
    dof = n_res - n_free
    sigma2 = float(r @ r) / dof
    n_s = n_res // n_out  # channel blocks: residuals are raveled channel by channel
    jac_groups = [[jac[j * n_s:(j + 1) * n_s]] for j in range(n_out)]
    err_groups = [[r[j * n_s:(j + 1) * n_s]] for j in range(n_out)]
    cov_result = least_squares_covariance("white" if kind == "bootstrap" else kind,
                                          jac_groups, err_groups, dof)
    if cov_result.singular:
        weak = weakest_parameters(jac, free_names)
        raise IdentifiabilityError(
            f"greybox: the outputs do not depend on the parameters independently (Jacobian "
            f"rank deficient, weakest direction mostly {', '.join(map(repr, weak))}); fix or "
            "remove a parameter"
        )
    d = np.where(is_log, theta[fidx], 1.0)  # dθ/dz
    cov = cov_result.covariance * np.outer(d, d)
    extra: dict[str, Any] = {}
    if kind == "bootstrap":
        assert generator is not None
        fitted = simulate_all(theta)
        z_hat = res.x

        def refit(resampled: list[list[NDArray[np.float64]]]) -> NDArray[np.float64] | None:
            y_star = fitted.copy()
            for j, (e,) in enumerate(resampled):
                y_star[start:, j] += e / w[j]
            out = solve(z_hat, y_star)
            if out.status <= 0 or np.any(np.asarray(out.fun) == _PENALTY):
                return None
            return to_theta(out.x)[fidx]

        boot = bootstrap_covariance(err_groups, dof, refit, n_bootstrap, generator)
        cov = _bootstrap_result(boot, n_bootstrap, "greybox")
        cov_result = CovarianceResult(cov, False, "bootstrap", max(boot.ar_orders),
                                      boot.ar_orders)
        extra["bootstrap"] = _bootstrap_options(boot, n_bootstrap, free_names)
    _warn_on_bounds(theta[fidx], lo, hi, list(free_names))
    summary = None
    if multistart:
        summary = summarise_starts(
            costs, [None if q is None else to_theta(q.x)[fidx] for q in results],
            _COST_FLOOR * float(np.sum((y[start:] * w) ** 2)))
        extra["multistart"] = summary.to_dict()

    def free_residuals(theta_free: NDArray[np.float64]) -> NDArray[np.float64]:
        th = theta.copy()
        th[fidx] = theta_free
        return raw_residuals(th)

    ident = assess(free_residuals, theta[fidx], r, jac / d, cov, free_names,
                   [[n_s]] * n_out, summary, covariance_kind=kind)
    per_channel = r.reshape(n_out, -1)
    channel_rms = (np.sqrt(np.mean(per_channel**2, axis=1)) / w).tolist()
    model = GreyboxModel(names, theta, tuple(bool(f) for f in free), simulate_all)
    return Estimate(
        model=model,
        parameters=theta[fidx],
        names=tuple(names[k] for k in fidx),
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_res,
        method="greybox",
        status="ok",
        options={
            "outputs": list(out_names),
            "fixed": {names[k]: float(theta[k]) for k in np.flatnonzero(~free)},
            "theta0": dict(zip(names, theta_all.tolist(), strict=True)),
            "weights": w.tolist(),
            "channel_rms": dict(zip(out_names, channel_rms, strict=True)),
            "integrator": "simulate" if simulate is not None else integrator,
            "substeps": int(substeps),
            "hold": hold,
            "start": int(start),
            "solver": method,
            "diff_step": diff_step,
            "nfev": int(res.nfev),
            "cost": float(res.cost),
            "message": str(res.message),
            "solver_status": int(res.status),
            "covariance": cov_result.kind,
            "covariance_ar_order": cov_result.ar_order,
            "covariance_ar_orders": None if cov_result.kind == "white" else
            dict(zip(out_names, cov_result.ar_orders, strict=True)),
            **extra,
            "identifiability": ident.to_dict(),
        },
        units=tuple(params[k].unit for k in fidx),
        residual_function=lambda: r.copy(),
    )


def _failure(
    res: optimize.OptimizeResult,
    to_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    names: tuple[str, ...],
) -> ConvergenceError | None:
    """The error for a search that failed, or None."""
    theta = to_theta(res.x)
    r = np.asarray(res.fun)
    jac = np.asarray(res.jac)
    # a penalised residual inside the finite-difference Jacobian means a perturbation of the
    # final point diverged: the optimum sits on the edge of the region where the model runs
    if (
        np.any(r == _PENALTY)
        or not np.all(np.isfinite(jac))
        or np.any(np.abs(jac) >= _PENALTY * 1e-10)
    ):
        return ConvergenceError(
            f"greybox: the simulation diverges at or next to the solver's final point "
            f"{dict(zip(names, theta.tolist(), strict=True))}; the model is unstable there or "
            "the integration is too coarse. Tighten the bounds, raise substeps or start closer"
        )
    if res.status <= 0:
        return ConvergenceError(
            f"greybox: the fit did not converge ({res.message.strip()}; {res.nfev} simulations, "
            f"cost {res.cost:.4g}). Start closer, check the excitation, or raise max_nfev"
        )
    return None


def _as_parameter(p: GreyboxParameter | tuple[Any, ...]) -> GreyboxParameter:
    if isinstance(p, GreyboxParameter):
        return p
    if isinstance(p, tuple) and 2 <= len(p) <= 7:
        return GreyboxParameter(*p)
    raise OptionTypeError(
        "parameters must be GreyboxParameter or (name, value, lower, upper, unit, fixed) "
        f"tuples, got {p!r}"
    )


def _check_parameter(p: GreyboxParameter) -> None:
    check_option(f"transform of {p.name}", p.transform, ("none", "log"))
    if not np.isfinite(p.value):
        raise DataError(f"parameter {p.name!r} needs a finite value, got {p.value}")
    if not p.lower < p.upper:
        raise DataError(
            f"parameter {p.name!r}: bounds need lower < upper, got [{p.lower}, {p.upper}]"
        )
    if not p.lower <= p.value <= p.upper:
        raise DataError(
            f"parameter {p.name!r}: start value {p.value} lies outside its bounds "
            f"[{p.lower}, {p.upper}]"
        )
    if p.transform == "log" and p.value <= 0:
        raise DataError(
            f"parameter {p.name!r} is log-transformed and needs a value > 0, got {p.value}"
        )


def _record(
    data: Experiment | tuple[ArrayLike, ArrayLike, ArrayLike], outputs: Sequence[str] | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], tuple[str, ...]]:
    if isinstance(data, Experiment):
        t = data.time
        u = data.u if data.u is not None else np.zeros((data.n_samples, 0))
        names = tuple(outputs) if outputs is not None else data.names_of("y")
        if not names:
            data.signal("y")  # raises a DataError that lists the channels
        y = np.column_stack([data[n] for n in names])
        return t, np.asarray(u, dtype=float), y, names
    if not isinstance(data, tuple) or len(data) != 3:
        raise OptionTypeError("data must be an Experiment or a tuple (t, u, y)")
    t = as_array("t", data[0], finite=False)
    u = as_array("u", data[1], finite=False)
    y = as_array("y", data[2], finite=False)
    u = u[:, None] if u.ndim == 1 else u
    y = y[:, None] if y.ndim == 1 else y
    if t.ndim != 1 or t.size < 2 or u.shape[0] != t.size or y.shape[0] != t.size:
        raise DataError(f"need t (N,), u (N, m), y (N, p); got {t.shape}, {u.shape}, {y.shape}")
    if np.any(np.diff(t) <= 0):
        raise DataError("t must be strictly increasing")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y)) and np.all(np.isfinite(t))):
        raise DataError("t, u and y must be finite")
    names = tuple(outputs) if outputs is not None else tuple(f"y{k}" for k in range(y.shape[1]))
    if len(names) != y.shape[1]:
        raise DataError(f"outputs names {len(names)} channels, y has {y.shape[1]}")
    return t, u, y, names


def _weights(
    noise_std: ArrayLike | None, weights: ArrayLike | None, y: NDArray[np.float64], p: int
) -> NDArray[np.float64]:
    if noise_std is not None and weights is not None:
        raise DataError("give noise_std or weights, not both")
    if noise_std is not None:
        s = np.broadcast_to(np.asarray(noise_std, dtype=float), (p,))
        if not np.all(s > 0):
            raise DataError(f"noise_std must be > 0 per channel, got {s.tolist()}")
        return 1.0 / s
    if weights is not None:
        w = np.broadcast_to(np.asarray(weights, dtype=float), (p,)).copy()
        if not np.all((w > 0) & np.isfinite(w)):
            raise DataError(f"weights must be finite and > 0 per channel, got {w.tolist()}")
        return w
    if p == 1:
        return np.ones(1)
    spread = np.std(y, axis=0)
    if not np.all(spread > 0):
        raise DataError("an output channel is constant; pass weights or noise_std explicitly")
    return 1.0 / spread


def _make_simulator(
    rhs: Rhs,
    x0: ArrayLike | Callable[[NDArray[np.float64]], ArrayLike],
    output: OutputMap | Sequence[int] | None,
    t: NDArray[np.float64],
    u: NDArray[np.float64],
    integrator: str,
    substeps: int,
    hold: str,
    ivp_options: Mapping[str, Any] | None,
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    def initial(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(x0(theta) if callable(x0) else x0, dtype=float).ravel()

    def outputs_of(x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        if output is None:
            return x
        if callable(output):
            return np.asarray(output(x, u, theta), dtype=float)
        return x[:, list(output)]

    def u_at(k: int, frac: float) -> NDArray[np.float64]:
        if hold == "zoh" or frac == 0.0 or k + 1 >= u.shape[0]:
            return u[k]
        return u[k] + frac * (u[k + 1] - u[k])

    times = t.tolist()  # floats: a numpy scalar per stage costs more than the arithmetic
    slope = np.diff(u, axis=0) if hold == "foh" else u
    held = [0.0, None]  # the last stage's time and input (the two midpoint stages share one)

    def rates(tt: float, x: NDArray[np.float64], k: int, theta: NDArray[np.float64]
              ) -> NDArray[np.float64]:
        if hold == "zoh" or tt == times[k]:
            uk = u[k]
        elif tt == held[0]:
            uk = held[1]
        else:
            uk = u[k] + (tt - times[k]) / (times[k + 1] - times[k]) * slope[k]
            held[0], held[1] = tt, uk
        return np.asarray(rhs(tt, x, uk, theta), dtype=float)

    step, unconstrained = rk4_step.py_func, keep.py_func  # the user's Python rhs: run as Python

    def run_rk4(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        x = initial(theta)
        xs = np.full((t.size, x.size), np.nan)
        xs[0] = x
        for k in range(t.size - 1):
            h = (t[k + 1] - t[k]) / substeps
            for j in range(substeps):
                x, _ = step(rates, unconstrained, t[k] + j * h, x, k, theta, h)
            if not np.all(np.isfinite(x)):
                return outputs_of(xs, theta)  # diverged: the rest stays NaN
            xs[k + 1] = x
        return outputs_of(xs, theta)

    opts = {"method": "RK45", "rtol": 1e-8, "atol": 1e-10} | dict(ivp_options or {})

    def run_ivp(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        def f(tt: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
            k = int(np.clip(np.searchsorted(t, tt, side="right") - 1, 0, t.size - 1))
            frac = 0.0 if k + 1 >= t.size else (tt - t[k]) / (t[k + 1] - t[k])
            return np.asarray(rhs(tt, x, u_at(k, frac), theta), dtype=float)

        if hold == "zoh":  # steps in u: do not let the adaptive solver step across samples
            opts.setdefault("max_step", float(np.min(np.diff(t))))
        sol = integrate.solve_ivp(f, (t[0], t[-1]), initial(theta), t_eval=t, **opts)
        xs = np.full((t.size, sol.y.shape[0]), np.nan)
        xs[: sol.y.shape[1]] = sol.y.T
        return outputs_of(xs, theta)

    return run_rk4 if integrator == "rk4" else run_ivp


def _warn_on_bounds(
    theta: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], names: list[str]
) -> None:
    for name, v, a, b in zip(names, theta, lo, hi, strict=True):
        for edge, label in ((a, "lower"), (b, "upper")):
            if np.isfinite(edge) and abs(v - edge) <= 1e-6 * max(abs(edge), 1.0):
                warn(
                    f"{name} = {v:.6g} ends on its {label} bound {edge:.6g}: the optimum is "
                    "constrained and its covariance (which ignores the bound) is not reliable; "
                    "widen the bound or revisit the model",
                    ServoidWarning,
                )
