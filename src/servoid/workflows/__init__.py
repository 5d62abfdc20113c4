"""Workflows: end-to-end runs that the command line exposes one to one."""

from ._closedloop import ClosedLoopIdentification, identify_closed_loop_spec, loop_from_table
from ._demo import DemoResult, run_demo
from ._identify import IdentificationResult, identify

__all__ = [
    "ClosedLoopIdentification",
    "DemoResult",
    "IdentificationResult",
    "identify",
    "identify_closed_loop_spec",
    "loop_from_table",
    "run_demo",
]
