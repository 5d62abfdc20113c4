"""Workflows: end-to-end runs that the command line exposes one to one.

:func:`identify` runs the method an experiment file names; every method is
registered in one place (:func:`get_method`, :func:`method_names`) with its
``[identify]`` options, its run and its report. :func:`load_results` reads
a ``results.json`` back into objects and :func:`rerender` writes a run's
report again from unchanged inputs.

Each name is imported on first use, so that the command line starts (and
``servoid methods`` lists the methods) without loading every method.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._closedloop import ClosedLoopIdentification, loop_from_table
    from ._common import DivergedRun
    from ._demo import DemoResult, run_demo
    from ._inverse import InverseDynamicsIdentification, controller_from_table
    from ._lti import IdentificationResult, OrderRow
    from ._methods import get_method, method_names
    from ._pneumatic import PneumaticIdentification
    from ._registry import Identification, Method, Option
    from ._results import Results, load_results, rerender
    from ._run import identify, write_results

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

#: the module that defines each export
_HOME = {
    "ClosedLoopIdentification": "_closedloop", "loop_from_table": "_closedloop",
    "DivergedRun": "_common",
    "DemoResult": "_demo", "run_demo": "_demo",
    "InverseDynamicsIdentification": "_inverse", "controller_from_table": "_inverse",
    "IdentificationResult": "_lti", "OrderRow": "_lti",
    "PneumaticIdentification": "_pneumatic",
    "Identification": "_registry", "Method": "_registry", "Option": "_registry",
    "Results": "_results", "load_results": "_results", "rerender": "_results",
    "get_method": "_methods", "method_names": "_methods",
    "identify": "_run", "write_results": "_run",
}


def __getattr__(name: str) -> Any:
    """Import an export on first use."""
    if name not in _HOME:
        raise AttributeError(f"module 'servoid.workflows' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOME[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
