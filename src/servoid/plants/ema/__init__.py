"""The electromechanical servo actuator (EMA): physics to identification.

A DC/BLDC motor, a gearbox and a ball screw with axial stiffness (and
optional backlash) drive a load; viscous and Coulomb friction act on both
sides; a sampled drive closes current, speed and position loops.  This
subpackage holds all of it:

* physics: :class:`EmaParameters` and the nominal set :data:`TVC_EMA`
  (every value with its reason), the loop :class:`EmaController` and
  :data:`TVC_CONTROLLER`;
* :func:`simulate_ema`: the actuator in its cascade, stepped by
  :func:`servoid.integrate.rk4_step` between the controller's samples;
* the virtual bench: :class:`EmaBench`, :func:`bench_reference`,
  :func:`run_bench` and :func:`write_bench` / :func:`write_run` (rig file
  in volts and counts, experiment file, ``truth.json``),
  :func:`write_fleet` (units with parameter scatter);
* physical identification from closed-loop records: :func:`fit_ema`
  (motor constant, resistance, inductance, inertias, frictions, screw
  stiffness, with intervals and identifiability verdicts) and the
  ``[identify] method = "ema"`` workflow (:data:`METHOD`, :class:`EmaResult`,
  ``[loop]`` read by :func:`controller_from_loop`).

The names load on first use (PEP 562): ``import servoid.plants`` reads
only :data:`PLANT`.  See ``docs/ema.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._exports import lazy_exports
from .._plant import Plant

if TYPE_CHECKING:
    from ._bench import EmaBench, EmaRun, bench_reference, run_bench, truth_parameters
    from ._bench_files import write_bench, write_run
    from ._control import TVC_CONTROLLER, EmaController
    from ._fleet import EmaFleet, write_fleet
    from ._identify import EmaIdentification, fit_ema
    from ._params import PARAMETER_SETS, TVC_EMA, EmaParameters
    from ._sim import EmaResponse, simulate_ema
    from ._workflow import METHOD, controller_from_loop
    from ._workflow_run import EmaResult

#: Exported name → the private module that defines it.
_WHERE = {
    "METHOD": "_workflow",
    "PARAMETER_SETS": "_params",
    "TVC_CONTROLLER": "_control",
    "TVC_EMA": "_params",
    "EmaBench": "_bench",
    "EmaController": "_control",
    "EmaFleet": "_fleet",
    "EmaIdentification": "_identify",
    "EmaParameters": "_params",
    "EmaResponse": "_sim",
    "EmaResult": "_workflow_run",
    "EmaRun": "_bench",
    "bench_reference": "_bench",
    "controller_from_loop": "_workflow",
    "fit_ema": "_identify",
    "run_bench": "_bench",
    "simulate_ema": "_sim",
    "truth_parameters": "_bench",
    "write_bench": "_bench_files",
    "write_fleet": "_fleet",
    "write_run": "_bench_files",
}

__all__ = [
    "METHOD",
    "PARAMETER_SETS",
    "PLANT",
    "TVC_CONTROLLER",
    "TVC_EMA",
    "EmaBench",
    "EmaController",
    "EmaFleet",
    "EmaIdentification",
    "EmaParameters",
    "EmaResponse",
    "EmaResult",
    "EmaRun",
    "bench_reference",
    "controller_from_loop",
    "fit_ema",
    "run_bench",
    "simulate_ema",
    "truth_parameters",
    "write_bench",
    "write_fleet",
    "write_run",
]

_HERE = __name__

#: The EMA as servoid's plants know it.
PLANT = Plant(
    name="ema",
    title="electromechanical servo actuator (motor, gearbox, ball screw, cascaded drive)",
    methods={"ema": "electromechanical actuator in its known drive ([loop] gains): motor "
                    "constant, resistance, inductance, inertias, viscous and Coulomb friction "
                    "and screw stiffness from a closed-loop record, with intervals; free-run "
                    "validation"},
    parts={
        "parameters": f"{_HERE}._params:PARAMETER_SETS",
        "rhs": f"{_HERE}._kernel:rates",
        "simulate": f"{_HERE}._sim:simulate_ema",
        "loop": f"{_HERE}._control:EmaController",
        "bench": f"{_HERE}._bench_files:write_bench",
        "fleet": f"{_HERE}._fleet:write_fleet",
        "cli": f"{_HERE}._cli:add_cli",
        "methods": f"{_HERE}._workflow:METHODS",
    },
)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
