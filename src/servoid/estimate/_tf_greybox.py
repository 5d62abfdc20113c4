"""Grey-box output-error fit of a discrete transfer function θ ↦ G(q, θ).

The criterion is ``Σ_t (y(t) − G(q, θ̂) u(t))²`` with the model simulated
from rest by :func:`scipy.signal.lfilter`; it is minimised by
Levenberg–Marquardt (MINPACK, through :func:`scipy.optimize.least_squares`)
or, with bounds, by a trust-region reflective method, in transformed
coordinates (``log`` keeps a parameter positive and makes steps relative).
The covariance is ``σ̂²·(JᵀJ)⁻¹`` from the solver's finite-difference
Jacobian at the optimum, mapped back to θ.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize
from scipy import signal as sps

from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    ServoidWarning,
    check_option,
)
from ..data import Experiment, ExperimentSet, as_segments
from ..models import TransferFunction
from ._channels import output_name
from ._estimate import Estimate

__all__ = ["fit_tf_greybox"]

Transform = Literal["none", "log"]
Solver = Literal["auto", "lm", "trf"]

_PENALTY = 1e100  # residual for a diverged simulation: finite, so LM rejects the step


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
        without bounds and "trf" with them.
    max_nfev : int, optional
        Limit on residual evaluations (default: 200·(n + 1)).
    tol : float
        Relative tolerance on cost, step and gradient.
    method_name : str
        Value of ``Estimate.method`` (callers building on this estimator
        name their method).

    Returns
    -------
    Estimate
        ``model`` is ``model_fn(θ̂)``; ``covariance`` is ``σ̂²(JᵀJ)⁻¹``
        in θ; ``options`` hold the solver report (nfev, cost, message).

    Raises
    ------
    ConvergenceError
        The solver stopped without meeting its tolerances.
    IdentifiabilityError
        The Jacobian at the optimum is rank deficient.
    """
    check_option("input", input, ("u", "r"))
    check_option("solver", solver, ("auto", "lm", "trf"))
    theta0 = np.asarray(theta0, dtype=float).ravel()
    n = theta0.size
    names = tuple(names)
    if len(names) != n:
        raise DataError(f"names needs one entry per parameter ({n}), got {len(names)}")
    units = tuple(units) if units is not None else ("",) * n
    if len(units) != n:
        raise DataError(f"units needs one entry per parameter ({n}), got {len(units)}")
    transform = tuple(transform) if transform is not None else ("none",) * n
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

    segments = as_segments(data)
    dt = segments[0].dt
    records = [_record(seg, input, output) for seg in segments]
    if start < 0 or any(u.size <= start + 1 for u, _ in records):
        raise DataError(f"start must be >= 0 and leave samples in every segment, got {start}")
    n_res = sum(u.size - start for u, _ in records)
    if n_res <= n:
        raise DataError(f"{n} parameters need more than {n} samples in the criterion, got {n_res}")
    _check_model(model_fn(theta0), dt)

    def to_theta(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(is_log, np.exp(np.where(is_log, z, 0.0)), z)

    def simulate(theta: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        g = model_fn(theta)
        numq = np.concatenate([np.zeros(g.den.size - g.num.size), g.num])
        return [sps.lfilter(numq, g.den, u) for u, _ in records]

    def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            parts = [(y - yh)[start:] for (_, y), yh in zip(records, simulate(to_theta(z)),
                                                             strict=True)]
            out = parts[0] if len(parts) == 1 else np.concatenate(parts)
        out[~np.isfinite(out)] = _PENALTY
        return out

    z0 = np.where(is_log, np.log(np.where(is_log, theta0, 1.0)), theta0)
    if chosen == "trf":
        z0 = np.clip(z0, lo + 1e-12 * np.abs(lo), hi - 1e-12 * np.abs(hi))
    res = optimize.least_squares(
        residuals, z0, method=chosen, bounds=(lo, hi) if chosen == "trf" else (-np.inf, np.inf),
        xtol=tol, ftol=tol, gtol=tol, x_scale=1.0,
        max_nfev=max_nfev if max_nfev is not None else 200 * (n + 1),
    )
    if res.status <= 0 or not np.all(np.isfinite(res.x)):
        raise ConvergenceError(
            f"{method_name}: the output-error fit did not converge ({res.message.strip()}; "
            f"{res.nfev} evaluations, cost {res.cost:.4g} from theta0 = {theta0.tolist()}). "
            "Start closer (e.g. from the two-step indirect or an ARX estimate), check that "
            "the input excites the model, or raise max_nfev"
        )
    z = res.x
    r = np.asarray(res.fun)
    if np.any(r == _PENALTY):
        raise ConvergenceError(
            f"{method_name}: the simulation diverges at the optimum θ = {to_theta(z).tolist()}; "
            "the model is unstable there. Start from a stable model"
        )
    theta = to_theta(z)
    # the solver's forward-difference Jacobian at x̂ (relative step √ε): accurate to ~1e-8,
    # ample for a covariance, and it saves 2n simulations
    jac = np.asarray(res.jac)
    sigma2 = float(r @ r) / max(n_res - n, 1)
    cov_z = _inverse_normal(jac, names) * sigma2
    d = np.where(is_log, theta, 1.0)  # dθ/dz
    cov = cov_z * np.outer(d, d)
    model = model_fn(theta)
    _warn_on_bound(theta, bounds, names)
    _warn_if_unstable(model, method_name)

    def residual_function() -> NDArray[np.float64]:
        return residuals(z)

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
            "solver": chosen,
            "nfev": int(res.nfev),
            "cost": float(res.cost),
            "optimality": float(res.optimality),
            "message": str(res.message),
            "solver_status": int(res.status),
        },
        units=units,
        residual_function=residual_function,
    )


def _bounds(
    bounds: tuple[ArrayLike, ArrayLike] | None, n: int, is_log: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if bounds is None:
        return np.full(n, -np.inf), np.full(n, np.inf)
    lo = np.broadcast_to(np.asarray(bounds[0], dtype=float), (n,)).copy()
    hi = np.broadcast_to(np.asarray(bounds[1], dtype=float), (n,)).copy()
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
        raise TypeError(f"model_fn must return a TransferFunction, got {type(model).__name__}")
    if model.dt is None or not math.isclose(model.dt, dt, rel_tol=1e-9):
        raise ModelError(
            f"model_fn must return a discrete model at the data's dt = {dt} s, got dt = {model.dt}"
        )


def _inverse_normal(jac: NDArray[np.float64], names: tuple[str, ...]) -> NDArray[np.float64]:
    # SVD of J instead of inverting JᵀJ: squares nothing, exposes rank loss
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    if s.size == 0 or s[-1] <= s[0] * np.finfo(float).eps * max(jac.shape):
        weak = names[int(np.argmax(np.abs(vt[-1])))] if s.size else "?"
        raise IdentifiabilityError(
            f"the output does not depend on the parameters independently (Jacobian rank "
            f"deficient, weakest direction mostly {weak!r}); fix or remove a parameter"
        )
    return (vt.T / s**2) @ vt


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
                warnings.warn(
                    f"{name} = {v:.6g} sits on its {label} bound {edge:.6g}: the optimum is "
                    "constrained and its covariance (which ignores the bound) is not reliable; "
                    "widen the bound or revisit the model",
                    ServoidWarning,
                    stacklevel=3,
                )


def _warn_if_unstable(model: TransferFunction, method_name: str) -> None:
    radius = float(np.max(np.abs(model.poles()))) if model.order else 0.0
    if radius > 1.0 + 1e-9:
        warnings.warn(
            f"{method_name}: the fitted model is unstable (largest pole magnitude "
            f"{radius:.6g} > 1); the data came from a bounded response, so suspect the start "
            "values or the model structure",
            ServoidWarning,
            stacklevel=3,
        )
