"""The loop's known constants against the DC gain the data carry.

The closed loop ``H = c·G0/(1 + F·G0)`` has DC gain ``c/F``, and the
one-step fit takes c and F as exact.  The data fix that gain themselves:
a reference gain, a channel gain (the reference or position sensitivity,
a reference read back without dither) or c off by a fraction ``a`` makes
the record ``y = (1 + a)·H·r`` exactly, and an error ``a`` of F does too
once K takes it up (``K·F`` is what the data fix).  Forced through
``c/F``, the reduced fit moves K, ω_hp, δ_hp by ``s·a`` instead, with
``s`` the projection of ŷ on the fit's gradient: for Set B at 30 dB a
0.3 % error puts K some 5σ off.

:func:`check_dc_gain` estimates ``a`` with its σ
(:func:`._first_order.first_order_fit`, where ŷ is a regressor) and

* compares it with the loop's stated tolerance ``t`` (``[loop]
  c_tolerance``, ``F_tolerance``, ``gain_tolerance`` per channel, relative,
  combined in quadrature): a mismatch when ``|a| > z·√(σ_a² + t²)`` at the
  level :data:`DC_LEVEL` (two-sided) is a verdict;
* propagates the tolerances into the reduced intervals::

      var θ_i  +=  s_i²·(t_c² + 2·t_gain²) + (K·[i = K] − s_i)²·t_F²

  (a c or channel error moves the fit by ``s·a``; an F error moves K by
  ``K·a`` and the fit by ``−s·a``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._lazy import stats
from ._first_order import FirstOrderFit
from ._loop import PARAMETER_NAMES
from ._result import ClosedLoopResult

__all__ = ["DC_LEVEL", "DcGainCheck", "Tolerances", "check_dc_gain", "with_tolerances"]

#: Two-sided level of the test of the DC gain against c/F and its tolerance.
DC_LEVEL = 0.01
_LABELS = {"K": "K", "omega_hp": "ω_hp", "delta_hp": "δ_hp"}


@dataclass(frozen=True)
class Tolerances:
    """Relative tolerances of the loop's known constants (0: exact).

    Parameters
    ----------
    c, F : float
        Of the forward gain c and the feedback F.
    gain : float
        Of each measured channel's gain (reference and position).
    """

    c: float = 0.0
    F: float = 0.0
    gain: float = 0.0

    @property
    def dc(self) -> float:
        """Tolerance of the DC gain c/F as the data carry it."""
        return math.sqrt(self.c**2 + self.F**2 + 2.0 * self.gain**2)

    @property
    def any(self) -> bool:
        """True when any tolerance is stated."""
        return self.dc > 0.0


@dataclass(frozen=True)
class DcGainCheck:
    """The data's DC gain against the loop's ``c/F``.

    Parameters
    ----------
    error, error_std : float
        ``a`` = the data's DC gain over c/F, minus 1, and its σ [-].
    dc_gain : float
        The loop's ``c/F``.
    tolerances : Tolerances
        The loop's stated tolerances.
    parameters : tuple of float
        K, ω_hp, δ_hp with the DC gain taken from the data, to first order
        (the reduced values less ``s·a``).
    reduced, reduced_std : tuple of float
        The reduced fit's K, ω_hp, δ_hp and σ.
    propagated_std : tuple of float
        Their σ with the tolerances propagated.
    level : float
        Two-sided level of the test.
    """

    error: float
    error_std: float
    dc_gain: float
    tolerances: Tolerances
    parameters: tuple[float, float, float]
    reduced: tuple[float, float, float]
    reduced_std: tuple[float, float, float]
    propagated_std: tuple[float, float, float]
    level: float = DC_LEVEL

    @property
    def z(self) -> float:
        """The error over its σ and the tolerance combined."""
        spread = math.hypot(self.error_std, self.tolerances.dc)
        return self.error / spread if spread > 0 else math.inf

    @property
    def mismatch(self) -> bool:
        """True when the data's DC gain departs from c/F beyond σ and tolerance."""
        return abs(self.z) > float(stats.norm.isf(self.level / 2.0))

    @property
    def shifts(self) -> tuple[float, float, float]:
        """How far taking the DC gain from the data moves K, ω_hp, δ_hp, in σ."""
        return tuple(float((a - b) / s) if s > 0 else 0.0  # type: ignore[return-value]
                     for a, b, s in zip(self.parameters, self.reduced, self.propagated_std,
                                        strict=True))

    @property
    def verdict(self) -> str:
        """One paragraph: the DC gain, the tolerance and what to do."""
        tol = self.tolerances.dc
        head = (f"DC gain: the data carry y/r = c/F·(1 {'+' if self.error >= 0 else '−'} "
                f"{abs(self.error) * 100:.3g} %) ± {self.error_std * 100:.2g} % (c/F = "
                f"{self.dc_gain:.6g}; stated tolerance ±{tol * 100:.3g} %; z = {self.z:+.1f})")
        if not self.mismatch:
            return f"{head}: consistent with the loop's constants"
        corrected = ", ".join(f"{_LABELS[n]} = {v:.5g}" for n, v in
                              zip(PARAMETER_NAMES, self.parameters, strict=True))
        moved = ", ".join(f"{_LABELS[n]} {s:+.1f}σ" for n, s in
                          zip(PARAMETER_NAMES, self.shifts, strict=True))
        return (f"{head}: beyond the tolerance, so c, F or a channel's calibration is not what "
                "the experiment file says (or a nonlinearity, friction or a dead zone, changes "
                f"the loop's static gain), and the reduced fit, forced through c/F, absorbs "
                f"the difference ({moved}). With the DC gain taken from the data: {corrected} "
                "(right when c or a channel gain is off; an F off by a fraction moves K by the "
                "same fraction). Check c and F, the reference and position sensitivities and "
                "offsets, a reference read back at low resolution without dither; or state "
                "their tolerances in [loop] (c_tolerance, F_tolerance, gain_tolerance)")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        t = self.tolerances
        return {
            "error": self.error, "error_std": self.error_std, "dc_gain": self.dc_gain,
            "tolerances": {"c": t.c, "F": t.F, "gain": t.gain, "dc": t.dc},
            "z": self.z, "mismatch": self.mismatch, "level": self.level,
            "parameters": dict(zip(PARAMETER_NAMES, self.parameters, strict=True)),
            "propagated_std": dict(zip(PARAMETER_NAMES, self.propagated_std, strict=True)),
            "verdict": self.verdict,
        }


def check_dc_gain(fit: FirstOrderFit, dc_gain: float,
                  tolerances: Tolerances | None = None, *,
                  level: float = DC_LEVEL) -> DcGainCheck:
    """Compare the data's DC gain with the loop's c/F and propagate the tolerances.

    Parameters
    ----------
    fit : FirstOrderFit
        The reduced fit's first-order regression
        (:func:`._first_order.first_order_fit`).
    dc_gain : float
        The loop's ``c/F``.
    tolerances : Tolerances, optional
        Stated relative tolerances; default none (exact constants).
    level : float
        Two-sided level of the test.

    Returns
    -------
    DcGainCheck
        The estimated error of the DC gain, the verdict and the
        propagated standard deviations.
    """
    tol = tolerances or Tolerances()
    s = np.asarray(fit.gain_sensitivity, dtype=float)
    var = np.asarray(fit.reduced_std, dtype=float) ** 2
    var = var + s**2 * (tol.c**2 + 2.0 * tol.gain**2)
    k_row = np.array([fit.reduced[0], 0.0, 0.0])
    var = var + (k_row - s) ** 2 * tol.F**2
    error = fit.coefficient("gain")
    # the reduced fit forced through c/F sits at θ + s·a (θ the truth): take s·a back
    corrected = np.asarray(fit.reduced, dtype=float) - s * error
    return DcGainCheck(
        error=error, error_std=fit.std("gain"), dc_gain=float(dc_gain),
        tolerances=tol,
        parameters=tuple(float(v) for v in corrected),  # type: ignore[arg-type]
        reduced=fit.reduced,
        reduced_std=fit.reduced_std,
        propagated_std=tuple(float(v) for v in np.sqrt(var)),  # type: ignore[arg-type]
        level=level,
    )


def with_tolerances(result: ClosedLoopResult, check: DcGainCheck) -> ClosedLoopResult:
    """Return the one-step result with the tolerances in its covariance.

    The added variance lies along the sensitivity directions; the
    correlations the fit found are kept, the diagonal grows to
    ``check.propagated_std²``.

    Parameters
    ----------
    result : ClosedLoopResult
        The reduced one-step fit.
    check : DcGainCheck
        Its DC-gain check, with the tolerances stated.

    Returns
    -------
    ClosedLoopResult
        `result` when no tolerance is stated, else a copy whose
        estimate's covariance carries them.
    """
    if not check.tolerances.any:
        return result
    est = result.estimate
    cov = np.array(est.covariance, dtype=float)
    old = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    new = np.asarray(check.propagated_std, dtype=float)
    ratio = np.divide(new, old, out=np.ones_like(new), where=old > 0)
    cov = cov * np.outer(ratio, ratio)
    return replace(result, estimate=replace(est, covariance=cov))
