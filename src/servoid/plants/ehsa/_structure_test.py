"""Do the data reject the reduced model? Nested structures compared.

One-step fits of nested plant structures (:mod:`._structures`) to the same
estimation data are compared three ways (Ljung, *System Identification*,
2nd ed., 1999, §16.4 and §16.6; Söderström & Stoica, *System
Identification*, 1989, §11.2–11.5):

**Likelihood ratio.**  With N residuals, ``V = Σε²/N`` and Gaussian white
output noise, the log-likelihood of an output-error fit is
``−(N/2)·ln V + const``, so for a structure S nested in a larger L with
Δd more parameters::

    LR = N·ln(V_S/V_L)  ~  χ²(Δd)   when S is right  (asymptotically)

(S&S's F form ``N(V_S − V_L)/V_L`` is the same to first order).  The
larger structures here add a valve lag τ_v >= 0 and reduce to S at
τ_v = 0, *on the bound*: then LR ~ ½χ²(0) + ½χ²(1) (Chernoff 1954; Self &
Liang 1987) and the p-value is half the χ²(1) tail.

**Coloured residuals.**  An output-error model has no noise model; its
residual keeps the noise's colour (here the rig's anti-alias filter and
decimation), and the likelihood above is a quasi-likelihood.  Then LR is
no longer χ²: to first order ``V_S − V_L`` is the squared projection of
the noise on the one direction the extra parameter adds,
``d = ŷ_L − ŷ_S = ε_S − ε_L``, whose variance is ``dᵀR_ε d/‖d‖²``, not
σ².  So ``LR ~ c·χ²(1)`` with::

    c = dᵀ R̂_ε d / (σ̂²·‖d‖²)

and the test uses ``LR/c`` (the scaled quasi-likelihood ratio; for one
restriction it equals the sandwich-robust Wald statistic of τ_v).  R̂_ε
is the larger model's residual autocovariance with its AIC-chosen AR
extension, the estimator every robust covariance in servoid uses
(:mod:`servoid.estimate._covariance`); c = 1 exactly when the residuals
look white.  For Δd > 1 the scale along d is an approximation (all
registered structures have Δd = 1).  AIC ``N ln V + 2d`` and BIC
``N ln V + d ln N`` are reported; their penalties assume white residuals
too and are not used for the verdict.

**Residual tests on the estimation data.**  Whiteness (Ljung–Box) and
independence of the residual from the reference r, by
:func:`servoid.validate.residual_analysis`; r is external to the loop, so
every lag is tested.  The output-error fit itself makes the residual
orthogonal to its gradient, which correlates with r at short lags, so on
estimation data the independence test is conservative.  Whiteness is
reported, not used: for output error a coloured residual says the noise is
coloured, not that the plant structure is wrong.

**Verdict.**  The smallest structure (the base, normally ``"reduced"``) is
rejected when a likelihood-ratio test against any larger structure or the
independence test of its residual rejects, each at ``level/m`` for m tests
(Bonferroni), so a right base model is rejected with probability at most
`level`.  A rejected model's intervals describe the noise only, not the
structural error, and understate the error of its parameters; the result
says so, with how far the larger structures move them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float, as_int, as_mapping, type_error
from ..._errors import ChannelError, DataError, OptionError, ServoidWarning
from ..._lazy import stats
from ..._warn import warn
from ...closedloop import sandwich
from ...data import Experiment, ExperimentSet, as_segments
from ...estimate import Estimate
from ...validate import residual_analysis
from ._loop import PARAMETER_NAMES
from ._result import ClosedLoopResult
from ._structures import STRUCTURES, PlantStructure

__all__ = ["NestedTest", "StructureFit", "StructureTest", "compare_structures"]

#: A lag below this is zero to the solver's precision when no standard deviation is known [s].
_TINY_LAG = 1e-12
#: Relative excess of the larger structure's cost over the smaller's that is still rounding
#: (the solvers stop at a relative cost change of 1e-10).
_COST_RTOL = 1e-8

Result = ClosedLoopResult | Estimate


@dataclass(frozen=True)
class StructureFit:
    """One structure's fit to the estimation data.

    Parameters
    ----------
    name : str
        The structure.
    n_parameters : int
        Number of parameters d.
    cost : float
        ``V = Σε²/N`` [output unit²].
    aic, bic : float
        ``N ln V + 2d`` and ``N ln V + d ln N``.
    whiteness_pvalue : float
        Ljung–Box test of the residual on the estimation data.
    independence_pvalue : float
        Test of the residual's independence from the reference r.
    parameters : dict of str to float
        The estimate θ̂ by name.
    reduced : dict of str to float
        K, omega_hp, delta_hp this θ̂ corresponds to.
    reduced_std : dict of str to float
        Their standard deviations (the fit's own, robust covariance),
        empty when the fit carries none.
    """

    name: str
    n_parameters: int
    cost: float
    aic: float
    bic: float
    whiteness_pvalue: float
    independence_pvalue: float
    parameters: dict[str, float] = field(default_factory=dict)
    reduced: dict[str, float] = field(default_factory=dict)
    reduced_std: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "name": self.name,
            "n_parameters": self.n_parameters,
            "cost": self.cost,
            "aic": self.aic,
            "bic": self.bic,
            "whiteness_pvalue": self.whiteness_pvalue,
            "independence_pvalue": self.independence_pvalue,
            "parameters": dict(self.parameters),
            "reduced": dict(self.reduced),
            "reduced_std": dict(self.reduced_std),
        }


@dataclass(frozen=True)
class NestedTest:
    """Likelihood-ratio test of a structure against a larger one.

    Parameters
    ----------
    smaller, larger : str
        The nested pair.
    df : int
        Δd, the number of restrictions.
    lr : float
        ``N·ln(V_smaller/V_larger)`` (0 when the larger fit ended above the
        smaller's cost, see `note`).
    scale : float
        c, the noise variance along the direction the extra parameters add
        over σ̂² (1: white residuals).
    lr_robust : float
        ``lr / scale``, the statistic tested.
    one_sided : bool
        The smaller structure lies on a bound of the larger (τ_v = 0): the
        null law is ½χ²(0) + ½χ²(1).
    p_value : float
        P-value of `lr_robust`.
    p_value_white : float
        P-value of `lr` itself (right only for white residuals).
    level : float
        Level this test is judged at (the Bonferroni share).
    extra : dict of str to float
        The extra parameters' estimates in the larger structure.
    note : str
        Why the statistic was clipped, empty otherwise.
    extra_std : dict of str to float
        Their standard deviations (the smallest value the data resolve).
    """

    smaller: str
    larger: str
    df: int
    lr: float
    scale: float
    lr_robust: float
    one_sided: bool
    p_value: float
    p_value_white: float
    level: float
    extra: dict[str, float] = field(default_factory=dict)
    note: str = ""
    extra_std: dict[str, float] = field(default_factory=dict)

    @property
    def rejected(self) -> bool:
        """True when the smaller structure is rejected at `level`."""
        return bool(self.p_value < self.level)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "smaller": self.smaller,
            "larger": self.larger,
            "df": self.df,
            "lr": self.lr,
            "scale": self.scale,
            "lr_robust": self.lr_robust,
            "one_sided": self.one_sided,
            "p_value": self.p_value,
            "p_value_white": self.p_value_white,
            "level": self.level,
            "rejected": self.rejected,
            "extra": dict(self.extra),
            "note": self.note,
            "extra_std": dict(self.extra_std),
        }


@dataclass(frozen=True)
class StructureTest:
    """Whether the data reject the base (reduced) structure.

    Parameters
    ----------
    base : str
        The smallest structure, nested in every other (``"reduced"``).
    fits : tuple of StructureFit
        Every structure's cost, information criteria and residual tests.
    tests : tuple of NestedTest
        The base against each larger structure.
    level : float
        Probability of rejecting a right base model (Bonferroni over
        `tests` and the base's independence test).
    n_samples : int
        Residuals N in the criterion.
    rejected : bool
        True when the data reject the base structure.
    reasons : tuple of str
        The tests that reject it, in words.
    preferred : str
        The base if not rejected, else the structure with the lowest BIC.
    shifts : dict
        Per larger structure, per reduced parameter: the move from the base
        estimate in units of the base's standard deviation.
    base_reduced : dict of str to tuple of float
        The base's K, omega_hp, delta_hp as (value, standard deviation).
    """

    base: str
    fits: tuple[StructureFit, ...]
    tests: tuple[NestedTest, ...]
    level: float
    n_samples: int
    rejected: bool
    reasons: tuple[str, ...]
    preferred: str
    shifts: dict[str, dict[str, float]] = field(default_factory=dict)
    base_reduced: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def intervals_understate(self) -> bool:
        """True when the base's intervals understate its error."""
        return self.rejected

    def fit(self, name: str) -> StructureFit:
        """Return the fit of the structure `name`.

        Parameters
        ----------
        name : str
            A structure in the comparison.
        """
        for f in self.fits:
            if f.name == name:
                return f
        raise ChannelError(f"no structure {name!r}; compared: "
                           f"{', '.join(f.name for f in self.fits)}")

    @property
    def verdict(self) -> str:
        """The verdict in words, with what it means for the intervals."""
        lvl = f"{100 * self.level:.3g} %"
        if not self.rejected:
            alts = "; ".join(f"{t.larger}: {_extra_text(t)}, {_p(t.p_value)}" for t in self.tests)
            base = self.fit(self.base)
            richer = (f"no richer structure explains significantly more ({alts})" if alts
                      else "no richer structure was compared")
            return (
                f"the data do not reject the {self.base} model (level {lvl}): {richer}, and its "
                f"residuals are independent of the reference ({_p(base.independence_pvalue)}); "
                "its intervals stand as far as the noise assumptions do"
            )
        text = (f"the data reject the {self.base} model (level {lvl}): "
                + "; ".join(self.reasons) + ". ")
        text += ("Its intervals understate the error: they describe the noise, not the "
                 "structural error")
        moved = self.shifts.get(self.preferred, {})
        pref = self.fit(self.preferred) if self.preferred != self.base else None
        if moved and pref is not None:
            parts = []
            for name, z in moved.items():
                value, std = self.base_reduced[name]
                own = pref.reduced_std.get(name, math.nan)
                spread = f" ± {own:.2g}" if math.isfinite(own) else ""
                parts.append(f"{name} {pref.reduced[name]:.5g}{spread} vs {value:.5g} ± "
                             f"{std:.2g} ({z:+.3g} σ)")
            text += f"; under {self.preferred} (lowest BIC): " + ", ".join(parts)
        return text

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "base": self.base,
            "level": self.level,
            "n_samples": self.n_samples,
            "rejected": self.rejected,
            "intervals_understate": self.intervals_understate,
            "preferred": self.preferred,
            "reasons": list(self.reasons),
            "verdict": self.verdict,
            "fits": [f.to_dict() for f in self.fits],
            "tests": [t.to_dict() for t in self.tests],
            "shifts": {k: dict(v) for k, v in self.shifts.items()},
            "base_reduced": {k: list(v) for k, v in self.base_reduced.items()},
        }

    def __str__(self) -> str:
        lines = [f"structure test, {self.n_samples} samples, level {self.level:.3g}"]
        lines.append(f"  {'structure':<12} {'d':>2} {'V':>11} {'AIC':>11} {'BIC':>11} "
                     f"{'white p':>8} {'indep p':>8}")
        for f in self.fits:
            lines.append(f"  {f.name:<12} {f.n_parameters:>2} {f.cost:>11.4g} {f.aic:>11.6g} "
                         f"{f.bic:>11.6g} {f.whiteness_pvalue:>8.2g} "
                         f"{f.independence_pvalue:>8.2g}")
        for t in self.tests:
            side = ", one-sided" if t.one_sided else ""
            lines.append(f"  {t.smaller} vs {t.larger}: LR {t.lr:.4g}, scale {t.scale:.3g}, "
                         f"robust {t.lr_robust:.4g} (χ²({t.df}){side}), {_p(t.p_value)}; "
                         f"{_extra_text(t)}")
            if t.note:
                lines.append(f"    ! {t.note}")
        mark = "!" if self.rejected else " "
        lines.append(f"{mark} {self.verdict}")
        return "\n".join(lines)


def compare_structures(
    results: Mapping[str, Result] | Sequence[Result],
    data: Experiment | ExperimentSet,
    *,
    level: float = 0.01,
    max_lag: int = 25,
    structures: Mapping[str, PlantStructure] | None = None,
) -> StructureTest:
    """Test whether the data reject the reduced plant structure.

    Likelihood-ratio tests of the smallest structure against each larger
    one that nests it, scaled for coloured residuals, AIC and BIC, and
    whiteness and reference–residual independence tests on the estimation
    data; see the module notes for the statistics (Ljung §16.4, §16.6;
    Söderström & Stoica §11.5).

    Parameters
    ----------
    results : mapping of str to result, or sequence of results
        One-step fits (:class:`ClosedLoopResult` or the output-error
        :class:`~servoid.estimate.Estimate` behind one) of nested
        structures to the same data, keyed by structure name.  A sequence
        works when each fit names its structure (``ClosedLoopResult.structure``,
        or ``options["structure"]`` of an Estimate).
    data : Experiment or ExperimentSet
        The estimation data the fits used (their reference r).
    level : float
        Probability of rejecting a right base model, in (0, 1).
    max_lag : int
        Largest lag M of the residual tests [samples].
    structures : mapping of str to PlantStructure, optional
        Structures beyond (or replacing) the registered ones, e.g. a
        :func:`full_order_structure` of the user's nominal set.

    Returns
    -------
    StructureTest
        The fits, the nested tests, the verdict in words and whether the
        base model's intervals understate its error.

    Raises
    ------
    DataError
        Fits of different lengths, or whose residuals do not match the data.
    OptionError
        An unknown structure name, or structures that do not nest.

    Warns
    -----
    ServoidWarning
        The base model is rejected; or a larger fit ended above the cost
        of the smaller one it contains (it missed its optimum).
    """
    level = as_float("level", level)
    if not 0.0 < level < 1.0:
        raise OptionError(f"level must lie in (0, 1), got {level}")
    max_lag = as_int("max_lag", max_lag, minimum=1)
    extra = {} if structures is None else as_mapping("structures", structures)
    for name, structure in extra.items():
        if not isinstance(structure, PlantStructure):
            raise type_error(f"structures[{name!r}]", structure, "a PlantStructure")
    catalogue = {**STRUCTURES, **extra}
    fits = _resolve(results, catalogue)
    base = _base(fits, catalogue)
    segments = as_segments(data)
    errors = {name: _residuals(est) for name, (_, est) in fits.items()}
    n = _common_length(errors)
    start = _common_start(fits)
    reference = _reference(segments, start, n)
    sizes = [seg.n_samples - start for seg in segments]
    confidence = 1.0 - level

    rows: list[StructureFit] = []
    for name, (_, est) in fits.items():
        e = errors[name]
        v = float(e @ e) / n
        d = est.parameters.size
        ra = residual_analysis(e, reference, max_lag=max_lag, confidence=confidence)
        structure = catalogue[name]
        theta = np.asarray(est.parameters, dtype=float)
        red = dict(zip(PARAMETER_NAMES, structure.reduced(theta), strict=True))
        rows.append(StructureFit(
            name, d, v, n * math.log(v) + 2 * d, n * math.log(v) + d * math.log(n),
            ra.whiteness_pvalue, ra.independence_pvalue,
            {k: float(x) for k, x in zip(est.names, theta, strict=True)}, red,
            {k: s for k, (_, s) in _base_reduced(fits[name], structure).items()}))

    larger = [name for name in fits if name != base]
    share = level / (len(larger) + 1)
    tests = tuple(
        _nested_test(base, name, fits, errors, catalogue, sizes, share) for name in larger
    )
    base_fit = next(f for f in rows if f.name == base)
    reasons = [
        f"{t.larger} explains significantly more (LR {t.lr:.4g}, robust {t.lr_robust:.4g}, "
        f"{_p(t.p_value)}; {_extra_text(t)})"
        for t in tests if t.rejected
    ]
    if base_fit.independence_pvalue < share:
        reasons.append(f"its residuals depend on the reference "
                       f"({_p(base_fit.independence_pvalue)})")
    rejected = bool(reasons)
    preferred = min(rows, key=lambda f: f.bic).name if rejected else base
    base_reduced = _base_reduced(fits[base], catalogue[base])
    shifts = {
        f.name: {k: (f.reduced[k] - base_reduced[k][0]) / base_reduced[k][1]
                 for k in PARAMETER_NAMES if base_reduced[k][1] > 0}
        for f in rows if f.name != base
    }
    result = StructureTest(base, tuple(rows), tests, level, n, rejected, tuple(reasons),
                           preferred, shifts, base_reduced)
    if rejected:
        warn(result.verdict, ServoidWarning)
    return result


# -- private helpers ---------------------------------------------------------------------------


def _resolve(
    results: Mapping[str, Result] | Sequence[Result], catalogue: Mapping[str, PlantStructure]
) -> dict[str, tuple[Result, Estimate]]:
    if isinstance(results, Mapping):
        items = list(results.items())
    elif isinstance(results, Sequence) and not isinstance(results, str):
        items = []
        for r in results:
            est = _source(r)
            name = r.structure if isinstance(r, ClosedLoopResult) else est.options.get("structure")
            if not isinstance(name, str):
                raise DataError(
                    f"a {type(r).__name__} in the sequence does not name its structure "
                    "(options['structure']); pass a mapping {structure name: result}"
                )
            items.append((name, r))
    else:
        raise type_error("results", results, "a mapping {structure name: result} or a "
                         "sequence of ClosedLoopResult/Estimate")
    if not items:
        raise DataError("results is empty: give at least the reduced model's fit")
    out: dict[str, tuple[Result, Estimate]] = {}
    for name, r in items:
        if name not in catalogue:
            raise OptionError(f"unknown structure {name!r}; known: {', '.join(catalogue)} "
                              "(pass others with structures=)")
        if name in out:
            raise DataError(f"structure {name!r} appears twice in results")
        est = _source(r)
        structure = catalogue[name]
        if est.parameters.size != structure.n_parameters:
            raise DataError(
                f"the {name!r} fit has {est.parameters.size} parameters "
                f"({', '.join(est.names)}), the structure {structure.n_parameters} "
                f"({', '.join(structure.names)})"
            )
        out[name] = (r, est)
    return out


def _source(r: object) -> Estimate:
    if isinstance(r, ClosedLoopResult):
        return r.source
    if isinstance(r, Estimate):
        return r
    raise type_error("each result", r, "a ClosedLoopResult or an Estimate (one fit per "
                     "structure)")


def _chain(name: str, catalogue: Mapping[str, PlantStructure]) -> list[str]:
    """The structure and every smaller one it nests, largest first."""
    out = [name]
    while (smaller := catalogue[out[-1]].nests) is not None:
        if smaller not in catalogue or smaller in out:
            raise OptionError(f"structure {out[-1]!r} nests {smaller!r}, which is unknown or "
                              "circular")
        out.append(smaller)
    return out


def _base(fits: Mapping[str, object], catalogue: Mapping[str, PlantStructure]) -> str:
    chains = {name: _chain(name, catalogue) for name in fits}
    roots = [name for name in fits if all(name in chain for chain in chains.values())]
    if not roots:
        raise OptionError(
            f"the structures {', '.join(fits)} do not all nest one of them; compare each "
            "larger structure with the one it contains (e.g. 'reduced')"
        )
    # the smallest common one: the root every chain reaches last among the fits
    return min(roots, key=lambda name: catalogue[name].n_parameters)


def _residuals(est: Estimate) -> NDArray[np.float64]:
    e = np.asarray(est.residuals, dtype=float)
    if e.size == 0:
        raise DataError(f"the {est.method} estimate carries no residuals to test")
    if not np.all(np.isfinite(e)):
        raise DataError(f"the {est.method} estimate has non-finite residuals")
    if not np.any(e):
        raise DataError(f"the {est.method} estimate fits the data exactly (zero residuals): "
                        "noise-free data carry no evidence for or against a structure")
    return e


def _common_length(errors: Mapping[str, NDArray[np.float64]]) -> int:
    sizes = {name: e.size for name, e in errors.items()}
    if len(set(sizes.values())) != 1:
        listed = ", ".join(f"{k}: {v}" for k, v in sizes.items())
        raise DataError(f"the fits have different numbers of residuals ({listed}); a structure "
                        "test needs every structure fitted to the same data with the same start")
    return next(iter(sizes.values()))


def _common_start(fits: Mapping[str, tuple[Result, Estimate]]) -> int:
    starts = {name: int(est.options.get("start", 0) or 0) for name, (_, est) in fits.items()}
    if len(set(starts.values())) != 1:
        listed = ", ".join(f"{k}: {v}" for k, v in starts.items())
        raise DataError(f"the fits start their criteria at different samples ({listed}); "
                        "fit every structure with the same start")
    return next(iter(starts.values()))


def _reference(segments: Sequence[Experiment], start: int, n: int) -> NDArray[np.float64]:
    parts = []
    for seg in segments:
        if not seg.names_of("r"):
            raise DataError("the structure test correlates the residuals with the reference, "
                            "but the data have no reference ('r') channel")
        parts.append(seg.signal("r")[start:, 0])
    r = np.concatenate(parts)
    if r.size != n:
        raise DataError(
            f"the fits have {n} residuals but the data give {r.size} reference samples after "
            f"start = {start}: were the fits made on these data?"
        )
    return r


def _split(e: NDArray[np.float64], sizes: Sequence[int]) -> list[NDArray[np.float64]]:
    return np.split(e, np.cumsum(sizes)[:-1])


def _nested_test(
    small: str,
    large: str,
    fits: Mapping[str, tuple[Result, Estimate]],
    errors: Mapping[str, NDArray[np.float64]],
    catalogue: Mapping[str, PlantStructure],
    sizes: Sequence[int],
    level: float,
) -> NestedTest:
    chain = _chain(large, catalogue)
    steps = chain[:chain.index(small)]
    one_sided = all(all(catalogue[s].is_on_bound()) for s in steps)
    df = catalogue[large].n_parameters - catalogue[small].n_parameters
    e_s, e_l = errors[small], errors[large]
    n = e_s.size
    v_s, v_l = float(e_s @ e_s), float(e_l @ e_l)
    est_l = fits[large][1]
    extra_names = catalogue[large].names[catalogue[small].n_parameters:]
    extra = {k: float(est_l[k]) for k in extra_names}
    std = dict(zip(est_l.names, np.asarray(est_l.std, dtype=float), strict=True))
    extra_std = {k: float(std.get(k, math.nan)) for k in extra_names}
    note = ""
    if v_l > v_s * (1.0 + _COST_RTOL):
        note = (f"the {large} fit ended at a cost {v_l / v_s - 1:.2g} above the {small} fit's, "
                f"which is a point of {large} ({', '.join(extra_names)} at their null values): "
                f"it missed its optimum; refit {large} from the {small} estimate. The test "
                "counts LR = 0")
        warn(note, ServoidWarning)
    lr = max(n * math.log(v_s / v_l), 0.0) if not note else 0.0
    scale = _scale(e_s - e_l, e_l, sizes) if lr > 0 else 1.0
    lr_robust = lr / scale
    return NestedTest(small, large, df, lr, scale, lr_robust, one_sided,
                      _pvalue(lr_robust, df, one_sided), _pvalue(lr, df, one_sided), level,
                      extra, note, extra_std)


def _scale(direction: NDArray[np.float64], residual: NDArray[np.float64],
           sizes: Sequence[int]) -> float:
    """c = dᵀR̂d/(σ̂²‖d‖²): noise variance along d relative to white noise."""
    n = residual.size
    dd = float(direction @ direction)
    if not dd > 0.0:
        return 1.0
    psis = [d[:, None] for d in _split(direction, sizes)]
    cov, _ = sandwich(psis, _split(residual, sizes))
    sigma2 = float(residual @ residual) / max(n - 1, 1)  # as sandwich() forms it
    return float(cov[0, 0]) * dd / sigma2


def _pvalue(stat: float, df: int, one_sided: bool) -> float:
    if not stat > 0.0:
        return 1.0
    tail = float(stats.chi2.sf(stat, df))
    # ½χ²(0) + ½χ²(1) for one parameter on its bound; with several the χ²(df) tail bounds
    # the mixture's from above (conservative)
    return 0.5 * tail if one_sided and df == 1 else tail


def _extra_text(t: NestedTest) -> str:
    return ", ".join(_extra(k, v, t.extra_std.get(k, math.nan)) for k, v in t.extra.items())


def _extra(name: str, value: float, std: float) -> str:
    """``tau_v = 1.2 ms ± 0.1 ms``; a value inside its own std is not resolved: "none"."""
    if math.isfinite(std) and std > 0 and abs(value) < std:
        return (f"{name}: none resolved (the estimate lies within its standard deviation "
                f"{_seconds(name, std)}, the resolution of these data)")
    if not math.isfinite(std) and name.startswith("tau") and abs(value) < _TINY_LAG:
        return f"{name}: none (below {_seconds(name, _TINY_LAG)})"
    spread = f" ± {_seconds(name, std)}" if math.isfinite(std) and std > 0 else ""
    return f"{name} = {_seconds(name, value)}{spread}"


def _seconds(name: str, value: float) -> str:
    if not name.startswith("tau"):
        return f"{value:.4g}"
    if abs(value) >= 1e-3:
        return f"{value * 1e3:.3g} ms"
    if abs(value) >= 1e-9 or value == 0.0:
        return f"{value * 1e6:.3g} µs"
    return f"{value:.2g} s"


def _p(value: float) -> str:
    # the χ² tail underflows to 0 beyond a statistic of about 1400
    return "p < 1e-300" if value < 1e-300 else f"p = {value:.2g}"


def _base_reduced(fit: tuple[Result, Estimate],
                  structure: PlantStructure) -> dict[str, tuple[float, float]]:
    result, est = fit
    shown = result.estimate if isinstance(result, ClosedLoopResult) else est
    values = structure.reduced(np.asarray(est.parameters, dtype=float))
    std = {k: float(s) for k, s in zip(shown.names, shown.std, strict=True)}
    return {k: (float(v), std.get(k, math.nan)) for k, v in zip(PARAMETER_NAMES, values,
                                                                 strict=True)}
