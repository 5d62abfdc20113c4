"""Workflows: end-to-end runs that the command line exposes one to one.

:func:`identify` runs the method an experiment file names; every method is
registered in one place (:func:`get_method`, :func:`method_names`) with its
``[identify]`` options, its run and its report. :func:`load_results` reads
a ``results.json`` back into objects and :func:`rerender` writes a run's
report again from unchanged inputs.
"""

from ._closedloop import ClosedLoopIdentification, loop_from_table
from ._common import DivergedRun
from ._demo import DemoResult, run_demo
from ._inverse import InverseDynamicsIdentification, controller_from_table
from ._lti import IdentificationResult, OrderRow
from ._pneumatic import PneumaticIdentification
from ._registry import Identification, Method, Option
from ._results import Results, load_results, rerender
from ._run import get_method, identify, method_names, write_results

__all__ = [
    "ClosedLoopIdentification",
    "DemoResult",
    "DivergedRun",
    "Identification",
    "IdentificationResult",
    "InverseDynamicsIdentification",
    "Method",
    "Option",
    "OrderRow",
    "PneumaticIdentification",
    "Results",
    "controller_from_table",
    "get_method",
    "identify",
    "load_results",
    "loop_from_table",
    "method_names",
    "rerender",
    "run_demo",
    "write_results",
]
