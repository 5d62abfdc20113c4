"""The servopneumatic actuator: physics to identification.

Study 2 of servoid: a servovalve-driven pneumatic cylinder with two
chambers, orifice mass flows and a piston with friction.  This subpackage
holds all of it:

* physics: :class:`PneumaticParameters` (:data:`PNEUMATIC_NOMINAL`), the
  orifice flow functions (:func:`psi_ellipse`, :func:`psi_saint_venant`,
  :func:`orifice_mass_flow`, :func:`chamber_pressure_rate`) and the
  compiled simulator (:func:`simulate_pneumatic`, stepped by
  :func:`servoid.integrate.rk4_step`) in its PD loop
  (:class:`PositionController`);
* the virtual bench: :class:`PneumaticBench`, :func:`run_pneumatic`,
  :func:`write_pneumatic_campaign` (the S0–S6 test campaign);
* physical identification equation group by equation group (S0–S6,
  :func:`identify_multistep` and each step alone) and the grey-box
  refinement :func:`refine_parameters`;
* the workflow ``[identify] method = "pneumatic-multistep"``
  (:class:`PneumaticIdentification`).

The names load on first use (PEP 562).  See ``docs/study2-pneumatic.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._exports import lazy_exports
from .._plant import Plant

if TYPE_CHECKING:
    from ._bench import (
        PNEUMATIC_CHANNELS,
        PNEUMATIC_TESTS,
        PneumaticBench,
        PneumaticRun,
        PneumaticTest,
        PneumaticTestName,
        run_pneumatic,
    )
    from ._bench_files import (
        pneumatic_experiment_document,
        pneumatic_truth_document,
        write_pneumatic_campaign,
    )
    from ._flow import (
        chamber_pressure_rate,
        critical_pressure_ratio,
        orifice_mass_flow,
        psi_ellipse,
        psi_max,
        psi_saint_venant,
    )
    from ._params import PNEUMATIC_NOMINAL, PneumaticParameters
    from ._pipeline import RECORDS, MultistepResult, identify_multistep
    from ._refine import (
        REFINABLE,
        RecordComparison,
        RefinementResult,
        compare_record,
        estimate_controller,
        refine_parameters,
        simulate_record,
    )
    from ._sim import (
        PNEUMATIC_STATE_NAMES,
        PneumaticResponse,
        PositionController,
        pneumatic_dt_int,
        pneumatic_rest_state,
        simulate_pneumatic,
    )
    from ._step_flow import EDGES, identify_critical_pressure, identify_flow
    from ._step_friction import (
        identify_critical_velocity,
        identify_low_speed_friction,
        identify_sliding_friction,
    )
    from ._step_thermo import identify_thermodynamics, zero_phase_derivatives
    from ._step_valve import identify_valve
    from ._steps import DERIVATIVES, MDOT_LIMIT, KnownConstants, StepResult
    from ._workflow import PneumaticIdentification

#: Exported name → the private module that defines it.
_WHERE = {
    "DERIVATIVES": "_steps",
    "EDGES": "_step_flow",
    "MDOT_LIMIT": "_steps",
    "PNEUMATIC_CHANNELS": "_bench",
    "PNEUMATIC_NOMINAL": "_params",
    "PNEUMATIC_STATE_NAMES": "_sim",
    "PNEUMATIC_TESTS": "_bench",
    "RECORDS": "_pipeline",
    "REFINABLE": "_refine",
    "KnownConstants": "_steps",
    "MultistepResult": "_pipeline",
    "PneumaticBench": "_bench",
    "PneumaticIdentification": "_workflow",
    "PneumaticParameters": "_params",
    "PneumaticResponse": "_sim",
    "PneumaticRun": "_bench",
    "PneumaticTest": "_bench",
    "PneumaticTestName": "_bench",
    "PositionController": "_sim",
    "RecordComparison": "_refine",
    "RefinementResult": "_refine",
    "StepResult": "_steps",
    "chamber_pressure_rate": "_flow",
    "compare_record": "_refine",
    "critical_pressure_ratio": "_flow",
    "estimate_controller": "_refine",
    "identify_critical_pressure": "_step_flow",
    "identify_critical_velocity": "_step_friction",
    "identify_flow": "_step_flow",
    "identify_low_speed_friction": "_step_friction",
    "identify_multistep": "_pipeline",
    "identify_sliding_friction": "_step_friction",
    "identify_thermodynamics": "_step_thermo",
    "identify_valve": "_step_valve",
    "orifice_mass_flow": "_flow",
    "pneumatic_dt_int": "_sim",
    "pneumatic_experiment_document": "_bench_files",
    "pneumatic_rest_state": "_sim",
    "pneumatic_truth_document": "_bench_files",
    "psi_ellipse": "_flow",
    "psi_max": "_flow",
    "psi_saint_venant": "_flow",
    "refine_parameters": "_refine",
    "run_pneumatic": "_bench",
    "simulate_pneumatic": "_sim",
    "simulate_record": "_refine",
    "write_pneumatic_campaign": "_bench_files",
    "zero_phase_derivatives": "_step_thermo",
}

__all__ = [
    "DERIVATIVES",
    "EDGES",
    "MDOT_LIMIT",
    "PLANT",
    "PNEUMATIC_CHANNELS",
    "PNEUMATIC_NOMINAL",
    "PNEUMATIC_STATE_NAMES",
    "PNEUMATIC_TESTS",
    "RECORDS",
    "REFINABLE",
    "KnownConstants",
    "MultistepResult",
    "PneumaticBench",
    "PneumaticIdentification",
    "PneumaticParameters",
    "PneumaticResponse",
    "PneumaticRun",
    "PneumaticTest",
    "PneumaticTestName",
    "PositionController",
    "RecordComparison",
    "RefinementResult",
    "StepResult",
    "chamber_pressure_rate",
    "compare_record",
    "critical_pressure_ratio",
    "estimate_controller",
    "identify_critical_pressure",
    "identify_critical_velocity",
    "identify_flow",
    "identify_low_speed_friction",
    "identify_multistep",
    "identify_sliding_friction",
    "identify_thermodynamics",
    "identify_valve",
    "orifice_mass_flow",
    "pneumatic_dt_int",
    "pneumatic_experiment_document",
    "pneumatic_rest_state",
    "pneumatic_truth_document",
    "psi_ellipse",
    "psi_max",
    "psi_saint_venant",
    "refine_parameters",
    "run_pneumatic",
    "simulate_pneumatic",
    "simulate_record",
    "write_pneumatic_campaign",
    "zero_phase_derivatives",
]

#: The pneumatic plant as servoid's plants know it.
PLANT = Plant(
    name="pneumatic",
    title="servopneumatic actuator (servovalve, two chambers, piston with friction)",
    methods={"pneumatic-multistep": (
             'servopneumatic actuator, equation group by equation group (S0–S6) from '
             'a campaign of experiment files, validated on pressures and mass flows')},
    parts={
        "parameters": f"{__name__}._params:PARAMETER_SETS",
        "rhs": f"{__name__}._kernel:rhs",
        "simulate": f"{__name__}._sim:simulate_pneumatic",
        "loop": f"{__name__}._sim:PositionController",
        "bench": f"{__name__}._bench_files:write_pneumatic_campaign",
        "cli": f"{__name__}._cli:add_cli",
        "methods": f"{__name__}._workflow:METHODS",
    },
)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
