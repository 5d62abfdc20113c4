"""Polynomial NARX by forward orthogonal regression: :func:`fit_narx`.

The candidates are every monomial of the lagged output y(t−1 … t−na)
and inputs u_i(t−nk_i … t−nk_i−nb_i+1) up to ``degree``, the constant
included. Terms enter one at a time, each the candidate with the largest
error reduction ratio (ERR), the share of Σy² its component orthogonal to
the terms already in explains (Chen, Billings & Luo 1989, Int. J. Control
50(5), 1873–1896; Billings 2013, *Nonlinear System Identification*, ch. 3).

Speed: one compiled pass (:mod:`._narx_kernel`) writes the candidates of a
block of rows at a time, and BLAS sums the augmented Gram matrix
[Φ y]ᵀ[Φ y] block by block, so Φ is never held whole. The selection then
works on that (M + 1)² matrix alone: orthogonalising the candidates
against a chosen term is one symmetric elimination step on the Gram matrix
(O(M²), independent of the record length), which gives every w_jᵀw_j and
w_jᵀy the ERR needs. The chosen terms' coefficients and covariance come
from a QR least-squares fit on their own columns (its accuracy does not
depend on the Gram route).
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int, type_error
from .._errors import DataError, OptionError, ServoidWarning, check_option
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Estimate, check_not_constant, lstsq
from ..estimate import output_name as _channel_output
from ._narx_kernel import fill_regressors, forward_select
from ._narx_model import NarxModel, Term, encode_terms, term_label

__all__ = ["MAX_CANDIDATES", "NarxCriterion", "candidate_terms", "fit_narx"]

NarxCriterion = Literal["aic", "bic", "err"]

#: Largest candidate set: the Gram matrix costs N·M² products and M² numbers
#: (1000 candidates: 8 MB, and 1e10 products on 1e4 samples, about a second).
MAX_CANDIDATES = 1000
#: Samples per block of the Gram pass (a block of 100 candidates, 1.6 MB, stays in L2/L3).
_BLOCK = 2048
#: A candidate whose part orthogonal to the chosen terms keeps less than this share of its
#: squared norm is a combination of them (to rounding of the Gram route, ~1e-13): skipped.
_DEPENDENT = 1e-9
#: The criterion path stops once it has not improved for this many terms: after the last
#: useful term each added term lowers N·ln σ̂² by a χ²(1) amount and raises the penalty by
#: 2 or ln N, so a new minimum this many terms later would need a run of chance gains.
_PATIENCE = 10
#: |mean|/std of a channel above which a fit of degree >= 2 warns (see _warn_on_offsets).
_OFFSET_RATIO = 50.0
#: Smallest residual sum of squares the criteria see, relative to Σy² (rounding level of
#: the Gram route): noise-free data stop at the exact terms instead of chasing rounding.
_RSS_FLOOR = 1e-13


def fit_narx(
    experiment: Experiment | ExperimentSet,
    *,
    na: int,
    nb: int | Sequence[int],
    nk: int | Sequence[int] = 1,
    degree: int = 2,
    max_terms: int | None = None,
    criterion: NarxCriterion = "bic",
    tolerance: float = 0.01,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
) -> Estimate:
    """Fit a polynomial NARX model, terms chosen by forward OLS.

    The model is ``y(t) = Σ_j θ_j·p_j(t) + e(t)`` where each ``p_j`` is a
    product of up to ``degree`` of y(t−1 … t−na) and u_i(t−nk_i …
    t−nk_i−nb_i+1) (a constant among them). Terms enter by largest error
    reduction ratio (orthogonal least squares, Chen, Billings & Luo 1989);
    the number kept minimises an information criterion on the one-step
    residual variance (then any kept term whose removal lowers it is
    dropped), or stops at an ERR threshold. The kept terms are
    refitted by least squares on the one-step equations, with covariance
    σ̂²(ΦᵀΦ)⁻¹. Free-run simulation (:func:`~servoid.validate.validate`)
    is how the model is judged.

    Parameters
    ----------
    experiment : Experiment or ExperimentSet
        Estimation data: one output, one or more inputs; the regressors
        of each segment of a set stay inside it.
    na : int
        Output lags y(t−1) … y(t−na) (0: no output feedback, NFIR).
    nb : int or sequence of int
        Input lags per input.
    nk : int or sequence of int
        Input delay per input [samples] (the first input lag).
    degree : int
        Highest degree of the monomials (1: linear ARX candidates).
    max_terms : int, optional
        Most terms to select (default: as many as the criterion wants).
    criterion : {"bic", "aic", "err"}
        ``"bic"``: minimise N·ln σ̂²_k + k·ln N; ``"aic"``: N·ln σ̂²_k + 2k
        (σ̂²_k: one-step residual variance with k terms); ``"err"``: stop
        once 1 − ΣERR, the unexplained share of Σy², is below `tolerance`.
        With many candidates AIC admits chance terms (each with
        probability ≈ 0.16); BIC rarely does.
    tolerance : float
        The ERR threshold ρ in (0, 1) for ``criterion="err"``; set it
        above the noise share σ²/mean(y²), or chance terms enter.
    input : {"u", "r"}
        Role of the input channels.
    output : str, optional
        Output channel when the experiment has several.

    Returns
    -------
    Estimate
        ``model`` is a :class:`NarxModel`; parameters are its terms (in
        candidate order), named like ``"y(t-1)*u(t-2)"``.  ``options``
        holds the orders, the candidate count and ``"selection"``: each
        term in the order it entered, with its ERR, the criterion after it
        and whether it was kept (``"yes"``, ``"no"``, ``"pruned"``).

    Raises
    ------
    OptionError
        Degree or lags giving more than :data:`MAX_CANDIDATES` candidates.
    DataError
        Too few samples for the candidates, or a missing channel.
    IdentifiabilityError
        A constant input.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.data import Experiment
    >>> from servoid.nonlinear import fit_narx
    >>> rng = np.random.default_rng(0)
    >>> u = rng.uniform(-1, 1, 2000)
    >>> y = np.zeros(2000)
    >>> for t in range(2, 2000):
    ...     y[t] = 0.5 * y[t-1] + u[t-1] - 0.3 * u[t-1] ** 2 + 0.01 * rng.standard_normal()
    >>> est = fit_narx(Experiment.from_arrays(0.01, u=u, y=y), na=2, nb=2)
    >>> est.names
    ('y(t-1)', 'u(t-1)', 'u(t-1)^2')
    """
    check_option("criterion", criterion, ("aic", "bic", "err"))
    check_option("input", input, ("u", "r"))
    segments = as_segments(experiment)
    first = segments[0]
    input_names = first.names_of(input)
    if not input_names:
        first.signal(input)  # a DataError naming what exists
    output_name = _channel_output(first, output)
    na = as_int("na", na, minimum=0)
    nbs = _per_input("nb", nb, len(input_names), minimum=1)
    nks = _per_input("nk", nk, len(input_names), minimum=0)
    degree = as_int("degree", degree, minimum=1)
    tolerance = as_float("tolerance", tolerance)
    if not 0.0 < tolerance < 1.0:
        raise OptionError(f"tolerance must lie in (0, 1) (the unexplained share of Σy² at which "
                        f"the ERR selection stops), e.g. 0.01, got {tolerance:g}")
    base = _base_variables(na, nbs, nks)
    n_candidates = math.comb(len(base) + degree, degree)
    if n_candidates > MAX_CANDIDATES:
        raise OptionError(
            f"na = {na}, nb = {_short(nbs)}, degree = {degree} give {n_candidates:,} candidate "
            f"terms, over the cap of {MAX_CANDIDATES} (the Gram matrix grows with their "
            "square); lower the degree or the lags")
    start = max((lag for _, lag in base), default=0)
    n_rows = sum(max(seg.n_samples - start, 0) for seg in segments)
    if n_rows <= n_candidates:
        raise DataError(
            f"{n_candidates} candidate terms (na = {na}, nb = {_short(nbs)}, degree = "
            f"{degree}) need more than {n_candidates} equations after the first {start} "
            f"samples, got {n_rows}; use a longer record, lower lags or a lower degree")
    if max_terms is not None:
        max_terms = as_int("max_terms", max_terms, minimum=1)
    limit = min(n_candidates, n_rows - 1) if max_terms is None else \
        min(max_terms, n_candidates, n_rows - 1)
    signals = [_signals(seg, output_name, input_names, degree) for seg in segments]
    for k, name in enumerate(input_names, start=1):
        check_not_constant(name, [z[k] for z in signals])
    if degree >= 2:
        _warn_on_offsets(signals, [output_name, *input_names])
    candidates = _candidates(base, degree)
    sig, lag = encode_terms(candidates)

    gram = np.zeros((n_candidates + 1, n_candidates + 1))
    for z in signals:
        if z.shape[1] > start:
            gram += _gram(z, sig, lag, start)
    if not np.all(np.isfinite(gram)):
        raise DataError("the candidate terms overflow double precision when squared and summed; "
                        "rescale the channels (calibrate them to SI units) or lower the degree")
    yy = float(gram[-1, -1])
    if not yy > 0.0:
        raise DataError(f"the output {output_name!r} is zero throughout: there is nothing to fit")
    penalty = {"aic": 2.0, "bic": math.log(n_rows), "err": -1.0}[criterion]
    order, err, rss_path, keep = _select(gram, yy, n_rows, limit, penalty, tolerance)
    _warn_on_stop(criterion, keep, len(order), limit, max_terms, rss_path, yy, tolerance)
    if keep == 0:
        raise DataError(f"the {criterion} criterion keeps no term (the output is noise to it); "
                        "check the channels, or use more data or criterion = \"err\"")
    kept = [int(j) for j in order[:keep]]
    pruned = _prune(gram, kept, yy, n_rows, penalty) if penalty >= 0 else []
    selection = _selection_rows(order, err, rss_path, yy, n_rows, penalty, candidates,
                                output_name, input_names, keep, pruned)
    chosen = sorted(j for j in kept if j not in pruned)  # candidate order: constant, linear, …
    terms = tuple(candidates[j] for j in chosen)
    names = tuple(term_label(t, output_name, input_names) for t in terms)
    phi, target = _design(signals, terms, start)
    result = lstsq(phi, target, names)
    del phi
    model = NarxModel(terms, result.theta, first.dt, covariance=result.covariance,
                      noise_variance=result.noise_variance, input_names=tuple(input_names),
                      output_name=output_name, output_unit=first.unit(output_name),
                      input_units=tuple(first.unit(n) for n in input_names))
    _warn_if_diverges(model, signals[0], start)

    def residuals() -> NDArray[np.float64]:
        return np.concatenate([model.residuals(z[0], z[1:].T)[start:] for z in signals
                               if z.shape[1] > start + 2])

    return Estimate(
        model=model,
        parameters=result.theta,
        names=names,
        covariance=result.covariance,
        noise_variance=result.noise_variance,
        n_samples=n_rows,
        method="narx",
        options={
            "na": na, "nb": list(nbs), "nk": list(nks), "degree": degree,
            "criterion": criterion, "tolerance": tolerance,
            "max_terms": max_terms, "n_candidates": n_candidates,
            "input": input, "inputs": list(input_names), "output": output_name,
            "start": start, "segments": len(segments), "condition": result.condition,
            "unexplained": float(max(rss_path[keep - 1], 0.0) / yy),
            "pruned": [term_label(candidates[j], output_name, input_names) for j in pruned],
            "selection": selection,
        },
        units=_units(terms, model),
        residual_function=residuals,
        model_function=model.with_coefficients,
    )


def candidate_terms(na: int, nb: int | Sequence[int], nk: int | Sequence[int] = 1,
                    degree: int = 2) -> tuple[Term, ...]:
    """Every candidate term of a NARX structure, in candidate order.

    Parameters
    ----------
    na : int
        Output lags.
    nb, nk : int or sequence of int
        Input lags and delay per input (a sequence: one value per input).
    degree : int
        Highest degree.

    Returns
    -------
    tuple of Term
        The constant, then the degree-1 terms, degree 2, …; each term as
        ``(signal, lag)`` factors (signal 0 = output).
    """
    na = as_int("na", na, minimum=0)
    n_inputs = len(nb) if _is_sequence(nb) else 1  # type: ignore[arg-type]
    nbs = _per_input("nb", nb, n_inputs, minimum=1)
    nks = _per_input("nk", nk, n_inputs, minimum=0)
    degree = as_int("degree", degree, minimum=1)
    base = _base_variables(na, nbs, nks)
    count = math.comb(len(base) + degree, degree)
    if count > MAX_CANDIDATES:
        raise OptionError(f"{count:,} candidate terms, over the cap of {MAX_CANDIDATES}; lower "
                          "the degree or the lags")
    return _candidates(base, degree)


# -- private ---------------------------------------------------------------------------------


def _base_variables(na: int, nbs: Sequence[int], nks: Sequence[int]) -> list[tuple[int, int]]:
    base = [(0, lag) for lag in range(1, na + 1)]
    for i, (nb, nk) in enumerate(zip(nbs, nks, strict=True), start=1):
        base += [(i, lag) for lag in range(nk, nk + nb)]
    return base


def _candidates(base: Sequence[tuple[int, int]], degree: int) -> tuple[Term, ...]:
    out: list[Term] = []
    for d in range(degree + 1):
        for combo in itertools.combinations_with_replacement(range(len(base)), d):
            out.append(tuple(sorted(base[k] for k in combo)))
    return tuple(out)


def _signals(seg: Experiment, output: str, inputs: Sequence[str],
             degree: int) -> NDArray[np.float64]:
    z = np.vstack([seg[output], *(seg[name] for name in inputs)]).astype(float)
    # A monomial of degree d of values up to P reaches P^d and its square P^2d: keep
    # P^d inside the range whose squares sum without overflow or underflow.
    peak = float(np.max(np.abs(z))) if z.size else 0.0
    low = min((float(np.max(np.abs(c))) for c in z if np.any(c)), default=1.0)
    if peak ** degree > 1e150 or low ** degree < 1e-150:
        raise DataError(
            f"the channels reach {peak:.3g} (smallest peak {low:.3g}): products of "
            f"{degree} such values overflow or underflow double precision when squared. "
            "Rescale the channels (calibrate them to SI units) or lower the degree")
    return np.ascontiguousarray(z)


def _warn_on_offsets(signals: Sequence[NDArray[np.float64]], names: Sequence[str]) -> None:
    # With an offset c ≫ spread s, x² = (c + δ)² is c² + 2cδ + δ²: all but (s/c)⁴ of its
    # squared norm is a combination of the constant and x, and the Gram route, which works
    # with squared norms, cannot separate the rest (the test system of the docs loses its
    # quadratic terms at c/s ≈ 170 and keeps them at 17).
    for k, name in enumerate(names):
        x = np.concatenate([z[k] for z in signals])
        mean, spread = float(np.mean(x)), float(np.std(x))
        if abs(mean) > _OFFSET_RATIO * spread:
            warn(
                f"channel {name!r} has mean {mean:.4g} and spread (std) {spread:.3g}: its "
                "powers and products are nearly combinations of lower-degree terms, which the "
                "term selection cannot tell apart in double precision. Remove the offset "
                "first (servoid.data.detrend, or [preprocess] detrend = \"mean\")",
                ServoidWarning)


def _gram(z: NDArray[np.float64], sig: NDArray[np.int64], lag: NDArray[np.int64],
          start: int) -> NDArray[np.float64]:
    m = sig.shape[0]
    n = z.shape[1]
    width = min(_BLOCK, n - start)
    buf = np.empty((m + 1, width))
    gram = np.zeros((m + 1, m + 1))
    for t0 in range(start, n, width):
        b = min(width, n - t0)
        block = buf if b == width else np.empty((m + 1, b))
        fill_regressors(z, sig, lag, t0, block)
        block[m] = z[0, t0 : t0 + b]
        gram += block @ block.T  # BLAS syrk: ~N·M²/2 multiply-adds in all
    return gram


def _select(gram: NDArray[np.float64], yy: float, n_rows: int, limit: int, penalty: float,
            tolerance: float) -> tuple[NDArray[np.int64], NDArray[np.float64],
                                       NDArray[np.float64], int]:
    m = gram.shape[0] - 1
    diag = np.diag(gram)[:m].copy()
    zero = ~(diag > 0.0)
    scale = np.sqrt(np.where(zero, 1.0, diag))
    g = gram[:m, :m] / np.outer(scale, scale)
    g[zero, zero] = 0.0  # an identically zero candidate never enters
    c = gram[:m, m] / scale
    order, err, rss_path, keep = forward_select(
        np.ascontiguousarray(g), np.ascontiguousarray(c), yy, n_rows, limit, penalty,
        tolerance, _PATIENCE, _DEPENDENT, _RSS_FLOOR * yy)
    return order, err, rss_path, int(keep)


def _prune(gram: NDArray[np.float64], kept: list[int], yy: float, n_rows: int,
           penalty: float) -> list[int]:
    """Drop, one at a time, the kept term whose removal lowers the criterion most.

    A term chosen early can be made redundant by the terms chosen after it
    (forward selection never looks back); backward elimination on the same
    criterion removes it (the pruning of Piroddi & Spinelli 2003, Int. J.
    Control 76(17), on the one-step criterion). RSS of a subset S is
    yᵀy − c_Sᵀ G_S⁻¹ c_S from the Gram matrix, so each trial costs O(k³).
    """
    m = gram.shape[0] - 1
    current = list(kept)
    dropped: list[int] = []

    def criterion(cols: list[int]) -> float:
        if not cols:
            return n_rows * math.log(max(yy, _RSS_FLOOR * yy) / n_rows)
        idx = np.array(cols)
        d = np.sqrt(np.diag(gram)[idx])
        g = gram[np.ix_(idx, idx)] / np.outer(d, d)
        c = gram[idx, m] / d
        try:
            explained = float(c @ np.linalg.solve(g, c))
        except np.linalg.LinAlgError:
            return math.inf
        rss = max(yy - explained, _RSS_FLOOR * yy)
        return n_rows * math.log(rss / n_rows) + penalty * len(cols)

    now = criterion(current)
    while len(current) > 1:
        trials = [(criterion([j for j in current if j != drop]), drop) for drop in current]
        best, drop = min(trials)
        if not best < now:
            break
        current.remove(drop)
        dropped.append(drop)
        now = best
    return dropped


def _selection_rows(order: NDArray[np.int64], err: NDArray[np.float64],
                    rss_path: NDArray[np.float64], yy: float, n_rows: int, penalty: float,
                    candidates: Sequence[Term], output: str, inputs: Sequence[str],
                    keep: int, pruned: Sequence[int]) -> list[dict[str, object]]:
    rows = []
    for k, (j, e, rss) in enumerate(zip(order, err, rss_path, strict=True), start=1):
        value = None
        if penalty >= 0:
            value = float(n_rows * math.log(max(rss, _RSS_FLOOR * yy) / n_rows) + penalty * k)
        rows.append({"term": term_label(candidates[int(j)], output, inputs), "err": float(e),
                     "unexplained": float(max(rss, 0.0) / yy), "criterion": value,
                     "kept": "pruned" if int(j) in pruned else "yes" if k <= keep else "no"})
    return rows


def _warn_on_stop(criterion: str, keep: int, n_path: int, limit: int, max_terms: int | None,
                  rss_path: NDArray[np.float64], yy: float, tolerance: float) -> None:
    if criterion == "err":
        if n_path and rss_path[n_path - 1] > tolerance * yy:
            warn(
                f"the ERR selection stopped after {n_path} terms with 1 − ΣERR = "
                f"{rss_path[n_path - 1] / yy:.3g}, above tolerance = {tolerance:g} "
                + ("(max_terms reached)" if max_terms is not None and n_path >= max_terms
                   else "(no candidate left that adds anything)")
                + "; the noise share of Σy² may exceed the tolerance: raise it or use "
                "criterion = \"bic\"", ServoidWarning)
    elif keep == limit and max_terms is not None and keep == max_terms:
        warn(
            f"the {criterion} criterion was still falling at max_terms = {max_terms}: more "
            "terms would fit better; raise max_terms", ServoidWarning)


def _design(signals: Sequence[NDArray[np.float64]], terms: Sequence[Term],
            start: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    sig, lag = encode_terms(terms)
    n_rows = sum(max(z.shape[1] - start, 0) for z in signals)
    phi = np.empty((len(terms), n_rows))
    target = np.empty(n_rows)
    row = 0
    for z in signals:
        n = z.shape[1] - start
        if n <= 0:
            continue
        block = np.empty((len(terms), n))
        fill_regressors(z, sig, lag, start, block)
        phi[:, row : row + n] = block
        target[row : row + n] = z[0, start:]
        row += n
    return phi.T, target


def _warn_if_diverges(model: NarxModel, z: NDArray[np.float64], start: int) -> None:
    if z.shape[1] <= start + 2:
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        model.replay(z[0], z[1:].T)
    if caught:
        warn(
            "the fitted NARX model's free run diverges on the estimation record: its one-step "
            "fit may be good, but it cannot simulate; try a lower degree, fewer terms or "
            "criterion = \"bic\"", ServoidWarning)


def _units(terms: Sequence[Term], model: NarxModel) -> tuple[str, ...]:
    y_unit = model.output_unit
    if not y_unit and not any(model.input_units):
        return ()
    out = []
    for term in terms:
        den: dict[str, int] = {}
        for s, _ in term:
            unit = (y_unit if s == 0 else model.input_units[s - 1]) or "1"
            den[unit] = den.get(unit, 0) + 1
        num = y_unit
        if num and den.get(num):  # y/y cancels
            den[num] -= 1
            num = ""
        parts = [u if p == 1 else f"{u}^{p}" for u, p in den.items() if p and u != "1"]
        if not parts:
            out.append(num)
        else:
            below = parts[0] if len(parts) == 1 else f"({'·'.join(parts)})"
            out.append(f"{num or '1'}/{below}")
    return tuple(out)


def _is_sequence(value: object) -> bool:
    """A list, tuple or array of one value per input (what fit_narx takes for nb, nk)."""
    return isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim > 0)


def _per_input(name: str, value: object, n_inputs: int, minimum: int) -> tuple[int, ...]:
    if _is_sequence(value):
        values = list(value)
    elif isinstance(value, (str, bytes)) or value is None:
        raise type_error(name, value, "an integer or one integer per input")
    else:
        values = [value] * n_inputs
    if len(values) != n_inputs:
        raise DataError(f"{name} needs one value per input ({n_inputs}), got {values}")
    return tuple(as_int(name, v, minimum=minimum) for v in values)


def _short(values: Sequence[int]) -> str:
    return str(values[0]) if len(values) == 1 else str(list(values))
