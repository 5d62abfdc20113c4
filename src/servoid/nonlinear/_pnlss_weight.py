"""The PNLSS cost weighted by the output's noise variance per DFT line (periodic records).

For a multisine test of M realisations × (transient + P measured) periods
(its :class:`~servoid.signals.MultisinePlan`), the simulation error of
each whole period is transformed by the DFT and every line k weighted
by 1/σ²_Y(k), the output's noise variance on that line (Paduart et al.,
Automatica 46(4), 2010, §4; Pintelon & Schoukens, *System Identification:
A Frequency Domain Approach*, 2nd ed., 2012, ch. 9–10)::

    V = Σ_periods (1/N) Σ_k c_k w_k |E_p(k)|²,   w_k = σ̄² / σ̂²_Y(k)

over every line k = 0 … N/2 of the N-sample period (c_k = 2 for the
lines that stand for a pair of conjugate ones, 1 for DC and Nyquist), so
that with w ≡ 1 the cost is the squared simulation error over the same
samples (Parseval), and with white noise w ≈ 1.  σ̄² is the mean of
σ̂²_Y over the lines, so the cost at the noise floor is that of the
unweighted fit (Σ_k c_k w_k σ²_Y(k) = Σ_k c_k σ²_Y(k)).

σ̂²_Y(k) is the period-to-period spread of the output's DFT — the same
sample variance :func:`servoid.frequency.estimate_bla` forms on the
excited lines for its noise variance, here on every line, since the
nonlinear distortion a PNLSS model must fit shows on the lines the
multisine leaves empty: per realisation with P_m ≥ 2 measured periods,
``Σ_p |Y_p(k) − Ȳ(k)|² / (P_m − 1)`` (2(P_m − 1) degrees of freedom),
pooled over the realisations (the noise does not depend on the
realisation), then averaged over neighbouring lines until it has at least
:data:`MIN_DOF` degrees of freedom: the reciprocal of a variance
estimated from 2 degrees of freedom (P = 2, one realisation) has no
finite mean, noise spectra are smooth, and the weights' own scatter
costs accuracy when the noise is white (``study_pnlss_weighting.py``,
median over seeds: with 20 degrees of freedom the weighted fit's error
was 8 % above the unweighted one's on white noise, with 40, 2 %).

The model is simulated through the whole record from each record's
estimated initial state, so the transient periods enter the cost as well
as the measured ones (the simulation follows the transient; only the
variance needs the steady state): with w ≡ 1 the weighted fit *is* the
plain one on a record of whole periods.  A trailing part of a period is
left out.  (Leaving the transient periods out, as Paduart et al. do,
discards a third of a 1 + 2-period test: ``study_pnlss_weighting.py``
measured that variant's error 27 % above the plain fit's on white
noise, median over seeds.)  A plan without transient periods leaves the switch from one
realisation to the next in its first measured period, whose spread then
counts as noise: plan at least one (``servoid excite random-multisine``
does by default).  The Jacobian of a period's weighted error is the
DFT of its rows of the time-domain Jacobian (a linear map), formed a few
periods at a time from the blocked sensitivity recursion, so memory stays
a block of samples × parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ConvergenceError, DataError, OptionTypeError, ServoidWarning
from .._warn import warn
from ._pnlss_kernel import jacobian_block, record_start, simulate

__all__ = ["MIN_DOF", "PeriodicWeights", "noise_spread", "periodic_weights"]

#: Degrees of freedom the smoothed noise variance of every line has at least.
MIN_DOF = 40

#: Largest weight relative to the mean (a line whose spread is nearly zero).
MAX_WEIGHT = 1e4

_FIX = ("record the test with its plan and at least two measured periods per realisation: "
        "servoid excite random-multisine --periods 2 (or more)")


@dataclass(frozen=True)
class PeriodicWeights:
    """Where the periods lie and the weight of each DFT line.

    Attributes
    ----------
    period : int
        Samples per period N at the records' rate.
    starts : tuple of tuple of int
        Per record, the first sample of each period in the cost.
    ends : tuple of int
        Per record, the sample after its last period in the cost (the
        simulation stops there).
    weight : ndarray
        w_k = σ̄²/σ̂²_Y(k) (N//2 + 1,), at most :data:`MAX_WEIGHT`.
    scale : ndarray
        sqrt(c_k·w_k / N): the DFT of a period times it gives the whitened
        error whose sum of squares is the cost.
    variance : ndarray
        The smoothed, pooled σ̂²_Y(k) of one period's DFT (the records'
        normalised output).
    info : dict
        What ``options["weighting_info"]`` reports.
    """

    period: int
    starts: tuple[tuple[int, ...], ...]
    ends: tuple[int, ...]
    weight: NDArray[np.float64]
    scale: NDArray[np.float64]
    variance: NDArray[np.float64]
    info: dict[str, Any]

    def plain(self) -> PeriodicWeights:
        """The same periods with w ≡ 1: the cost is then the plain squared error."""
        from dataclasses import replace

        return replace(self, weight=np.ones_like(self.weight),
                       scale=self.scale / np.sqrt(self.weight))

    @property
    def n_samples(self) -> int:
        """Samples in the cost (periods × N)."""
        return self.period * sum(len(s) for s in self.starts)


def noise_spread(y: NDArray[np.float64], period: int, first: int, periods: int
                 ) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """The per-period noise variance of the output's DFT from the spread over periods.

    Parameters
    ----------
    y : ndarray
        The record's output.
    period : int
        Samples per period N.
    first : int
        First sample of the realisation's first measured period.
    periods : int
        Its measured periods P ≥ 2 (all inside ``y``).

    Returns
    -------
    variance : ndarray
        ``Σ_p |Y_p(k) − Ȳ(k)|² / (P − 1)`` on the lines k = 0 … N//2
        (divide by P for the variance of the mean Ȳ, as
        :func:`servoid.frequency.estimate_bla` uses it).
    mean : ndarray
        Ȳ(k), the DFT averaged over the periods.
    """
    block = np.fft.rfft(y[first:first + periods * period].reshape(periods, period), axis=1)
    mean = block.mean(axis=0)
    dev = block - mean
    return np.sum(dev.real**2 + dev.imag**2, axis=0) / (periods - 1), mean


def periodic_weights(outputs: Sequence[NDArray[np.float64]], dt: float, plan: Any,
                     transients: bool = True) -> PeriodicWeights:
    """The periods of each record in the cost and the weights 1/σ̂²_Y(k) (normalised).

    Parameters
    ----------
    outputs : sequence of ndarray
        Each record's output; each record starts with the first period of
        the plan's first realisation.
    dt : float
        The records' sample period [s]: the plan's or an integer multiple
        of it that divides the period.
    plan : MultisinePlan
        The test's plan.
    transients : bool
        Put the transient periods in the cost too (the variance comes from
        the measured ones either way).

    Returns
    -------
    PeriodicWeights

    Raises
    ------
    DataError
        No plan, a plan of one measured period, a sample period that does
        not fit the plan, records holding no realisation with two complete
        measured periods.
    """
    from ..signals import MultisinePlan

    if plan is None:
        raise DataError(f'weighting = "bla" needs the multisine plan of the record; {_FIX}')
    if not isinstance(plan, MultisinePlan):
        raise OptionTypeError(f"plan must be a MultisinePlan, got {type(plan).__name__}")
    if plan.periods < 2:
        raise DataError(f'weighting = "bla" needs the output\'s noise variance from the spread '
                        f"over periods, but the plan measures {plan.periods} period per "
                        f"realisation; {_FIX}")
    ratio = dt / plan.dt
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-9 * max(ratio, 1.0) or plan.period % factor:
        raise DataError(f"the record's sample period {dt:g} s does not fit the plan's "
                        f"{plan.dt:g} s: it must be the same or an integer multiple that "
                        f"divides the period ({plan.period} samples); check [preprocess] "
                        "decimate and the plan file")
    n = plan.period // factor
    p_tr, p = plan.transient_periods, plan.periods
    span = (p_tr + p) * n
    starts: list[tuple[int, ...]] = []
    ends: list[int] = []
    pooled = np.zeros(n // 2 + 1)
    dof = 0  # Σ (P_m − 1): complex degrees of freedom of the pooled variance
    for y in outputs:
        mine: list[int] = []
        for begin in range(0, y.size, span):
            first = begin + p_tr * n
            whole = max(0, min(p, (y.size - first) // n))
            lead = range(begin, first, n) if transients and first + n <= y.size else ()
            mine += [*lead, *(first + j * n for j in range(whole))]
            if whole >= 2:
                var, _ = noise_spread(y, n, first, whole)
                pooled += (whole - 1) * var
                dof += whole - 1
        starts.append(tuple(mine))
        ends.append(mine[-1] + n if mine else 0)
    if dof == 0:
        raise DataError(f'weighting = "bla" needs a realisation with at least two complete '
                        f"measured periods of {n} samples in the fitted records (after "
                        f"{p_tr} transient period(s)); they hold none; {_FIX}")
    # lines averaged until 2·dof·width ≥ MIN_DOF (the reciprocal needs a few dof to be stable)
    half = max(0, math.ceil((MIN_DOF / (2 * dof) - 1) / 2))
    variance = _smooth(pooled / dof, half)
    mult = np.full(n // 2 + 1, 2.0)
    mult[0] = 1.0
    if n % 2 == 0:
        mult[-1] = 1.0
    mean = float(np.sum(mult * variance) / np.sum(mult))
    if not mean > 0:
        warn('weighting = "bla": the output repeats exactly from period to period (no noise '
             "to weight by); the fit is unweighted", ServoidWarning)
        weight = np.ones_like(variance)
    else:
        weight = mean / np.maximum(variance, mean / MAX_WEIGHT)
    info = {"kind": "bla", "period": n, "periods": sum(len(s) for s in starts),
            "unused_samples": int(sum(y.size for y in outputs)) - n * sum(len(s) for s in starts),
            "variance_dof": 2 * dof * (2 * half + 1), "smoothing_lines": 2 * half + 1,
            "weight_min": float(weight.min()), "weight_max": float(weight.max()),
            "lines": int(weight.size)}
    return PeriodicWeights(n, tuple(starts), tuple(ends), weight,
                           np.sqrt(mult * weight / n), variance, info)


def weighted_cost(args: tuple[Any, ...], records: Sequence[tuple[Any, Any]],
                  x0s: Sequence[NDArray[np.float64]], w: PeriodicWeights) -> float:
    """Σ over the periods in the cost of the weighted squared DFT of the simulation error."""
    total = 0.0
    nx = args[0].shape[0]
    for (u, y), x0, starts, end in zip(records, x0s, w.starts, w.ends, strict=True):
        if not starts:
            continue
        ys = np.empty(end)
        xs = np.empty((end + 1, nx))
        if simulate(*args, u[:end], x0, ys, xs) >= 0:
            return np.inf
        r = _periods(ys - y[:end], starts, w.period)
        z = np.fft.rfft(r, axis=1) * w.scale
        total += float(np.sum(z.real**2 + z.imag**2))
    return total


def weighted_normal_equations(args: tuple[Any, ...], records: Sequence[tuple[Any, Any]],
                              x0s: Sequence[NDArray[np.float64]], w: PeriodicWeights,
                              nown: int, nmod: int, block: int
                              ) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                         NDArray[np.float64]]:
    """Re(JᴴWJ), Re(JᴴWr) and the time-domain errors of the periods in the cost.

    J is the DFT of each period's rows of the exact Jacobian
    (columns: the model's first ``nown`` parameters of ``nmod`` and each
    record's initial state), formed over blocks of whole periods (about
    ``block`` samples, at least one period) carried one to the next.
    """
    nx = args[0].shape[0]
    n = w.period
    n_all = nmod + nx * len(records)
    H = np.zeros((n_all, n_all))
    g = np.zeros(n_all)
    errors = []
    step = max(1, block // n) * n
    for k, ((u, y), x0, starts, end) in enumerate(zip(records, x0s, w.starts, w.ends,
                                                      strict=True)):
        if not starts:
            continue
        cols, x, S, Hk, gk = record_start(x0, k, nown, nmod, nx)
        Jb = np.empty((min(step, end), nown + nx))
        in_cost = set(starts)
        for a in range(0, end, step):
            b = min(a + step, end)
            J, ys = Jb[:b - a], np.empty(b - a)
            if jacobian_block(*args, u[a:b], x, S, 0, ys, J) >= 0:
                raise ConvergenceError("the PNLSS simulation diverged at an accepted point; "
                                       "lower the degree or n_states")
            mine = [s - a for s in range(a, b, n) if s in in_cost and s + n <= b]
            if not mine:
                continue
            r = _periods(ys - y[a:b], mine, n)
            errors.append(r.ravel())
            rows = np.stack([J[s:s + n] for s in mine])  # (periods, N, columns)
            FJ = np.fft.rfft(rows, axis=1) * w.scale[None, :, None]
            FR = np.fft.rfft(r, axis=1) * w.scale
            FJ = FJ.reshape(-1, FJ.shape[2])
            FR = FR.ravel()
            Hk += FJ.real.T @ FJ.real + FJ.imag.T @ FJ.imag
            gk += FJ.real.T @ FR.real + FJ.imag.T @ FR.imag
        H[np.ix_(cols, cols)] += Hk
        g[cols] += gk
    return H, g, np.concatenate(errors)


def _periods(r: NDArray[np.float64], starts: Sequence[int], n: int) -> NDArray[np.float64]:
    """The error of each period starting at ``starts`` (periods, N)."""
    return np.stack([r[s:s + n] for s in starts])


def _smooth(v: NDArray[np.float64], half: int) -> NDArray[np.float64]:
    """Moving average over 2·half + 1 neighbouring lines (fewer at the ends)."""
    if half == 0:
        return v
    kernel = np.ones(2 * half + 1)
    return np.convolve(v, kernel, "same") / np.convolve(np.ones_like(v), kernel, "same")
