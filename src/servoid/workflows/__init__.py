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

from typing import TYPE_CHECKING

from .._exports import lazy_exports
from .._moved import moved_names

if TYPE_CHECKING:
    from ._common import DivergedRun
    from ._lti import IdentificationResult, OrderRow
    from ._methods import get_method, method_names
    from ._registry import Identification, Method, Option
    from ._results import Results, load_results, rerender
    from ._run import identify, write_results
    from ._summary import ParameterValue, RecordSummary

__all__ = [
    "DivergedRun",
    "Identification",
    "IdentificationResult",
    "Method",
    "Option",
    "OrderRow",
    "ParameterValue",
    "RecordSummary",
    "Results",
    "get_method",
    "identify",
    "load_results",
    "method_names",
    "rerender",
    "write_results",
]

#: the module that defines each export
_HOME = {
    "DivergedRun": "_common",
    "IdentificationResult": "_lti", "OrderRow": "_lti",
    "Identification": "_registry", "Method": "_registry", "Option": "_registry",
    "ParameterValue": "_summary", "RecordSummary": "_summary",
    "Results": "_results", "load_results": "_results", "rerender": "_results",
    "get_method": "_methods", "method_names": "_methods",
    "identify": "_run", "write_results": "_run",
}

# For servoid's front ends (cli, fleet): imported through this package, not part of __all__.
_HOME.update({
    "METHODS": "_methods", "method_of": "_methods", "set_command": "_provenance",
    "greybox_record": "_results", "summarise": "_summary", "toml_value": "_registry",
    "candidate_models": "_leaderboard", "method_for": "_choice", "listed_methods": "_choice",
    "candidates_on": "_choice",
})


#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "ClosedLoopIdentification": "servoid.plants.ehsa",
    "DemoResult": "servoid.plants.ehsa",
    "InverseDynamicsIdentification": "servoid.plants.rigid",
    "PneumaticIdentification": "servoid.plants.pneumatic",
    "controller_from_table": "servoid.plants.rigid",
    "loop_from_table": "servoid.plants.ehsa",
    "run_demo": "servoid.plants.ehsa",
}
_moved = moved_names(__name__, _MOVED)

__getattr__, __dir__ = lazy_exports(__name__, _HOME, fallback=_moved)
