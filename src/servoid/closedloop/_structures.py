"""Plant structures the one-step closed-loop fit can take.

A structure is a continuous plant G0(s, θ) with named, unit-carrying
parameters, the transforms the optimiser works in, and a start built from
the reduced EHSA parameters (K, ω_hp, δ_hp).  The reduced model of the
source study is one structure; richer ones (an added valve lag, the
full-order plant) are alternatives a structure test compares with it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..models import TransferFunction
from ._loop import PARAMETER_NAMES, PARAMETER_UNITS, reduced_plant

__all__ = ["STRUCTURES", "PlantStructure"]

Transform = Literal["none", "log"]


@dataclass(frozen=True, eq=False)
class PlantStructure:
    """A parameterised continuous plant for the one-step closed-loop fit.

    Attributes
    ----------
    name : str
        Its label (``"reduced"``, …).
    names, units : tuple of str
        Parameter names and units, in the order of θ.
    transforms : tuple of {"none", "log"}
        Coordinates the optimiser uses (``"log"`` keeps a parameter
        positive and makes its steps relative).
    plant : callable
        ``plant(theta) -> TransferFunction``, continuous.
    start : callable
        ``start(reduced) -> theta0`` from reduced parameters (K, ω_hp, δ_hp).
    reduced : callable
        ``reduced(theta) -> (K, ω_hp, δ_hp)``: the reduced parameters this
        θ corresponds to, for reporting one set of physical numbers.
    """

    name: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    transforms: tuple[Transform, ...]
    plant: Callable[[NDArray[np.float64]], TransferFunction]
    start: Callable[[Sequence[float]], NDArray[np.float64]]
    reduced: Callable[[NDArray[np.float64]], tuple[float, float, float]]

    @property
    def n_parameters(self) -> int:
        """Number of parameters."""
        return len(self.names)


def _reduced_start(reduced: Sequence[float]) -> NDArray[np.float64]:
    return np.asarray(reduced, dtype=float)


def _reduced_of(theta: NDArray[np.float64]) -> tuple[float, float, float]:
    k, w, d = (float(x) for x in theta[:3])
    return k, w, d


REDUCED = PlantStructure(
    name="reduced",
    names=PARAMETER_NAMES,
    units=PARAMETER_UNITS,
    transforms=("log", "log", "none"),
    plant=reduced_plant,
    start=_reduced_start,
    reduced=_reduced_of,
)

#: Registered structures by name; richer ones are added beside the reduced model.
STRUCTURES: Mapping[str, PlantStructure] = MappingProxyType({"reduced": REDUCED})
