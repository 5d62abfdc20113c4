"""Physics of servo actuators: hydraulic, pneumatic and electromechanical.

* The electro-hydraulic servo actuator (EHSA) of models-spec §1: physical
  parameters with units and sources (:class:`EhsaParameters`, sets
  :data:`SET_B`, :data:`SET_C`), reduced and full-order linear models,
  the source study's model decoded (:data:`SET_A`, :func:`paper_consistency`),
  and a compiled nonlinear simulator (:func:`simulate_ehsa`).
* The servopneumatic actuator of models-spec §2
  (:class:`PneumaticParameters`, :func:`simulate_pneumatic`) with reusable
  flow functions (:func:`psi_ellipse`, :func:`psi_saint_venant`,
  :func:`orifice_mass_flow`, :func:`chamber_pressure_rate`).
* Friction models usable by any actuator (Coulomb, viscous, Stribeck,
  Karnopp, the three-regime law).
* A rigid axis with friction in a cascaded position loop (the EMPS axis:
  :class:`RigidAxis`, :class:`CascadeController`, :func:`simulate_rigid_loop`).
"""

from ._ehsa_linear import (
    ReducedEhsa,
    StabilityMargins,
    closed_loop_bandwidth,
    full_order_closed_loop,
    full_order_plant,
    loop_margins,
)
from ._ehsa_params import SET_B, SET_C, EhsaParameters
from ._ehsa_sim import STATE_NAMES, EhsaResponse, default_dt_int, simulate_ehsa
from ._flow import (
    chamber_pressure_rate,
    critical_pressure_ratio,
    orifice_mass_flow,
    psi_ellipse,
    psi_max,
    psi_saint_venant,
)
from ._friction import (
    coulomb_friction,
    karnopp_friction,
    stribeck_friction,
    three_regime_friction,
    viscous_friction,
)
from ._paper import SET_A, PaperConsistency, PaperSetA, paper_consistency
from ._pneumatic_params import PNEUMATIC_NOMINAL, PneumaticParameters
from ._pneumatic_sim import (
    PNEUMATIC_STATE_NAMES,
    PneumaticResponse,
    PositionController,
    pneumatic_dt_int,
    pneumatic_rest_state,
    simulate_pneumatic,
)
from ._rigid import CascadeController, RigidAxis, RigidLoopResponse, simulate_rigid_loop

__all__ = [
    "PNEUMATIC_NOMINAL",
    "PNEUMATIC_STATE_NAMES",
    "SET_A",
    "SET_B",
    "SET_C",
    "STATE_NAMES",
    "CascadeController",
    "EhsaParameters",
    "EhsaResponse",
    "PaperConsistency",
    "PaperSetA",
    "PneumaticParameters",
    "PneumaticResponse",
    "PositionController",
    "ReducedEhsa",
    "RigidAxis",
    "RigidLoopResponse",
    "StabilityMargins",
    "chamber_pressure_rate",
    "closed_loop_bandwidth",
    "coulomb_friction",
    "critical_pressure_ratio",
    "default_dt_int",
    "full_order_closed_loop",
    "full_order_plant",
    "karnopp_friction",
    "loop_margins",
    "orifice_mass_flow",
    "paper_consistency",
    "pneumatic_dt_int",
    "pneumatic_rest_state",
    "psi_ellipse",
    "psi_max",
    "psi_saint_venant",
    "simulate_ehsa",
    "simulate_pneumatic",
    "simulate_rigid_loop",
    "stribeck_friction",
    "three_regime_friction",
    "viscous_friction",
]
