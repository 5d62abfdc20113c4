"""Is a logged signal a staircase (a DAC command) or band-limited (a measurement)?

A sequence of samples does not say how the signal ran between them; the
way it was logged does.  A command written to a DAC and logged as its
codes is a *staircase*: runs of exactly equal samples separated by
single-sample jumps, or only a few distinct levels (a PRBS changes at
every sample when its clock is one sample).  A signal read back through
an analog anti-alias filter, an ADC and a decimating FIR is *band-limited*:
it changes over several samples and takes many values.  The estimators
need the answer to pick the matching exact discretisation (zero-order
hold for a staircase, a continuous-time criterion for a band-limited
signal); :func:`detect_intersample` gives it with the evidence.

The rules are heuristics on exact sample equality, so a declaration (the
experiment file's ``[rig]`` table, an explicit option) always overrides
them; a staircase whose every sample differs (a multisine written to a
DAC at the logging rate) cannot be told from a band-limited signal and
must be declared.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from .._checks import as_array
from .._errors import DataError

__all__ = ["IntersampleCheck", "detect_intersample"]

IntersampleKind = Literal["zoh", "bandlimited"]

#: Share of zero steps above which runs of equal samples suggest a staircase.
_FLAT = 0.5
#: Share of the jumps that must be isolated (flat on both sides) in a staircase.
_ISOLATED = 0.9
#: Most distinct values a multi-level command may take, as a share of the samples.
_LEVEL_SHARE = 0.01
_MIN_SAMPLES = 8


@dataclass(frozen=True)
class IntersampleCheck:
    """Verdict of :func:`detect_intersample`, with its evidence.

    Parameters
    ----------
    kind : {"zoh", "bandlimited"}
        ``"zoh"``: a staircase held over each sample (a DAC command);
        ``"bandlimited"``: a smooth signal sampled through a filter.
    flat_fraction : float
        Share of the steps ``x[k+1] − x[k]`` that are exactly zero.
    isolated_jumps : float
        Share of the non-zero steps with a zero step on both sides (a
        single-sample jump between flat runs).
    levels : int
        Number of distinct sample values.
    reason : str
        The evidence in words, for reports.
    """

    kind: IntersampleKind
    flat_fraction: float
    isolated_jumps: float
    levels: int
    reason: str


def detect_intersample(signal: ArrayLike) -> IntersampleCheck:
    """Tell a staircase (DAC command) from a band-limited signal.

    A signal whose typical jump is one converter code (the smallest
    spacing of its values) is band-limited: a slowly varying signal read
    by an ADC.  Otherwise a staircase is declared when at least half of
    the steps are exactly zero and at least 90 % of the jumps are isolated
    (runs of equal samples), or when the signal takes at most ``max(3, N/100)`` distinct
    values and its successive steps do not continue one another (a
    multi-level command, e.g. a PRBS clocked at every sample; a noise-free
    read-back takes few values too, but its transitions run over several
    samples in one direction).  Everything else is band-limited.

    Parameters
    ----------
    signal : array_like, shape (N,)
        The logged samples, N >= 8, not constant.

    Returns
    -------
    IntersampleCheck
        The verdict and the numbers behind it.

    Raises
    ------
    DataError
        Fewer than 8 samples, non-finite values or a constant signal.

    Examples
    --------
    >>> import numpy as np
    >>> detect_intersample(np.repeat([1.0, -1.0, -1.0, 1.0], 10)).kind
    'zoh'
    >>> detect_intersample(np.sin(0.05 * np.arange(400))).kind
    'bandlimited'
    """
    x = as_array("signal", signal, finite=False)
    if x.ndim != 1 or x.size < _MIN_SAMPLES:
        raise DataError(f"signal must be 1-D with at least {_MIN_SAMPLES} samples, "
                        f"got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise DataError("signal must be finite to judge its course between samples")
    steps = np.diff(x)
    flat = steps == 0.0
    if np.all(flat):
        raise DataError("signal is constant: it carries no excitation and no intersample "
                        "behaviour to detect")
    flat_fraction = float(np.mean(flat))
    padded = np.concatenate([[True], flat, [True]])
    jumps = ~flat
    isolated = padded[:-2] & padded[2:]  # flat step before and after each step
    isolated_jumps = float(np.mean(isolated[jumps]))
    values = np.unique(x)
    levels = int(values.size)
    code = float(np.min(np.diff(values)))
    typical = float(np.median(np.abs(steps[jumps])))
    if levels > 3 and typical <= 1.5 * code:
        return IntersampleCheck(
            "bandlimited", flat_fraction, isolated_jumps, levels,
            f"band-limited: {levels} distinct values, and it moves one converter code at a "
            "time (a slowly varying signal quantised by an ADC; were it a DAC ramp, the two "
            "models agree for a signal this slow)")
    if flat_fraction >= _FLAT and isolated_jumps >= _ISOLATED:
        return IntersampleCheck(
            "zoh", flat_fraction, isolated_jumps, levels,
            f"staircase: {100 * flat_fraction:.0f} % of the samples repeat the previous one "
            f"and {100 * isolated_jumps:.0f} % of the changes are single-sample jumps between "
            "flat runs (a DAC command held over each sample)")
    # a band-limited transition moves on over several samples (successive steps alike), a
    # held command jumps afresh at every change (successive steps uncorrelated or opposed)
    lag1 = float(steps[:-1] @ steps[1:]) / float(steps @ steps)
    if levels <= max(3, int(_LEVEL_SHARE * x.size)) and (levels <= 3 or lag1 <= 0.0):
        return IntersampleCheck(
            "zoh", flat_fraction, isolated_jumps, levels,
            f"staircase: the signal takes only {levels} distinct values and jumps between "
            "them (a multi-level command held over each sample)")
    return IntersampleCheck(
        "bandlimited", flat_fraction, isolated_jumps, levels,
        f"band-limited: {levels} distinct values and only {100 * flat_fraction:.0f} % repeated "
        "samples; the signal changes over several samples (read back through a filter and "
        "an ADC)")
