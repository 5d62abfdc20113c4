"""Actuators: one subpackage each, behind one small record (:class:`Plant`).

Each ``servoid.plants.<name>`` holds an actuator's physics, simulator, loop,
virtual bench and physical identification, and exports its ``PLANT``.
:data:`PLANTS` lists them; adding an actuator is its subpackage and one
line here.
"""

from ._plant import PARTS, Plant
from .ema import PLANT as _EMA

__all__ = ["PARTS", "PLANTS", "Plant"]

#: Every actuator servoid knows, by name.
PLANTS: dict[str, Plant] = {plant.name: plant for plant in (_EMA,)}
