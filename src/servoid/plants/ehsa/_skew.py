"""A channel skew the data cannot resolve, carried in the one-step intervals.

A multiplexed ADC reads the position a few µs after the reference.  The
reduced model absorbs that delay into ω_hp, and on a typical record the
two are nearly collinear: on Set B at 30 dB with 15 s of PRBS the
``reduced+skew`` structure (:func:`~._structures.skew_structure`)
resolves τ_d only to σ ≈ 7 µs, so a 12.5 µs skew is 1.8 σ — below any
test at a sane level (``benchmarks/bench_ehsa_validity.py``: the
structure test prefers the skew structure in 12 % of the records) — yet
it moves ω_hp by about 2 σ of the reduced interval.  No test can name a
cause the data do not resolve; the intervals can carry it instead when
the user states how large the skew may be.

``[loop] skew_tolerance = t`` [s] is read as the standard deviation of a
normal prior on the skew, τ_d ~ N(0, t²) (as the loop's other tolerances
are read as standard deviations, :mod:`._dc_gain`).  The ``reduced+skew``
fit gives θ̂ = (K, ω_hp, δ_hp, τ_d) with covariance Σ; the prior is one
more observation 0 = τ_d + e, e ~ N(0, t²), and conditioning the
linearised Gaussian on it gives::

    g = Σ[:, τ]/(Σ[τ, τ] + t²),   θ = θ̂ − g·τ̂,   Σ_θ = Σ − g·Σ[τ, :]

For t → ∞ these are the free skew fit's estimates and intervals; for
t → 0 they approach the reduced fit's (to first order).  The models of
the result (closed loop, plant, poles) stay the reduced fit's, which the
validation judges: the skew's Padé pole is a model of the measurement,
not of the actuator, and would be flagged as a plant pole.  A skew estimate beyond the prior
(``|τ̂| > 3·√(Σ[τ, τ] + t²)``) is a verdict: the channels are further
apart than stated.

Without a stated tolerance the reduced intervals assume no skew.  When the
record resolves the skew only coarsely, :func:`unresolved_skew` says so
from the ``reduced+skew`` fit the structure test makes anyway: a skew of
1.96 σ_τ — one the record cannot tell from none at 95 % — moves each
reduced parameter by ``g_i·1.96 σ_τ`` with ``g = Σ[:, τ]/Σ[τ, τ]`` (the
joint fit's regression of θ on τ_d), and where that exceeds the reduced
σ_i (:data:`SKEW_SHIFT`) the verdict states the assumption (an ``info``
check, since the data cannot tell) with the numbers and the skew fit's own
interval (which covers a skew of either size).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._checks import as_float
from ..._errors import ModelError, ServoidWarning
from ._loop import FeedbackLoop
from ._onestep import fit_one_step
from ._result import ClosedLoopResult
from ._structure_test import _seconds
from ._structures import skew_structure

__all__ = ["SkewAdjustment", "UnresolvedSkew", "skew_prior", "unresolved_skew",
           "with_skew_tolerance"]

#: |τ̂| beyond this many standard deviations of (data + prior) is a skew beyond the tolerance.
SKEW_BEYOND = 3.0
#: A skew the record cannot resolve (1.96 σ_τ) moving a parameter by more than this many of its
#: reduced σ is stated in the verdict.
SKEW_SHIFT = 1.0
#: The reduced parameters, their labels in the note.
_LABELS = {"K": "K", "omega_hp": "ω_hp", "delta_hp": "δ_hp"}


@dataclass(frozen=True)
class SkewAdjustment:
    """The one-step result with a stated channel skew in its intervals.

    Parameters
    ----------
    result : ClosedLoopResult
        The adjusted one-step result: the reduced fit's models, its
        estimate K, ω_hp, δ_hp from the skew fit with the prior applied.
    tolerance : float
        The stated skew tolerance t [s] (the prior's standard deviation).
    tau : float
        The free fit's skew estimate τ̂ [s].
    tau_std : float
        Its standard deviation from the data alone [s].
    tau_posterior : float
        The skew with the prior applied [s].
    """

    result: ClosedLoopResult
    tolerance: float
    tau: float
    tau_std: float
    tau_posterior: float

    @property
    def z(self) -> float:
        """τ̂ over the spread of data and prior combined."""
        return self.tau / math.hypot(self.tau_std, self.tolerance)

    @property
    def beyond(self) -> bool:
        """True when the skew estimate lies beyond the stated tolerance."""
        return abs(self.z) > SKEW_BEYOND

    @property
    def note(self) -> str:
        """The note for the result: the skew found and what the intervals carry."""
        head = (f"one-step: the intervals carry a channel skew of ±{_seconds('tau', self.tolerance)}"
                f" ([loop] skew_tolerance): the skew is estimated beside K, ω_hp and δ_hp "
                f"(tau_d = {_seconds('tau', self.tau)} ± {_seconds('tau', self.tau_std)} from "
                f"the data, {_seconds('tau', self.tau_posterior)} with the tolerance); the models "
                "shown and validated are the reduced fit's")
        if not self.beyond:
            return head
        return (head + f"; the skew lies beyond the tolerance (z = {self.z:+.1f}): the position "
                "is read further from the reference than stated — check the ADC's channel "
                "sequence or a dead time in the reference path, or state a larger "
                "skew_tolerance")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for JSON."""
        return {"tolerance": self.tolerance, "tau": self.tau, "tau_std": self.tau_std,
                "tau_posterior": self.tau_posterior, "z": self.z, "beyond": self.beyond}


@dataclass(frozen=True)
class UnresolvedSkew:
    """How far a skew the record cannot resolve could move the reduced estimates.

    Parameters
    ----------
    tau : float
        The ``reduced+skew`` fit's skew τ̂_d [s].
    tau_std : float
        Its standard deviation σ_τ [s].
    shifts : dict of str to float
        Per reduced parameter, the move a skew of 1.96 σ_τ causes, in
        units of its reduced σ (signed; a positive skew reads y late).
    free : dict of str to tuple of float
        The skew fit's (value, std) of K, omega_hp, delta_hp: the
        estimates with the skew left free.
    """

    tau: float
    tau_std: float
    shifts: dict[str, float]
    free: dict[str, tuple[float, float]]

    @property
    def fires(self) -> bool:
        """True when an unresolved skew moves a parameter by more than SKEW_SHIFT σ."""
        return any(abs(v) > SKEW_SHIFT for v in self.shifts.values())

    @property
    def worst(self) -> str:
        """The parameter an unresolved skew moves most (in its σ)."""
        return max(self.shifts, key=lambda n: abs(self.shifts[n]))

    @property
    def value(self) -> str:
        """Short form for the verdict: the skew's σ and the largest move."""
        w = self.worst
        return (f"±{_seconds('tau', self.tau_std)} → {_LABELS[w]} "
                f"{abs(self.shifts[w]):.1f}σ")

    @property
    def note(self) -> str:
        """The assumption in words, with the numbers and what to do."""
        moved = ", ".join(f"{_LABELS[n]} by {abs(v):.1f}σ"
                          for n, v in sorted(self.shifts.items(), key=lambda kv: -abs(kv[1]))
                          if abs(v) > SKEW_SHIFT)
        w = self.worst
        value, std = self.free[w]
        return (f"channel skew: the intervals assume the reference and position channels are "
                f"sampled together; the record fixes the skew between the reference and position "
                f"channels only to ±{_seconds('tau', self.tau_std)} (σ; estimate "
                f"{_seconds('tau', self.tau)}), and a skew of "
                f"{_seconds('tau', 1.96 * self.tau_std)} that it cannot tell from none would move "
                f"{moved} of the reduced intervals; with the skew free, "
                f"{_LABELS[w]} = {value:.5g} ± {1.96 * std:.3g} (95 %). If the ADC multiplexes "
                "its channels or the reference path has a dead time, state [loop] "
                "skew_tolerance (its standard deviation [s]) and the intervals carry it")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for JSON."""
        return {"tau": self.tau, "tau_std": self.tau_std, "shifts": dict(self.shifts),
                "free": {k: list(v) for k, v in self.free.items()}, "fires": self.fires}


def unresolved_skew(wide: ClosedLoopResult, reduced: ClosedLoopResult) -> UnresolvedSkew:
    """Return how far a skew the record cannot resolve moves the reduced estimates.

    Parameters
    ----------
    wide : ClosedLoopResult
        A one-step fit of the ``reduced+skew`` structure.
    reduced : ClosedLoopResult
        The reduced fit on the same data, whose σ the moves are measured in.

    Returns
    -------
    UnresolvedSkew
        σ_τ, the moves per parameter and the skew fit's estimates.
    """
    src = wide.source
    k = src.names.index("tau_d")
    cov = np.asarray(src.covariance, dtype=float)
    var = float(cov[k, k])
    tau_std = math.sqrt(max(var, 0.0))
    red = reduced.estimate
    shifts, free = {}, {}
    for name in _LABELS:
        i, j = src.names.index(name), red.names.index(name)
        slope = float(cov[i, k]) / var if var > 0 else 0.0
        std = float(red.std[j])
        shifts[name] = slope * 1.96 * tau_std / std if std > 0 else 0.0
        free[name] = (float(src.parameters[i]), float(math.sqrt(max(cov[i, i], 0.0))))
    return UnresolvedSkew(float(src.parameters[k]), tau_std, shifts, free)


def with_skew_tolerance(reduced: ClosedLoopResult, data: Any, loop: FeedbackLoop,
                        tolerance: float, **options: Any) -> SkewAdjustment:
    """Return the one-step fit with an unresolved channel skew in its intervals.

    Fits the ``reduced+skew`` structure from the reduced estimate and
    conditions it on the prior τ_d ~ N(0, tolerance²); see the module
    notes.

    Parameters
    ----------
    reduced : ClosedLoopResult
        The reduced one-step fit.
    data : Experiment or ExperimentSet
        Its estimation data.
    loop : FeedbackLoop
        The known loop; its feedback must be a static gain F > 0.
    tolerance : float
        Standard deviation of the skew the rig may have [s], > 0.
    **options
        Passed to :func:`~servoid.plants.ehsa.fit_one_step` (the rig
        chain, the discretisation).

    Returns
    -------
    SkewAdjustment
        The adjusted result, the skew and the note.

    Raises
    ------
    ModelError
        A dynamic feedback (the skew structure needs a static F).
    """
    tolerance = as_float("skew_tolerance", tolerance, positive=True, unit="s")
    if not loop.is_static:
        raise ModelError("[loop] skew_tolerance needs a static feedback F (a number): the skew "
                         "structure writes the delay outside the loop through F")
    structure = skew_structure(float(loop.F))  # type: ignore[arg-type]
    theta = reduced.estimate.parameters
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        wide = fit_one_step(data, loop, (*theta[:3], 0.0), structure=structure, **options)
    return skew_prior(wide, tolerance, reduced)


def skew_prior(wide: ClosedLoopResult, tolerance: float,
               reduced: ClosedLoopResult | None = None) -> SkewAdjustment:
    """Condition a ``reduced+skew`` fit on the prior τ_d ~ N(0, tolerance²).

    Parameters
    ----------
    wide : ClosedLoopResult
        A one-step fit of the ``reduced+skew`` structure.
    tolerance : float
        Standard deviation of the skew the rig may have [s], > 0.
    reduced : ClosedLoopResult, optional
        The reduced fit whose models the result keeps (default: the skew
        fit's own).

    Returns
    -------
    SkewAdjustment
        The adjusted result, the skew and the note.
    """
    src = wide.source
    k = src.names.index("tau_d")
    values = np.asarray(src.parameters, dtype=float)
    cov = np.asarray(src.covariance, dtype=float)
    tau, var = float(values[k]), float(cov[k, k])
    gain = cov[:, k] / (var + tolerance * tolerance)
    post = values - gain * tau
    post_cov = cov - np.outer(gain, cov[k, :])
    post_cov = 0.5 * (post_cov + post_cov.T)
    keep = [src.names.index(n) for n in wide.estimate.names]
    base = wide if reduced is None else reduced
    est = dataclasses.replace(base.estimate, parameters=post[keep],
                              covariance=post_cov[np.ix_(keep, keep)])
    return SkewAdjustment(dataclasses.replace(base, estimate=est), tolerance, tau,
                          math.sqrt(max(var, 0.0)), float(post[k]))
