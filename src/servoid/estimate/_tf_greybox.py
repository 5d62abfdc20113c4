"""Grey-box output-error fit of a discrete transfer function θ ↦ G(q, θ).

The criterion is ``Σ_t (y(t) − G(q, θ̂) u(t))²`` with the model simulated
from rest by :func:`scipy.signal.lfilter`; it is minimised by
Levenberg–Marquardt (MINPACK, through :func:`scipy.optimize.least_squares`)
or, with bounds, by a trust-region reflective method, in transformed
coordinates (``log`` keeps a parameter positive and makes steps relative),
from the given start and ``multistart`` random ones (the lowest cost wins).

Long records (100 000 samples or more, no bounds, ``solver="auto"``) take
a streamed Gauss–Newton instead (:mod:`servoid.estimate._tf_greybox_stream`):
G read in q⁻¹ is an OE model B/F, so JᵀJ and Jᵀr follow from the exact
coefficient gradient summed in one compiled pass and the small matrix
∂(B, F)/∂θ; the N × n Jacobian, its copies and the n + 1 simulations per
finite-difference Jacobian are never made.  The covariance then uses JᵀJ
(white) or the Gram matrix of J's columns filtered by the residuals' AR
model, from one more compiled pass (robust), and the
identifiability checks a square root of JᵀJ in place of J (they read J
only through JᵀJ).

Covariance (``covariance=``), from the solver's finite-difference Jacobian
J at the optimum, mapped back to θ:

* ``"white"``: ``σ̂²·(JᵀJ)⁻¹``, right when the output noise is white;
* ``"robust"`` (``"auto"``): the sandwich ``(JᵀJ)⁻¹·Σ_τ r̂_ε(τ) Σ_t
  J(t)J(t−τ)ᵀ·(JᵀJ)⁻¹`` with an AIC-chosen AR model of the residuals,
  right for coloured noise (:mod:`servoid.estimate._covariance`); it is
  the white formula when the residuals look white;
* ``"bootstrap"``: the spread of B refits on ``ŷ(θ̂) + ε*`` with ε* an
  autoregressive-sieve resample of the residuals (same module).

Every fit also runs the identifiability checks of
:mod:`servoid.estimate._diagnostics` and stores them in
``options["identifiability"]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_generator, as_int, as_str_list, type_error
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
from .._lazy import signal as sps
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..models import TransferFunction
from ._channels import output_name
from ._covariance import (
    GREYBOX_COVARIANCES,
    BootstrapResult,
    CovarianceResult,
    GreyboxCovariance,
    bootstrap_covariance,
    least_squares_covariance,
    resolve,
    sandwich_covariance,
)
from ._diagnostics import (
    MAX_STARTS,
    assess,
    draw_starts,
    summarise_starts,
    weakest_parameters,
)
from ._estimate import Estimate
from ._tf_greybox_stream import stream_filtered_gram, stream_least_squares, stream_residuals

__all__ = ["fit_tf_greybox"]

Transform = Literal["none", "log"]
Solver = Literal["auto", "lm", "trf"]

#: Records at least this long (samples in the criterion) are fitted by the streamed
#: Gauss–Newton when ``solver="auto"`` and there are no bounds: MINPACK's N × n Jacobian
#: and its copies took 24× the record at 1e7 samples.
_STREAM_MIN_SAMPLES = 100_000
_PENALTY = 1e100  # residual for a diverged simulation: finite, so LM rejects the step
#: Costs within this multiple of N·(rms y)² are rounding: two starts there are at one minimum.
_COST_FLOOR = 1e-24


def fit_tf_greybox(
    data: Experiment | ExperimentSet,
    model_fn: Callable[[NDArray[np.float64]], TransferFunction],
    theta0: ArrayLike,
    names: Sequence[str],
    units: Sequence[str] | None = None,
    *,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    transform: Sequence[Transform] | None = None,
    bounds: tuple[ArrayLike, ArrayLike] | None = None,
    start: int = 0,
    solver: Solver = "auto",
    max_nfev: int | None = None,
    tol: float = 1e-10,
    method_name: str = "tf_greybox",
    covariance: GreyboxCovariance = "auto",
    multistart: int = 0,
    n_bootstrap: int = 200,
    rng: np.random.Generator | int | None = None,
) -> Estimate:
    """Fit physical parameters of a discrete transfer function by OE.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with one input channel of role `input` and one output.
    model_fn : callable
        ``model_fn(theta) -> TransferFunction``, discrete at the data's dt.
    theta0 : array_like, shape (n,)
        Starting values, in physical units.
    names : sequence of str
        A name per parameter.
    units : sequence of str, optional
        A unit per parameter.
    input : {"u", "r"}
        Role of the input channel (``"r"`` for a closed loop from r to y).
    output : str, optional
        Output channel name when there are several.
    transform : sequence of {"none", "log"}, optional
        Per parameter: optimise θ itself or log θ (θ stays > 0 and steps
        are relative). Default: all ``"none"``.
    bounds : (array_like, array_like), optional
        Lower and upper bounds on θ (±inf for none); uses the "trf" solver.
    start : int
        First sample of each segment in the criterion; earlier samples only
        settle the simulation (initial conditions are not estimated).
    solver : {"auto", "lm", "trf"}
        ``"lm"`` = Levenberg–Marquardt (no bounds); ``"auto"`` picks "lm"
        without bounds and "trf" with them — except on records of 100 000
        samples or more without bounds, where it runs a streamed
        Gauss–Newton (module notes) and reports ``options["solver"] =
        "gauss-newton"``.
    max_nfev : int, optional
        Limit on residual evaluations per start (default: 200·(n + 1)).
    tol : float
        Relative tolerance on cost, step and gradient.
    method_name : str
        Value of ``Estimate.method`` (callers building on this estimator
        name their method).
    covariance : {"auto", "white", "robust", "bootstrap"}
        ``"white"`` σ̂²(JᵀJ)⁻¹; ``"robust"`` the coloured-residual sandwich;
        ``"bootstrap"`` the spread of `n_bootstrap` refits on resampled
        residuals; ``"auto"`` is ``"robust"`` (output error has no noise
        model, so its residuals keep the noise's colour).  Module notes.
    multistart : int
        Extra random starts, >= 0 (within a factor 3 of θ₀ for log
        parameters, θ₀ ± 50 % otherwise, uniform between finite bounds);
        the lowest cost wins and ``options["multistart"]`` says how many
        starts reached it.
    n_bootstrap : int
        Refits for ``covariance="bootstrap"``, >= 2.
    rng : numpy.random.Generator or int, optional
        Source of the random starts and resamples (a seed for
        reproducibility).

    Returns
    -------
    Estimate
        ``model`` is ``model_fn(θ̂)``; ``covariance`` in θ as chosen;
        ``options`` hold the solver report (nfev, cost, message),
        ``covariance`` (``"white"``, ``"robust"`` or ``"bootstrap"``: what
        the intervals use), ``covariance_ar_order`` (the residual AR order
        of the robust sandwich or the bootstrap's sieve; None for white),
        ``bootstrap`` (resamples, failures, percentile intervals) and
        ``multistart`` when used, and ``identifiability``
        (:meth:`Identifiability.to_dict`).

    Raises
    ------
    ConvergenceError
        The solver stopped without meeting its tolerances (from every start).
    IdentifiabilityError
        The Jacobian at the optimum is rank deficient (to 1e-6 of its
        column-normalised singular values: below the finite differences'
        accuracy); the message names the parameters.

    Warns
    -----
    ServoidWarning
        A parameter on a bound, an unstable model, and each failed
        identifiability check (correlation, near-null direction, std above
        the value or below the noise floor, a non-quadratic cost, local
        minima).

    Notes
    -----
    Memory: about 5 N × 8 bytes beyond the record on the streamed path
    (100 000 samples or more, no bounds, ``solver="auto"``): the residual
    vectors of the identifiability checks; the normal equations are summed
    in one compiled pass and no N × n Jacobian exists.  MINPACK and the
    trust-region solver (shorter records, bounds, or an explicit
    ``solver``) hold the N × n Jacobian and its working copies: about
    (6n + 6) N × 8 bytes.
    """
    check_option("input", input, ("u", "r"))
    check_option("solver", solver, ("auto", "lm", "trf"))
    check_option("covariance", covariance, GREYBOX_COVARIANCES)
    multistart = as_int("multistart", multistart, minimum=0)
    if multistart > MAX_STARTS:  # each start is a full fit
        raise DataError(f"multistart must be <= {MAX_STARTS} extra starts, got {multistart}")
    n_bootstrap = as_int("n_bootstrap", n_bootstrap, minimum=2)
    start = as_int("start", start, minimum=0)
    if not callable(model_fn):
        raise type_error("model_fn", model_fn, "a function theta -> TransferFunction")
    theta0 = as_array("theta0", theta0, finite=False).ravel()
    n = theta0.size
    if n == 0:
        raise DataError("theta0 must hold at least one parameter, got an empty array")
    names = tuple(as_str_list("names", names))
    if len(names) != n:
        raise DataError(f"names needs one entry per parameter ({n}), got {len(names)}")
    units = tuple(as_str_list("units", units)) if units is not None else ("",) * n
    if len(units) != n:
        raise DataError(f"units needs one entry per parameter ({n}), got {len(units)}")
    transform = tuple(as_str_list("transform", transform)) if transform is not None \
        else ("none",) * n
    if len(transform) != n:
        raise DataError(f"transform needs one entry per parameter ({n}), got {len(transform)}")
    for t in transform:
        check_option("transform", t, ("none", "log"))
    if not np.all(np.isfinite(theta0)):
        raise DataError(f"theta0 must be finite, got {theta0}")
    is_log = np.array([t == "log" for t in transform])
    if np.any(theta0[is_log] <= 0):
        bad = [nm for nm, v, lg in zip(names, theta0, is_log, strict=True) if lg and v <= 0]
        raise DataError(f"log-transformed parameters need theta0 > 0: {', '.join(bad)}")
    if solver == "lm" and bounds is not None:
        raise OptionError("solver='lm' does not take bounds; use solver='auto' or 'trf'")
    chosen = ("lm" if bounds is None else "trf") if solver == "auto" else solver
    lo, hi = _bounds(bounds, n, is_log)
    kind = resolve(covariance, noise_model=False)
    generator = as_generator(rng) if multistart or kind == "bootstrap" else None

    segments = as_segments(data)
    dt = segments[0].dt
    records = [_record(seg, input, output) for seg in segments]
    if start < 0 or any(u.size <= start + 1 for u, _ in records):
        raise DataError(f"start must be >= 0 and leave samples in every segment, got {start}")
    sizes = [u.size - start for u, _ in records]
    n_res = sum(sizes)
    if n_res <= n:
        raise DataError(f"{n} parameters need more than {n} samples in the criterion, got {n_res}")
    _check_model(model_fn(theta0), dt)
    measured = [y for _, y in records]

    # long records without bounds: Gauss–Newton on streamed normal equations (no N × n
    # Jacobian, no finite-difference simulations); see _tf_greybox_stream
    streamed = solver == "auto" and chosen == "lm" and n_res >= _STREAM_MIN_SAMPLES
    budget = max_nfev if max_nfev is not None else 200 * (n + 1)

    def to_theta(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(is_log, np.exp(np.where(is_log, z, 0.0)), z)

    def simulate(theta: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        g = model_fn(theta)
        numq = np.concatenate([np.zeros(g.den.size - g.num.size), g.num])
        return [sps.lfilter(numq, g.den, u) for u, _ in records]

    def raw_residuals(theta: NDArray[np.float64],
                      ys: Sequence[NDArray[np.float64]] = measured) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            if streamed:  # one compiled pass per segment into the residual array itself
                parts = stream_residuals(model_fn, records, start, theta, ys)
            else:
                parts = [(y - yh)[start:] for y, yh in zip(ys, simulate(theta), strict=True)]
            out = parts[0] if len(parts) == 1 else np.concatenate(parts)
        out[~np.isfinite(out)] = np.nan
        return out

    def solve(z_start: NDArray[np.float64],
              ys: Sequence[NDArray[np.float64]] = measured) -> optimize.OptimizeResult:
        if streamed:
            return stream_least_squares(model_fn, to_theta, records, start, z_start, tol,
                                        budget, None if ys is measured else ys)

        def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
            out = raw_residuals(to_theta(z), ys)
            out[np.isnan(out)] = _PENALTY
            return out

        if chosen == "trf":  # strictly inside finite bounds; infinite ones need no margin
            inner_lo = np.where(np.isfinite(lo), np.nextafter(lo + 1e-12 * np.abs(lo), np.inf), lo)
            inner_hi = np.where(np.isfinite(hi), np.nextafter(hi - 1e-12 * np.abs(hi), -np.inf), hi)
            z_start = np.clip(z_start, inner_lo, inner_hi)
        return optimize.least_squares(
            residuals, z_start, method=chosen,
            bounds=(lo, hi) if chosen == "trf" else (-np.inf, np.inf),
            xtol=tol, ftol=tol, gtol=tol, x_scale=1.0,
            max_nfev=max_nfev if max_nfev is not None else 200 * (n + 1),
        )

    z0 = np.where(is_log, np.log(np.where(is_log, theta0, 1.0)), theta0)
    starts = [z0]
    if multistart:
        assert generator is not None
        starts += draw_starts(z0, lo, hi, is_log, multistart, generator)
    results: list[optimize.OptimizeResult | None] = []
    first_failure: ConvergenceError | None = None
    for k, z_start in enumerate(starts):
        res = solve(z_start)
        failure = _failure(res, to_theta, theta0, method_name)
        if failure is not None and not multistart:
            raise failure
        results.append(None if failure is not None else res)
        if k == 0:
            first_failure = failure
    if all(r is None for r in results):
        raise ConvergenceError(f"every one of the {len(starts)} starts failed; the first: "
                               f"{first_failure}")
    costs = [2.0 * r.cost if r is not None else np.inf for r in results]
    k_best = int(np.argmin(costs))
    res = results[k_best]
    assert res is not None
    z = res.x
    theta = to_theta(z)
    dof = max(n_res - n, 1)
    cuts = np.cumsum(sizes)[:-1]
    d = np.where(is_log, theta, 1.0)  # dθ/dz
    if streamed:
        # J itself is never formed: a square root R of JᵀJ (RᵀR = JᵀJ) stands in for it in
        # the rank and identifiability checks, which read J only through JᵀJ
        r = raw_residuals(theta)
        jac = _gram_root(res.jtj)
        sigma2 = float(r @ r) / dof
        gram = stream_filtered_gram(model_fn, to_theta, records, start, z, np.ones(n))
        cov_result = sandwich_covariance("white" if kind == "bootstrap" else kind, res.jtj,
                                         sigma2, dof, lambda: np.split(r, cuts), gram,
                                         gram_bread=True)
    else:
        r = np.asarray(res.fun)
        # the solver's forward-difference Jacobian at x̂ (relative step √ε): accurate to ~1e-8,
        # ample for a covariance, and it saves 2n simulations
        jac = np.asarray(res.jac)
        sigma2 = float(r @ r) / dof
        cov_result = least_squares_covariance("white" if kind == "bootstrap" else kind,
                                              [np.split(jac, cuts)], [np.split(r, cuts)], dof)
    if cov_result.singular:
        weak = weakest_parameters(jac, names)
        raise IdentifiabilityError(
            f"the output does not depend on the parameters independently (Jacobian rank "
            f"deficient, weakest direction mostly {', '.join(map(repr, weak))}); fix or "
            "remove a parameter"
        )
    cov = cov_result.covariance * np.outer(d, d)
    options_extra: dict[str, Any] = {}
    if kind == "bootstrap":
        assert generator is not None
        fitted = simulate(theta)

        def refit(resampled: list[list[NDArray[np.float64]]]) -> NDArray[np.float64] | None:
            ys = []
            for yh, e in zip(fitted, resampled[0], strict=True):
                y_star = yh.copy()
                y_star[start:] += e
                ys.append(y_star)
            out = solve(z, ys)
            if out.status <= 0 or np.any(np.asarray(out.fun) == _PENALTY):
                return None
            return to_theta(out.x)

        boot = bootstrap_covariance([np.split(r, cuts)], dof, refit, n_bootstrap, generator)
        cov = _bootstrap_result(boot, n_bootstrap, method_name)
        cov_result = CovarianceResult(cov, False, "bootstrap", boot.ar_orders[0],
                                      boot.ar_orders)
        options_extra["bootstrap"] = _bootstrap_options(boot, n_bootstrap, names)
    model = model_fn(theta)
    _warn_on_bound(theta, bounds, names)
    _warn_if_unstable(model, method_name)
    summary = None
    if multistart:
        y_rms2 = float(np.mean(np.concatenate(measured) ** 2))
        summary = summarise_starts(costs, [None if q is None else to_theta(q.x) for q in results],
                                   _COST_FLOOR * n_res * y_rms2)
        options_extra["multistart"] = summary.to_dict()
    ident = assess(raw_residuals, theta, r, jac / d, cov, names, [sizes], summary,
                   covariance_kind=kind)

    def residual_function() -> NDArray[np.float64]:
        return raw_residuals(theta)

    return Estimate(
        model=model,
        parameters=theta,
        names=names,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_res,
        method=method_name,
        status="ok",
        options={
            "input": input,
            "output": output_name(segments[0], output),
            "transform": list(transform),
            "bounds": None if bounds is None else [np.asarray(b, float).tolist() for b in bounds],
            "theta0": theta0.tolist(),
            "start": start,
            "solver": "gauss-newton" if streamed else chosen,
            "nfev": int(res.nfev),
            "cost": float(res.cost),
            "optimality": float(res.optimality),
            "message": str(res.message),
            "solver_status": int(res.status),
            "covariance": cov_result.kind,
            "covariance_ar_order": cov_result.ar_order,
            **options_extra,
            "identifiability": ident.to_dict(),
        },
        units=units,
        residual_function=residual_function,
    )


def _gram_root(jtj: NDArray[np.float64]) -> NDArray[np.float64]:
    """R (n × n) with RᵀR = JᵀJ: same column norms and right singular vectors as J."""
    lam, vec = np.linalg.eigh(0.5 * (jtj + jtj.T))
    return np.sqrt(np.clip(lam, 0.0, None))[:, None] * vec.T


def _bounds(
    bounds: tuple[ArrayLike, ArrayLike] | None, n: int, is_log: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if bounds is None:
        return np.full(n, -np.inf), np.full(n, np.inf)
    if isinstance(bounds, (str, bytes)) or not isinstance(bounds, (tuple, list)) or \
            len(bounds) != 2:
        raise type_error("bounds", bounds, "a pair (lower, upper) of numbers or arrays")
    lo_in = as_array("bounds[0]", bounds[0], finite=False)
    hi_in = as_array("bounds[1]", bounds[1], finite=False)
    try:
        lo = np.broadcast_to(lo_in, (n,)).copy()
        hi = np.broadcast_to(hi_in, (n,)).copy()
    except ValueError as exc:  # shapes that do not broadcast to one value per parameter
        raise DataError(f"bounds must hold a number or {n} values each ({exc})") from None
    if np.any(lo >= hi):
        raise DataError(f"bounds need lower < upper, got {lo.tolist()} and {hi.tolist()}")
    with np.errstate(divide="ignore"):
        lo[is_log] = np.log(np.maximum(lo[is_log], 0.0))
        hi[is_log] = np.log(hi[is_log])
    return lo, hi


def _record(
    seg: Experiment, role: Literal["u", "r"], output: str | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    u = seg.signal(role)
    if u.shape[1] != 1:
        raise DataError(f"the OE fit takes one {role!r} channel, got {u.shape[1]}")
    return np.ascontiguousarray(u[:, 0]), seg[output_name(seg, output)]


def _check_model(model: object, dt: float) -> None:
    if not isinstance(model, TransferFunction):
        raise OptionTypeError(f"model_fn must return a TransferFunction, "
                              f"got {type(model).__name__}")
    if model.dt is None or not math.isclose(model.dt, dt, rel_tol=1e-9):
        raise ModelError(
            f"model_fn must return a discrete model at the data's dt = {dt} s, got dt = {model.dt}"
        )


def _failure(
    res: optimize.OptimizeResult,
    to_theta: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    theta0: NDArray[np.float64],
    method_name: str,
) -> ConvergenceError | None:
    """The error for a search that failed, or None."""
    if res.status <= 0 or not np.all(np.isfinite(res.x)):
        return ConvergenceError(
            f"{method_name}: the output-error fit did not converge ({res.message.strip()}; "
            f"{res.nfev} evaluations, cost {res.cost:.4g} from theta0 = {theta0.tolist()}). "
            "Start closer (e.g. from the two-step indirect or an ARX estimate), check that "
            "the input excites the model, or raise max_nfev"
        )
    if np.any(np.asarray(res.fun) == _PENALTY):
        return ConvergenceError(
            f"{method_name}: the simulation diverges at the optimum "
            f"θ = {to_theta(res.x).tolist()}; the model is unstable there. Start from a "
            "stable model"
        )
    return None


def _bootstrap_result(boot: BootstrapResult, n_bootstrap: int, method: str) -> NDArray[np.float64]:
    """The bootstrap covariance; warns on many failed refits."""
    ok = boot.samples.shape[0]
    if ok < 2:
        raise ConvergenceError(
            f"{method}: only {ok} of {n_bootstrap} bootstrap refits converged; no bootstrap "
            "covariance. Use covariance='robust' or check the model"
        )
    if boot.failed > 0.1 * n_bootstrap:
        warn(
            f"{method}: {boot.failed} of {n_bootstrap} bootstrap refits failed and were left "
            "out; the bootstrap covariance may understate the spread (the failures are the "
            "resamples the model fits worst)",
            ServoidWarning,
        )
    return boot.covariance


def _bootstrap_options(boot: BootstrapResult, n_bootstrap: int,
                       names: Sequence[str]) -> dict[str, Any]:
    """JSON-friendly summary: resamples, failures, sieve order, percentile intervals."""
    lo, hi = np.percentile(boot.samples, [2.5, 97.5], axis=0)
    return {
        "method": "ar-sieve",
        "resamples": int(n_bootstrap),
        "failed": int(boot.failed),
        "ar_orders": list(boot.ar_orders),
        "percentile_95": {nm: [float(a), float(b)]
                          for nm, a, b in zip(names, lo, hi, strict=True)},
    }


def _warn_on_bound(
    theta: NDArray[np.float64], bounds: tuple[ArrayLike, ArrayLike] | None, names: tuple[str, ...]
) -> None:
    if bounds is None:
        return
    lo = np.broadcast_to(np.asarray(bounds[0], dtype=float), theta.shape)
    hi = np.broadcast_to(np.asarray(bounds[1], dtype=float), theta.shape)
    for name, v, a, b in zip(names, theta, lo, hi, strict=True):
        for edge, label in ((a, "lower"), (b, "upper")):
            if np.isfinite(edge) and abs(v - edge) <= 1e-6 * max(abs(edge), 1.0):
                warn(
                    f"{name} = {v:.6g} sits on its {label} bound {edge:.6g}: the optimum is "
                    "constrained and its covariance (which ignores the bound) is not reliable; "
                    "widen the bound or revisit the model",
                    ServoidWarning,
                )


def _warn_if_unstable(model: TransferFunction, method_name: str) -> None:
    radius = float(np.max(np.abs(model.poles()))) if model.order else 0.0
    if radius > 1.0 + 1e-9:
        warn(
            f"{method_name}: the fitted model is unstable (largest pole magnitude "
            f"{radius:.6g} > 1); the data came from a bounded response, so suspect the start "
            "values or the model structure",
            ServoidWarning,
        )
