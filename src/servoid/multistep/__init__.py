"""Multi-step identification of the servopneumatic actuator (S0–S6).

The scheme of Hahn & Piepenbrink (IFAC SYSID 1994, [S2] Fig. 17;
models-spec §3.9) identifies the physical model equation group by
equation group, each from the test that excites it, inserting earlier
estimates into later equations, and validates the assembled model by
simulation:

* steps usable alone, each returning a :class:`StepResult`:
  :func:`identify_critical_pressure` and :func:`identify_critical_velocity`
  (S0), :func:`identify_valve` (S1), :func:`identify_thermodynamics` (S2),
  :func:`identify_flow` (S3), :func:`identify_sliding_friction` (S4),
  :func:`identify_low_speed_friction` (S5), :func:`compare_record` (S6);
* the pipeline :func:`identify_multistep` → :class:`MultistepResult`;
* grey-box refinement of the full model with the compiled simulator,
  :func:`refine_parameters` → :class:`RefinementResult`.

The known constants (geometry, mass, supply) are a :class:`KnownConstants`.
"""

from ._common import DERIVATIVES, MDOT_LIMIT, KnownConstants, StepResult
from ._flow import EDGES, identify_critical_pressure, identify_flow
from ._friction import (
    identify_critical_velocity,
    identify_low_speed_friction,
    identify_sliding_friction,
)
from ._pipeline import RECORDS, MultistepResult, identify_multistep
from ._refine import (
    REFINABLE,
    RecordComparison,
    RefinementResult,
    compare_record,
    estimate_controller,
    refine_parameters,
    simulate_record,
)
from ._thermo import identify_thermodynamics, zero_phase_derivatives
from ._valve import identify_valve

__all__ = [
    "DERIVATIVES",
    "EDGES",
    "MDOT_LIMIT",
    "RECORDS",
    "REFINABLE",
    "KnownConstants",
    "MultistepResult",
    "RecordComparison",
    "RefinementResult",
    "StepResult",
    "compare_record",
    "estimate_controller",
    "identify_critical_pressure",
    "identify_critical_velocity",
    "identify_flow",
    "identify_low_speed_friction",
    "identify_multistep",
    "identify_sliding_friction",
    "identify_thermodynamics",
    "identify_valve",
    "refine_parameters",
    "simulate_record",
    "zero_phase_derivatives",
]
