"""Closed-loop identification: known loops, unknown controllers, feedback test.

Any plant, black box (:mod:`._blackbox`, :mod:`._indirect`,
:mod:`._feedback`)::

    feedback_test      residuals against future inputs: was the record taken in closed loop?
    fit_indirect_tf    known controller C: OE on r → y, then the plant of any order
    fit_two_stage      unknown controller: û_r = Ŝ r by FIR (or projection), then OE/BJ
    fit_cliv           unknown controller: IV with instruments from r
    (direct)           servoid.estimate.fit_bj on (u, y): PEM with a noise model

The electro-hydraulic actuator study: the plant G0 runs in a known loop
``H = c·G0/(1 + F·G0)`` (:class:`FeedbackLoop`). Every approach returns a
:class:`ClosedLoopResult` with the physical parameters of the reduced
EHSA model ``K/(s(s²/ω_hp² + 2δ_hp·s/ω_hp + 1))``, their covariance, the
discrete and continuous models and a pole report that flags what cannot
be physical::

    identify_closed_loop(data, loop, approach=...)
    ├── "indirect"  fit_indirect   ARX on (r, y), G0 = B/(c·A − F·B), d2c
    ├── "one-step"  fit_one_step   OE on Gcl(q, θ), θ = (K, ω_hp, δ_hp)
    └── "direct"    fit_direct     ARX/OE on (u, y), u measured or c·r − F·y

Richer plant structures (:data:`STRUCTURES`: the reduced model with a valve
lag, the full-order plant) and :func:`compare_structures`, which says
whether the data reject the reduced model and so whether its intervals can
be trusted.

The nonlinear EHSA of models-spec §1.4 (flow law at the measured supply
pressure, saturations, friction, dead time) refined from the same records
with the compiled simulator (:mod:`._nonlinear`)::

    refine_nonlinear_ehsa(data, loop, start, parameters)  → Estimate, model NonlinearEhsa
    refine_after_linear(estimation, validation, loop, result) → NonlinearRefinement
    validate_nonlinear_ehsa(model, record)                → ValidationReport
"""

from ._api import APPROACHES, identify_closed_loop, simulate_closed_loop
from ._blackbox import fit_cliv, fit_two_stage
from ._feedback import FeedbackTest, feedback_test, warn_if_feedback
from ._indirect import fit_indirect_tf
from ._loop import FeedbackLoop, reduced_plant
from ._nonlinear import NONLINEAR_DEFAULTS, refine_nonlinear_ehsa
from ._nonlinear_check import NonlinearRefinement, refine_after_linear, validate_nonlinear_ehsa
from ._nonlinear_model import NONLINEAR_PARAMETERS, NonlinearEhsa
from ._onestep import DISCRETIZATIONS, fit_one_step
from ._result import ClosedLoopResult, PoleInfo
from ._structure_test import NestedTest, StructureFit, StructureTest, compare_structures
from ._structures import STRUCTURES, PlantStructure, full_order_structure
from ._twostep import fit_direct, fit_indirect

__all__ = [
    "APPROACHES",
    "DISCRETIZATIONS",
    "NONLINEAR_DEFAULTS",
    "NONLINEAR_PARAMETERS",
    "STRUCTURES",
    "ClosedLoopResult",
    "FeedbackLoop",
    "FeedbackTest",
    "NestedTest",
    "NonlinearEhsa",
    "NonlinearRefinement",
    "PlantStructure",
    "PoleInfo",
    "StructureFit",
    "StructureTest",
    "compare_structures",
    "feedback_test",
    "fit_cliv",
    "fit_direct",
    "fit_indirect",
    "fit_indirect_tf",
    "fit_one_step",
    "fit_two_stage",
    "full_order_structure",
    "identify_closed_loop",
    "reduced_plant",
    "refine_after_linear",
    "refine_nonlinear_ehsa",
    "simulate_closed_loop",
    "validate_nonlinear_ehsa",
    "warn_if_feedback",
]
