"""Does the valve's flow law show in the data?  A first-order test of the reduced model.

The reduced model takes the valve flow as ``Q = K_qs·x_s``.  A real
critically lapped valve follows Merritt's law (*Hydraulic Control Systems*,
§2.7)::

    Q = K_qs·x_s·√(1 − sgn(x_s)·P_L/P_s)
      ≈ K_qs·(x_s − |x_s|·P_L/(2·P_s))             (first order in P_L/P_s)

so the plant's input is not the flapper error ``u = c·r − F·y`` but
``u − |u|·P_L/(2·P_s)``.  The load pressure is what accelerates the load,
``P_L ≈ M_t·ÿ/A_p`` (the damping ``B_p·ẏ`` is below 1 % of it in the band
of a loaded actuator), so the departure is one extra input to the plant,

    d = −γ·|u|·ÿ,       γ = M_t/(2·A_p·(P_s − P_T))   [s²/m]

and one extra output direction ``z = ∂ŷ/∂γ = −G/(1 + F·G)·(|u|·ÿ)``, both
computed from the identified model and the test (``ŷ``, ``ÿ`` and ``u``
simulated from r).  The residual of the output-error fit is regressed on
the fit's own gradient (∂ŷ/∂K, ∂ŷ/∂ω_hp, ∂ŷ/∂δ_hp), z, ŷ itself (an
error of the loop's DC gain, :mod:`._dc_gain`) and a constant
(:func:`._first_order.first_order_fit`):
the coefficient of z estimates γ (a score test of γ = 0, with the same
coloured-residual sandwich covariance as the one-step intervals), and the
coefficients of the gradient are how far the reduced parameters move when
the flow law is modelled to first order.  The estimate of γ also gives the
peak load pressure the test drove, ``max|P_L|/(P_s − P_T) ≈ 2·γ·max|ÿ|``,
with no physical constant needed.

The verdict: the flow law is *seen* when γ differs from 0 at the level
:data:`FLOW_LEVEL` (two-sided), and it *biases the reduced model* when it
is seen and moves some parameter by more than its 95 % half-interval.
On a Merritt rig (Set B, ±0.2 mm PRBS, |P_L| ≤ 0.28·P_s, 30 dB) the
reduced fit has δ_hp +7.4 % (z ≈ +31) and K −2.1 % (z ≈ −12); the test
gives γ at z ≈ 43, the load pressure at 0.28–0.29 of the supply, and the
first-order correction puts every parameter within 2σ of the truth
(``tests/plants/ehsa/test_flow_law.py``; the seed study is
``benchmarks/bench_ehsa_validity.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..._checks import type_error
from ..._lazy import stats
from ...data import Experiment, ExperimentSet
from ._first_order import FirstOrderFit, first_order_fit
from ._loop import PARAMETER_NAMES
from ._result import ClosedLoopResult

__all__ = ["FLOW_LEVEL", "FlowLawCheck", "check_flow_law", "flow_law_of"]

#: Two-sided level of the test of γ = 0 (the flow law seen).
FLOW_LEVEL = 0.01
_LABELS = {"K": "K", "omega_hp": "ω_hp", "delta_hp": "δ_hp"}


@dataclass(frozen=True)
class FlowLawCheck:
    """The flow law's first-order effect, estimated on the data.

    Parameters
    ----------
    gamma, gamma_std : float
        γ = M_t/(2·A_p·(P_s − P_T)) as the data estimate it, and its
        standard deviation [s²/m].
    pressure_ratio : float
        Peak load pressure the test drove, as a fraction of the supply,
        ``2·γ·max|ÿ|`` [-].
    parameters, std : tuple of float
        K, ω_hp, δ_hp with the flow law modelled to first order, and their
        standard deviations (the joint sandwich covariance).
    reduced, reduced_std : tuple of float
        The reduced fit's K, ω_hp, δ_hp and standard deviations.
    level : float
        Two-sided level of the test of γ = 0.
    """

    gamma: float
    gamma_std: float
    pressure_ratio: float
    parameters: tuple[float, float, float]
    std: tuple[float, float, float]
    reduced: tuple[float, float, float]
    reduced_std: tuple[float, float, float]
    level: float = FLOW_LEVEL

    @property
    def z(self) -> float:
        """γ in standard deviations."""
        return self.gamma / self.gamma_std if self.gamma_std > 0 else math.inf

    @property
    def seen(self) -> bool:
        """True when γ differs from 0 at `level`."""
        return abs(self.z) > float(stats.norm.isf(self.level / 2.0))

    @property
    def shifts(self) -> tuple[float, float, float]:
        """How far the flow law moves K, ω_hp, δ_hp, in the reduced fit's σ."""
        return tuple(float((a - b) / s) if s > 0 else 0.0  # type: ignore[return-value]
                     for a, b, s in zip(self.parameters, self.reduced, self.reduced_std,
                                        strict=True))

    @property
    def biased(self) -> bool:
        """True when the flow law is seen and moves a parameter beyond its 95 % interval."""
        return self.seen and any(abs(s) > float(stats.norm.isf(0.025)) for s in self.shifts)

    @property
    def verdict(self) -> str:
        """One paragraph: what the test says and what to do."""
        head = (f"flow law: γ = {self.gamma:.3g} ± {self.gamma_std:.2g} s²/m (z = "
                f"{self.z:+.1f})")
        if not self.seen:
            return (f"{head}: the data show no departure from the linear valve flow; the test "
                    f"drove the load pressure to at most about {_percent(self.pressure_ratio)} "
                    "of the supply")
        moved = ", ".join(f"{_LABELS[n]} {s:+.1f}σ" for n, s in
                          zip(PARAMETER_NAMES, self.shifts, strict=True))
        corrected = ", ".join(f"{_LABELS[n]} = {v:.5g} ± {s:.2g}" for n, v, s in
                              zip(PARAMETER_NAMES, self.parameters, self.std, strict=True))
        if self.gamma < 0:
            cause = ("the residual follows |u|·ÿ with the sign opposite to the flow law's (flow "
                     "that grows with the load pressure): a nonlinearity other than the valve's "
                     "flow law, e.g. friction or a pressure-dependent leakage")
        else:
            cause = ("the valve's flow falls with the load pressure as Merritt's law Q ∝ "
                     "x·√(P_s − sgn(x)·P_L) says; the test drove the load pressure to about "
                     f"{_percent(self.pressure_ratio)} of the supply")
        if not self.biased:
            return (f"{head}: {cause}. Modelled to first order it moves {moved}, within the "
                    "reduced model's intervals")
        if self.gamma < 0:
            return (f"{head}: {cause}. It moves {moved}: beyond the reduced model's 95 % "
                    "intervals, which describe the noise only. Refine with the nonlinear EHSA "
                    "(`[identify] refine = true`)")
        return (f"{head}: {cause}. Modelled to first order it moves {moved}: beyond the reduced "
                f"model's 95 % intervals, which describe the noise only. With the flow law: "
                f"{corrected}. Lower the amplitude (the load pressure, and with it the effect, "
                "falls with it) or refine with the nonlinear EHSA (`[identify] refine = true`)")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "gamma": self.gamma, "gamma_std": self.gamma_std, "z": self.z,
            "pressure_ratio": self.pressure_ratio, "level": self.level, "seen": self.seen,
            "biased": self.biased,
            "parameters": dict(zip(PARAMETER_NAMES, self.parameters, strict=True)),
            "std": dict(zip(PARAMETER_NAMES, self.std, strict=True)),
            "shifts_sigma": dict(zip(PARAMETER_NAMES, self.shifts, strict=True)),
            "verdict": self.verdict,
        }


def check_flow_law(
    result: ClosedLoopResult,
    data: Experiment | ExperimentSet,
    *,
    level: float = FLOW_LEVEL,
) -> FlowLawCheck | None:
    """Estimate the valve flow law's effect on a reduced one-step fit.

    Parameters
    ----------
    result : ClosedLoopResult
        A one-step fit of the reduced structure (its residuals and
        K, ω_hp, δ_hp with standard deviations).
    data : Experiment or ExperimentSet
        The estimation record(s) it was fitted to.
    level : float
        Two-sided level of the test of γ = 0.

    Returns
    -------
    FlowLawCheck or None
        None when the check does not apply: another structure or
        approach, or a dynamic feedback F.

    Raises
    ------
    DataError
        The residuals do not match the records.
    """
    if not isinstance(result, ClosedLoopResult):
        raise type_error("result", result, "a ClosedLoopResult (a one-step fit of the reduced "
                         "structure, e.g. from fit_one_step)")
    fit = first_order_fit(result, data)
    return None if fit is None else flow_law_of(fit, level=level)


def flow_law_of(fit: FirstOrderFit, *, level: float = FLOW_LEVEL) -> FlowLawCheck:
    """Return the flow-law check of a first-order regression (:func:`check_flow_law`)."""
    return FlowLawCheck(
        gamma=fit.coefficient("gamma"), gamma_std=fit.std("gamma"),
        pressure_ratio=2.0 * fit.coefficient("gamma") * fit.peak_acceleration,
        parameters=fit.corrected(), std=fit.corrected_std(),
        reduced=fit.reduced, reduced_std=fit.reduced_std, level=level,
    )


def _percent(x: float) -> str:
    return f"{100.0 * x:.2g} %"
