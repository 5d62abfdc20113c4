"""Physics of servo actuators: the electro-hydraulic servo actuator.

The EHSA of models-spec §1 ([S1]): physical parameters with units and
sources (:class:`EhsaParameters`, sets :data:`SET_B` and :data:`SET_C`),
the reduced third-order and full eighth-order linear models, the
paper's identified model decoded and checked (:data:`SET_A`,
:func:`paper_consistency`), and a compiled nonlinear simulator
(:func:`simulate_ehsa`).
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
from ._paper import SET_A, PaperConsistency, PaperSetA, paper_consistency

__all__ = [
    "SET_A",
    "SET_B",
    "SET_C",
    "STATE_NAMES",
    "EhsaParameters",
    "EhsaResponse",
    "PaperConsistency",
    "PaperSetA",
    "ReducedEhsa",
    "StabilityMargins",
    "closed_loop_bandwidth",
    "default_dt_int",
    "full_order_closed_loop",
    "full_order_plant",
    "loop_margins",
    "paper_consistency",
    "simulate_ehsa",
]
