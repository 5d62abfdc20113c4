"""Former home of the actuators' physics, now :mod:`servoid.plants` (for one release).

Each actuator lives in its own subpackage: the electro-hydraulic actuator in
:mod:`servoid.plants.ehsa`, the servopneumatic one in
:mod:`servoid.plants.pneumatic`, the rigid axis in :mod:`servoid.plants.rigid`,
the friction laws in :mod:`servoid.plants`.  A name imported from here still
works, with a :class:`DeprecationWarning` naming its new path.
"""

from .._moved import moved_names

__all__: list[str] = []

#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "CascadeController": "servoid.plants.rigid",
    "EhsaParameters": "servoid.plants.ehsa",
    "EhsaResponse": "servoid.plants.ehsa",
    "PNEUMATIC_NOMINAL": "servoid.plants.pneumatic",
    "PNEUMATIC_STATE_NAMES": "servoid.plants.pneumatic",
    "PaperConsistency": "servoid.plants.ehsa",
    "PaperSetA": "servoid.plants.ehsa",
    "PneumaticParameters": "servoid.plants.pneumatic",
    "PneumaticResponse": "servoid.plants.pneumatic",
    "PositionController": "servoid.plants.pneumatic",
    "ReducedEhsa": "servoid.plants.ehsa",
    "RigidAxis": "servoid.plants.rigid",
    "RigidLoopResponse": "servoid.plants.rigid",
    "SET_A": "servoid.plants.ehsa",
    "SET_B": "servoid.plants.ehsa",
    "SET_C": "servoid.plants.ehsa",
    "STATE_NAMES": "servoid.plants.ehsa",
    "StabilityMargins": "servoid.plants.ehsa",
    "chamber_pressure_rate": "servoid.plants.pneumatic",
    "closed_loop_bandwidth": "servoid.plants.ehsa",
    "coulomb_friction": "servoid.plants",
    "critical_pressure_ratio": "servoid.plants.pneumatic",
    "default_dt_int": "servoid.plants.ehsa",
    "full_order_closed_loop": "servoid.plants.ehsa",
    "full_order_plant": "servoid.plants.ehsa",
    "karnopp_friction": "servoid.plants",
    "loop_margins": "servoid.plants.ehsa",
    "orifice_mass_flow": "servoid.plants.pneumatic",
    "paper_consistency": "servoid.plants.ehsa",
    "pneumatic_dt_int": "servoid.plants.pneumatic",
    "pneumatic_rest_state": "servoid.plants.pneumatic",
    "psi_ellipse": "servoid.plants.pneumatic",
    "psi_max": "servoid.plants.pneumatic",
    "psi_saint_venant": "servoid.plants.pneumatic",
    "simulate_ehsa": "servoid.plants.ehsa",
    "simulate_pneumatic": "servoid.plants.pneumatic",
    "simulate_rigid_loop": "servoid.plants.rigid",
    "stribeck_friction": "servoid.plants",
    "three_regime_friction": "servoid.plants",
    "viscous_friction": "servoid.plants",
}
__getattr__ = moved_names(__name__, _MOVED)
