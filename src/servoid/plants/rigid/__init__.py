"""A rigid axis with friction in a cascaded position loop (the EMPS axis).

* physics: :class:`RigidAxis` (mass, asymmetric viscous and Coulomb
  friction, offset; :data:`PARAMETER_SETS` holds the published EMPS
  values) and the cascade :class:`CascadeController`, simulated together
  by :func:`simulate_rigid_loop` (exact between events, or RK4 stepped by
  :func:`servoid.integrate.rk4_step`);
* physical identification: the inverse model by least squares
  (:func:`fit_inverse_dynamics`, :func:`inverse_dynamics_regression`) and
  the closed-loop output-error refinement (:func:`fit_closed_loop_oe`);
* the workflow ``[identify] method = "inverse-dynamics"``
  (:class:`InverseDynamicsIdentification`).

The names load on first use (PEP 562).  See ``docs/emps.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._exports import lazy_exports
from .._plant import Plant

if TYPE_CHECKING:
    from ._axis import CascadeController, RigidAxis, RigidLoopResponse, simulate_rigid_loop
    from ._inverse import (
        FRICTION_MODELS,
        InverseDynamicsRegression,
        fit_closed_loop_oe,
        fit_inverse_dynamics,
        inverse_dynamics_regression,
    )
    from ._workflow import InverseDynamicsIdentification, controller_from_table

#: Exported name → the private module that defines it.
_WHERE = {
    "FRICTION_MODELS": "_inverse",
    "CascadeController": "_axis",
    "InverseDynamicsIdentification": "_workflow",
    "InverseDynamicsRegression": "_inverse",
    "RigidAxis": "_axis",
    "RigidLoopResponse": "_axis",
    "controller_from_table": "_workflow",
    "fit_closed_loop_oe": "_inverse",
    "fit_inverse_dynamics": "_inverse",
    "inverse_dynamics_regression": "_inverse",
    "simulate_rigid_loop": "_axis",
}

__all__ = [
    "FRICTION_MODELS",
    "PLANT",
    "CascadeController",
    "InverseDynamicsIdentification",
    "InverseDynamicsRegression",
    "RigidAxis",
    "RigidLoopResponse",
    "controller_from_table",
    "fit_closed_loop_oe",
    "fit_inverse_dynamics",
    "inverse_dynamics_regression",
    "simulate_rigid_loop",
]

#: The rigid plant as servoid's plants know it.
PLANT = Plant(
    name="rigid",
    title="rigid axis with friction in a cascaded position loop (EMPS)",
    methods={"inverse-dynamics": (
             'rigid axis with friction in its known cascade loop ([loop] kp, kv, '
             'gtau): IDIM-LS of M, Fv, Fc, closed-loop OE refinement, hold-out check '
             'or cross-test ([validation] file)')},
    parts={
        "parameters": f"{__name__}._axis:PARAMETER_SETS",
        "rhs": f"{__name__}._axis:_rates",
        "simulate": f"{__name__}._axis:simulate_rigid_loop",
        "loop": f"{__name__}._axis:CascadeController",
        "methods": f"{__name__}._workflow:METHODS",
    },
)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
