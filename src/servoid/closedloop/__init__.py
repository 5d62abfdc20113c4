"""Closed-loop identification of any plant: unknown or known controllers, feedback test.

Black box, for any plant in a loop (:mod:`._blackbox`, :mod:`._indirect`,
:mod:`._feedback`)::

    feedback_test      residuals against future inputs: was the record taken in closed loop?
    fit_indirect_tf    known controller C: OE on r → y, then the plant of any order
    fit_two_stage      unknown controller: û_r = Ŝ r by FIR (or projection), then OE/BJ
    fit_cliv           unknown controller: IV with instruments from r
    fit_direct_bj      the direct approach: Box–Jenkins on (u, y), started from CLIV too

The electro-hydraulic actuator's physical identification in its known loop
(``FeedbackLoop``, ``identify_closed_loop``, the structure test, the
nonlinear refinement) lives in :mod:`servoid.plants.ehsa`; its names are
still found here for one release, with a :class:`DeprecationWarning`.
"""

from .._moved import moved_names
from ._blackbox import fit_cliv, fit_two_stage
from ._direct import fit_direct_bj
from ._feedback import FeedbackTest, feedback_test, warn_if_feedback
from ._indirect import fit_indirect_tf

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._channels import check_name as check_name
from ._channels import output_name as output_name
from ._channels import reference_name as reference_name
from ._coloured import sandwich as sandwich

__all__ = [
    "FeedbackTest",
    "feedback_test",
    "fit_cliv",
    "fit_direct_bj",
    "fit_indirect_tf",
    "fit_two_stage",
    "warn_if_feedback",
]

#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "APPROACHES": "servoid.plants.ehsa",
    "ClosedLoopResult": "servoid.plants.ehsa",
    "DISCRETIZATIONS": "servoid.plants.ehsa",
    "FeedbackLoop": "servoid.plants.ehsa",
    "NONLINEAR_DEFAULTS": "servoid.plants.ehsa",
    "NONLINEAR_PARAMETERS": "servoid.plants.ehsa",
    "NestedTest": "servoid.plants.ehsa",
    "NonlinearEhsa": "servoid.plants.ehsa",
    "NonlinearRefinement": "servoid.plants.ehsa",
    "PlantStructure": "servoid.plants.ehsa",
    "PoleInfo": "servoid.plants.ehsa",
    "STRUCTURES": "servoid.plants.ehsa",
    "StructureFit": "servoid.plants.ehsa",
    "StructureTest": "servoid.plants.ehsa",
    "compare_structures": "servoid.plants.ehsa",
    "fit_direct": "servoid.plants.ehsa",
    "fit_indirect": "servoid.plants.ehsa",
    "fit_one_step": "servoid.plants.ehsa",
    "full_order_structure": "servoid.plants.ehsa",
    "identify_closed_loop": "servoid.plants.ehsa",
    "reduced_plant": "servoid.plants.ehsa",
    "refine_after_linear": "servoid.plants.ehsa",
    "refine_nonlinear_ehsa": "servoid.plants.ehsa",
    "simulate_closed_loop": "servoid.plants.ehsa",
    "validate_nonlinear_ehsa": "servoid.plants.ehsa",
}
__getattr__ = moved_names(__name__, _MOVED)
