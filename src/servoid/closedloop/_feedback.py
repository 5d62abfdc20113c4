"""Is there feedback in a record? Residuals against future inputs.

Under feedback the plant input depends on past outputs, hence on past noise:
the residual ε(t) of a model of y correlates with *future* inputs u(t + τ),
τ > 0, while in open loop it is independent of u at every lag (Ljung,
*System Identification*, 2nd ed., §16.6; Söderström & Stoica, *System
Identification*, 1989, §12.10).  The verdict uses the regression form of
that statement (Sims, "Money, income and causality", *Am. Econ. Rev.*
62(4), 1972; Granger, *Econometrica* 37(3), 1969)::

    restricted:  s(t) = Σ_{k=1..n} α_k s(t−k) + Σ_{k=0..n} β_k u(t−k) + w(t)
    full:        … + Σ_{τ=1..M} γ_τ u(t+τ)

with s = y (no model given) or s = ε (the residuals of a given model).  The
restricted part is a high-order ARX model of s on u (order n by AIC), so
it whitens the residual and absorbs what a given model missed of the
dynamics; the F test of γ = 0 then holds its level for any input spectrum
(it conditions on u), where a plain χ² sum of the correlations does not
for a coloured input.  The reported cross-correlation is that of the
restricted residual with the part of u(t + τ) the restricted regressors do
not explain (for a smooth input nearly all of u(t + τ) is its own past),
with the band ±z/√N a white, input-independent residual stays inside at
the confidence level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int, type_error
from .._errors import DataError, IdentifiabilityError, ModelError, ServoidWarning
from .._lazy import stats
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Estimate
from ..models import PolynomialModel, TransferFunction
from ._channels import (
    aic_order_gram,
    check_excites,
    check_name,
    output_name,
    single_name,
)

__all__ = ["FeedbackTest", "feedback_test", "warn_if_feedback"]

#: Largest ARX order the default search tries (AIC picks within 0..this).
_MAX_ORDER = 30
#: Rows per restricted-model parameter below which the order search stops growing.
_ROWS_PER_PARAMETER = 10
#: Rows of the residuals formed at a time (they are summed, never kept whole).
_CHUNK = 1 << 16


@dataclass(frozen=True, eq=False)
class FeedbackTest:
    """Verdict of the feedback test, with its evidence.

    Attributes
    ----------
    statistic : float
        F statistic of the future-input coefficients.
    pvalue : float
        Probability of a statistic this large without feedback.
    dof : tuple of int
        Degrees of freedom (numerator, denominator) of the F law.
    lags : ndarray of int
        τ = 1…M [samples].
    cross_correlation : ndarray
        Normalised correlation of the residual ε(t) with the part of
        u(t + τ) that the past of u and y does not explain.
    bound : float
        ±z/√N band for `cross_correlation` at the confidence level.
    confidence : float
        Level of the band and of the verdict.
    order : int
        ARX order n of the residual model (AIC unless given).
    n_samples : int
        Number of equations N of the test regression.
    input : str
        Input channel tested.
    output : str
        Output channel.
    residuals : str
        ``"arx"`` (high-order ARX of y on u) or ``"model"`` (a given model).
    """

    statistic: float
    pvalue: float
    dof: tuple[int, int]
    lags: NDArray[np.int64]
    cross_correlation: NDArray[np.float64]
    bound: float
    confidence: float
    order: int
    n_samples: int
    input: str
    output: str
    residuals: str

    def __post_init__(self) -> None:
        for name in ("lags", "cross_correlation"):
            arr = np.array(getattr(self, name))
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def level(self) -> float:
        """Significance level 1 − confidence."""
        return 1.0 - self.confidence

    @property
    def has_feedback(self) -> bool:
        """True when the test rejects 'no feedback' at the level."""
        return bool(self.pvalue < self.level)

    @property
    def fraction_outside(self) -> float:
        """Share of lags whose correlation leaves the band."""
        return float(np.mean(np.abs(self.cross_correlation) > self.bound))

    @property
    def message(self) -> str:
        """The verdict in plain words, with what to do about it."""
        p = f"p = {self.pvalue:.2g}"
        lvl = f"{self.level:.2g}"
        if self.has_feedback:
            return (
                f"feedback detected ({p} < {lvl}): the residuals of {self.output} correlate with "
                f"future values of {self.input}, so {self.input} depends on past outputs and the "
                "record was taken in closed loop. Open-loop estimators (ARX, OE, IV on u → y) "
                "are biased on it; use the direct approach with a noise model (fit_bj), the "
                "two-stage method (fit_two_stage), closed-loop IV (fit_cliv) or, with a known "
                "controller, the indirect approach (fit_indirect_tf)"
            )
        return (
            f"no evidence of feedback ({p} >= {lvl}): the residuals of {self.output} do not "
            f"correlate with future values of {self.input}; open-loop estimators apply"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "statistic": self.statistic,
            "pvalue": self.pvalue,
            "dof": list(self.dof),
            "lags": self.lags.tolist(),
            "cross_correlation": self.cross_correlation.tolist(),
            "bound": self.bound,
            "confidence": self.confidence,
            "order": self.order,
            "n_samples": self.n_samples,
            "input": self.input,
            "output": self.output,
            "residuals": self.residuals,
            "has_feedback": self.has_feedback,
            "message": self.message,
        }


def feedback_test(
    data: Experiment | ExperimentSet,
    *,
    model: PolynomialModel | TransferFunction | Estimate | None = None,
    input: str = "u",
    output: str | None = None,
    max_lag: int = 25,
    confidence: float = 0.99,
    order: int | None = None,
) -> FeedbackTest:
    """Test a record for feedback from the output to the input.

    See the module notes for the statistic (Ljung §16.6; Sims 1972).  A
    record taken in closed loop makes the test fire; on an open-loop record
    it fires with probability 1 − `confidence`.  The reference channel, if
    any, is not used.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the input and the output; segments are not joined.
    model : PolynomialModel, TransferFunction or Estimate, optional
        A model of y from u whose one-step residuals are tested.  Default:
        none; the high-order ARX model of the test regression is the model.
    input : str
        Input channel name, or ``"u"`` for the only plant input.
    output : str, optional
        Output channel name when there are several.
    max_lag : int
        Number M of future inputs u(t + 1)…u(t + M) [samples], >= 1.
    confidence : float
        Level in (0, 1); the test fires when p < 1 − confidence.
    order : int, optional
        ARX order n of the residual model (lags of s and u); default: the
        AIC choice within 0…30 (fewer for short records).

    Returns
    -------
    FeedbackTest
        Statistic, p-value, cross-correlation with its band and verdict.

    Raises
    ------
    DataError
        A missing channel, or too few samples for `max_lag` and the order.
    IdentifiabilityError
        A constant input, or future inputs that past inputs predict
        exactly (a pure periodic signal: nothing left to test).
    ModelError
        A model at another dt or with several inputs.

    Examples
    --------
    >>> from servoid.bench import simulate_lti
    >>> from servoid.models import TransferFunction
    >>> u = np.sign(np.random.default_rng(0).standard_normal(2000))
    >>> exp = simulate_lti(TransferFunction([4.0], [1.0, 2.0]), u, 0.1, noise_std=0.1)
    >>> feedback_test(exp).has_feedback
    False
    """
    m_lag = as_int("max_lag", max_lag, minimum=1)
    conf = as_float("confidence", confidence)
    if not 0.0 < conf < 1.0:
        raise DataError(f"confidence must lie in (0, 1), got {confidence!r}")
    segments = as_segments(data)
    first = segments[0]
    u_name = single_name(first, "u", check_name("input", input), "plant input")
    y_name = output_name(first, output)
    us = [np.asarray(seg[u_name], dtype=float) for seg in segments]
    check_excites(u_name, us, "u")
    if model is None:
        ss = [np.asarray(seg[y_name], dtype=float) for seg in segments]
    else:
        ss = [_model_residuals(model, seg[y_name], u, seg.dt) for seg, u in zip(segments, us,
                                                                                strict=True)]
    lengths = [u.size for u in us]
    usable = sum(max(n - m_lag, 0) for n in lengths)
    if order is None:
        n_max = int(min(_MAX_ORDER, max((usable // _ROWS_PER_PARAMETER - m_lag - 1) // 2, 0)))
    else:
        n_max = as_int("order", order, minimum=0)
    head = max(n_max, 1)
    n_rows = sum(max(n - head - m_lag, 0) for n in lengths)
    n_cols = 2 * n_max + 1 + m_lag
    if n_rows <= n_cols + 10:
        raise DataError(
            f"the feedback test with max_lag = {m_lag} and ARX order {n_max} needs more than "
            f"{head + m_lag + n_cols + 10} samples, got {max(lengths)}; use a longer record or "
            "a smaller max_lag"
        )
    # The regression is never formed: its columns are lags of s and u, so one Gram matrix of
    # lagged products gives every fit, and the residuals come from the data with the fitted
    # coefficients (memory a few N, not N × (2n + M) several times over).
    cols = _Columns(n_max, m_lag)
    centred = _segments(ss, us, cols, head)
    gram, sums = _lagged_sums(centred, cols)
    pt = np.r_[np.arange(cols.n_past), cols.target]
    n = n_max if order is not None else aic_order_gram(gram[np.ix_(pt, pt)], n_rows, [
        1 + 2 * k for k in range(n_max + 1)])
    k_r = 1 + 2 * n
    normal = _Normal(gram)
    restricted = np.arange(k_r)
    future = cols.future
    full = np.r_[restricted, future]
    coef_r, rank_r = normal.solve(restricted, cols.target)
    coef_f, rank_f = normal.solve(full, cols.target)
    fit = _residual_sums(centred, cols, (restricted, coef_r), (full, coef_f),
                         np.r_[restricted, future])
    rss_r, rss_f = fit.squares
    q = rank_f - rank_r
    if q < 1:
        raise IdentifiabilityError(
            f"the future values of {u_name!r} are exact linear combinations of its past (a "
            "noiseless periodic signal with few harmonics), so the record cannot show whether "
            f"{u_name!r} depends on past outputs; test a record with a random or noisy input"
        )
    dof_den = n_rows - rank_f
    stat = ((rss_r - rss_f) / q) / (rss_f / dof_den) if rss_f > 0 else math.inf
    pvalue = float(stats.f.sf(stat, q, dof_den))
    # only the part of u(t + τ) its past does not explain can show the noise fed back
    corr = _new_part_correlation(normal, gram, sums, fit, restricted, future, n_rows)
    bound = float(stats.norm.ppf(0.5 + conf / 2) / np.sqrt(n_rows))
    return FeedbackTest(
        statistic=float(stat), pvalue=pvalue, dof=(int(q), int(dof_den)),
        lags=np.arange(1, m_lag + 1), cross_correlation=corr, bound=bound, confidence=conf,
        order=int(n), n_samples=int(n_rows), input=u_name, output=y_name,
        residuals="arx" if model is None else "model",
    )


def warn_if_feedback(
    data: Experiment | ExperimentSet,
    method: str,
    *,
    input: str = "u",
    output: str | None = None,
    confidence: float = 0.99,
) -> FeedbackTest:
    """Warn when an open-loop method meets closed-loop data.

    Runs :func:`feedback_test` with its defaults and, when it fires, issues
    a :class:`~servoid.ServoidWarning` that names `method` and the remedies.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s) the open-loop method is about to fit.
    method : str
        Name of that method, for the message (e.g. ``"oe"``).
    input : str
        Input channel name, or ``"u"`` for the only plant input.
    output : str, optional
        Output channel name when there are several.
    confidence : float
        Level of the test, in (0, 1).

    Returns
    -------
    FeedbackTest
        The test, whether it fired or not.
    """
    test = feedback_test(data, input=input, output=output, confidence=confidence)
    if test.has_feedback:
        warn(f"{method} is an open-loop method, but {test.message}", ServoidWarning)
    return test


def _model_residuals(
    model: object, y: NDArray[np.float64], u: NDArray[np.float64], dt: float
) -> NDArray[np.float64]:
    m = model.model if isinstance(model, Estimate) else model
    if isinstance(m, PolynomialModel):
        if m.n_inputs != 1:
            raise ModelError(f"the feedback test takes a single-input model, got {m.n_inputs} "
                             "inputs; test each input with its own model")
        _check_dt(m.dt, dt)
        return np.asarray(m.residuals(y, u), dtype=float)
    if isinstance(m, TransferFunction):
        if m.dt is None:
            raise ModelError("model is continuous; discretise it at the data dt with c2d first")
        _check_dt(m.dt, dt)
        return np.asarray(y - m.simulate(u), dtype=float)
    raise type_error("model", model, "a PolynomialModel, a discrete TransferFunction or an "
                     "Estimate")


def _check_dt(model_dt: float, dt: float) -> None:
    if not math.isclose(model_dt, dt, rel_tol=1e-9):
        raise ModelError(f"the model has dt = {model_dt} s but the data have dt = {dt} s; use a "
                         "model identified at the data rate")


@dataclass(frozen=True)
class _Columns:
    """The test regression's columns as (signal, lag) of z = (s, u), in a shifted time.

    Interleaved u(t), s(t−1), u(t−1), …, s(t−n), u(t−n) (so order k is the
    first 2k + 1), then u(t+1)…u(t+M), then the target s(t).  Time is counted
    from t' = t + M, so every lag is ≥ 0 and the rows t = head…N−M−1 are
    t' = head + M…N−1.
    """

    n_max: int
    m_lag: int

    @property
    def n_past(self) -> int:
        return 2 * self.n_max + 1

    @property
    def future(self) -> NDArray[np.int64]:
        return np.arange(self.n_past, self.n_past + self.m_lag)

    @property
    def target(self) -> int:
        return self.n_past + self.m_lag

    @cached_property
    def signal(self) -> NDArray[np.int64]:
        past = [1] + [k % 2 for k in range(2 * self.n_max)]  # u, then s, u, s, u, …
        return np.array(past + [1] * self.m_lag + [0], dtype=np.int64)

    @cached_property
    def lag(self) -> NDArray[np.int64]:
        m = self.m_lag
        past = [m] + [m + 1 + k // 2 for k in range(2 * self.n_max)]
        return np.array(past + [m - tau for tau in range(1, m + 1)] + [m], dtype=np.int64)

    def view(self, z: tuple[NDArray[np.float64], ...], col: int,
             start: int) -> NDArray[np.float64]:
        """Column ``col`` over the rows t' = start…N−1 (a view of the signal)."""
        x = z[int(self.signal[col])]
        lag = int(self.lag[col])
        return x[start - lag : x.size - lag]


#: A segment of the test: z = (s, u) centred on the segment, and its first row t'.
_Segment = tuple[tuple[NDArray[np.float64], NDArray[np.float64]], int]


def _segments(ss: list[NDArray[np.float64]], us: list[NDArray[np.float64]], cols: _Columns,
              head: int) -> list[_Segment]:
    """The segments with rows, centred once for the Gram sums and the residual sums."""
    return [((s - s.mean(), u - u.mean()), head + cols.m_lag)
            for s, u in zip(ss, us, strict=True) if s.size - cols.m_lag - head > 0]


def _lagged_sums(segments: list[_Segment],
                 cols: _Columns) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gram matrix of the columns over every segment's rows, and each column's sum."""
    from ..estimate import lagged_gram

    size = cols.target + 1
    gram, sums = np.zeros((size, size)), np.zeros(size)
    for z, start in segments:
        gram += lagged_gram(z, cols.signal, cols.lag, start)
        sums += [float(np.sum(cols.view(z, c, start))) for c in range(size)]
    return gram, sums


class _Fit(NamedTuple):
    """What the tests need of the residuals of the target's fits, summed over segments."""

    squares: tuple[float, ...]  # Σ e² of each fit
    total: float  # Σ e of the first fit
    products: NDArray[np.float64]  # Σ e·x_c of the first fit's residual with the columns asked


def _residual_sums(segments: list[_Segment], cols: _Columns,
                   first: tuple[NDArray[np.int64], NDArray[np.float64]],
                   second: tuple[NDArray[np.int64], NDArray[np.float64]],
                   against: NDArray[np.int64]) -> _Fit:
    """Sums of the residuals e = s(t) − Σ c_j x_j(t) of two fits, from the data.

    Formed a chunk of rows at a time, so no residual of the record's length
    is held beyond the centred signals.
    """
    squares = [0.0, 0.0]
    total = 0.0
    products = np.zeros(against.size)
    for z, start in segments:
        views = {int(c): cols.view(z, int(c), start)
                 for c in np.r_[first[0], second[0], against, cols.target]}
        rows = views[cols.target].size
        e = np.empty(min(rows, _CHUNK))
        tmp = np.empty_like(e)
        for lo in range(0, rows, _CHUNK):
            hi = min(lo + _CHUNK, rows)
            ec, tc = e[: hi - lo], tmp[: hi - lo]
            for k, (which, coef) in ((1, second), (0, first)):  # the first fit's residual last
                ec[:] = views[cols.target][lo:hi]
                for c, w in zip(which, coef, strict=True):
                    np.multiply(views[int(c)][lo:hi], w, out=tc)
                    ec -= tc
                squares[k] += float(ec @ ec)
            total += float(np.sum(ec))
            products += [float(ec @ views[int(c)][lo:hi]) for c in against]
    return _Fit((squares[0], squares[1]), total, products)


class _Normal:
    """Least squares on column subsets of one column-scaled Gram matrix."""

    def __init__(self, gram: NDArray[np.float64]) -> None:
        scale = np.sqrt(np.diag(gram).copy())
        scale[scale == 0] = 1.0
        self.scale = scale
        self.gram = gram / np.outer(scale, scale)

    def solve(self, cols: NDArray[np.int64], target: int | NDArray[np.int64],
              rcond: float = 1e-10) -> tuple[NDArray[np.float64], int]:
        """Coefficients of column(s) ``target`` on columns ``cols``, and the rank used."""
        eig, vec = np.linalg.eigh(self.gram[np.ix_(cols, cols)])
        keep = eig > rcond * max(float(eig[-1]), 1e-300)
        rhs = self.gram[cols][:, target]
        shape = (-1,) + (1,) * (np.ndim(rhs) - 1)
        coef = vec[:, keep] @ ((vec[:, keep].T @ rhs) / eig[keep].reshape(shape))
        return coef / self.scale[cols].reshape(shape) * self.scale[target], int(keep.sum())


def _new_part_correlation(normal: _Normal, gram: NDArray[np.float64], sums: NDArray[np.float64],
                          fit: _Fit, restricted: NDArray[np.int64], future: NDArray[np.int64],
                          n_rows: int) -> NDArray[np.float64]:
    """Correlation of the restricted residual e with f_τ = u(t + τ) less its fit on the past.

    From sums only: ⟨e, f_τ⟩ = ⟨e, u(t+τ)⟩ − c_τ·⟨e, x_past⟩, Σf_τ and ‖f_τ‖² from the Gram
    matrix (c_τ the coefficients of u(t + τ) on the past), both centred on their means.
    """
    c, _ = normal.solve(restricted, future)  # (k_r, M)
    k_r = restricted.size
    ef = fit.products[k_r:] - c.T @ fit.products[:k_r]
    f_sum = sums[future] - c.T @ sums[restricted]
    g_rr = gram[np.ix_(restricted, restricted)]
    f_sq = (np.diag(gram)[future] - 2.0 * np.einsum("rt,rt->t", c, gram[np.ix_(restricted, future)])
            + np.einsum("rt,rs,st->t", c, g_rr, c))
    e_mean = fit.total / n_rows
    e_sq = fit.squares[0] - fit.total * e_mean
    f_c = np.maximum(f_sq - f_sum * f_sum / n_rows, 0.0)
    norm = np.sqrt(max(e_sq, 0.0) * f_c)
    out = np.zeros(future.size)
    ok = norm > 0
    out[ok] = (ef - e_mean * f_sum)[ok] / norm[ok]
    return out
