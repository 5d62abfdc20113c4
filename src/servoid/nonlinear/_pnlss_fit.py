"""Fitting a PNLSS model: a linear start, then Levenberg–Marquardt on the simulation error.

The linear start is a discrete state-space model: the caller's
(``initial``: e.g. the best linear approximation turned into state space)
or n4sid's on the same records (``linear = "n4sid"``), or an OE model
turned into state space (``linear = "oe"``).  Its states are rescaled to
unit variance over the record, so the monomials of the states are of order
one.  The search then fits A … F and each record's initial state together
on the squared simulation error, with the exact Jacobian from the compiled
sensitivity recursion (:mod:`._pnlss_kernel`); a step whose simulation
diverges, or that does not lower the cost, is rejected and the damping
raised.  A ridge term ``ridge·N·‖(E, F)‖²`` keeps unneeded nonlinear
coefficients near zero.

With ``held_out`` records, every accepted iterate is also run freely on
them (from an estimated initial state) and the search returns the iterate
with the lowest held-out RMS error (early stopping): the linear start is
the first candidate, then the linear stage's iterates, then those of the
full model, so the result is never worse there than its linear start, and
an iterate that diverges there is never returned.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int, as_str, type_error
from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    ServoidWarning,
    check_option,
)
from ..data import Experiment, ExperimentSet
from ..estimate import Estimate, output_name
from ._pnlss import MONOMIALS, Monomials, PnlssModel, exponents
from ._pnlss_kernel import jacobian_block, record_start, simulate
from ._pnlss_prune import prune_monomials as _prune
from ._pnlss_weight import (
    PeriodicWeights,
    periodic_weights,
    weighted_cost,
    weighted_normal_equations,
)

__all__ = ["LINEAR_STARTS", "WEIGHTINGS", "fit_pnlss"]

#: Where the linear start comes from when no ``initial`` model is given.
LINEAR_STARTS = ("n4sid", "oe")

#: How the simulation error is weighted: not at all, or per DFT line by 1/σ²_Y (periodic data).
WEIGHTINGS = ("none", "bla")

#: Samples per block of the Jacobian: JᵀJ and Jᵀr are summed block by block, so memory is
#: BLOCK × parameters, not N × parameters.
BLOCK = 4096

#: Accepted iterations without a lower held-out error after which a stage stops early.
PATIENCE = 10
#: Gauss–Newton iterations on the initial states alone when ``max_iter = 0`` (the model kept).
X0_ITERATIONS = 20

Record = tuple[NDArray[np.float64], NDArray[np.float64]]  # (u (N, nu), y (N,))


def fit_pnlss(
    data: Experiment | ExperimentSet,
    n_states: int = 2,
    degree: int = 3,
    *,
    monomials: Monomials = "full",
    initial: Any = None,
    linear: Literal["n4sid", "oe"] = "n4sid",
    ridge: float = 0.0,
    prune: float = 0.0,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
    held_out: Experiment | ExperimentSet | None = None,
    offset: float | Literal["start"] | None = None,
    weighting: Literal["none", "bla"] | None = None,
    plan: Any = None,
) -> Estimate:
    """Fit a PNLSS model by simulation error (Levenberg–Marquardt).

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the input(s) of role `input` and the output; each
        record gets its own initial state.
    n_states : int
        Number of states (ignored with `initial`, whose order is used).
    degree : int
        Highest degree of the monomials (1: the linear model refined by
        output error; 2 … 6 otherwise).
    monomials : {"full", "state", "input"}
        Products of states and inputs, of states alone, or of inputs alone.
    initial : StateSpace or Estimate, optional
        The linear start: a discrete state-space model (or an Estimate of
        one) at the records' sample period, e.g. the best linear
        approximation from a frequency-domain fit turned into state space.
        Default: n4sid (or OE) on the same records.
    linear : {"n4sid", "oe"}
        The linear start's method when `initial` is not given.
    ridge : float
        Weight α ≥ 0 of the penalty α·N·‖(E, F)‖² on the normalised
        coefficients (0: none).
    prune : float
        Significance level α of the pruning (0: none, else 0 < α < 1): a
        monomial whose coefficients (its column of E and its entry of F)
        the Wald test cannot tell from zero at level α is removed (fixed at
        0) and the rest refitted, in rounds until none is removed.  The
        removed monomials are ``options["pruned"]``.
    input : {"u", "r"}
        Role of the input channel(s).
    output : str, optional
        The output channel when there are several.
    max_iter : int
        Most Levenberg–Marquardt iterations (Jacobian evaluations).  0 keeps the
        start as it is and fits only the records' initial states (the cost and
        covariance then describe the given model, not its start-up from x = 0).
    tol : float
        Relative decrease of the cost below which the search stops.
    held_out : Experiment or ExperimentSet, optional
        Records not fitted, on which each accepted iterate's free run
        (initial state estimated) is scored: the search returns the
        iterate with the lowest held-out RMS error, starting with the
        linear start itself, so never one worse there than the start or
        than the best linear iterate (E = F = 0), and never one that
        diverges there; a stage stops after :data:`PATIENCE` iterations
        without a lower held-out error.  ``options["held_out"]`` says which
        was kept and why.
    offset : float or "start", optional
        The output offset (the model's ``y_mean``) [output unit], fixed; ``"start"``:
        G(1)·ū of the linear start (a model fitted with no offset of its own reads so on
        centred inputs; the output's mean when G(1) is not finite or puts it more than 10
        output standard deviations away).  Default the output's mean (with `held_out` and a
        fitted start also G(1)·ū: the better there).
    weighting : {"none", "bla"}, optional
        ``"bla"``: the squared simulation error of each whole period of
        a multisine test, line by line of its DFT, weighted by 1/σ̂²_Y(k),
        the output's noise variance from the spread over periods (as in
        :func:`servoid.frequency.estimate_bla`), on every line; the records
        must follow `plan` from their first sample, with at least two
        measured periods in a realisation.  None or ``"none"``: the plain
        squared simulation error over every sample.
        ``options["weighting_info"]`` gives the periods, the smoothing
        and the range of the weights.
    plan : MultisinePlan, optional
        The multisine test's plan, for ``weighting = "bla"``.

    Returns
    -------
    Estimate
        Method ``"pnlss"``; model a :class:`PnlssModel`; parameters A, B,
        C, D, E, F on the normalised signals (:attr:`PnlssModel.names`);
        covariance σ̂²·(JᵀJ + ridge)⁻¹ of those, the initial states
        marginalised; residuals the simulation errors [output unit];
        options with the costs, iterations, rejected steps, each record's
        initial state and the linear start (``linear_start``: A, B, C, D
        in the data's units).

    Raises
    ------
    DataError
        Fewer samples than parameters, non-finite samples, a linear start
        of the wrong shape or sample period; with ``weighting = "bla"`` no
        plan, or fewer than two measured periods per realisation.
    IdentifiabilityError
        A constant input.
    ConvergenceError
        The linear start's own simulation diverges (an unstable start).
    """
    check_option("monomials", monomials, MONOMIALS)
    check_option("linear", linear, LINEAR_STARTS)
    check_option("input", input, ("u", "r"))
    weighting = "none" if weighting is None else weighting
    check_option("weighting", weighting, WEIGHTINGS)
    n_states = as_int("n_states", n_states, minimum=1, maximum=20)
    degree = as_int("degree", degree, minimum=1, maximum=6)
    ridge = as_float("ridge", ridge, nonneg=True)
    prune = as_float("prune", prune, nonneg=True)
    if prune >= 1:
        raise OptionError(f"prune is a significance level: 0 (no pruning) or between 0 and 1, "
                          f"e.g. 0.01; got {prune:g}")
    max_iter = as_int("max_iter", max_iter, minimum=0)
    tol = as_float("tol", tol, positive=True)
    records, names = _records(data, input, output)
    dt = float(data.dt)
    nu = records[0][0].shape[1]
    u_all = np.concatenate([u for u, _ in records])
    y_all = np.concatenate([y for _, y in records])
    u_mean, u_scale = u_all.mean(axis=0), u_all.std(axis=0)
    y_mean, y_scale = float(y_all.mean()), float(y_all.std()) or 1.0
    if np.any(u_scale == 0):
        raise IdentifiabilityError(f"an input of {', '.join(names['inputs'])} is constant: it "
                                   "excites nothing; excite the system with a multisine, PRBS "
                                   "or chirp")
    weights = (periodic_weights([y for _, y in records], dt, plan) if weighting == "bla"
               else None)
    if weights is not None:
        y_all = np.concatenate([y[s:s + weights.period] for (_, y), starts
                                in zip(records, weights.starts, strict=True) for s in starts])
    held = None
    if held_out is not None:
        held = _held_records(held_out, input, output, names, dt)
    if initial is None:
        _check_size(n_states, nu, degree, monomials, len(records), y_all.size)
    start = _linear_start(data, initial, linear, n_states, input, output, dt, nu,
                          (u_mean, u_scale, y_mean, y_scale))
    nx = start[0].shape[0]
    powers = exponents(nx, nu, degree, monomials)
    nm = powers.shape[0]
    n_total = y_all.size
    n_free = _check_size(nx, nu, degree, monomials, len(records), n_total)
    normal_u = [(u - u_mean) / u_scale for u, _ in records]
    A, B, C, D = _balanced(*start, normal_u)

    def setup(offset: float) -> _Search:
        """The search with the output offset `offset` (the model's y_mean)."""
        model = PnlssModel(A, B, C, D, np.zeros((nx, nm)), np.zeros(nm), powers, dt,
                           u_mean=u_mean, u_scale=u_scale, y_mean=offset, y_scale=y_scale,
                           monomials=monomials, input_names=tuple(names["inputs"]),
                           output_name=names["output"],
                           input_units=tuple(names["input_units"]),
                           output_unit=names["output_unit"])
        normal = [(un, (y - offset) / y_scale) for un, (_, y) in zip(normal_u, records,
                                                                      strict=True)]
        return _Search(model, normal, ridge, held, weights)

    if isinstance(offset, str) and offset != "start":
        raise OptionError(f'offset = {offset!r}: give a number [output unit], "start" (G(1)·ū '
                          "of the linear start) or None (the output's mean)")
    search = setup(y_mean if offset is None else
                   _offset(start, u_mean, u_scale, y_mean, y_scale) if offset == "start" else
                   as_float("offset", offset))
    theta, x0s, info = search.run(max_iter, tol)
    offset_rule = ("the output's mean" if offset is None else
                   "G(1)·ū, the linear start's own" if offset == "start" else "given")
    if held is not None and initial is None and offset is None:
        # the start fitted on the records as they are (no offset) is E = F = 0 only with the
        # offset G(1)·ū; the output's mean is the other natural one (a static nonlinearity
        # shifts the mean): the whole search runs from both, the better on held-out kept
        offset = _offset(start, u_mean, u_scale, y_mean, y_scale)
        if offset != y_mean:
            other = setup(offset)
            run = other.run(max_iter, tol)
            score = [s.best.score if s.best else np.inf for s in (search, other)]
            better = score[1] < score[0]
            rules = ("the output's mean", "G(1)·ū, the linear start's own")[::-1 if better else 1]
            offset_rule = (f"{rules[0]}: held-out RMS {min(score) * y_scale:.4g} against "
                           f"{max(score) * y_scale:.4g} from {rules[1].split(',')[0]}")
            if better:
                search, (theta, x0s, info) = other, run
    model = search.model
    fixed = np.zeros(0, dtype=np.int64)
    pruned: list[str] = []
    if prune > 0 and search.ef.size and np.any(theta[search.ef] != 0):
        before = (theta, x0s, search.held_rms(theta))
        theta, x0s, fixed, pruned = _prune(search, theta, x0s, prune, info, max_iter, tol)
        if held is not None and not search.held_rms(theta) <= before[2]:
            # pruning raised the held-out error: keep the model before it
            theta, x0s, _ = before
            fixed, pruned = np.zeros(0, dtype=np.int64), []
            info["held_out"]["why"] += "; pruning raised the held-out error and was undone"
    fitted = model.with_parameters(theta)
    n_model = model.n_parameters
    cov, r, _ = search.covariance(theta, x0s, fixed, n_free - fixed.size)
    sse = float(r @ r)
    sigma2 = sse / max(n_total - n_free + fixed.size, 1)  # normalised units
    noise = sigma2 * y_scale**2
    fitted = _with_covariance(fitted, cov, noise)
    resid = r * y_scale
    labels = fitted.names
    options = {
        "n_states": nx, "degree": degree, "monomials": monomials, "ridge": ridge,
        "linear": "given" if initial is not None else linear, "input": input,
        "inputs": list(names["inputs"]), "output": names["output"],
        "max_iter": max_iter, "tol": tol, "prune": prune, "pruned": pruned,
        "iterations": info["iterations"],
        "rejected": info["rejected"], "diverged_steps": info["diverged"],
        "cost_start": info["cost_start"] * y_scale**2 / n_total,
        "cost": sse * y_scale**2 / n_total,
        "initial_states": [x.tolist() for x in x0s], "n_monomials": nm,
        "n_parameters": n_model, "linear_rms": info["linear_rms"] * y_scale,
        "linear_start": _physical(start, u_scale, y_scale),
        "held_out": _held_summary(info.get("held_out"), y_scale, offset_rule),
        "weighting": weighting, "weighting_info": None if weights is None else weights.info,
    }
    return Estimate(model=fitted, parameters=theta, names=labels, covariance=cov,
                    noise_variance=noise, n_samples=n_total, method="pnlss",
                    status=info["status"], options=options,
                    residual_function=lambda: resid.copy())


# -- the search ---------------------------------------------------------------------------


class _Search:
    """Levenberg–Marquardt over A … F and the records' initial states.

    With held-out records (``held``: raw (u, y) pairs), :meth:`run` keeps
    the iterate whose free run there has the lowest RMS error.
    """

    def __init__(self, model: PnlssModel, records: Sequence[Record], ridge: float,
                 held: Sequence[Record] | None = None,
                 weights: PeriodicWeights | None = None) -> None:
        self.model = model
        self.records = [(np.ascontiguousarray(u), y) for u, y in records]
        self.weights = weights  # the cost per DFT line of the whole periods (None: plain)
        self.n_total = (sum(y.size for _, y in records) if weights is None
                        else weights.n_samples)
        nx, nm, nu = model.n_states, model.n_monomials, model.n_inputs
        self.n_model = model.n_parameters
        self.n_linear = nx * nx + nx * nu + nx + nu  # A, B, C, D lead θ
        self.ef = np.arange(self.n_model - nx * nm - nm, self.n_model)
        self.rho = ridge * self.n_total
        self.held = held
        self.best: _Best | None = None
        self.linear_best: _Best | None = None
        self.linear: tuple[Any, Any, dict[str, Any]] | None = None

    def penalty_matrix(self) -> NDArray[np.float64]:
        P = np.zeros((self.n_model, self.n_model))
        P[self.ef, self.ef] = self.rho
        return P

    def _args(self, theta: NDArray[np.float64], linear: bool = False) -> tuple[Any, ...]:
        """The kernels' arguments; ``linear``: without monomials (E = F = 0 must hold), so
        the Jacobian kernel forms the columns of A, B, C, D and the initial state alone."""
        m = self.model.with_parameters(theta)
        args = m._kernel_args()
        if not linear:
            return args
        A, B, C, D, _, _, P = args
        return (A, B, C, D, np.zeros((A.shape[0], 0)), np.zeros(0),
                np.zeros((0, P.shape[1]), dtype=P.dtype))

    def cost(self, theta: NDArray[np.float64], x0s: Sequence[NDArray[np.float64]]
             ) -> float:
        """Σ squared simulation error + penalty; inf for a diverging run."""
        args = self._args(theta)
        total = self.rho * float(theta[self.ef] @ theta[self.ef])
        if self.weights is not None:
            return total + weighted_cost(args, self.records, x0s, self.weights)
        for (u, y), x0 in zip(self.records, x0s, strict=True):
            ys = np.empty(y.size)
            xs = np.empty((y.size + 1, self.model.n_states))
            if simulate(*args, u, x0, ys, xs) >= 0:
                return np.inf
            total += float(np.sum((ys - y) ** 2))
        return total

    def held_rms(self, theta: NDArray[np.float64]) -> float:
        """RMS free-run error on the held-out records (normalised units; inf if a run
        diverges; NaN without held-out records), each from its estimated initial state."""
        if self.held is None:
            return np.nan
        m = self.model.with_parameters(theta)
        total, n = 0.0, 0
        for u, y in self.held:
            x0 = m.initial_state(y, u)
            ys, where = m._run(m._normalised(u), x0, False)
            if where >= 0:
                return np.inf
            total += float(np.sum((ys - (y - m.y_mean) / m.y_scale) ** 2))
            n += y.size
        return float(np.sqrt(total / n))

    def normal_equations(self, theta: NDArray[np.float64], x0s: Sequence[NDArray[np.float64]],
                         linear: bool = False
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                    NDArray[np.float64]]:
        """JᵀJ, Jᵀr and r = simulated − measured, J (N, n_model + nx·records) the exact
        Jacobian, accumulated over blocks of :data:`BLOCK` samples so that J is never held
        whole (a block's rows are those of the whole record, bit for bit).  ``linear``
        (E = F = 0): only the columns of A, B, C, D and the initial states are formed, the
        rows and columns of E and F are left zero.  ConvergenceError if the run diverges
        (it cannot: only accepted points are differentiated)."""
        args = self._args(theta, linear)
        nx, nmod = self.model.n_states, self.n_model
        nown = self.n_linear if linear else nmod  # the model's columns the kernel forms
        if self.weights is not None:  # JᴴWJ of the periods' DFTs; r: the periods' errors
            return weighted_normal_equations(args, self.records, x0s, self.weights, nown,
                                             nmod, BLOCK)
        n_all = nmod + nx * len(self.records)
        H = np.zeros((n_all, n_all))
        g = np.zeros(n_all)
        r = np.empty(self.n_total)
        row = 0
        for k, ((u, y), x0) in enumerate(zip(self.records, x0s, strict=True)):
            cols, x, S, Hk, gk = record_start(x0, k, nown, nmod, nx)
            Jb = np.empty((min(BLOCK, y.size), nown + nx))
            for a in range(0, y.size, BLOCK):
                b = min(a + BLOCK, y.size)
                Jk, ys = Jb[:b - a], np.empty(b - a)
                if jacobian_block(*args, u[a:b], x, S, 0, ys, Jk) >= 0:
                    raise ConvergenceError("the PNLSS simulation diverged at an accepted "
                                           "point; lower the degree or n_states")
                rk = ys - y[a:b]
                Hk += Jk.T @ Jk
                gk += Jk.T @ rk
                r[row + a:row + b] = rk
            H[np.ix_(cols, cols)] += Hk
            g[cols] += gk
            row += y.size
        return H, g, r

    def covariance(self, theta: NDArray[np.float64], x0s: Sequence[NDArray[np.float64]],
                   fixed: NDArray[np.int64], n_free: int
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """σ̂²(JᵀJ + penalty)⁺ of the model's parameters (the initial states marginalised,
        the ``fixed`` ones zero), the residuals and σ̂² (normalised units)."""
        H, _, r = self.normal_equations(theta, x0s)
        H[:self.n_model, :self.n_model] += self.penalty_matrix()
        sse = float(r @ r) if self.weights is None else weighted_cost(
            self._args(theta), self.records, x0s, self.weights)  # the cost H belongs to
        sigma2 = sse / max(self.n_total - n_free, 1)
        keep = np.setdiff1d(np.arange(H.shape[0]), fixed)
        cov_all = np.zeros_like(H)
        cov_all[np.ix_(keep, keep)] = _inverse(H[np.ix_(keep, keep)])
        return sigma2 * cov_all[:self.n_model, :self.n_model], r, sigma2

    def run(self, max_iter: int, tol: float
            ) -> tuple[NDArray[np.float64], list[NDArray[np.float64]], dict[str, Any]]:
        """The linear part alone first (E = F = 0, as the start of Paduart et al.), then all.

        With held-out records each stage starts from, and the search returns, the best
        iterate there so far (the linear start is the first)."""
        if self.linear is None:
            self.run_linear(max_iter, tol)
        theta, x0s, first = self.linear  # type: ignore[misc]
        info = dict(first)
        sse = first["cost"] if self.weights is None else weighted_cost(
            self._args(theta), self.records, x0s, self.weights.plain())  # not the weighted one
        info["linear_rms"] = np.sqrt(sse / self.n_total)
        if self.ef.size:
            n_all = self.n_model + self.model.n_states * len(self.records)
            theta, x0s, second = self._lm(theta, x0s, max_iter, tol, np.arange(n_all),
                                          "nonlinear")
            info.update(status=second["status"], cost=second["cost"])
            for key in ("iterations", "rejected", "diverged"):
                info[key] += second[key]
        if self.best is not None and self.linear_best is not None:
            theta, x0s = self.best.theta, self.best.x0s
            info["cost"] = self.cost(theta, x0s)
            info["held_out"] = self._held_info(self.linear_best)
        return theta, x0s, info

    def run_linear(self, max_iter: int, tol: float) -> None:
        """The linear stage (E = F = 0): :attr:`linear` (θ, x(0)s, info) — with held-out
        records the best iterate there, also :attr:`linear_best`."""
        nx = self.model.n_states
        theta = self.model.parameters.copy()
        x0s = [np.zeros(nx) for _ in self.records]
        n_all = self.n_model + nx * len(self.records)
        self.best = None
        if max_iter == 0 and self.held is None:
            # the model as given: only its initial states are fitted (from x = 0, an unstable
            # or slow model's cost and covariance would describe its start-up, not the model)
            theta, x0s, _ = self._lm(theta, x0s, X0_ITERATIONS, tol,
                                     np.arange(self.n_model, n_all), "initial states")
        self._watch(theta, x0s, "the linear start", 0)
        theta, x0s, first = self._lm(theta, x0s, max_iter, tol,
                                     np.setdiff1d(np.arange(n_all), self.ef), "linear")
        self.linear_best = self.best
        if self.linear_best is not None:
            theta, x0s = self.linear_best.theta, self.linear_best.x0s
            first["cost"] = self.cost(theta, x0s)
        self.linear = (theta, x0s, first)

    def _watch(self, theta: NDArray[np.float64], x0s: list[NDArray[np.float64]], stage: str,
               iteration: int) -> bool:
        """Score an iterate on the held-out records; True if it is the best so far."""
        if self.held is None:
            return False
        score = self.held_rms(theta)
        if self.best is None:
            self.best = _Best(score, theta.copy(), [x.copy() for x in x0s], stage, iteration,
                              score)
            return True
        if score < self.best.score:
            self.best = _Best(score, theta.copy(), [x.copy() for x in x0s], stage, iteration,
                              self.best.start)
            return True
        return False

    def _held_info(self, linear: _Best) -> dict[str, Any]:
        """Which iterate was kept on the held-out records, and why (normalised units)."""
        best = self.best or linear
        if best.stage == "nonlinear":
            why = (f"the nonlinear terms lowered the held-out RMS error from {{linear:.4g}} "
                   f"(linear part, E = F = 0) to {{chosen:.4g}}: kept the iterate "
                   f"{best.iteration} of the full model's search")
        elif best.stage == "linear":
            why = ("no iterate with nonlinear terms lowered the held-out RMS error below the "
                   "linear part's {linear:.4g}: kept E = F = 0 (the linear model refined by "
                   f"output error, iterate {best.iteration})")
        else:
            why = ("no iterate lowered the held-out RMS error below the linear start's "
                   "{start:.4g}: kept the linear start, E = F = 0")
        return {"start": best.start, "linear": linear.score, "chosen": best.score,
                "kept": best.stage, "iteration": best.iteration, "why": why,
                "samples": int(sum(y.size for _, y in self.held or ()))}

    def _lm(self, theta: NDArray[np.float64], x0s: list[NDArray[np.float64]], max_iter: int,
            tol: float, free: NDArray[np.int64], stage: str = ""
            ) -> tuple[NDArray[np.float64], list[NDArray[np.float64]], dict[str, Any]]:
        nx = self.model.n_states
        cost = self.cost(theta, x0s)
        if not np.isfinite(cost):
            raise ConvergenceError("the linear start's simulation diverges on the record (an "
                                   "unstable linear model); give a stable initial model or "
                                   "use linear = \"oe\"")
        info: dict[str, Any] = {"cost_start": cost, "iterations": 0, "rejected": 0,
                                "diverged": 0, "status": "ok"}
        # E and F fixed at zero: the Jacobian's columns of A, B, C, D and x(0) suffice
        linear = not np.isin(self.ef, free).any() and not np.any(theta[self.ef])
        lam = 1e-3
        small = 0
        stale = 0  # accepted iterations since the last lower held-out error
        n_model = self.n_model
        for it in range(max_iter):
            H, g, _ = self.normal_equations(theta, x0s, linear)
            info["iterations"] = it + 1
            H[:n_model, :n_model] += self.penalty_matrix()
            g[self.ef] += self.rho * theta[self.ef]
            H_all = H.shape[0]
            H = H[np.ix_(free, free)]
            g = g[free]
            d = np.diag(H).copy()
            d = np.maximum(d, 1e-12 * max(float(d.max()), 1e-300))
            accepted = False
            while lam < 1e10:
                step = np.zeros(H_all)
                try:
                    step[free] = -np.linalg.solve(H + lam * np.diag(d), g)
                except np.linalg.LinAlgError:
                    lam *= 10.0
                    continue
                t_new = theta + step[:n_model]
                x_new = [x + step[n_model + k * nx: n_model + (k + 1) * nx]
                         for k, x in enumerate(x0s)]
                c_new = self.cost(t_new, x_new)
                if not np.isfinite(c_new):
                    info["diverged"] += 1
                if c_new < cost:
                    accepted = True
                    drop = (cost - c_new) / cost
                    theta, x0s, cost = t_new, x_new, c_new
                    lam = max(lam / 3.0, 1e-10)
                    break
                info["rejected"] += 1
                lam *= 10.0
            if not accepted:
                break  # no damping lowers the cost: a (local) minimum
            if stage and self.held is not None:
                stale = 0 if self._watch(theta, x0s, stage, it + 1) else stale + 1
                if stale >= PATIENCE:
                    info["status"] = (f"stopped early: {PATIENCE} iterations without a lower "
                                      "held-out error")
                    break
            small = small + 1 if drop < tol else 0
            if small >= 2:
                break
        else:
            if max_iter > 0:
                info["status"] = f"stopped after max_iter = {max_iter} iterations"
        info["cost"] = cost
        return theta, x0s, info


@dataclass(frozen=True)
class _Best:
    """The iterate with the lowest held-out RMS error so far."""

    score: float
    theta: NDArray[np.float64]
    x0s: list[NDArray[np.float64]]
    stage: str  # "the linear start", "linear" or "nonlinear"
    iteration: int
    start: float  # the linear start's score


# -- the linear start ---------------------------------------------------------------------


def _linear_start(data: Any, initial: Any, linear: str, n_states: int, input: str,
                  output: str | None, dt: float, nu: int,
                  scales: tuple[Any, Any, float, float]
                  ) -> tuple[NDArray[np.float64], ...]:
    """A, B, C, D of a discrete linear model on the normalised signals."""
    from ..models import StateSpace

    _, u_scale, _, y_scale = scales
    if initial is not None:
        model = getattr(initial, "model", initial)
        if not isinstance(model, StateSpace):
            if hasattr(model, "to_ss") and getattr(model, "dt", None) is not None:
                model = model.to_ss()
            else:
                raise type_error("initial", initial, "a discrete StateSpace (or an Estimate of "
                                 "one), e.g. the best linear approximation in state space")
        if model.dt is None or abs(model.dt - dt) > 1e-9 * dt:
            raise DataError(f"initial must be discrete at the records' sample period dt = "
                            f"{dt:g} s, got dt = {model.dt}; discretise it first "
                            "(servoid.models.c2d)")
        A, B, C, D = (np.asarray(model.A, float), np.asarray(model.B, float),
                      np.asarray(model.C, float), np.asarray(model.D, float))
        if B.shape[1] != nu or C.shape[0] != 1:
            raise DataError(f"initial must have {nu} input(s) and one output, got "
                            f"{B.shape[1]} and {C.shape[0]}")
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            A, B, C, D = _fit_linear(data, linear, n_states, input, output)
    return (A, B * u_scale[None, :], C[0] / y_scale, D[0] * u_scale / y_scale)


def _fit_linear(data: Any, linear: str, n_states: int, input: str, output: str | None
                ) -> tuple[NDArray[np.float64], ...]:
    from ..estimate import fit_n4sid, fit_oe

    if linear == "n4sid":
        # short horizons: a band-limited multisine is not persistently exciting of the default
        # order, and the start only has to be close
        try:
            est = fit_n4sid(data, n_states, input=input, output=output,
                            horizon=max(2 * n_states + 2, 6))
        except IdentifiabilityError:
            first = data if isinstance(data, Experiment) else data[0]
            if len(first.names_of(input)) != 1:
                raise
            return _fit_linear(data, "oe", n_states, input, output)  # the same model by OE
        m = est.model
        return (np.asarray(m.A, float), np.asarray(m.B, float), np.asarray(m.C, float),
                np.asarray(m.D, float))
    from ..models import StateSpace  # noqa: F401  (the OE model becomes one)

    first = data if isinstance(data, Experiment) else data[0]
    if len(first.names_of(input)) != 1:
        raise ModelError('linear = "oe" starts a single-input model; use linear = "n4sid" '
                         "for several inputs")
    est = fit_oe(data, nb=n_states, nf=n_states, nk=1, input=input, output=output)
    tf = est.model.transfer_function(0)
    ss = tf.to_ss()
    return (np.asarray(ss.A, float), np.asarray(ss.B, float), np.asarray(ss.C, float),
            np.asarray(ss.D, float))


def _offset(start: Sequence[NDArray[np.float64]], u_mean: NDArray[np.float64],
            u_scale: NDArray[np.float64], y_mean: float, y_scale: float) -> float:
    """The output offset that makes E = F = 0 the fitted linear start itself.

    n4sid and OE fit y = G u on the records as they are, with no offset;
    on the inputs centred at their mean the same model reads
    y = G(1)·ū + G (u − ū), so the model's output offset is G(1)·ū, not
    the output's mean (which would add an offset ȳ − G(1)·ū the linear
    start never had).  The output's mean when G(1) is not finite or puts
    the offset more than 10 output standard deviations away (a near
    integrator).
    """
    A, B, C, D = start
    try:
        gain = (C @ np.linalg.solve(np.eye(A.shape[0]) - A, B) + D) * y_scale / u_scale
    except np.linalg.LinAlgError:
        return y_mean
    offset = float(gain @ u_mean)
    return offset if np.isfinite(offset) and abs(offset - y_mean) < 10 * y_scale else y_mean


def _balanced(A: NDArray[np.float64], B: NDArray[np.float64], C: NDArray[np.float64],
              D: NDArray[np.float64], inputs: Sequence[NDArray[np.float64]]
              ) -> tuple[NDArray[np.float64], ...]:
    """The same linear model with states of unit covariance over the records' inputs."""
    nx = A.shape[0]
    states = []
    for u in inputs:
        x = np.zeros(nx)
        xs = np.empty((u.shape[0], nx))
        for t in range(u.shape[0]):
            xs[t] = x
            x = A @ x + B @ u[t]
            if not np.all(np.abs(x) < 1e12):
                raise ConvergenceError("the linear start's simulation diverges on the record "
                                       "(an unstable linear model); give a stable initial "
                                       "model or try linear = \"oe\"")
        states.append(xs)
    cov = np.cov(np.concatenate(states).T).reshape(nx, nx)
    try:
        T = np.linalg.cholesky(cov + 1e-12 * np.trace(cov) * np.eye(nx))
    except np.linalg.LinAlgError:
        return A, B, C, D
    Ti = np.linalg.inv(T)
    return Ti @ A @ T, Ti @ B, C @ T, D


# -- private ------------------------------------------------------------------------------


def _records(data: object, role: str, output: str | None
             ) -> tuple[list[Record], dict[str, Any]]:
    if isinstance(data, Experiment):
        exps = [data]
    elif isinstance(data, ExperimentSet):
        exps = list(data)
    else:
        raise type_error("data", data, "an Experiment or ExperimentSet")
    if output is not None:
        as_str("output", output)
    out: list[Record] = []
    names: dict[str, Any] = {}
    for exp in exps:
        y_name = output_name(exp, output)
        u = np.asarray(exp.signal(role), dtype=float)  # type: ignore[arg-type]
        y = np.asarray(exp[y_name], dtype=float)
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise DataError("the record has NaN or inf samples; remove or interpolate them")
        if y.size < 20:
            raise DataError(f"a PNLSS model needs at least 20 samples per record, got {y.size}")
        out.append((u.reshape(y.size, -1), y))
        inputs = exp.names_of(role)
        names = {"inputs": list(inputs), "output": y_name, "output_unit": exp.unit(y_name),
                 "input_units": [exp.unit(n) for n in inputs]}
    return out, names


def _held_records(data: object, role: str, output: str | None, names: dict[str, Any],
                  dt: float) -> list[Record]:
    """The held-out records' raw (u (N, nu), y), checked against the fitted ones."""
    if not isinstance(data, (Experiment, ExperimentSet)):
        raise type_error("held_out", data, "an Experiment or ExperimentSet")
    records, held = _records(data, role, names["output"] if output is None else output)
    if held["inputs"] != names["inputs"]:
        raise DataError(f"held_out must have the inputs {', '.join(names['inputs'])} of the "
                        f"fitted records, got {', '.join(held['inputs'])}")
    if abs(float(data.dt) - dt) > 1e-9 * dt:
        raise DataError(f"held_out must be sampled as the fitted records (dt = {dt:g} s), got "
                        f"dt = {float(data.dt):g} s")
    return records


def _held_summary(held: dict[str, Any] | None, y_scale: float, offset: str
                  ) -> dict[str, Any] | None:
    """The held-out choice in the output's unit, with its sentence (None without one)."""
    if held is None:
        return None
    out = dict(held, offset=offset)
    for key in ("start", "linear", "chosen"):
        out[key] = float(held[key] * y_scale)
    out["why"] = held["why"].format(**{k: out[k] for k in ("start", "linear", "chosen")})
    return out


def _check_size(nx: int, nu: int, degree: int, monomials: Monomials, n_records: int,
                n_total: int) -> int:
    """The number of free parameters, or a DataError when the records are too short."""
    nm = exponents(nx, nu, degree, monomials).shape[0]
    n_free = nx * nx + nx * nu + nx + nu + nx * nm + nm + nx * n_records
    if n_free >= n_total - 1:
        raise DataError(f"{n_free} parameters (with the initial states) cannot be fitted to "
                        f"{n_total} samples; record more data, or lower n_states or degree")
    return n_free


def _physical(start: Sequence[NDArray[np.float64]], u_scale: NDArray[np.float64],
              y_scale: float) -> dict[str, list[Any]]:
    """The linear start in the data's units, as lists (a StateSpace's A, B, C, D)."""
    A, B, C, D = start
    return {"A": A.tolist(), "B": (B / u_scale[None, :]).tolist(),
            "C": [(C * y_scale).tolist()], "D": [(D * y_scale / u_scale).tolist()]}


def _inverse(H: NDArray[np.float64]) -> NDArray[np.float64]:
    """The pseudo-inverse of H by its eigenvalues.

    A state-space model's similarity transforms leave the output alone, so
    nx² directions of θ are not fixed by any data: the covariance is that of
    the parameters orthogonal to them (as a minimal parametrisation would
    give), not an infinite one.
    """
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    keep = w > 1e-9 * max(float(w.max()), 1e-300)
    return (V[:, keep] / w[keep]) @ V[:, keep].T


def _with_covariance(model: PnlssModel, cov: NDArray[np.float64], noise: float) -> PnlssModel:
    from dataclasses import replace

    return replace(model, covariance=cov if np.all(np.isfinite(cov)) else None,
                   noise_variance=noise)
