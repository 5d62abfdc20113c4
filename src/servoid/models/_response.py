"""Typed time-response results and the sample grids they are built on."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ModelError
from ._common import readonly

__all__ = ["TimeResponse", "response_grid"]


@dataclass(frozen=True, eq=False)
class TimeResponse:
    """Sampled response of a model to a test signal.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s], starting at 0.
    y : ndarray, shape (N,)
        Output samples (model output units).
    kind : str
        ``"step"`` or ``"impulse"``.
    """

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    kind: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", readonly(self.t, name="t"))
        object.__setattr__(self, "y", readonly(self.y, name="y"))


def response_grid(t: int | ArrayLike, dt: float | None) -> tuple[NDArray[np.float64], float]:
    """Return the time grid [s] and its spacing [s] for a response.

    ``t`` is a number of samples (discrete models only) or a uniform grid of
    times starting at 0.  For a discrete model the grid must be ``k·dt``.
    """
    if isinstance(t, (int, np.integer)) and not isinstance(t, bool):
        if dt is None:
            raise ModelError(
                "a continuous-time model needs a time grid t [s] (uniform, from 0), "
                f"not a number of samples ({t})"
            )
        if t < 1:
            raise DataError(f"the number of samples must be >= 1, got {t}")
        return np.arange(int(t)) * dt, dt
    grid = as_array("t", t, finite=False)
    if grid.ndim != 1 or grid.size < 2:
        raise DataError(f"t must be a 1-D grid of at least 2 times [s], got shape {grid.shape}")
    step = float(grid[1] - grid[0])
    if grid[0] != 0.0 or step <= 0.0:
        raise DataError(f"t must start at 0 and increase, got t[0]={grid[0]}, t[1]={grid[1]}")
    # uniform to a few ulps of the end time: the grid is usually built by arange/linspace
    if np.max(np.abs(np.diff(grid) - step)) > 1e-9 * max(step, 1e-300) * grid.size:
        raise DataError("t must be uniformly spaced")
    if dt is not None and not np.isclose(step, dt, rtol=1e-9, atol=0.0):
        raise DataError(f"t must have spacing dt = {dt} s for this discrete model, got {step}")
    return grid, step
