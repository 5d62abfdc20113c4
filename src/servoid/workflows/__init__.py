"""Workflows: end-to-end runs that the command line exposes one to one."""

from ._closedloop import ClosedLoopIdentification, identify_closed_loop_spec, loop_from_table
from ._demo import DemoResult, run_demo
from ._identify import IdentificationResult, identify
from ._inverse import (
    InverseDynamicsIdentification,
    controller_from_table,
    identify_inverse_dynamics_spec,
)
from ._pneumatic import PneumaticIdentification, identify_pneumatic_spec

__all__ = [
    "ClosedLoopIdentification",
    "DemoResult",
    "IdentificationResult",
    "InverseDynamicsIdentification",
    "PneumaticIdentification",
    "controller_from_table",
    "identify",
    "identify_closed_loop_spec",
    "identify_inverse_dynamics_spec",
    "identify_pneumatic_spec",
    "loop_from_table",
    "run_demo",
]
