"""The direct approach: Box–Jenkins on (u, y), started where the loop cannot mislead it.

With a noise model that can describe the noise, the prediction-error fit of
``y = B/F u + C/D e`` on the plant's own input and output is consistent and
efficient whatever the controller (Ljung, *System Identification*, 2nd ed.,
§13.4).  Its search is what fails in a loop: the default start (IV on u)
is biased by the feedback, and from it the search can stall in a valley.
:func:`fit_direct_bj` therefore also starts from the closed-loop IV
estimate (instruments from r, consistent for any controller) when the
reference is recorded, and keeps the lower cost.

An unstable plant has an unstable Box–Jenkins predictor (it simulates
``B/F u``).  When the closed-loop IV start has poles outside the unit
circle, the search uses the stabilised predictor of Forssell & Ljung
(*IEEE TAC* 45(1), 2000): with ``F = F_s·F_a`` (F_a the roots outside the
unit circle) and F_a* the monic polynomial of their mirror images
1/p̄,

    ε = (D/C) · (F y − B u(t − nk)) / (F_s · F_a*) / Π|p|

is the Box–Jenkins prediction error passed through the all-pass
``F_a/(F_a*·Π|p|)`` (unit gain at every frequency).  Every filter in it is
stable, and since an all-pass filter leaves the variance of a stationary
signal unchanged its criterion is the Box–Jenkins criterion: the same
minimum, consistent whatever the controller.  It is minimised by
Levenberg–Marquardt on a finite-difference Jacobian J, and the covariance
is ``σ̂² (JᵀJ)⁻¹`` (white prediction errors: an all-pass filter keeps white
noise white).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
from numpy.typing import NDArray

from .._errors import ConvergenceError, ServoidError, ServoidWarning
from .._lazy import signal as sps
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Estimate, fit_bj, fit_iv
from ..models import PolynomialModel
from ._channels import output_name, single_name
from ._linearity import interval_check, is_noise_free

__all__ = ["fit_direct_bj"]

#: A pole this far beyond the unit circle (|z| − 1) counts as unstable.
_UNSTABLE_MARGIN = 1e-3


def fit_direct_bj(
    data: Experiment | ExperimentSet,
    nb: int,
    nc: int,
    nd: int,
    nf: int,
    nk: int = 1,
    *,
    output: str | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
) -> Estimate:
    """Fit the plant by the direct approach: Box–Jenkins on u → y.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the plant input u and the output y; a reference r,
        when recorded, gives the closed-loop IV start.
    nb, nc, nd, nf, nk : int
        Orders as in :func:`servoid.estimate.fit_bj`.
    output : str, optional
        Output channel name when there are several.
    max_iter, tol
        Passed to :func:`~servoid.estimate.fit_bj`.

    Returns
    -------
    Estimate
        Method ``"direct-bj"``; parameters ``b0…, f1…, c1…, d1…``;
        ``options["start"]`` names the start that reached the lower cost,
        ``options["predictor"]`` whether the stabilised predictor was used
        (an unstable plant).

    Raises
    ------
    ConvergenceError
        Every start failed.
    """
    segments = as_segments(data)
    single_name(segments[0], "u", None, "plant input")
    y_name = output_name(segments[0], output)
    has_r = bool(segments[0].names_of("r"))
    start = None
    radius = None
    if has_r and nf > 0:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ServoidWarning)
                iv = fit_iv(data, nf, nb, nk, instrument="r", output=y_name)
            a = np.asarray(iv.parameters[:nf], dtype=float)
            radius = float(np.max(np.abs(np.roots(np.concatenate([[1.0], a])))))
            start = np.concatenate([iv.parameters[nf:], a, np.zeros(nc + nd)])
        except ServoidError:
            start = None
    unstable = radius is not None and radius > 1.0 + _UNSTABLE_MARGIN
    fits: list[tuple[Estimate, str, list]] = []
    failure: ConvergenceError | None = None
    starts = [(None, "default (IV on u)")]
    if start is not None and not unstable:
        starts.append((start, "closed-loop IV"))
    for init, label in starts:
        try:
            with warnings.catch_warnings(record=True) as said:
                warnings.simplefilter("always", ServoidWarning)
                est = fit_bj(data, nb, nc, nd, nf, nk, output=y_name, init=init,
                             max_iter=max_iter, tol=tol)
            fits.append((dataclasses.replace(est, options={
                **est.options, "predictor": "box-jenkins"}), label, list(said)))
        except ConvergenceError as exc:
            failure = failure or exc
    wanted_out = not fits or any(fit[0].options.get("reflected", 0) for fit in fits)
    if unstable and wanted_out:
        # the closed-loop IV start is unstable and the BJ search met the unit circle (or
        # failed): the stabilised predictor can reach an unstable plant
        assert start is not None and radius is not None
        try:
            with warnings.catch_warnings(record=True) as said:
                warnings.simplefilter("always", ServoidWarning)
                est = _fit_unstable(segments, y_name, start, nb, nc, nd, nf, nk, radius,
                                    max_iter=max_iter, tol=tol)
            fits.append((est, "closed-loop IV, stabilised predictor", list(said)))
        except (ConvergenceError, np.linalg.LinAlgError, ValueError) as exc:
            failure = failure or ConvergenceError(f"the stabilised search failed: {exc}")
    if not fits:
        assert failure is not None
        raise failure
    if unstable and wanted_out and len(fits) > 1:
        # one criterion for every candidate: the stabilised one (the BJ criterion where
        # the BJ predictor is stable, up to the start-up transient)
        criterion = _Criterion(segments, y_name, nb, nc, nd, nf, nk)
        cost = lambda fit: criterion.cost(np.asarray(fit[0].parameters))
    else:
        cost = lambda fit: float(fit[0].options["cost"])
    est, label, said = min(fits, key=cost)
    for w in said:
        warn(str(w.message), ServoidWarning)
    broken = []
    if not has_r and est.options.get("reflected", 0):
        # without r there is no closed-loop IV estimate to say whether the plant is stable:
        # a search that kept leaving the stable region is the only evidence
        broken.append(
            f"the Box–Jenkins search met the unit circle ({est.options['reflected']} "
            "reflected steps): the plant may be unstable, which its predictor cannot follow; "
            "record the reference r so that the closed-loop IV start and the stabilised "
            "predictor can be used"
        )
        warn(f"the direct Box–Jenkins estimate may not be consistent: {broken[0]}",
             ServoidWarning)
    if not broken:
        criterion = _Criterion(segments, y_name, nb, nc, nd, nf, nk)
        theta = np.asarray(est.parameters, dtype=float)
        base = _white_covariance(criterion, theta)
        if base is not None and not is_noise_free([criterion.errors(theta)], criterion.ys):
            _, verdict = interval_check(theta, base,
                                        lambda th: _white_covariance(criterion, th),
                                        list(est.names))
            if verdict is not None:
                broken.append(verdict)
                warn(f"the direct Box–Jenkins estimate's intervals do not hold on this "
                     f"record: {verdict}", ServoidWarning)
    return dataclasses.replace(est, method="direct-bj", options={
        **est.options, "start": label, "starts": [fit[1] for fit in fits],
        "consistent": not broken, "broken_assumptions": broken,
    })


def _white_covariance(criterion: _Criterion,
                      theta: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """``σ̂²(JᵀJ)⁻¹`` of the stabilised criterion at θ (central differences), or None."""
    with np.errstate(all="ignore"):
        eps = criterion.errors(theta)
        if not np.all(np.isfinite(eps)):
            return None
        cols = []
        for j in range(theta.size):
            h = 1e-6 * (1.0 + abs(float(theta[j])))
            step = np.zeros(theta.size)
            step[j] = h
            cols.append((criterion.errors(theta + step) - criterion.errors(theta - step))
                        / (2.0 * h))
        jac = np.column_stack(cols)
    if not np.all(np.isfinite(jac)):
        return None
    sigma2 = float(eps @ eps) / max(eps.size - theta.size, 1)
    return sigma2 * np.linalg.pinv(jac.T @ jac)


def _split(f: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """F_s, F_a* (monic, mirrored unstable roots) and Π|p| of a monic F."""
    roots = np.roots(f) if f.size > 1 else np.zeros(0)
    out = np.abs(roots) > 1.0
    stable = np.real(np.poly(roots[~out])) if np.any(~out) else np.ones(1)
    mirror = np.real(np.poly(1.0 / np.conj(roots[out]))) if np.any(out) else np.ones(1)
    return stable, mirror, float(np.prod(np.abs(roots[out]))) if np.any(out) else 1.0


def _inside(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """A monic polynomial with its roots outside the unit circle reflected inside."""
    if p.size <= 1:
        return p
    roots = np.roots(p)
    big = np.abs(roots) > 1.0
    if not np.any(big):
        return p
    roots[big] = 1.0 / np.conj(roots[big])
    return np.real(np.poly(roots))


class _Criterion:
    """The stabilised Box–Jenkins prediction errors of (u, y) (module notes)."""

    def __init__(self, segments: tuple[Experiment, ...], y_name: str, nb: int, nc: int,
                 nd: int, nf: int, nk: int) -> None:
        self.u_name = segments[0].names_of("u")[0]
        us = [np.asarray(seg[self.u_name], dtype=float) for seg in segments]
        ys = [np.asarray(seg[y_name], dtype=float) for seg in segments]
        self.us = [u - u.mean() for u in us]
        self.ys = [y - y.mean() for y in ys]
        self.orders = (nb, nc, nd, nf, nk)

    def polys(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        nb, nc, _, nf, nk = self.orders
        b = np.concatenate([np.zeros(nk), theta[:nb]])
        f = np.concatenate([[1.0], theta[nb:nb + nf]])
        c = _inside(np.concatenate([[1.0], theta[nb + nf:nb + nf + nc]]))
        d = np.concatenate([[1.0], theta[nb + nf + nc:]])
        return b, f, c, d

    def errors(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        b, f, c, d = self.polys(theta)
        stable, mirror, gain = _split(f)
        den = np.convolve(stable, mirror)
        out = []
        for u, y in zip(self.us, self.ys, strict=True):
            w = sps.lfilter(f, [1.0], y) - sps.lfilter(b, [1.0], u)
            out.append(sps.lfilter(d, c, sps.lfilter([1.0], den, w)) / gain)
        return np.concatenate(out)

    def cost(self, theta: NDArray[np.float64]) -> float:
        e = self.errors(theta)
        return float(e @ e) if np.all(np.isfinite(e)) else np.inf


def _fit_unstable(
    segments: tuple[Experiment, ...], y_name: str, start: NDArray[np.float64],
    nb: int, nc: int, nd: int, nf: int, nk: int, radius: float, *, max_iter: int, tol: float,
) -> Estimate:
    """Box–Jenkins with the all-pass-stabilised predictor (module notes)."""
    from scipy.optimize import least_squares

    criterion = _Criterion(segments, y_name, nb, nc, nd, nf, nk)
    u_name = criterion.u_name
    errors = criterion.errors
    solution = least_squares(errors, start, method="lm", x_scale="jac", xtol=tol, ftol=tol,
                             max_nfev=max(50, 20 * max_iter))
    theta = solution.x
    # C is reflected inside inside the predictor: report the polynomial it used
    c_used = _inside(np.concatenate([[1.0], theta[nb + nf:nb + nf + nc]]))
    theta = np.concatenate([theta[:nb + nf], c_used[1:], theta[nb + nf + nc:]])
    eps = errors(theta)
    n = eps.size
    dof = max(n - theta.size, 1)
    sigma2 = float(eps @ eps) / dof
    jac = np.asarray(solution.jac)
    cov = sigma2 * np.linalg.pinv(jac.T @ jac)
    converged = bool(solution.status > 0)
    if not converged:
        warn("the stabilised Box–Jenkins search stopped before converging; increase max_iter "
             "or check the orders", ServoidWarning)
    f_poly = np.concatenate([[1.0], theta[nb:nb + nf]])
    out_radius = float(np.max(np.abs(np.roots(f_poly)))) if nf else 0.0
    names = tuple([f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)]
                  + [f"c{j}" for j in range(1, nc + 1)] + [f"d{j}" for j in range(1, nd + 1)])
    dt = segments[0].dt

    def model_at(p: NDArray[np.float64]) -> PolynomialModel:
        p = np.asarray(p, dtype=float)
        return PolynomialModel(
            [1.0], (p[:nb],), (nk,), dt, f=(np.concatenate([[1.0], p[nb:nb + nf]]),),
            c=np.concatenate([[1.0], p[nb + nf:nb + nf + nc]]),
            d=np.concatenate([[1.0], p[nb + nf + nc:]]), noise_variance=sigma2,
            input_names=(u_name,), output_name=y_name,
        )

    return Estimate(
        model=model_at(theta), parameters=theta, names=names,
        covariance=0.5 * (cov + cov.T), noise_variance=sigma2, n_samples=n,
        method="direct-bj", status="ok" if converged else "stopped before converging",
        options={
            "nb": nb, "nc": nc, "nd": nd, "nf": nf, "nk": nk, "input": "u",
            "inputs": [u_name], "output": y_name, "cost": float(eps @ eps),
            "predictor": (f"stabilised (the closed-loop IV start has a pole at |z| = "
                          f"{radius:.3g}; the estimate's largest pole is at |z| = "
                          f"{out_radius:.3g})"),
            "covariance": "white (Gauss–Newton, finite-difference Jacobian)",
            "iterations": int(solution.nfev), "converged": converged,
        },
        residual_function=lambda: eps,
        model_function=model_at,
    )
