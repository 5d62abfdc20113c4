"""Former home of the servopneumatic S0–S6 scheme, now :mod:`servoid.plants.pneumatic`.

A name imported from here still works for one release, with a
:class:`DeprecationWarning` naming its new path.
"""

from .._moved import moved_names

__all__: list[str] = []

#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "DERIVATIVES": "servoid.plants.pneumatic",
    "EDGES": "servoid.plants.pneumatic",
    "KnownConstants": "servoid.plants.pneumatic",
    "MDOT_LIMIT": "servoid.plants.pneumatic",
    "MultistepResult": "servoid.plants.pneumatic",
    "RECORDS": "servoid.plants.pneumatic",
    "REFINABLE": "servoid.plants.pneumatic",
    "RecordComparison": "servoid.plants.pneumatic",
    "RefinementResult": "servoid.plants.pneumatic",
    "StepResult": "servoid.plants.pneumatic",
    "compare_record": "servoid.plants.pneumatic",
    "estimate_controller": "servoid.plants.pneumatic",
    "identify_critical_pressure": "servoid.plants.pneumatic",
    "identify_critical_velocity": "servoid.plants.pneumatic",
    "identify_flow": "servoid.plants.pneumatic",
    "identify_low_speed_friction": "servoid.plants.pneumatic",
    "identify_multistep": "servoid.plants.pneumatic",
    "identify_sliding_friction": "servoid.plants.pneumatic",
    "identify_thermodynamics": "servoid.plants.pneumatic",
    "identify_valve": "servoid.plants.pneumatic",
    "refine_parameters": "servoid.plants.pneumatic",
    "simulate_record": "servoid.plants.pneumatic",
    "zero_phase_derivatives": "servoid.plants.pneumatic",
}
__getattr__ = moved_names(__name__, _MOVED)
