"""Prediction-error methods: OE, ARMAX, Box–Jenkins and the general structure.

``A(q) y(t) = Σ_i B_i(q)/F_i(q) u_i(t − nk_i) + C(q)/D(q) e(t)`` is fitted
by minimising ``Σ ε(t)²``, the one-step prediction errors ``ε = (D/C)(A y −
Σ B_i/F_i u_i)`` (Ljung, *System Identification*, 2nd ed., ch. 7 and 10).

The search
----------
* **Start**: a consistent estimate from instrumental variables and
  Hannan–Rissanen (:mod:`servoid.estimate._pem_start`), a model or vector
  you give (``init``), plus ``multistart`` random stable starts.  For
  output error with one input the IV start competes with Steiglitz–McBride
  iterates: all are scored by their simulation cost (on at most 20 000
  samples per segment) and the search runs from the best — on short
  records also from the next two, keeping the lowest minimum.
* **Initial values** (``initial="auto"``, default): after the search from
  zero initial conditions, estimated ones are tried when the slowest
  predictor pole rings over more than 1 % of a segment, and kept when
  they lower the cost by a margin (see :func:`_auto_initial`).
* **Steps**: Gauss–Newton on the exact gradient ψ = −∂ε/∂θ, formed by
  filtering the data (:mod:`servoid.estimate._pem_predictor`; no finite
  differences), damped Levenberg–Marquardt style (λ·diag(ΨᵀΨ)) whenever a
  full step does not lower the cost (:mod:`servoid.estimate._pem_search`).
* **Stability**: a full Gauss–Newton step that carries a root of F_i, C
  or D out of the unit circle is first halved until it stays inside;
  otherwise the root is reflected to 1/conj(z), as MATLAB's System
  Identification Toolbox does; C and D then describe the same noise spectrum, F a different (stable)
  system from which the search continues.  Every reflection is counted in
  ``options["reflected"]`` and named in ``status``.
* **Stop**: when the Gauss–Newton step would lower the cost by less than
  ``tol`` relative (or change the predictions by less than 1e-12 of the
  output's RMS); at ``max_iter`` steps with a :class:`ServoidWarning`.
* **Covariance** (``covariance=``, :mod:`servoid.estimate._covariance`):
  ``"white"`` is ``σ̂² (ΨᵀΨ)⁻¹`` at the minimum with the exact Ψ and
  ``σ̂² = Σε²/(N − d)`` (Ljung §9.3), right when the prediction errors are
  white; ``"robust"`` is the sandwich ``(ΨᵀΨ)⁻¹ Ψᵀ R̂_ε Ψ (ΨᵀΨ)⁻¹`` with the
  residuals' autocovariance (an AR model chosen by AIC), right for output
  error with coloured noise; ``"auto"`` (default) takes ``"robust"`` when
  na = nc = nd = 0 and ``"white"`` otherwise.  With estimated initial
  values ΨᵀΨ is the Schur complement that accounts for them (see the
  predictor module).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_generator, as_int
from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionTypeError,
    ServoidWarning,
    check_option,
)
from .._warn import warn
from ..data import Experiment, ExperimentSet
from ..models import PolynomialModel
from ._arx import _warn_if_unstable
from ._cancel import cancellation_notes
from ._covariance import COVARIANCES, Covariance, parameter_covariance, resolve
from ._diagnostics import MAX_STARTS
from ._estimate import Estimate
from ._oe_kernel import StreamProblem
from ._pem_orders import PemOrders, Polys, SignalData, check_record, prepare
from ._pem_predictor import Problem, initial_sizes
from ._pem_search import ADVICE, Search, search
from ._pem_start import iv_start, random_start, sm_starts, stabilize

__all__ = ["fit_armax", "fit_bj", "fit_oe", "fit_pem"]

Initial = Literal["auto", "zero", "estimate"]
InputRole = Literal["u", "r"]
Init = PolynomialModel | ArrayLike | None

#: The search has converged when a step would change the predictions by less
#: than this fraction of the output's RMS (the floor of double-precision data).
_PREDICTION_FLOOR = 1e-12
#: Two starts reached "the same minimum" when their costs agree this closely.
_SAME_MINIMUM = 1e-6
#: Steiglitz–McBride iterates among the candidate starts of an output-error fit.
_SM_ITERATIONS = 4
#: Samples per segment on which the candidate starts are made and scored.
_SCORE_SAMPLES = 20_000
#: Records up to this many equations descend from the best few starts, not only the best.
_MULTI_DESCENT_ROWS = 20_000
#: ... and this many of them.
_DESCENTS = 3
#: ``initial="auto"`` considers estimating the initial values only when the slowest
#: predictor pole's transient (to 1 %) is longer than this share of a segment.
_TRANSIENT_SHARE = 0.01
#: ... and only when eliminating them lowers the cost by more than this share: coloured
#: noise on records from rest lowers it by 0.01–0.3 % by chance (tests/estimate/test_pem_start.py).
_TRANSIENT_COST = 0.02


def fit_pem(
    data: Experiment | ExperimentSet,
    *,
    na: int = 0,
    nb: int | Sequence[int],
    nc: int = 0,
    nd: int = 0,
    nf: int | Sequence[int] = 0,
    nk: int | Sequence[int] = 1,
    input: InputRole = "u",
    output: str | None = None,
    initial: Initial = "auto",
    init: Init = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    start: int = 0,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit the general polynomial model by prediction error.

    ``A y = Σ_i B_i/F_i u_i(t − nk_i) + C/D e``; :func:`fit_oe`,
    :func:`fit_armax` and :func:`fit_bj` are this with some orders zero.
    See the module notes for the search, stability and covariance.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s); segments are never joined, each starts its own predictor.
    na, nc, nd : int
        Orders of A, C, D (coefficients after the leading 1), >= 0.
    nb : int or sequence of int
        Number of B coefficients per input, >= 1.
    nf : int or sequence of int
        Order of F per input, >= 0.
    nk : int or sequence of int
        Input delay per input [samples], >= 0.
    input : {"u", "r"}
        Role of the input channels (``"r"``: the reference, for a model from r to y).
    output : str, optional
        Output channel when there are several.
    initial : {"auto", "zero", "estimate"}
        Initial conditions of the predictor filters: zero (the record starts
        at rest), or estimated — eliminated by linear least squares at every
        step (variable projection), which removes the start-up transient of
        a record that does not start at rest.  ``"auto"`` (default) searches
        from zero, then estimates them when the model's slowest pole leaves
        a transient longer than 1 % of a segment and Akaike's criterion
        says they lower the cost by more than their number explains (a
        lightly damped system on a short record); long records and fast
        poles stay on the streamed zero-start search.
    init : PolynomialModel or array_like, optional
        Start of the search instead of the IV start: a model with these
        orders, or θ in the order of the returned ``names``.
    multistart : int
        Extra random stable starts, >= 0; the lowest cost wins.
    rng : numpy.random.Generator or int, optional
        Source of the random starts (a seed for reproducibility).
    max_iter : int
        Most Gauss–Newton steps per start, >= 0.
    tol : float
        Relative cost decrease below which a step is not worth taking, in (0, 1).
    start : int
        First sample of each segment whose prediction error enters the cost
        (the predictors still run from sample 0); a common start makes fits
        of different orders comparable.
    covariance : {"auto", "white", "robust"}
        Parameter covariance: ``"white"`` σ̂²(ΨᵀΨ)⁻¹, valid when the
        prediction errors are white; ``"robust"`` the sandwich with the
        residuals' autocovariance, valid for coloured noise independent of
        the input (output error); ``"auto"`` is ``"robust"`` when
        na = nc = nd = 0 and ``"white"`` otherwise.  See the module notes.

    Returns
    -------
    Estimate
        ``model`` is a :class:`~servoid.models.PolynomialModel`; parameters
        ``a1…``, per input ``b0…, f1…`` (``<input>:`` prefix with several
        inputs), ``c1…``, ``d1…``; ``model_function`` maps θ to the model;
        ``n_samples`` counts the prediction errors in the cost.  ``options``
        holds the orders (``nb``, ``nf``, ``nk`` as lists per input),
        ``input``, ``inputs``, ``output``, ``initial`` (``"zero"`` or
        ``"estimate"``, what was used), ``initial_requested``, ``iterations``,
        ``converged``, ``start`` (how the start values were made),
        ``reflected`` (roots reflected into the unit circle), ``first_sample``
        (the ``start`` keyword), ``cost`` (Σε²), ``initial_values`` (number
        eliminated), ``covariance`` (``"white"`` or ``"robust"``, what
        ``"auto"`` resolved to), ``covariance_ar_order`` (order of the
        residual AR model of the robust covariance, 0 when the residuals
        look white; None for ``"white"``) and, with ``multistart``, a
        ``multistart`` table: starts,
        how many reached the same minimum (cost within 1e-6), failures, the
        winner and every final cost.

    Raises
    ------
    DataError
        Orders too long for the record, bad option values, huge signal values.
    IdentifiabilityError
        A constant input.
    OptionError, OptionTypeError
        An unknown ``initial``/``input``/``covariance``, or an option of the
        wrong type.
    ConvergenceError
        The prediction errors overflow at the start, or the search cannot
        lower the cost although the gradient is not small.

    Notes
    -----
    Memory: about 3 N × 8 bytes beyond the record without C and D and
    with ``initial="zero"``: the prediction errors and their gradient are
    streamed (:mod:`servoid.estimate._oe_kernel`), and what remains is the
    instrumental-variable start and the residuals of the robust covariance.
    A noise model (C, D) or ``initial="estimate"`` runs the buffered
    predictor instead: about (10 + 4·n_inputs) N × 8 bytes of padded
    signals, kept for the whole search.
    """
    return _fit(data, na, nb, nc, nd, nf, nk, "pem", input=input, output=output,
                initial=initial, init=init, multistart=multistart, rng=rng,
                max_iter=max_iter, tol=tol, start=start, covariance=covariance)


def fit_oe(
    data: Experiment | ExperimentSet,
    nb: int | Sequence[int],
    nf: int | Sequence[int],
    nk: int | Sequence[int] = 1,
    *,
    input: InputRole = "u",
    output: str | None = None,
    initial: Initial = "auto",
    init: Init = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    start: int = 0,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit an output-error model ``y = Σ B_i/F_i u_i + e``.

    The prediction error is the simulation error, so the fit is the best
    simulation of the output; no noise model is estimated.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s).
    nb : int or sequence of int
        Number of B coefficients per input.
    nf : int or sequence of int
        Order of F per input.
    nk : int or sequence of int
        Input delay per input [samples].
    input, output, initial, init, multistart, rng, max_iter, tol, start, covariance
        As in :func:`fit_pem` (``"auto"`` covariance: ``"robust"``).

    Returns
    -------
    Estimate
        Method ``"oe"``; parameters per input ``b0…, f1…``.

    Notes
    -----
    Memory: about 3 N × 8 bytes beyond the record (``initial="zero"``:
    streamed passes; see :func:`fit_pem`).  Time is linear in N.
    """
    return _fit(data, 0, nb, 0, 0, nf, nk, "oe", input=input, output=output,
                initial=initial, init=init, multistart=multistart, rng=rng,
                max_iter=max_iter, tol=tol, start=start, covariance=covariance)


def fit_armax(
    data: Experiment | ExperimentSet,
    na: int,
    nb: int | Sequence[int],
    nc: int,
    nk: int | Sequence[int] = 1,
    *,
    input: InputRole = "u",
    output: str | None = None,
    initial: Initial = "auto",
    init: Init = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    start: int = 0,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit an ARMAX model ``A y = Σ B_i u_i + C e``.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s).
    na : int
        Order of A.
    nb : int or sequence of int
        Number of B coefficients per input.
    nc : int
        Order of C.
    nk : int or sequence of int
        Input delay per input [samples].
    input, output, initial, init, multistart, rng, max_iter, tol, start, covariance
        As in :func:`fit_pem` (``"auto"`` covariance: ``"white"``).

    Returns
    -------
    Estimate
        Method ``"armax"``; parameters ``a1…, b0…, c1…``.
    """
    return _fit(data, na, nb, nc, 0, 0, nk, "armax", input=input, output=output,
                initial=initial, init=init, multistart=multistart, rng=rng,
                max_iter=max_iter, tol=tol, start=start, covariance=covariance)


def fit_bj(
    data: Experiment | ExperimentSet,
    nb: int | Sequence[int],
    nc: int,
    nd: int,
    nf: int | Sequence[int],
    nk: int | Sequence[int] = 1,
    *,
    input: InputRole = "u",
    output: str | None = None,
    initial: Initial = "auto",
    init: Init = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    start: int = 0,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit a Box–Jenkins model ``y = Σ B_i/F_i u_i + C/D e``.

    The plant and the noise have their own dynamics; with a noise model
    this is also the direct method for closed-loop data.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s).
    nb : int or sequence of int
        Number of B coefficients per input.
    nc, nd : int
        Orders of the noise numerator C and denominator D.
    nf : int or sequence of int
        Order of F per input.
    nk : int or sequence of int
        Input delay per input [samples].
    input, output, initial, init, multistart, rng, max_iter, tol, start, covariance
        As in :func:`fit_pem` (``"auto"`` covariance: ``"white"``, ``"robust"`` if nc = nd = 0).

    Returns
    -------
    Estimate
        Method ``"bj"``; parameters per input ``b0…, f1…``, then ``c1…, d1…``.
    """
    return _fit(data, 0, nb, nc, nd, nf, nk, "bj", input=input, output=output,
                initial=initial, init=init, multistart=multistart, rng=rng,
                max_iter=max_iter, tol=tol, start=start, covariance=covariance)


def _fit(
    data: Experiment | ExperimentSet,
    na: Any, nb: Any, nc: Any, nd: Any, nf: Any, nk: Any,
    method: str,
    *,
    input: InputRole,
    output: str | None,
    initial: Initial,
    init: Init,
    multistart: int,
    rng: np.random.Generator | int | None,
    max_iter: int,
    tol: float,
    start: int,
    covariance: Covariance,
) -> Estimate:
    check_option("initial", initial, ("auto", "zero", "estimate"))
    check_option("covariance", covariance, COVARIANCES)
    max_iter = as_int("max_iter", max_iter, minimum=0)
    multistart = as_int("multistart", multistart, minimum=0)
    if multistart > MAX_STARTS:  # each start is a full fit
        raise DataError(f"multistart must be <= {MAX_STARTS} extra starts, got {multistart}")
    start = as_int("start", start, minimum=0)
    tol = as_float("tol", tol, positive=True)
    if not tol < 1:
        raise DataError(f"tol is a relative cost decrease and must lie in (0, 1), got {tol:g}")
    sd = prepare(data, input, output)
    orders = PemOrders(na, nb, nc, nd, nf, nk, len(sd.inputs))
    cov_kind = resolve(covariance, noise_model=bool(orders.na or orders.nc or orders.nd))
    estimate_ic = initial == "estimate"
    n_ic = sum(initial_sizes(orders)[1]) + initial_sizes(orders)[0] if estimate_ic else 0
    n_par = orders.n_parameters
    label = repr(orders) + (f" with {n_ic} initial values per segment" if n_ic else "")
    n_rows = check_record(label, n_par + n_ic * len(sd.y), sd, start, orders.max_lag)
    names = orders.names(sd.inputs)
    problem = _problem(orders, sd, start, estimate_ic)
    floor = n_rows * (_PREDICTION_FLOOR * sd.y_rms) ** 2

    others: list[NDArray[np.float64]] = []
    if init is None:
        theta0, how = _default_start(orders, sd, start, problem)
        theta0, how, others = _scored_starts(orders, sd, start, problem, theta0, how, n_rows)
    else:
        theta0, how = _user_start(init, orders, names), "user"
    theta0, reflected0 = stabilize(orders, theta0)
    generator = as_generator(rng) if multistart else None
    results: list[Search | None] = []
    failure: ConvergenceError | None = None
    for k in range(multistart + 1):
        if k == 0:
            theta_k = theta0
        else:
            assert generator is not None
            theta_k = random_start(orders, problem, generator)
        try:
            if k == 0 and others:
                found, won = _descents(problem, orders, theta_k, others, max_iter, tol, floor)
                results.append(found)
                if won:
                    how += (f"; the descent from the runner-up start {won} reached the lowest "
                            "cost")
            else:
                results.append(search(problem, orders, theta_k, max_iter, tol, floor))
        except ConvergenceError as exc:
            if not multistart:
                # advise only what is not already in use
                text = str(exc).replace(ADVICE, _advice(multistart, initial))
                if initial == "estimate":
                    text = text.replace("initial='estimate' or ", "")
                raise ConvergenceError(text) from None
            failure = failure or exc
            results.append(None)
    if all(r is None for r in results):
        raise ConvergenceError(f"every one of the {multistart + 1} starts failed; the first: "
                               f"{failure}")
    costs = [r.cost if r is not None else np.inf for r in results]
    k_best = int(np.argmin(costs))
    best = results[k_best]
    assert best is not None

    if initial == "auto":
        switched = _auto_initial(problem, orders, sd, start, best, max_iter, tol, floor)
        if switched is not None:
            problem, best, estimate_ic = switched[0], switched[1], True
    start_word = how if k_best == 0 else f"random start {k_best} of {multistart}"
    if initial == "auto" and estimate_ic:
        start_word += ("; then initial values estimated (auto: the record does not start at "
                       "rest)")
    n_ic_used = problem.ic_rank if estimate_ic else 0
    if estimate_ic:  # the rank of the eliminated initial values at the chosen θ
        problem.cost(best.theta)
        problem.normal_equations(best.theta)
        n_ic_used = problem.ic_rank
    dof = max(n_rows - n_par - n_ic_used, 1)
    sigma2 = best.cost / dof
    cov_result = parameter_covariance(problem, best.theta, best.h, sigma2, dof, cov_kind)
    cov, singular = cov_result.covariance, cov_result.singular
    reflected = best.reflected + (reflected0 if k_best == 0 else 0)
    status = _status(best, reflected, singular)
    if not best.converged:
        warn(
            f"the {method} search stopped at max_iter={max_iter} before converging; increase "
            f"max_iter, try {_advice(multistart, initial, tail=('check the orders',))}",
            ServoidWarning)
    if singular:
        warn(
            f"the {method} parameters are not all identifiable (singular information matrix: "
            "a pole–zero cancellation or a noise model without noise); the covariance uses a "
            "pseudo-inverse. Lower the orders",
            ServoidWarning)
    p = orders.split(best.theta)
    _warn_if_unstable(p.a)
    cancelled = cancellation_notes(orders, best.theta, cov, sd.inputs) if method == "oe" else []
    for note in cancelled:
        warn(f"the oe fit: {note}", ServoidWarning)
    same = sum(1 for c in costs if np.isfinite(c) and abs(c - best.cost) <= _SAME_MINIMUM
               * max(best.cost, floor))

    def model_at(theta: NDArray[np.float64]) -> PolynomialModel:
        return orders.model(theta, sd.dt, sigma2, sd.inputs, sd.output)

    theta_best = best.theta.copy()

    def residuals() -> NDArray[np.float64]:
        # a fresh predictor, so the estimate does not keep the search's buffers alive
        return _problem(orders, sd, start, estimate_ic).residuals(theta_best)

    options: dict[str, Any] = {
        **orders.as_options(),
        "input": input,
        "inputs": list(sd.inputs),
        "output": sd.output,
        "initial": "estimate" if estimate_ic else "zero",
        "initial_requested": initial,
        "iterations": best.iterations,
        "converged": best.converged,
        "start": start_word,
        "reflected": reflected,
        "first_sample": start,
        "segments": len(sd.y),
        "cost": best.cost,
        "initial_values": n_ic_used,
        "max_iter": max_iter,
        "tol": tol,
        "covariance": cov_result.kind,
        "covariance_ar_order": cov_result.ar_order,
    }
    if cancelled:
        options["cancellations"] = cancelled
    if multistart:
        options["multistart"] = {
            "starts": multistart + 1,
            "same_minimum": same,
            "failed": sum(r is None for r in results),
            "best": k_best,
            "costs": [float(c) if np.isfinite(c) else None for c in costs],
        }
    return Estimate(
        model=model_at(best.theta),
        parameters=best.theta,
        names=names,
        covariance=cov,
        noise_variance=sigma2,
        n_samples=n_rows,
        method=method,
        status=status,
        options=options,
        residual_function=residuals,
        model_function=model_at,
    )


def _scored_starts(orders: PemOrders, sd: SignalData, start: int,
                   problem: Problem | StreamProblem, theta0: NDArray[np.float64], how: str,
                   n_rows: int) -> tuple[NDArray[np.float64], str, list[NDArray[np.float64]]]:
    """The IV start and the Steiglitz–McBride iterates, ordered by simulation cost.

    The output-error criterion has local minima, and with lightly damped
    poles and coloured noise the IV start often lies in the basin of a
    worse one (tests/estimate/test_pem_start.py).  The candidates are
    scored by their cost Σε² — on the first :data:`_SCORE_SAMPLES`
    samples of each segment when the record is longer, so that the extra
    passes stay bounded at any N.  Returns the best start, its word, and
    the runners-up (empty when the record is long: one descent only).
    """
    candidates = sm_starts(orders, sd, start, _SM_ITERATIONS, _SCORE_SAMPLES)
    if not candidates:
        return theta0, how, []
    candidates = [stabilize(orders, theta0)[0], *(stabilize(orders, c)[0] for c in candidates)]
    words = [how, *(f"Steiglitz-McBride iterate {k + 1} from ARX"
                    for k in range(len(candidates) - 1))]
    scorer = problem
    if max(sd.lengths) > _SCORE_SAMPLES:
        short = SignalData(tuple(y[:_SCORE_SAMPLES] for y in sd.y),
                           tuple(tuple(x[:_SCORE_SAMPLES] for x in u) for u in sd.u),
                           sd.r, sd.inputs, sd.output, sd.references, sd.dt)
        scorer = _problem(orders, short, start, False)
    costs = np.array([scorer.cost(c) for c in candidates])
    costs[~np.isfinite(costs)] = np.inf
    order = [int(k) for k in np.argsort(costs, kind="stable") if np.isfinite(costs[k])]
    if not order:
        return theta0, how, []
    best = order[0]
    runners = [candidates[k] for k in order[1:_DESCENTS]] if n_rows <= _MULTI_DESCENT_ROWS else []
    word = words[best] + (f" (lowest simulation cost of {len(candidates)} starts: IV and "
                          "Steiglitz-McBride)")
    return candidates[best], word, runners


def _descents(problem: Problem | StreamProblem, orders: PemOrders, theta0: NDArray[np.float64],
              others: Sequence[NDArray[np.float64]], max_iter: int, tol: float,
              floor: float) -> tuple[Search, int]:
    """The search from the best start and the runners-up; the lowest final cost, its index."""
    found: list[tuple[bool, float, int, Search]] = []
    failure: ConvergenceError | None = None
    for k, theta in enumerate((theta0, *others)):
        try:
            r = search(problem, orders, theta, max_iter, tol, floor)
        except ConvergenceError as exc:
            failure = failure or exc
            continue
        found.append((not r.converged, r.cost, k, r))
    if not found:
        assert failure is not None
        raise failure
    best = min(found, key=lambda x: x[:3])
    return best[3], best[2]


def _auto_initial(problem: Problem | StreamProblem, orders: PemOrders, sd: SignalData,
                  start: int, best: Search, max_iter: int, tol: float,
                  floor: float) -> tuple[Problem, Search] | None:
    """The search again with estimated initial values, when they are worth it; else None.

    Two tests, the first free: the predictor's slowest pole (F_i, C; A
    acts on y directly) must leave a transient — to 1 % of its start —
    longer than :data:`_TRANSIENT_SHARE` of the shortest segment; then the
    cost with the initial values eliminated at the zero-start minimum, V₁,
    must beat the zero-start cost V₀ by more than their number explains
    (Schwarz's criterion, ``N ln(V₀/V₁) > n_ic ln N``; Akaike's 2 n_ic
    let coloured output noise through on records that start at rest) and
    by more than :data:`_TRANSIENT_COST` of it.  The search then continues from that
    minimum (Ljung, *System Identification*, 2nd ed., §10.4: unknown
    initial conditions as extra parameters).
    """
    p = orders.split(best.theta)
    radius = max([float(np.max(np.abs(np.roots(f)))) if f.size > 1 else 0.0
                  for f in (*p.f, p.c)] or [0.0])
    if not 0.0 < radius < 1.0:
        return None
    transient = np.log(0.01) / np.log(radius)
    if transient <= _TRANSIENT_SHARE * min(y.size for y in sd.y):
        return None
    n_ic = (sum(initial_sizes(orders)[1]) + initial_sizes(orders)[0]) * len(sd.y)
    try:
        check_record(repr(orders), orders.n_parameters + n_ic, sd, start, orders.max_lag)
    except DataError:
        return None
    fresh = Problem(orders, sd, start, True)
    rows = sd.rows(start)
    cost = fresh.cost(best.theta)
    drop = best.cost / max(cost, floor)
    if not (np.isfinite(cost) and drop > 1.0 / (1.0 - _TRANSIENT_COST)
            and rows * np.log(drop) > n_ic * np.log(rows)):
        return None
    try:
        return fresh, search(fresh, orders, best.theta, max_iter, tol, floor)
    except ConvergenceError:
        return None


def _problem(orders: PemOrders, sd: SignalData, start: int,
             estimate_ic: bool) -> Problem | StreamProblem:
    """The streamed pass for noise-free structures from rest, else the buffered predictor."""
    if StreamProblem.supports(orders, estimate_ic):
        return StreamProblem(orders, sd, start)
    return Problem(orders, sd, start, estimate_ic)


def _default_start(orders: PemOrders, sd: SignalData, start: int,
                   problem: Problem) -> tuple[NDArray[np.float64], str]:
    try:
        return iv_start(orders, sd, start)
    except (IdentifiabilityError, DataError) as exc:
        # e.g. more poles than the input excites: start from F = C = D = 1 and let the
        # damped search find its way (the information matrix will say what is not determined)
        theta = np.zeros(orders.n_parameters)
        a, bs, _, _, _ = orders.blocks()
        linear = np.concatenate([np.arange(a.start, a.stop),
                                 *(np.arange(s.start, s.stop) for s in bs)])
        problem.cost(theta)
        h, g = problem.normal_equations(theta)
        sub = h[np.ix_(linear, linear)]
        theta[linear] = np.linalg.lstsq(sub, g[linear], rcond=None)[0]
        return theta, f"least squares with F = C = D = 1 (the IV start failed: {exc})"


def _user_start(init: Init, orders: PemOrders, names: tuple[str, ...]) -> NDArray[np.float64]:
    if isinstance(init, PolynomialModel):
        got = (init.na, init.nb, init.nc, init.nd, init.nf, init.nk)
        want = (orders.na, orders.nb, orders.nc, orders.nd, orders.nf, orders.nk)
        if got != want:
            raise ModelError(
                f"init has orders (na, nb, nc, nd, nf, nk) = {got}, the fit asks for {want}; "
                "pass a model with the same orders or a parameter vector")
        return orders.join(Polys(np.asarray(init.a), tuple(init.b), tuple(init.f or ()),
                                 np.asarray(init.c), np.asarray(init.d)))
    if isinstance(init, (str, bytes)) or not isinstance(init, (Sequence, np.ndarray)):
        raise OptionTypeError(
            f"init must be a PolynomialModel or a parameter vector, got {type(init).__name__}")
    theta = as_array("init", init, finite=False)
    if theta.shape != (orders.n_parameters,):
        raise DataError(f"init must have {orders.n_parameters} values ({', '.join(names)}), "
                        f"got shape {theta.shape}")
    if not np.all(np.isfinite(theta)):
        raise DataError("init must be finite")
    return theta.copy()


def _advice(multistart: int, initial: str,
            tail: tuple[str, ...] = ("lower orders", "detrended data")) -> str:
    """The remedies for a stalled search, without the ones the fit already used."""
    parts = [*(() if multistart else ("multistart=5",)),
             *(() if initial == "estimate" else ("initial='estimate'",)), *tail]
    return ", ".join(parts[:-1]) + " or " + parts[-1] if len(parts) > 1 else parts[0]


def _status(best: Search, reflected: int, singular: bool) -> str:
    parts = []
    if not best.converged:
        parts.append(f"stopped at max_iter after {best.iterations} steps, not converged")
    if best.note:
        parts.append(best.note)
    if reflected:
        parts.append(f"reflected {reflected} root(s) of F/C/D from outside the unit circle to "
                     "1/conj(z) to keep the predictor stable")
    if singular:
        parts.append("singular information matrix: covariance from a pseudo-inverse")
    return "; ".join(parts) if parts else "ok"
