"""θ ↦ the one-step fit's discrete closed loop, as a model and as lfilter coefficients.

:func:`model_function` turns a plant structure, the known loop and the
discretisation into two functions of θ: one returning the
:class:`~servoid.models.TransferFunction` that
:func:`~servoid.estimate.fit_tf_greybox` fits, one returning the same
model's ``(b, a)`` for the start ranking, which simulates it at every step
and cannot afford to build a TransferFunction each time (that costs more
than simulating a record).  For an exact sampled model both come from one
compiled computation (:func:`._sampling.sampled_coefficients`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..._errors import OptionError
from ...models import TransferFunction
from ._loop import FeedbackLoop, poly_add, tustin, tustin_arrays
from ._sampling import Hold, sampled_coefficients, sampled_loop
from ._structures import PlantStructure

__all__ = ["Coefficients", "model_function"]

#: θ ↦ ``(b, a)``: lfilter's form of the model, b as long as a, a monic.
Coefficients = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]


def model_function(
    plant_structure: PlantStructure, loop: FeedbackLoop, dt: float, discretization: str,
    hold: Hold | None, anti_alias: TransferFunction | None, decimation: int,
) -> tuple[Callable[[NDArray[np.float64]], TransferFunction], Coefficients, int]:
    """θ ↦ the discrete closed loop at dt, θ ↦ its ``(b, a)`` for lfilter, and its advance.

    The second is what the start ranking simulates at every step: the same
    model as the first without building a TransferFunction (which costs more
    than the simulation of a record).
    """
    plant_of = plant_structure.plant
    reduced_of = plant_structure.reduced
    if hold is not None:
        if isinstance(loop.F, TransferFunction) and loop.F.dt is not None:
            raise OptionError(
                f"discretization={discretization!r} samples the continuous closed loop, but F is "
                f"discrete (dt = {loop.F.dt} s); give F as a continuous TransferFunction or a "
                "gain, or use discretization='tustin'"
            )

        f = loop.feedback_at(None)
        f_num, f_den, c = np.asarray(f.num, float), np.asarray(f.den, float), loop.c
        plant_arrays = _plant_arrays(plant_structure)

        def coefficients(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                               NDArray[np.float64]]:
            # c·G/(1 + F·G) as polynomials: no intermediate TransferFunction to build
            p_num, p_den = plant_arrays(theta)
            num = c * np.convolve(p_num, f_den)
            den = poly_add(np.convolve(p_den, f_den), np.convolve(f_num, p_num))
            b, a, _ = sampled_coefficients(num, den, dt, hold, anti_alias=anti_alias,
                                           decimation=decimation)
            return b, a

        def exact(theta: NDArray[np.float64]) -> TransferFunction:
            return TransferFunction(*coefficients(theta), dt)

        _, advance = sampled_loop(loop.close(plant_of(_probe(plant_structure))), dt, hold,
                                  anti_alias=anti_alias, decimation=decimation)
        return exact, coefficients, advance
    if discretization == "prewarp":

        def prewarped(theta: NDArray[np.float64]) -> TransferFunction:
            # Tustin with s = k(z − 1)/(z + 1), k = ω/tan(ωT/2): the map of step 2/k.
            w = reduced_of(theta)[1]
            h = 2.0 * math.tan(0.5 * w * dt) / w
            plant = plant_of(theta)
            mapped = tustin_arrays(plant.num, plant.den, h)
            return loop.close(TransferFunction(mapped.num, mapped.den, dt, "tustin", w))

        return prewarped, _arrays_of(prewarped), 0
    if loop.is_static and plant_structure.name == "reduced":
        f, c = float(loop.F), loop.c  # type: ignore[arg-type]

        def fast(theta: NDArray[np.float64]) -> TransferFunction:
            # static F: close in s, then one Tustin map (it commutes with the loop algebra)
            k, w, d = theta
            kw2 = k * w * w
            return tustin_arrays([c * kw2], [1.0, 2.0 * d * w, w * w, f * kw2], dt)

        return fast, _arrays_of(fast), 0

    def mapped(theta: NDArray[np.float64]) -> TransferFunction:
        return loop.close(tustin(plant_of(theta), dt))

    return mapped, _arrays_of(mapped), 0


def _plant_arrays(plant_structure: PlantStructure) -> Coefficients:
    """θ ↦ the continuous plant's (num, den); the reduced plant without a TransferFunction."""
    if plant_structure.name == "reduced":

        def reduced(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                         NDArray[np.float64]]:
            # plant_of_theta's K·ω²/(s³ + 2δω·s² + ω²·s), already monic
            k, w, d = (float(x) for x in theta)
            return np.array([k * w * w]), np.array([1.0, 2.0 * d * w, w * w, 0.0])

        return reduced
    plant_of = plant_structure.plant

    def general(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        plant = plant_of(theta)
        return np.asarray(plant.num, float), np.asarray(plant.den, float)

    return general


def _arrays_of(model_fn: Callable[[NDArray[np.float64]], TransferFunction]) -> Coefficients:
    """θ ↦ ``(b, a)`` of `model_fn`'s model, b padded to a's length (lfilter's form)."""

    def coefficients(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                           NDArray[np.float64]]:
        return _lfilter_form(model_fn(theta))

    return coefficients


def _lfilter_form(model: TransferFunction) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    numq = np.concatenate([np.zeros(model.den.size - model.num.size), model.num])
    return np.ascontiguousarray(numq, dtype=float), np.ascontiguousarray(model.den, dtype=float)


def _probe(plant_structure: PlantStructure) -> NDArray[np.float64]:
    # any valid θ fixes the advance, which depends only on the hold and the rig chain
    return plant_structure.start((1.0, 1.0, 0.5))
