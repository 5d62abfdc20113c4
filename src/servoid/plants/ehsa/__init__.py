"""The electro-hydraulic servo actuator (EHSA): physics to identification.

Study 1 of servoid: the actuator that swivels a launcher's nozzle, run
inside its mechanical position feedback, so that only closed-loop records
exist.  This subpackage holds all of it:

* physics: :class:`EhsaParameters` with the nominal sets :data:`SET_B` and
  :data:`SET_C` (units and sources), the source study's own model decoded
  (:data:`SET_A`, :func:`paper_consistency`), the reduced and full-order
  linear models (:class:`ReducedEhsa`, :func:`full_order_plant`,
  :func:`loop_margins`) and the compiled nonlinear simulator
  (:func:`simulate_ehsa`, stepped by :func:`servoid.integrate.rk4_step`);
* the loop: :class:`FeedbackLoop` (``H = c·G0/(1 + F·G0)``);
* the virtual bench: :class:`EhsaBench`, :func:`run`, :func:`digitize`,
  :func:`write_bench_files`, :func:`write_virtual_fleet`, and the test it
  can run: :func:`excitation_limits` (load pressure within
  :data:`PRESSURE_FRACTION` of the supply, valve, velocity, stroke);
* physical identification from closed-loop records:
  :func:`identify_closed_loop` (two-step indirect, one-step output error,
  direct), the structure test :func:`compare_structures`, the flow-law
  check :func:`check_flow_law`, the nonlinear
  refinement :func:`refine_nonlinear_ehsa`;
* the workflow ``[identify] method = "closedloop"``
  (:class:`ClosedLoopIdentification`) and the demo (:func:`run_demo`).

The names load on first use (PEP 562): ``import servoid.plants`` reads
only :data:`PLANT`.  See ``docs/study1-ehsa.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._exports import lazy_exports
from .._plant import Plant

if TYPE_CHECKING:
    from ._api import APPROACHES, identify_closed_loop, simulate_closed_loop
    from ._bench import CHANNELS, BenchRun, EhsaTruth, digitize, run
    from ._bench_config import FIDELITIES, REFERENCES, EhsaBench, Fidelity, Reference
    from ._bench_files import RigFormat, experiment_document, truth_document, write_bench_files
    from ._demo import DemoResult, run_demo
    from ._fleet import FLEET_LIMITS, FLEET_SCATTER, VirtualFleet, write_virtual_fleet
    from ._flow_check import FLOW_LEVEL, FlowLawCheck, check_flow_law
    from ._limits import PRESSURE_FRACTION, PlannedTest, excitation_limits, within_limits
    from ._linear import (
        ReducedEhsa,
        StabilityMargins,
        closed_loop_bandwidth,
        full_order_closed_loop,
        full_order_plant,
        loop_margins,
    )
    from ._loop import FeedbackLoop, reduced_plant
    from ._nonlinear import NONLINEAR_DEFAULTS, refine_nonlinear_ehsa
    from ._nonlinear_check import NonlinearRefinement, refine_after_linear, validate_nonlinear_ehsa
    from ._nonlinear_model import NONLINEAR_PARAMETERS, NonlinearEhsa
    from ._onestep import DISCRETIZATIONS, fit_one_step
    from ._paper import SET_A, PaperConsistency, PaperSetA, paper_consistency
    from ._params import SET_B, SET_C, EhsaParameters
    from ._result import ClosedLoopResult, PoleInfo
    from ._sim import STATE_NAMES, EhsaResponse, default_dt_int, simulate_ehsa
    from ._structure_test import NestedTest, StructureFit, StructureTest, compare_structures
    from ._structures import STRUCTURES, PlantStructure, full_order_structure
    from ._twostep import fit_direct, fit_indirect
    from ._workflow import ClosedLoopIdentification, loop_from_table

#: Exported name → the private module that defines it.
_WHERE = {
    "APPROACHES": "_api",
    "CHANNELS": "_bench",
    "DISCRETIZATIONS": "_onestep",
    "FIDELITIES": "_bench_config",
    "FLEET_LIMITS": "_fleet",
    "FLEET_SCATTER": "_fleet",
    "FLOW_LEVEL": "_flow_check",
    "NONLINEAR_DEFAULTS": "_nonlinear",
    "NONLINEAR_PARAMETERS": "_nonlinear_model",
    "PRESSURE_FRACTION": "_limits",
    "REFERENCES": "_bench_config",
    "SET_A": "_paper",
    "SET_B": "_params",
    "SET_C": "_params",
    "STATE_NAMES": "_sim",
    "STRUCTURES": "_structures",
    "BenchRun": "_bench",
    "ClosedLoopIdentification": "_workflow",
    "ClosedLoopResult": "_result",
    "DemoResult": "_demo",
    "EhsaBench": "_bench_config",
    "EhsaParameters": "_params",
    "EhsaResponse": "_sim",
    "EhsaTruth": "_bench",
    "FeedbackLoop": "_loop",
    "Fidelity": "_bench_config",
    "FlowLawCheck": "_flow_check",
    "NestedTest": "_structure_test",
    "NonlinearEhsa": "_nonlinear_model",
    "NonlinearRefinement": "_nonlinear_check",
    "PaperConsistency": "_paper",
    "PaperSetA": "_paper",
    "PlannedTest": "_limits",
    "PlantStructure": "_structures",
    "PoleInfo": "_result",
    "ReducedEhsa": "_linear",
    "Reference": "_bench_config",
    "RigFormat": "_bench_files",
    "StabilityMargins": "_linear",
    "StructureFit": "_structure_test",
    "StructureTest": "_structure_test",
    "VirtualFleet": "_fleet",
    "check_flow_law": "_flow_check",
    "closed_loop_bandwidth": "_linear",
    "compare_structures": "_structure_test",
    "default_dt_int": "_sim",
    "digitize": "_bench",
    "excitation_limits": "_limits",
    "experiment_document": "_bench_files",
    "fit_direct": "_twostep",
    "fit_indirect": "_twostep",
    "fit_one_step": "_onestep",
    "full_order_closed_loop": "_linear",
    "full_order_plant": "_linear",
    "full_order_structure": "_structures",
    "identify_closed_loop": "_api",
    "loop_from_table": "_workflow",
    "loop_margins": "_linear",
    "paper_consistency": "_paper",
    "reduced_plant": "_loop",
    "refine_after_linear": "_nonlinear_check",
    "refine_nonlinear_ehsa": "_nonlinear",
    "run": "_bench",
    "run_demo": "_demo",
    "simulate_closed_loop": "_api",
    "simulate_ehsa": "_sim",
    "truth_document": "_bench_files",
    "validate_nonlinear_ehsa": "_nonlinear_check",
    "within_limits": "_limits",
    "write_bench_files": "_bench_files",
    "write_virtual_fleet": "_fleet",
}

__all__ = [
    "APPROACHES",
    "CHANNELS",
    "DISCRETIZATIONS",
    "FIDELITIES",
    "FLEET_LIMITS",
    "FLEET_SCATTER",
    "FLOW_LEVEL",
    "NONLINEAR_DEFAULTS",
    "NONLINEAR_PARAMETERS",
    "PLANT",
    "PRESSURE_FRACTION",
    "REFERENCES",
    "SET_A",
    "SET_B",
    "SET_C",
    "STATE_NAMES",
    "STRUCTURES",
    "BenchRun",
    "ClosedLoopIdentification",
    "ClosedLoopResult",
    "DemoResult",
    "EhsaBench",
    "EhsaParameters",
    "EhsaResponse",
    "EhsaTruth",
    "FeedbackLoop",
    "Fidelity",
    "FlowLawCheck",
    "NestedTest",
    "NonlinearEhsa",
    "NonlinearRefinement",
    "PaperConsistency",
    "PaperSetA",
    "PlannedTest",
    "PlantStructure",
    "PoleInfo",
    "ReducedEhsa",
    "Reference",
    "RigFormat",
    "StabilityMargins",
    "StructureFit",
    "StructureTest",
    "VirtualFleet",
    "check_flow_law",
    "closed_loop_bandwidth",
    "compare_structures",
    "default_dt_int",
    "digitize",
    "excitation_limits",
    "experiment_document",
    "fit_direct",
    "fit_indirect",
    "fit_one_step",
    "full_order_closed_loop",
    "full_order_plant",
    "full_order_structure",
    "identify_closed_loop",
    "loop_from_table",
    "loop_margins",
    "paper_consistency",
    "reduced_plant",
    "refine_after_linear",
    "refine_nonlinear_ehsa",
    "run",
    "run_demo",
    "simulate_closed_loop",
    "simulate_ehsa",
    "truth_document",
    "validate_nonlinear_ehsa",
    "within_limits",
    "write_bench_files",
    "write_virtual_fleet",
]

#: The ehsa plant as servoid's plants know it.
PLANT = Plant(
    name="ehsa",
    title="electro-hydraulic servo actuator in its mechanical position feedback",
    methods={"closedloop": (
             'physical parameters K, ω_hp, δ_hp of the reduced electro-hydraulic '
             'plant inside its known loop ([loop] c, F): two-step indirect, one-step '
             'OE, direct')},
    parts={
        "parameters": f"{__name__}._params:PARAMETER_SETS",
        "rhs": f"{__name__}._kernel:rhs",
        "simulate": f"{__name__}._sim:simulate_ehsa",
        "loop": f"{__name__}._loop:FeedbackLoop",
        "bench": f"{__name__}._bench_files:write_bench",
        "fleet": f"{__name__}._fleet:write_virtual_fleet",
        "cli": f"{__name__}._cli:add_cli",
        "limits": f"{__name__}._limits:plan_test",
        "methods": f"{__name__}._workflow:METHODS",
    },
)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
