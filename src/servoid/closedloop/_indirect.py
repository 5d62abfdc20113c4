"""The indirect approach for any plant order when the controller is known.

Loop convention (negative feedback, a reference r at the summing point)::

    u = C(q)·(r − F(q)·y),   y = G(q)·u + v
    Gcl = G·C/(1 + G·C·F),   G = Gcl/(C·(1 − F·Gcl))

with F = 1 (unit feedback) unless a feedback gain or filter is given.  The
closed loop r → y is fitted first: r is uncorrelated with the noise, so an
output-error fit of Gcl is consistent with any noise colour (Ljung,
*System Identification*, 2nd ed., §13.5; Van den Hof, "Closed-loop
issues in system identification", *Annu. Rev. Control* 22, 1998).

The plant then follows from polynomial algebra in q⁻¹.  With ``C = Cn/Cd``,
``F = Fn/Fd``, ``Gcl = Bcl/Fcl`` and the plant ``G = q^(−nk)·B/Fp``::

    Bcl = q^(−nk)·B·Cn·Fd
    Fcl = Fp·Cd·Fd + q^(−nk)·B·Cn·Fn

so the closed-loop parameters are an affine function ``θ_cl = H·θ + h`` of
the plant parameters θ = (b0…, f1…).  Inverting ``G = Gcl/(C·(1 − F·Gcl))``
directly would give a plant of inflated order whose extra poles and zeros
only nearly cancel; instead θ is the Markov (minimum-distance) estimate
``θ̂ = argmin (θ̂_cl − Hθ − h)ᵀ P_cl⁻¹ (θ̂_cl − Hθ − h) = (HᵀP_cl⁻¹H)⁻¹
HᵀP_cl⁻¹(θ̂_cl − h)``, whose covariance ``(HᵀP_cl⁻¹H)⁻¹`` is exact for the
affine map and asymptotically that of the best estimate from θ̂_cl
(Söderström & Stoica, *System Identification*, 1989, §C4.4 and §10.5;
the "indirect approach with structure" of Ljung §13.5).

By default the two-step estimate then starts a Levenberg–Marquardt search
of the same output-error criterion with the closed loop parameterised by
the plant, ``Σ (y − Gcl(q, θ) r)²`` with ``θ_cl = Hθ + h`` (so
``ψ = Ψ_cl·H``): the one-step indirect method, the prediction-error
estimate of the plant itself.  It converges in a few steps where a free
closed-loop OE of higher order crawls along the valleys of near pole-zero
cancellations.  Its covariance is the coloured-noise sandwich of
:mod:`servoid.closedloop._coloured`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_int, type_error
from .._errors import (
    ConvergenceError,
    IdentifiabilityError,
    ModelError,
    ServoidError,
    ServoidWarning,
    check_option,
)
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Estimate, fit_arx, fit_iv, fit_oe
from ..models import PolynomialModel, TransferFunction, c2d
from ._channels import check_excites, output_name, reference_name
from ._coloured import oe_gradient, sandwich
from ._discretisation import DISCRETISATIONS, discretisation_check
from ._linearity import interval_check, is_noise_free

__all__ = ["fit_indirect_tf"]

Structure = Literal["oe", "arx"]
Discretisation = Literal["tustin", "zoh", "foh"]

#: Damping increases (×10 each) tried before the refinement stops.
_MAX_DAMPING = 15


def fit_indirect_tf(
    data: Experiment | ExperimentSet,
    controller: TransferFunction | float,
    nb: int,
    nf: int,
    nk: int = 1,
    *,
    feedback: TransferFunction | float = 1.0,
    structure: Structure = "oe",
    closed_loop: tuple[int, int, int] | None = None,
    refine: bool = True,
    output: str | None = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    discretisation: Discretisation = "tustin",
) -> Estimate:
    """Fit the plant in a known loop by the indirect approach.

    Step 1 fits the closed loop r → y (OE by default, see
    :func:`~servoid.estimate.fit_oe`); step 2 finds the plant whose
    closed loop with the known controller is nearest to it, weighted by
    its covariance (see the module notes for the loop convention
    ``u = C·(r − F·y)`` and the algebra).  Any plant order works,
    including unstable plants that only run in closed loop.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the reference r and the output y (u is not needed).
    controller : TransferFunction or float
        The controller C, discrete at the data dt (as it ran), or a gain;
        or continuous (``dt=None``), when only the design is known: it is
        then discretised at the data dt by `discretisation`, and the
        estimate claims consistency only where the other discretisations
        of the design differ from it by less than the plant's own relative
        standard deviation at every frequency
        (:mod:`servoid.closedloop._discretisation`).
    nb : int
        Number of B coefficients of the plant ``G = q^(−nk)·B/F``.
    nf : int
        Order of the plant denominator F.
    nk : int
        Plant delay [samples].
    feedback : TransferFunction or float
        Feedback path F of ``u = C·(r − F·y)``: 1 (unit feedback), a
        sensor gain, or a discrete filter at the data dt.
    structure : {"oe", "arx"}
        Closed-loop model of step 1.  ``"oe"`` is consistent for any noise
        colour; ``"arx"`` is faster but biased unless the noise is white
        equation error of the closed loop.
    closed_loop : (nb, nf, nk), optional
        Orders of the closed-loop model; default: those a plant of the
        given orders in this loop has.
    output : str, optional
        Output channel name when there are several.
    refine : bool
        Refine the two-step estimate by output error on the closed loop
        parameterised by the plant (the one-step indirect method); the
        result is then the prediction-error estimate, and a closed-loop
        search that has not converged only has to supply the start.
    multistart, rng, max_iter, tol
        Passed to :func:`~servoid.estimate.fit_oe` (``"oe"`` only);
        `max_iter` and `tol` also bound the refinement.
    discretisation : {"tustin", "zoh", "foh"}
        How a continuous controller is discretised at the data dt.

    Returns
    -------
    Estimate
        Method ``"indirect"``; ``model`` is the plant as an OE
        :class:`~servoid.models.PolynomialModel` (its
        ``transfer_function()`` is G); parameters ``b0…, f1…`` with the
        delta-method covariance; ``residuals`` are those of the closed-loop
        fit; ``options["closed_loop"]`` holds that fit.
        ``options["consistent"]`` is False, with the reason in
        ``options["broken_assumptions"]`` and a warning, when the refined
        estimate's covariance changes by more than ×1.4 one standard
        deviation away or, when u is recorded, at the closed-loop IV
        estimate of the same plant (:mod:`servoid.closedloop._linearity`):
        the record then carries too little information for its intervals;
        or when a continuous controller's discretisations differ by more
        than the plant's relative standard deviation (the controller is
        too fast for the sampling to pin it down).

    Raises
    ------
    ModelError
        A controller at another dt, a continuous feedback, or an
        algebraic loop.
    DataError
        No reference channel, or too few samples.
    IdentifiabilityError
        A constant reference.

    Examples
    --------
    >>> from servoid.bench import simulate_lti_loop
    >>> from servoid.models import TransferFunction
    >>> plant = TransferFunction([4.0], [1.0, 2.0])
    >>> pi = TransferFunction([0.6, -0.5], [1.0, -1.0], 0.1)
    >>> r = np.repeat(np.sign(np.random.default_rng(1).standard_normal(500)), 4)
    >>> exp = simulate_lti_loop(plant, pi, r, 0.1, noise_std=0.01, rng=2)
    >>> est = fit_indirect_tf(exp, pi, nb=1, nf=1)
    >>> round(float(est.model.transfer_function().dc_gain()), 2)
    2.0
    """
    check_option("structure", structure, ("oe", "arx"))
    refine = as_bool("refine", refine)
    nb = as_int("nb", nb, minimum=1)
    nf = as_int("nf", nf, minimum=0)
    nk = as_int("nk", nk, minimum=0)
    check_option("discretisation", discretisation, DISCRETISATIONS)
    segments = as_segments(data)
    dt = segments[0].dt
    design = None
    if isinstance(controller, TransferFunction) and controller.dt is None:
        design = controller
        controller = c2d(controller, dt, discretisation)
    cn, cd = _q_polynomials("controller", controller, dt)
    fn, fd = _q_polynomials("feedback", feedback, dt)
    if not np.any(cn):
        raise ModelError("the controller is zero: the reference never reaches the plant")
    if not np.any(fn):
        raise ModelError("the feedback is zero: the loop is open; fit the plant from (u, y) "
                         "with an open-loop method instead")
    kc = int(np.flatnonzero(cn)[0])
    if nk + kc + int(np.flatnonzero(fn)[0]) == 0:
        raise ModelError(
            "plant, controller and feedback all pass their input through at once (nk = 0 and "
            "direct feed-through in C and F): an algebraic loop no sampled system has; set nk "
            ">= 1 (a sampled plant has at least one sample of delay)"
        )
    r_name = reference_name(data, "the indirect approach")
    check_excites(r_name, [np.asarray(seg[r_name]) for seg in segments], "r")
    y_name = output_name(segments[0], output)
    loop_map = _ClosedLoopMap(cn, cd, fn, fd, nb, nf, nk)
    if closed_loop is None:
        nb_cl, nf_cl, nk_cl = loop_map.orders
    else:
        if not isinstance(closed_loop, (tuple, list)) or len(closed_loop) != 3:
            raise type_error("closed_loop", closed_loop, "a tuple (nb, nf, nk)")
        nb_cl = as_int("closed_loop nb", closed_loop[0], minimum=1)
        nf_cl = as_int("closed_loop nf", closed_loop[1], minimum=0)
        nk_cl = as_int("closed_loop nk", closed_loop[2], minimum=0)
        need_b, need_f, need_k = loop_map.orders
        if nk_cl > need_k or nk_cl + nb_cl < need_k + need_b or nf_cl < need_f:
            raise ModelError(
                f"closed_loop = ({nb_cl}, {nf_cl}, {nk_cl}) cannot hold the closed loop of this "
                f"plant in this loop, which needs nb + nk >= {need_b + need_k}, nf >= {need_f} "
                f"and nk <= {need_k}; the default {loop_map.orders} is exact"
            )

    rs = [np.asarray(seg[r_name], dtype=float) for seg in segments]
    ys = [np.asarray(seg[y_name], dtype=float) for seg in segments]
    orders_cl = (nb_cl, nf_cl, nk_cl)
    fits = _step1(data, structure, orders_cl, y_name, refine,
                  {"multistart": multistart, "rng": rng, "max_iter": max_iter, "tol": tol})
    starts = [(fit, *loop_map.project(fit.theta, fit.covariance, orders_cl)) for fit in fits]
    primary, theta, cov = starts[0]
    cl = primary.estimate
    u_names = segments[0].names_of("u")
    status, n_samples, cov_note = cl.status, cl.n_samples, primary.note
    sigma2 = float(cl.noise_variance)
    refined: dict[str, object] = {"refined": False}
    broken: list[str] = []
    residuals: Callable[[], NDArray[np.float64]] = lambda: cl.residuals
    if refine:
        step = _Refinement(loop_map, rs, ys)
        runs = []
        for fit, theta0, _ in starts:
            try:
                runs.append((*step.run(theta0, max_iter, tol), fit.label))
            except ConvergenceError:
                continue
        if not runs:
            raise ConvergenceError(
                "the closed loop simulated from every start of the indirect refinement "
                "diverges: the closed-loop fits are poor; check the orders and the controller, "
                "or pass refine=False"
            )
        # several starts guard against a closed-loop search that stopped in a valley
        theta, errors, iterations, converged, start = min(
            runs, key=lambda run: sum(float(e @ e) for e in run[1]))
        cov, ar = step.covariance(theta)
        cov_note = f"sandwich, AR({ar}) residual spectrum"
        n_samples = sum(e.size for e in errors)
        sigma2 = float(sum(e @ e for e in errors)) / max(n_samples - theta.size, 1)
        status = "ok" if converged else f"stopped at max_iter after {iterations} steps"
        if not converged:
            warn(
                f"the indirect refinement stopped at max_iter={max_iter} before converging; "
                "increase max_iter or check the orders and the controller",
                ServoidWarning,
            )
        final = np.concatenate(errors)
        residuals = lambda: final
        names = [f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)]
        verdict = (None if is_noise_free(errors, ys)
                   else interval_check(theta, cov, step.covariance_or_none, names,
                                       _cliv_point(data, segments, nb, nf, nk, y_name))[1])
        if verdict is not None:
            broken.append(verdict)
            warn(f"the indirect estimate's intervals do not hold on this record: {verdict}",
                 ServoidWarning)
        refined = {"refined": True, "iterations": iterations, "converged": converged,
                   "start": start, "starts": [fit.label for fit in fits]}

    if design is not None:
        alternatives = _other_discretisations(
            data, design, discretisation, nb, nf, nk,
            {"feedback": feedback, "structure": structure, "closed_loop": closed_loop,
             "refine": refine, "output": output, "multistart": multistart, "rng": rng,
             "max_iter": max_iter, "tol": tol})
        verdict = discretisation_check(
            design, discretisation, dt, theta, cov, nb, alternatives,
            [f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)])[1]
        if verdict is not None:
            broken.append(verdict)
            warn(f"the indirect estimate is not consistent on this record: {verdict}",
                 ServoidWarning)

    def model_at(p: NDArray[np.float64]) -> PolynomialModel:
        p = np.asarray(p, dtype=float)
        return PolynomialModel(
            [1.0], (p[:nb],), (nk,), dt, f=(np.concatenate([[1.0], p[nb:]]),),
            noise_variance=sigma2, input_names=u_names[:1] if len(u_names) == 1 else None,
            output_name=y_name,
        )

    names = tuple([f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)])
    cl_names = [f"b{j}" for j in range(nb_cl)] + [f"f{j}" for j in range(1, nf_cl + 1)]
    return Estimate(
        model=model_at(theta),
        parameters=theta,
        names=names,
        covariance=0.5 * (cov + cov.T),
        noise_variance=sigma2,
        n_samples=n_samples,
        method="indirect",
        status=status,
        options={
            "nb": nb,
            "nf": nf,
            "nk": nk,
            "loop": "u = C·(r − F·y)",
            "controller": {"num": [float(x) for x in cn], "den": [float(x) for x in cd]},
            "discretisation": None if design is None else discretisation,
            "feedback": {"num": [float(x) for x in fn], "den": [float(x) for x in fd]},
            "reference": r_name,
            "output": y_name,
            "closed_loop": {
                "structure": structure,
                "nb": nb_cl,
                "nf": nf_cl,
                "nk": nk_cl,
                "method": primary.label,
                "parameters": dict(zip(cl_names, primary.theta.tolist(), strict=True)),
                "std": dict(zip(cl_names, np.sqrt(np.diag(primary.covariance)).tolist(),
                                strict=True)),
                "status": cl.status,
            },
            "covariance": cov_note,
            "consistent": not broken,
            "broken_assumptions": broken,
            **refined,
        },
        residual_function=residuals,
        model_function=model_at,
    )


@dataclass(frozen=True, eq=False)
class _Step1:
    """A closed-loop fit r → y with its parameters in (b…, f1…) order."""

    estimate: Estimate
    theta: NDArray[np.float64]
    covariance: NDArray[np.float64]
    note: str
    label: str


def _step1(
    data: Experiment | ExperimentSet,
    structure: Structure,
    orders: tuple[int, int, int],
    y_name: str,
    refine: bool,
    pem: dict[str, Any],
) -> list[_Step1]:
    """The closed-loop fits: the structure asked for, then IV as a second start."""
    nb_cl, nf_cl, nk_cl = orders
    fits: list[_Step1] = []
    errors: list[Exception] = []
    arx_order = np.concatenate([np.arange(nf_cl, nf_cl + nb_cl), np.arange(nf_cl)])
    if structure == "oe":
        try:
            with warnings.catch_warnings():
                if refine:  # the refinement finishes the search; its own status counts
                    warnings.filterwarnings("ignore", ".*stopped at max_iter", ServoidWarning)
                # the OE fit's own covariance is already the coloured-noise sandwich
                cl = fit_oe(data, nb_cl, nf_cl, nk_cl, input="r", output=y_name,
                            covariance="robust", **pem)
            ar = cl.options["covariance_ar_order"]
            fits.append(_Step1(cl, np.asarray(cl.parameters), cl.covariance,
                               f"sandwich, AR({ar}) residual spectrum", "oe"))
        except (ConvergenceError, IdentifiabilityError) as exc:
            if not refine:
                raise
            errors.append(exc)
    else:
        cl = fit_arx(data, nf_cl, nb_cl, nk_cl, input="r", output=y_name)
        fits.append(_Step1(cl, np.asarray(cl.parameters)[arx_order],
                           cl.covariance[np.ix_(arx_order, arx_order)],
                           "least squares (white equation error assumed)", "arx"))
    if not refine:
        return fits
    # IV from r (exogenous for the closed loop) is consistent and has no local minima: a
    # second start for the refinement when the free closed-loop search stopped in a valley
    try:
        iv = fit_iv(data, nf_cl, nb_cl, nk_cl, input="r", output=y_name)
        fits.append(_Step1(iv, np.asarray(iv.parameters)[arx_order],
                           iv.covariance[np.ix_(arx_order, arx_order)], "iv", "iv"))
    except (ConvergenceError, IdentifiabilityError) as exc:
        errors.append(exc)
    if not fits:
        raise errors[0]
    return fits


def _cliv_point(
    data: Experiment | ExperimentSet, segments: tuple[Experiment, ...], nb: int, nf: int,
    nk: int, y_name: str,
) -> list[tuple[str, NDArray[np.float64]]]:
    """The closed-loop IV estimate of the same plant as (b…, f1…), when u is recorded.

    It is consistent whatever the controller, so the intervals of the indirect estimate
    claim to hold it: their covariance must not change there either.
    """
    if nf == 0 or len(segments[0].names_of("u")) != 1:
        return []
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            iv = fit_iv(data, nf, nb, nk, instrument="r", output=y_name)
    except (ServoidError, np.linalg.LinAlgError):
        return []
    p = np.asarray(iv.parameters, dtype=float)
    return [("the closed-loop IV estimate of the same plant", np.concatenate([p[nf:], p[:nf]]))]


class _Refinement:
    """Output error on the closed loop, parameterised by the plant (one-step indirect)."""

    def __init__(self, loop_map: _ClosedLoopMap, rs: list[NDArray[np.float64]],
                 ys: list[NDArray[np.float64]]) -> None:
        self.map = loop_map
        self.orders = loop_map.orders
        n = loop_map.nb + loop_map.nf
        self.h = loop_map.closed_loop(np.zeros(n), self.orders)
        self.big_h = np.column_stack([loop_map.closed_loop(e, self.orders) - self.h
                                      for e in np.eye(n)])
        self.rs, self.ys = rs, ys

    def evaluate(
        self, theta: NDArray[np.float64]
    ) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]] | None:
        """Residuals and ψ = ∂ŷ/∂θ per segment, or None if the simulation diverges.

        A slightly unstable closed loop is simulated as it is: over a finite
        record its error is merely large, so the search can walk back to
        stability (a start from a noisy closed-loop fit may sit just outside).
        """
        nb_cl, _, nk_cl = self.orders
        theta_cl = self.h + self.big_h @ theta
        fcl = np.concatenate([[1.0], theta_cl[nb_cl:]])
        errors, psis = [], []
        with np.errstate(all="ignore"):
            for r, y in zip(self.rs, self.ys, strict=True):
                yhat, psi = oe_gradient(theta_cl[:nb_cl], fcl, nk_cl, r)
                if not (np.all(np.isfinite(yhat)) and np.all(np.isfinite(psi))):
                    return None
                errors.append(y - yhat)
                psis.append(psi @ self.big_h)
            if not np.isfinite(sum(float(e @ e) for e in errors)):
                return None
            # a closed loop just outside stability grows; past ~1e150 its Gram matrix
            # overflows, and a LAPACK solve on inf never returns
            if not all(np.isfinite(np.einsum("ij,ij->", p, p)) for p in psis):
                return None
        return errors, psis

    def run(
        self, theta: NDArray[np.float64], max_iter: int, tol: float
    ) -> tuple[NDArray[np.float64], list[NDArray[np.float64]], int, bool]:
        """Levenberg–Marquardt from θ; return θ̂, residuals, steps and convergence."""
        state = self.evaluate(theta)
        if state is None:
            raise ConvergenceError(
                "the closed loop simulated from the start of the indirect refinement diverges: "
                "the closed-loop fit is poor; check the orders and the controller, or pass "
                "refine=False"
            )
        errors, psis = state
        cost = sum(float(e @ e) for e in errors)
        floor = 1e-28 * sum(float(y @ y) for y in self.ys)
        lam = 1e-3
        for it in range(1, max_iter + 1):
            grad = sum(p.T @ e for p, e in zip(psis, errors, strict=True))
            hess = sum(p.T @ p for p in psis)
            diag = np.diag(np.diag(hess) + 1e-300)
            for _ in range(_MAX_DAMPING):
                step = np.linalg.lstsq(hess + lam * diag, grad, rcond=None)[0]
                trial = self.evaluate(theta + step)
                new = (np.inf if trial is None
                       else sum(float(e @ e) for e in trial[0]))
                if new < cost:
                    break
                lam *= 10.0
            else:
                return theta, errors, it, True  # no damped step lowers the cost: a minimum
            decrease = cost - new
            theta = theta + step
            errors, psis = trial  # type: ignore[misc]
            cost = new
            lam = max(lam / 10.0, 1e-12)
            if decrease <= tol * cost or cost <= floor:
                return theta, errors, it, True
        return theta, errors, max_iter, False

    def covariance(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
        """Coloured-noise sandwich covariance at θ."""
        state = self.evaluate(theta)
        assert state is not None
        errors, psis = state
        return sandwich(psis, errors)

    def covariance_or_none(self, theta: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The covariance at θ, or None where the closed loop cannot be simulated."""
        nb_cl = self.orders[0]
        fcl = np.concatenate([[1.0], (self.h + self.big_h @ theta)[nb_cl:]])
        # an unstable closed loop is not one the interval can describe
        if np.max(np.abs(np.roots(fcl)), initial=0.0) >= 1.0 or self.evaluate(theta) is None:
            return None
        return self.covariance(theta)[0]


class _ClosedLoopMap:
    """The affine map θ ↦ θ_cl from plant to closed-loop parameters."""

    def __init__(self, cn: NDArray[np.float64], cd: NDArray[np.float64],
                 fn: NDArray[np.float64], fd: NDArray[np.float64],
                 nb: int, nf: int, nk: int) -> None:
        self.kn = np.convolve(cn, fd)  # Bcl = q^(−nk)·B·kn
        self.kd = np.convolve(cd, fd)  # Fcl = Fp·kd + q^(−nk)·B·ke
        self.ke = np.convolve(cn, fn)
        self.nb, self.nf, self.nk = nb, nf, nk
        bcl, fcl = self._polynomials(np.zeros(nb + nf), nonzero=True)
        lead = int(np.flatnonzero(bcl)[0])
        last_b = int(np.flatnonzero(bcl)[-1])
        last_f = int(np.flatnonzero(fcl)[-1])
        #: (nb, nf, nk) of the closed loop this plant makes in this loop
        self.orders = (last_b - lead + 1, last_f, lead)

    def _polynomials(
        self, theta: NDArray[np.float64], nonzero: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        # with nonzero=True every coefficient is 1, which exposes the generic support
        b = np.ones(self.nb) if nonzero else theta[: self.nb]
        f = np.concatenate([[1.0], np.ones(self.nf) if nonzero else theta[self.nb:]])
        if nonzero:
            kn, kd, ke = (np.abs(k) + (k != 0) for k in (self.kn, self.kd, self.ke))
        else:
            kn, kd, ke = self.kn, self.kd, self.ke
        bq = np.concatenate([np.zeros(self.nk), b])
        return np.convolve(bq, kn), _add(np.convolve(f, kd), np.convolve(bq, ke))

    def closed_loop(self, theta: NDArray[np.float64],
                    orders: tuple[int, int, int]) -> NDArray[np.float64]:
        """Closed-loop parameters (b…, f1…) of the given orders."""
        nb_cl, nf_cl, nk_cl = orders
        bcl, fcl = self._polynomials(theta)
        b = np.zeros(nb_cl)
        part = bcl[nk_cl: nk_cl + nb_cl]
        b[: part.size] = part
        f = np.zeros(nf_cl)
        part = fcl[1: nf_cl + 1]
        f[: part.size] = part
        return np.concatenate([b, f])

    def project(
        self, theta_cl: NDArray[np.float64], cov_cl: NDArray[np.float64],
        orders: tuple[int, int, int],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Markov estimate of θ from θ̂_cl and its covariance."""
        n = self.nb + self.nf
        h = self.closed_loop(np.zeros(n), orders)
        # affine: unit steps give the matrix exactly
        big_h = np.column_stack([self.closed_loop(e, orders) - h for e in np.eye(n)])
        eig, vec = np.linalg.eigh(0.5 * (cov_cl + cov_cl.T))
        keep = eig > eig[-1] * 1e-14
        whiten = vec[:, keep].T / np.sqrt(eig[keep])[:, None]  # W with Wᵀ W = P_cl⁺
        a = whiten @ big_h
        theta = np.linalg.lstsq(a, whiten @ (theta_cl - h), rcond=None)[0]
        info = np.linalg.pinv(a.T @ a)
        return theta, 0.5 * (info + info.T)


def _add(p: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.zeros(max(p.size, q.size))
    out[: p.size] += p
    out[: q.size] += q
    return out


def _other_discretisations(
    data: Experiment | ExperimentSet, design: TransferFunction, used: str, nb: int, nf: int,
    nk: int, options: dict[str, Any],
) -> dict[str, NDArray[np.float64]]:
    """The plant fitted with each other discretisation of a continuous controller."""
    dt = as_segments(data)[0].dt
    out = {}
    for method in DISCRETISATIONS:
        if method == used:
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ServoidWarning)
                alt = fit_indirect_tf(data, c2d(design, dt, method), nb, nf, nk, **options)
        except ServoidError:
            continue
        out[method] = np.asarray(alt.parameters, dtype=float)
    return out


def _q_polynomials(
    name: str, value: TransferFunction | float, dt: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and monic denominator of a discrete TF (or gain) in q⁻¹."""
    if isinstance(value, TransferFunction):
        if value.dt is None:
            raise ModelError(
                f"the {name} is continuous; the indirect approach needs it as it ran in the "
                f"digital loop: discretise it at the data dt = {dt} s with c2d({name}, {dt}, "
                "method) using the method it was implemented with (zoh or tustin)"
            )
        if value.dt < dt * (1 - 1e-9):
            raise ModelError(
                f"the {name} ran every {value.dt:g} s, faster than the record's {dt:g} s: the "
                "loop acted between the recorded samples, so no loop at the record's rate holds "
                "the data and the indirect approach cannot be consistent on them. Record at the "
                f"{name}'s rate, or identify without the {name}: method = \"cliv\" or "
                "\"two-stage\" need only the reference (\"closedloop-auto\" picks)"
            )
        if not math.isclose(value.dt, dt, rel_tol=1e-9):
            raise ModelError(
                f"the {name} is discrete with dt = {value.dt} s but the data have dt = {dt} s; "
                f"give the {name} at the data rate (d2c then c2d at {dt} s, or resample the "
                "record to the controller's rate)"
            )
        den = np.asarray(value.den, dtype=float)
        num = np.concatenate([np.zeros(den.size - value.num.size), value.num])
        num = np.trim_zeros(num, "b") if np.any(num) else np.zeros(1)
        den = np.trim_zeros(den, "b")
        return num / den[0], den / den[0]
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise type_error(name, value, "a discrete TransferFunction or a number")
    gain = float(value)
    if not math.isfinite(gain):
        raise ModelError(f"the {name} gain must be finite, got {gain}")
    return np.array([gain]), np.ones(1)
