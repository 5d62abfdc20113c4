"""Acceptance numbers with intervals, read from a fitted model, and pass/fail limits.

An actuator is accepted on a few numbers of its frequency response:
bandwidth, phase lag at a named frequency, resonance frequency and peak,
DC gain, and how linear it is.  :func:`acceptance_numbers` reads each from
the model fitted by :func:`fit_ml` — on the model's own fine grid, with
crossings and peaks located by Brent's methods
(:func:`servoid.models.bandwidth`, :func:`~servoid.models.phase_lag`,
:func:`~servoid.models.resonance_peak`), not on the measured lines — and
gives it a standard deviation by the delta method: the gradient of the
number with respect to the parameters (central differences of a hundredth
of each parameter's standard deviation) against the parameter covariance,
``σ² = ∇ᵀ·C_θ·∇``, and the interval ``value ± z·σ`` at the confidence
asked (z the normal quantile).  Beside each number is the value read from
the nonparametric lines (linear interpolation between lines, the highest
line for a peak) as a cross-check: the two agree to the line spacing when
the model passes its cost test.

The nonlinear distortion's number is the largest of the detection lines'
odd, even and total levels (dB below the output, the noise removed), with
its one-sided 95 % upper bound: its interval runs from the level to that
bound.  Where the lines hold no more than the noise, the number is the
noise level (no lower distortion can be shown).

:func:`judge` applies limits under the rule the fleet uses: a number
passes a limit only when its whole interval lies inside it; an interval
that straddles the limit, or a number without one, fails.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._checks import as_float
from .._errors import OptionError, OptionTypeError, ServoidError
from .._lazy import stats
from ..models import bandwidth, phase_lag, resonance_peak
from ._measured import DistortionLevels
from ._ml import MlFit

__all__ = ["LIMIT_KEYS", "RULE", "AcceptanceCheck", "SpecNumber", "acceptance_numbers",
           "judge"]

RULE = ("a number passes a limit only when its whole 95 % interval lies inside it; an interval "
        "that straddles the limit, or a number without one, fails")

#: number → unit; the limits are ``<number>_min`` and ``<number>_max``
_NUMBERS = {"bandwidth": "Hz", "phase_lag": "deg", "resonance_frequency": "Hz",
            "resonance_peak": "dB", "dc_gain": "", "distortion": "dB"}
#: every key an acceptance table may hold
LIMIT_KEYS: tuple[str, ...] = tuple(f"{n}_{side}" for n in _NUMBERS for side in ("min", "max"))
# central-difference step as a fraction of each parameter's standard deviation
_STEP = 0.01


@dataclass(frozen=True)
class SpecNumber:
    """One acceptance number with its interval.

    Attributes
    ----------
    name : str
        ``bandwidth``, ``phase_lag``, ``resonance_frequency``,
        ``resonance_peak``, ``dc_gain`` or ``distortion`` (the fleet's
        column and the ``[acceptance]`` key's stem).
    label : str
        The number in words with its unit.
    value : float
        From the fitted model (NaN where undefined).
    std : float
        Standard deviation (delta method; NaN where undefined).
    ci_low, ci_high : float
        Interval at the confidence asked.
    unit : str
        Unit.
    measured : float
        The same number read from the nonparametric lines (NaN where
        undefined there).
    """

    name: str
    label: str
    value: float
    std: float
    ci_low: float
    ci_high: float
    unit: str
    measured: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """Plain data (non-finite numbers as None)."""
        return {"name": self.name, "label": self.label, "value": _num(self.value),
                "std": _num(self.std), "ci_low": _num(self.ci_low),
                "ci_high": _num(self.ci_high), "unit": self.unit,
                "measured": _num(self.measured)}


@dataclass(frozen=True)
class AcceptanceCheck:
    """One limit applied to one number.

    Attributes
    ----------
    name : str
        The number.
    limit : str
        The limit in words (``">= 5 Hz"``).
    low, high : float
        The limit's bounds (``-inf``/``inf`` when one-sided).
    passed : bool
        The whole interval lies inside.
    reason : str
        Why, with the interval.
    """

    name: str
    limit: str
    low: float
    high: float
    passed: bool
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {"name": self.name, "limit": self.limit, "low": _num(self.low),
                "high": _num(self.high), "passed": self.passed, "reason": self.reason}


def acceptance_numbers(
    fit: MlFit,
    *,
    level_db: float = -3.0,
    phase_frequency: float | None = None,
    confidence: float = 0.95,
    distortion: DistortionLevels | None = None,
) -> tuple[SpecNumber, ...]:
    """The acceptance numbers of a fitted model with their intervals.

    Parameters
    ----------
    fit : MlFit
        From :func:`fit_ml`.
    level_db : float
        Bandwidth level below the low-frequency gain [dB], < 0.
    phase_frequency : float, optional
        Where to read the phase lag [Hz]; without it no phase lag.
    confidence : float
        Of the intervals, in (0, 1).
    distortion : DistortionLevels, optional
        The detection lines' levels (a multisine with empty lines);
        default those of the fit's measurement.

    Returns
    -------
    tuple of SpecNumber
        DC gain, bandwidth, phase lag (if asked), resonance frequency and
        peak, distortion (if measured), in that order.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.frequency import FrfMeasurement, acceptance_numbers, fit_ml
    >>> f = np.linspace(0.5, 30, 120)
    >>> w = 2 * np.pi * 8.0
    >>> g = w**2 / ((1j * 2 * np.pi * f) ** 2 + 0.8 * w * 1j * 2 * np.pi * f + w**2)
    >>> var = np.full(120, 1e-6)
    >>> frm = FrfMeasurement(f, g, var, var, None, np.inf, np.inf, 1, "periodic")
    >>> nums = {n.name: n for n in acceptance_numbers(fit_ml(frm, 2, 0))}
    >>> round(nums["resonance_frequency"].value, 2), round(nums["resonance_peak"].value, 2)
    (6.6, 2.7)
    """
    if not isinstance(fit, MlFit):
        raise OptionTypeError(f"fit must be an MlFit (from fit_ml), got {type(fit).__name__}")
    level = as_float("level_db", level_db)
    if not level < 0:
        raise OptionError(f"level_db must be < 0 dB, got {level:g}")
    conf = as_float("confidence", confidence, positive=True)
    if not conf < 1:
        raise OptionError(f"confidence must lie in (0, 1), got {conf:g}")
    f_phase = None if phase_frequency is None else as_float("phase_frequency", phase_frequency,
                                                            positive=True, unit="Hz")
    z = float(stats.norm.ppf(0.5 + conf / 2))
    frd = fit.measurement.to_frd()
    unit = fit.measurement.unit
    readers: list[tuple[str, str, str, Callable[[Any], float]]] = [
        ("dc_gain", "DC gain" + (f" [{unit}]" if unit else ""), unit, _dc_gain),
        ("bandwidth", f"bandwidth ({level:g} dB) [Hz]", "Hz",
         lambda m: bandwidth(m, level)),
    ]
    if f_phase is not None:
        readers.append(("phase_lag", f"phase lag at {f_phase:g} Hz [deg]", "deg",
                        lambda m: phase_lag(m, f_phase)))
    readers += [
        ("resonance_frequency", "resonance frequency [Hz]", "Hz", _peak_frequency),
        ("resonance_peak", "resonance peak [dB]", "dB", lambda m: resonance_peak(m).peak_db),
    ]
    out = []
    for name, label, u, read in readers:
        value, std = _delta(fit, read)
        measured = math.nan if name == "dc_gain" else _safe(lambda r=read: r(frd))
        if name == "resonance_peak" and value == 0.0:
            std = math.nan  # no peak: nothing to be uncertain about
        out.append(SpecNumber(name, label, value, std, value - z * std, value + z * std, u,
                              measured))
    dist = distortion if distortion is not None else fit.measurement.distortion
    if dist is not None:
        out.append(_distortion_number(dist))
    return tuple(out)


def judge(numbers: tuple[SpecNumber, ...], limits: Mapping[str, float | None],
          ) -> tuple[AcceptanceCheck, ...]:
    """Judge the numbers against their limits (:data:`RULE`).

    Parameters
    ----------
    numbers : tuple of SpecNumber
        From :func:`acceptance_numbers`.
    limits : mapping of str to float or None
        Keys from :data:`LIMIT_KEYS`; None or absent: no limit.

    Returns
    -------
    tuple of AcceptanceCheck
        One per number that has a limit, in the order of `numbers` (a
        limit on a number that was not computed fails, saying so).
    """
    if not isinstance(numbers, (tuple, list)) or not all(isinstance(n, SpecNumber)
                                                          for n in numbers):
        raise OptionTypeError("numbers must be a tuple of SpecNumber (from acceptance_numbers), "
                              f"got {type(numbers).__name__}")
    if not isinstance(limits, Mapping):
        raise OptionTypeError(f"limits must be a mapping of limit name to number, got "
                              f"{type(limits).__name__}")
    unknown = sorted(set(limits) - set(LIMIT_KEYS))
    if unknown:
        raise OptionError(f"unknown acceptance limit(s) {', '.join(unknown)}; valid keys are "
                          f"{', '.join(LIMIT_KEYS)}")
    by_name = {n.name: n for n in numbers}
    checks = []
    for name, unit in _NUMBERS.items():
        lo, hi = limits.get(f"{name}_min"), limits.get(f"{name}_max")
        if lo is None and hi is None:
            continue
        low = -math.inf if lo is None else as_float(f"{name}_min", lo)
        high = math.inf if hi is None else as_float(f"{name}_max", hi)
        text = _limit_text(low, high, unit)
        num = by_name.get(name)
        if num is None:
            checks.append(AcceptanceCheck(name, text, low, high, False,
                                          f"not computed (needs {_NEEDS.get(name, 'the data')})"))
            continue
        if not (math.isfinite(num.ci_low) and math.isfinite(num.ci_high)):
            checks.append(AcceptanceCheck(name, text, low, high, False,
                                          "no interval: not shown to be inside"))
            continue
        inside = low <= num.ci_low and num.ci_high <= high
        interval = f"[{num.ci_low:.4g}, {num.ci_high:.4g}]{' ' + unit if unit else ''}"
        reason = (f"interval {interval} inside" if inside else
                  f"interval {interval} " + ("straddles the limit" if (
                      num.ci_low < low <= num.ci_high or num.ci_low <= high < num.ci_high)
                      else "outside"))
        checks.append(AcceptanceCheck(name, text, low, high, inside, reason))
    return tuple(checks)


# -- helpers -------------------------------------------------------------------------------------
_NEEDS = {"phase_lag": "phase_frequency", "distortion": "a multisine with detection lines"}


def _delta(fit: MlFit, read: Callable[[Any], float]) -> tuple[float, float]:
    """The number at the estimate and its delta-method standard deviation."""
    value = _safe(lambda: read(fit.model))
    if not math.isfinite(value):
        return math.nan, math.nan
    theta = fit.parameters
    sd = fit.std
    cov = fit.covariance
    if not np.all(np.isfinite(cov)):
        return value, math.nan
    grad = np.zeros(theta.size)
    for i in range(theta.size):
        h = _STEP * sd[i] if sd[i] > 0 else 1e-8 * max(abs(theta[i]), 1.0)
        step = np.zeros(theta.size)
        step[i] = h
        up = _safe(lambda s=step: read(fit.model_at(theta + s)))
        down = _safe(lambda s=step: read(fit.model_at(theta - s)))
        if not (math.isfinite(up) and math.isfinite(down)):
            return value, math.nan
        grad[i] = (up - down) / (2 * h)
    return value, float(math.sqrt(max(float(grad @ cov @ grad), 0.0)))


def _dc_gain(model: Any) -> float:
    return float(np.real(model.dc_gain()))


def _peak_frequency(model: Any) -> float:
    peak = resonance_peak(model)
    return float(peak.frequency) if peak.peak_db > 0 else math.nan


def _distortion_number(d: DistortionLevels) -> SpecNumber:
    """The worst level with its one-sided bound (at least the noise level: no less is shown)."""
    pairs = [(v, u) for v, u in ((d.odd_db, d.odd_upper_db), (d.even_db, d.even_upper_db),
                                 (d.total_db, d.total_upper_db)) if v is not None]
    label = "nonlinear distortion [dB re output]"
    if not pairs:
        return SpecNumber("distortion", label, math.nan, math.nan, math.nan, math.nan, "dB")
    level = max(v for v, _ in pairs)
    upper = max((u for _, u in pairs if u is not None and math.isfinite(u)), default=math.nan)
    # nothing above the noise: the distortion is shown to be at most the noise level
    value = level if math.isfinite(level) else d.noise_db
    if not math.isfinite(value):
        return SpecNumber("distortion", label, math.nan, math.nan, math.nan, math.nan, "dB")
    high = max(upper, value) if math.isfinite(upper) else value
    return SpecNumber("distortion", label, value, math.nan, value, high, "dB")


def _limit_text(low: float, high: float, unit: str) -> str:
    u = f" {unit}" if unit else ""
    if math.isinf(low):
        return f"<= {high:g}{u}"
    if math.isinf(high):
        return f">= {low:g}{u}"
    return f"{low:g}..{high:g}{u}"


def _safe(fn: Callable[[], float]) -> float:
    try:
        return float(fn())
    except (ServoidError, ZeroDivisionError, FloatingPointError):
        return math.nan


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)
