"""Actuators: one subpackage each, behind one small record (:class:`Plant`).

Each ``servoid.plants.<name>`` holds an actuator's physics, simulator, loop,
virtual bench and physical identification, and exports its ``PLANT``:

* :mod:`servoid.plants.ehsa`: the electro-hydraulic servo actuator (study 1);
* :mod:`servoid.plants.pneumatic`: the servopneumatic actuator (study 2);
* :mod:`servoid.plants.rigid`: a rigid axis with friction in a cascade (EMPS);
* :mod:`servoid.plants.ema`: the electromechanical actuator.

:data:`PLANTS` lists them; adding an actuator is its subpackage and one
line here.  The friction laws any plant may use are here too
(:func:`coulomb_friction`, :func:`viscous_friction`,
:func:`stribeck_friction`, :func:`karnopp_friction`,
:func:`three_regime_friction`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._exports import lazy_exports
from ._plant import PARTS, Plant
from .ehsa import PLANT as _EHSA
from .ema import PLANT as _EMA
from .pneumatic import PLANT as _PNEUMATIC
from .rigid import PLANT as _RIGID

if TYPE_CHECKING:
    from ._friction import (
        coulomb_friction,
        karnopp_friction,
        stribeck_friction,
        three_regime_friction,
        viscous_friction,
    )

__all__ = [
    "PARTS",
    "PLANTS",
    "Plant",
    "coulomb_friction",
    "karnopp_friction",
    "stribeck_friction",
    "three_regime_friction",
    "viscous_friction",
]

#: Every actuator servoid knows, by name.
PLANTS: dict[str, Plant] = {plant.name: plant for plant in (_EHSA, _PNEUMATIC, _RIGID, _EMA)}

_FRICTION = ("coulomb_friction", "karnopp_friction", "stribeck_friction",
             "three_regime_friction", "viscous_friction")

__getattr__, __dir__ = lazy_exports(__name__, dict.fromkeys(_FRICTION, "_friction"))
