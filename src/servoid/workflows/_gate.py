"""The gate of ``method = "auto"``: when are the nonlinear families worth fitting?

``auto`` first scores the linear candidates.  It adds the block-oriented and
NARX candidates when a test on the estimation data says the best linear
candidate (refitted on the whole estimation record) leaves structure it
cannot explain.  Two tests, each at the 1 % level, so the gate opens on a
linear system in at most about 2 % of records (and then only costs time: the
one-standard-error rule still prefers the simpler linear model):

* the higher-order correlation tests of every validation
  (:func:`~servoid.validate.nonlinearity_tests`: ε–u², ε²–u², ε–εu);
* :func:`output_power_pvalue`, a regression specification test (Ramsey's
  RESET, 1969) on the model's own simulated output ŷ: do ŷ² and ŷ³
  explain the residuals beyond the past residuals, the lagged inputs and ŷ
  itself?  It sees what the correlations with u² cannot: an *odd* static
  nonlinearity after the dynamics (a Wiener tanh or saturation under a
  symmetric input), whose residual is odd in u and so uncorrelated with
  u² and with ε·u at every lag.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ServoidError
from .._lazy import stats
from ..data import ExperimentSpec, as_segments
from ._choice import Fold, Score, _HeldSpec, auto_candidates, parsed_options, score_candidates
from ._methods import get_method

__all__ = ["GATE_LEVEL", "gate", "output_power_pvalue"]

#: Level of each test of the gate.
GATE_LEVEL = 0.01
#: Lags of each input (0…) and of the residual (1…) in the test's null regression.
_INPUT_LAGS = 20
_RESIDUAL_LAGS = 10


def gate(spec: ExperimentSpec, options: Mapping[str, Any], folds: Sequence[Fold],
         scores: list[Score]) -> tuple[list[Score], str]:
    """``auto``: the scores with the nonlinear families added when the data ask, and why."""
    ok = [s for s in scores if s.admissible]
    if not ok:
        return scores, ""
    best = max(ok, key=lambda s: s.mean)
    found = _leaves_structure(spec, options, best)
    if not found:
        return scores, (f"the higher-order tests and the output-power test found no "
                        f"nonlinearity left by the best linear candidate "
                        f"({best.candidate.label}); no nonlinear family was fitted")
    added = score_candidates(spec, auto_candidates(nonlinear=True), options, folds)
    return scores + added, (f"the {found} found a nonlinearity left by the best linear "
                            f"candidate ({best.candidate.label}): the block-oriented and NARX "
                            "candidates were added")


def output_power_pvalue(residuals: ArrayLike, simulated: ArrayLike, u: ArrayLike) -> float:
    """p-value of the output-power test: do ŷ², ŷ³ explain the residuals?

    Parameters
    ----------
    residuals : array_like, shape (N,)
        The model's simulation errors y − ŷ.
    simulated : array_like, shape (N,)
        Its free-run simulated output ŷ (a function of the input alone).
    u : array_like, shape (N,) or (N, n_inputs)
        The input(s) over the same samples.

    Returns
    -------
    float
        The F-test's p-value of the two power terms (NaN: too few samples).

    Notes
    -----
    The null regression holds a constant, the residual's lags 1…10 (its
    colour), each input's lags 0…20 and ŷ itself (a wrong *linear* model
    leaves a linear function of the input, which they absorb; for a
    Gaussian input ŷ absorbs the linear part of ŷ³ exactly); the test adds
    the standardised ŷ² and ŷ³.  A right model leaves noise independent of
    the input, so of ŷ; on the residuals of the true linear model with
    AR(1) noise it holds its level (``benchmarks/bench_model_choice.py``).
    """
    e = np.asarray(residuals, dtype=float).ravel()
    s = np.asarray(simulated, dtype=float).ravel()
    x = np.asarray(u, dtype=float).reshape(e.size, -1)
    keep = np.isfinite(e) & np.isfinite(s) & np.all(np.isfinite(x), axis=1)
    e, s, x = e[keep], s[keep], x[keep]
    start = max(_INPUT_LAGS, _RESIDUAL_LAGS)
    spread = float(s.std())
    if e.size < start + 10 * (_INPUT_LAGS * x.shape[1] + _RESIDUAL_LAGS) or not spread > 0:
        return math.nan
    s = (s - s.mean()) / spread
    null = [np.ones(e.size - start), _lagged(e, range(1, _RESIDUAL_LAGS + 1), start),
            s[start:, None]]
    null += [_lagged(x[:, j], range(_INPUT_LAGS + 1), start) for j in range(x.shape[1])]
    x0 = np.column_stack(null)
    z = np.column_stack([s[start:] ** 2, s[start:] ** 3])
    x1 = np.column_stack([x0, z])
    t = e[start:]
    r0 = t - x0 @ np.linalg.lstsq(x0, t, rcond=None)[0]
    r1 = t - x1 @ np.linalg.lstsq(x1, t, rcond=None)[0]
    dof = t.size - x1.shape[1]
    rss1 = float(r1 @ r1)
    if not rss1 > 0:
        return math.nan
    f = ((float(r0 @ r0) - rss1) / z.shape[1]) / (rss1 / dof)
    return float(stats.f.sf(max(f, 0.0), z.shape[1], dof))


def _lagged(x: NDArray[np.float64], lags: Any, start: int) -> NDArray[np.float64]:
    n = x.shape[0]
    return np.column_stack([x[start - k: n - k] for k in lags])


def _leaves_structure(spec: ExperimentSpec, options: Mapping[str, Any], best: Score) -> str:
    """Which test found structure left by the best linear candidate ('' when none).

    The held parts are short; the candidate refitted on the whole estimation data and
    tested on it has the power of the whole record (a test of structure, not a score).
    """
    if best.nonlinearity:
        return "higher-order tests"
    estimation = spec.records()[0]
    segments = as_segments(estimation)
    whole = Fold(estimation, segments)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = get_method(best.candidate.method).run(
                _HeldSpec(spec, whole), parsed_options(best.candidate, options, spec),  # type: ignore[arg-type]
                None)
    except ServoidError:
        return ""
    validations = list(getattr(result, "validations", ()))
    if any(getattr(getattr(v, "nonlinearity", None), "detected", False) for v in validations):
        return "higher-order tests"
    for v in validations:
        seg = next((g for g in segments if g.n_samples == np.size(getattr(v, "measured", ()))
                    and g.u is not None), None)
        if seg is None:
            continue
        first = int(v.first)
        y, yhat = np.asarray(v.measured, float), np.asarray(v.simulated, float)
        p = output_power_pvalue(y[first:] - yhat[first:], yhat[first:],
                                np.asarray(seg.u, float)[first:])
        if p < GATE_LEVEL:
            return f"output-power test (p = {p:.2g})"
    return ""
