"""Separable least squares: one nonlinear parameter β, linear θ (spec §3.8).

A *Type IV* equation is linear in θ but nonlinear in a parameter that no
reparameterisation removes — the critical pressure ratio b = p_krit inside
the flow function ψ_b, or a switching threshold such as ẋ_krit. For each
fixed β it is an ordinary *Type II* regression ``y(β) = Φ(β) θ + e``, solved
by the batch core :func:`~servoid.estimate.lstsq`. The profile

    RSS(β) = min_θ ‖y(β) − Φ(β) θ‖²

is then minimised over β alone (variable projection): a grid over the
search interval finds the global basin, Brent's bounded method (golden
section with parabolic steps) refines it, and the linear θ̂ is the inner
solution at β̂. The caller supplies ``build(β) -> (Φ, y)``.

**Covariance.** The full model has residual r(β, θ) = y(β) − Φ(β)θ and
Jacobian J = [∂r/∂β, −Φ] with ∂r/∂β = y′(β) − Φ′(β)θ̂ by central
differences of ``build``. The joint covariance is σ̂²(JᵀJ)⁻¹ with
σ̂² = RSS(β̂)/(N − n − 1): this gives var β̂, var θ̂ *inflated* for not
knowing β, and their cross-covariance. As a check, the profile likelihood
gives the same var β̂ to first order,

    var β̂ ≈ 2σ̂² / RSS″(β̂),

(RSS″ by central differences), reported as ``options["beta_std_profile"]``.
When ``build`` changes the number of rows with β (a threshold that selects
samples), ∂r/∂β does not exist: the covariance is then block diagonal —
the profile variance for β and the inner LS covariance for θ — and
``options["covariance"]`` says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float_list, as_str_list, type_error
from .._errors import DataError, IdentifiabilityError, ServoidWarning, check_option
from .._lazy import optimize
from .._warn import warn
from ._estimate import Estimate
from ._ls import lstsq

__all__ = ["fit_separable"]

SearchMethod = Literal["grid", "golden", "grid+golden"]
Builder = Callable[[float], tuple[ArrayLike, ArrayLike]]

_METHODS = ("grid", "golden", "grid+golden")
#: Relative spread of RSS over the grid below which RSS(β) counts as flat: well above the
#: rounding of an RSS (≈ N·ε), well below any real dependence.
FLAT_RTOL = 1e-9


def fit_separable(
    build: Builder,
    bounds: tuple[float, float],
    *,
    grid: int | ArrayLike = 51,
    method: SearchMethod = "grid+golden",
    names: Sequence[str] | None = None,
    beta_name: str = "beta",
    units: Sequence[str] | None = None,
    beta_unit: str = "",
    xtol: float | None = None,
) -> Estimate:
    """Fit y(β) = Φ(β)θ by an outer search on β and inner LS on θ.

    Parameters
    ----------
    build : callable
        ``build(beta) -> (phi, y)``: the linear regression for a fixed β,
        phi of shape (N, n) and y of shape (N,). It must be deterministic.
    bounds : (float, float)
        Search interval [β_lo, β_hi].
    grid : int or array_like
        Number of equally spaced grid points over ``bounds`` (≥ 3), or the
        grid itself (increasing, inside ``bounds``). Unused by "golden".
    method : {"grid", "golden", "grid+golden"}
        "grid": best grid point only; "golden": Brent's bounded search over
        the whole interval (assumes RSS(β) unimodal); "grid+golden": Brent
        inside the two grid cells around the best grid point.
    names : sequence of str, optional
        Names of the linear parameters (default ``theta0``, ...).
    beta_name : str
        Name of the nonlinear parameter.
    units : sequence of str, optional
        Units of the linear parameters.
    beta_unit : str
        Unit of β.
    xtol : float, optional
        Absolute tolerance on β for the refinement (default 1e-8 of the
        interval width; the grid spacing for "grid").

    Returns
    -------
    Estimate
        Parameters (β, θ₁, …, θ_n); joint covariance (module notes);
        ``model`` is the inner :class:`LeastSquaresResult` at β̂;
        ``options`` hold the grid, its RSS values and the profile std of β.

    Raises
    ------
    IdentifiabilityError
        RSS(β) is flat over the search (β does not change the fit), the
        full Jacobian is rank deficient, or the inner regression is rank
        deficient at β̂.
    DataError
        Bad bounds or grid, or ``build`` returns inconsistent arrays.

    Warns
    -----
    ServoidWarning
        β̂ on an end of the search interval, or a second grid minimum
        nearly as deep as the best (a multimodal profile).

    Notes
    -----
    Type IV → Type II (spec §3.8): with β fixed, e.g. the flow equation
    ``ṁ = a·d·x_v·ψ_b(p/p_S)·p_S·√(2/RT)`` is linear in a·d, so ``build``
    computes the regressor column ψ_b(π)·x_v·p_S·√(2/RT) for the b it is
    given and returns it with the measured ṁ. The outer search then
    treats b as the single nonlinear unknown; its variance comes from the
    full Jacobian (module notes), cross-checked by 2σ̂²/RSS″(b̂).
    """
    check_option("method", method, _METHODS)
    if not callable(build):
        raise type_error("build", build, "a function beta -> (phi, y)")
    lo, hi = as_float_list("bounds", bounds, length=2, finite=False)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise DataError(f"bounds must be finite with lower < upper, got {bounds}")
    points = _grid(grid, lo, hi)
    tol = xtol if xtol is not None else 1e-8 * (hi - lo)
    first = _regression(build, points[len(points) // 2])
    n = first[0].shape[1]
    names_t = tuple(as_str_list("names", names)) if names is not None else tuple(
        f"theta{k}" for k in range(n))
    if len(names_t) != n:
        raise DataError(f"names needs one entry per column of phi ({n}), got {len(names_t)}")
    units_t = tuple(as_str_list("units", units)) if units is not None else ("",) * n
    if len(units_t) != n:
        raise DataError(f"units needs one entry per column of phi ({n}), got {len(units_t)}")

    def rss(beta: float) -> float:
        phi, y = _regression(build, beta)
        try:
            return lstsq(phi, y, names_t).rss
        except IdentifiabilityError:
            return math.inf  # this β makes the regression degenerate: never the optimum

    grid_rss = np.array([rss(b) for b in points]) if method != "golden" else np.empty(0)
    if method != "golden":
        _check_profile(points, grid_rss, beta_name)
    if method == "grid":
        beta = float(points[int(np.argmin(grid_rss))])
    else:
        if method == "golden":
            a, b = lo, hi
        else:
            k = int(np.argmin(grid_rss))
            a, b = float(points[max(k - 1, 0)]), float(points[min(k + 1, len(points) - 1)])
        res = optimize.minimize_scalar(rss, bounds=(a, b), method="bounded", options={"xatol": tol})
        beta = float(res.x)
        if method == "grid+golden" and rss(beta) > grid_rss.min():
            beta = float(points[int(np.argmin(grid_rss))])  # Brent can stop on a shoulder
    if method == "golden":
        _check_profile(np.array([lo, beta, hi]), np.array([rss(lo), rss(beta), rss(hi)]), beta_name)

    phi, y = _regression(build, beta)
    inner = lstsq(phi, y, names_t)
    n_res = inner.n_rows
    n_par = n + 1
    if n_res <= n_par:
        raise DataError(f"{n_par} parameters need more than {n_par} equations, got {n_res}")
    sigma2 = inner.rss / (n_res - n_par)
    h = _step(beta, lo, hi, points)
    profile_std = _profile_std(rss, beta, h, inner.rss, sigma2)
    jac_beta = _beta_column(build, beta, h, inner.theta, n_rows=phi.shape[0])
    all_names = (beta_name, *names_t)
    if jac_beta is not None:
        cov = _joint_covariance(jac_beta, phi, sigma2, all_names)
        cov_kind = "joint: σ̂²(JᵀJ)⁻¹ with a central-difference ∂r/∂β"
    else:
        cov = np.zeros((n_par, n_par))
        cov[0, 0] = profile_std**2
        if inner.rss > 0:  # the inner covariance with the joint model's dof N − n − 1
            cov[1:, 1:] = inner.covariance * (sigma2 / inner.noise_variance)
        cov_kind = "block diagonal: build changes the rows with beta, no ∂r/∂β"
    _warn_edges(beta, lo, hi, tol, beta_name, points, grid_rss)
    theta = np.concatenate([[beta], inner.theta])

    def residual_function() -> NDArray[np.float64]:
        return y - phi @ inner.theta

    return Estimate(
        model=inner,
        parameters=theta,
        names=all_names,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_res,
        method="separable_ls",
        status="ok",
        options={
            "method": method,
            "bounds": [lo, hi],
            "grid": points.tolist() if method != "golden" else [],
            "grid_rss": grid_rss.tolist(),
            "xtol": tol,
            "difference_step": h,
            "beta_std_profile": profile_std,
            "covariance": cov_kind,
        },
        units=(beta_unit, *units_t),
        residual_function=residual_function,
    )


#: Most grid points of the profile search (each one a build() and a least-squares fit).
_MAX_GRID = 100_000


def _grid(grid: int | ArrayLike, lo: float, hi: float) -> NDArray[np.float64]:
    if isinstance(grid, (int, np.integer)) and not isinstance(grid, bool):
        if grid < 3:
            raise DataError(f"grid needs at least 3 points, got {grid}")
        if grid > _MAX_GRID:
            # each point is one build() and one least-squares fit: refuse an endless search
            raise DataError(f"grid must have at most {_MAX_GRID:,} points, got {grid:,}; the "
                            "golden-section refinement supplies the precision, not the grid")
        return np.linspace(lo, hi, int(grid))
    pts = as_array("grid", grid, finite=False).ravel()
    if pts.size < 3 or np.any(np.diff(pts) <= 0) or pts[0] < lo or pts[-1] > hi:
        raise DataError(
            f"grid must be ≥ 3 increasing points inside bounds [{lo}, {hi}], got {pts.size} "
            f"points from {pts.min() if pts.size else None} to {pts.max() if pts.size else None}"
        )
    return pts


def _regression(build: Builder, beta: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    out = build(float(beta))
    if not isinstance(out, tuple) or len(out) != 2:
        raise DataError("build(beta) must return a tuple (phi, y)")
    phi = as_array("phi from build(beta)", out[0], finite=False)
    y = as_array("y from build(beta)", out[1], finite=False)
    if phi.ndim == 1:
        phi = phi[:, None]
    if phi.ndim != 2 or y.ndim != 1 or phi.shape[0] != y.shape[0]:
        raise DataError(
            f"build(beta) must return phi (N, n) and y (N,), got {phi.shape}, {y.shape}"
        )
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(y))):
        raise DataError(f"build({beta:.6g}) returned non-finite values")
    return phi, y


def _check_profile(points: NDArray[np.float64], values: NDArray[np.float64], name: str) -> None:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        raise IdentifiabilityError(
            f"the regression is rank deficient for every {name} searched; check build()"
        )
    spread = float(finite.max() - finite.min())
    if spread <= FLAT_RTOL * float(finite.max()):
        raise IdentifiabilityError(
            f"RSS({name}) is flat over [{points[0]:.6g}, {points[-1]:.6g}] (relative spread "
            f"{spread / max(float(finite.max()), 1e-300):.2g}): the data do not depend on {name}. "
            f"Excite the region where {name} acts, or fix it from a preliminary experiment"
        )


def _step(beta: float, lo: float, hi: float, points: NDArray[np.float64]) -> float:
    # central differences: ε^(1/3)-relative step for ∂r/∂β, but no larger than a tenth
    # of a grid cell and inside the search interval where possible
    h = np.cbrt(np.finfo(float).eps) * max(abs(beta), hi - lo)
    if points.size > 1:
        h = min(h, 0.1 * float(np.min(np.diff(points))))
    return float(h)


def _beta_column(
    build: Builder, beta: float, h: float, theta: NDArray[np.float64], n_rows: int
) -> NDArray[np.float64] | None:
    phi_p, y_p = _regression(build, beta + h)
    phi_m, y_m = _regression(build, beta - h)
    if phi_p.shape[0] != n_rows or phi_m.shape[0] != n_rows:
        return None
    r_p = y_p - phi_p @ theta
    r_m = y_m - phi_m @ theta
    return (r_p - r_m) / (2 * h)


def _profile_std(
    rss: Callable[[float], float], beta: float, h: float, rss0: float, sigma2: float
) -> float:
    # RSS is smooth and quadratic near β̂: a wider step than for ∂r/∂β keeps the second
    # difference above the rounding of RSS (≈ ε·N·σ²)
    hh = 100 * h
    curv = (rss(beta + hh) - 2 * rss0 + rss(beta - hh)) / hh**2
    if not curv > 0:
        return math.inf
    return float(math.sqrt(2 * sigma2 / curv))


def _joint_covariance(
    jac_beta: NDArray[np.float64],
    phi: NDArray[np.float64],
    sigma2: float,
    names: tuple[str, ...],
) -> NDArray[np.float64]:
    jac = np.column_stack([jac_beta, -phi])
    scale = np.sqrt(np.einsum("ij,ij->j", jac, jac))
    if not np.all(scale > 0):
        raise IdentifiabilityError(
            f"the residual does not depend on {names[int(np.argmin(scale))]} at the optimum; "
            "it is not identifiable from these data"
        )
    _, s, vt = np.linalg.svd(jac / scale, full_matrices=False)
    if s[-1] <= s[0] * 1e-10:
        weak = names[int(np.argmax(np.abs(vt[-1])))]
        raise IdentifiabilityError(
            f"∂r/∂{names[0]} is (almost) a combination of the regressors (full Jacobian rank "
            f"deficient, weakest direction mostly {weak!r}): {names[0]} and the linear "
            "parameters cannot be told apart; fix one of them"
        )
    cov_s = (vt.T / s**2) @ vt
    return sigma2 * cov_s / np.outer(scale, scale)


def _warn_edges(
    beta: float,
    lo: float,
    hi: float,
    tol: float,
    name: str,
    points: NDArray[np.float64],
    grid_rss: NDArray[np.float64],
) -> None:
    if min(beta - lo, hi - beta) <= max(10 * tol, 1e-12 * (hi - lo)):
        warn(
            f"{name} = {beta:.6g} sits on an end of the search interval [{lo:.6g}, {hi:.6g}]: "
            "the minimum may lie outside; widen the interval. Its std assumes an interior "
            "optimum",
            ServoidWarning,
        )
    if grid_rss.size >= 3:
        finite = np.where(np.isfinite(grid_rss), grid_rss, np.inf)
        interior = (finite[1:-1] < finite[:-2]) & (finite[1:-1] < finite[2:])
        minima = np.flatnonzero(interior) + 1
        if minima.size >= 2:
            depths = np.sort(finite[minima])
            best, second = depths[0], depths[1]
            if second - best <= 0.1 * (finite.max() - best):
                warn(
                    f"RSS({name}) has several local minima of similar depth on the grid "
                    f"(best {best:.4g}, next {second:.4g}); check the answer against the "
                    "physics or refine the grid",
                    ServoidWarning,
                )
