"""One entry point for every closed-loop approach, and closed-loop simulation."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float, as_instance, type_error
from ..._errors import DataError, ModelError, OptionError, OptionTypeError, check_option
from ...data import Experiment, ExperimentSet
from ...models import TransferFunction, c2d
from ._loop import FeedbackLoop, reduced_plant
from ._onestep import fit_one_step
from ._result import ClosedLoopResult
from ._twostep import fit_direct, fit_indirect

__all__ = ["APPROACHES", "identify_closed_loop", "simulate_closed_loop"]

Approach = Literal["indirect", "one-step", "direct"]
#: The approaches :func:`identify_closed_loop` knows, in the order a user meets them.
APPROACHES: tuple[Approach, ...] = ("indirect", "one-step", "direct")


def identify_closed_loop(
    data: Experiment | ExperimentSet,
    loop: FeedbackLoop | None,
    approach: Approach = "indirect",
    **options: Any,
) -> ClosedLoopResult:
    """Identify K, ω_hp, δ_hp of a plant running in a known loop.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with r and y (indirect, one-step) or u/r and y (direct).
    loop : FeedbackLoop or None
        Known forward gain c and feedback F (None only for "direct" with
        a measured u).
    approach : {"indirect", "one-step", "direct"}
        Two-step indirect (:func:`fit_indirect`), one-step output error
        on the parameterised closed loop (:func:`fit_one_step`), or direct
        on (u, y) (:func:`fit_direct`).
    **options
        Keyword options of the chosen function (orders, theta0, ...).

    Returns
    -------
    ClosedLoopResult
        Physical estimate, models and the pole report.

    Raises
    ------
    OptionError
        An unknown approach or an option the approach does not take.
    """
    check_option("approach", approach, APPROACHES)
    if loop is None and approach != "direct":
        raise ModelError(
            f"the {approach} approach needs the known loop: pass loop=FeedbackLoop(c, F)"
        )
    funcs = {"indirect": fit_indirect, "one-step": fit_one_step, "direct": fit_direct}
    try:
        return funcs[approach](data, loop, **options)  # type: ignore[operator]
    except TypeError as exc:
        if "unexpected keyword argument" in str(exc):
            raise OptionError(f"approach {approach!r}: {exc}") from None
        raise


def simulate_closed_loop(
    model: ClosedLoopResult | Sequence[float] | NDArray[np.float64],
    r: ArrayLike,
    dt: float | None = None,
    loop: FeedbackLoop | None = None,
) -> NDArray[np.float64]:
    """Simulate the closed loop driven by the reference r, from rest.

    Parameters
    ----------
    model : ClosedLoopResult or sequence of float
        A result (its discrete closed loop as fitted, the reference held
        beyond the record for a model that looks ahead, or its plant
        closed by `loop` when one is given) or θ = (K [1/s], ω_hp [rad/s], δ_hp [-]) of the
        reduced plant, closed by `loop` after Tustin discretisation.
    r : array_like, shape (N,)
        Reference samples.
    dt : float, optional
        Sample period [s]; required with θ, checked against a result.
    loop : FeedbackLoop, optional
        The loop; required with θ.

    Returns
    -------
    ndarray, shape (N,)
        The output y.

    Examples
    --------
    >>> y = simulate_closed_loop((3451.7, 163.3, 0.249), np.ones(3000), 1e-3,
    ...                          FeedbackLoop(0.01, 0.01))
    >>> round(float(y[-1]), 3)
    1.0
    """
    if loop is not None:
        loop = as_instance("loop", loop, FeedbackLoop, "a FeedbackLoop(c, F) or None")
    if dt is not None:
        dt = as_float("dt", dt, positive=True, unit="s")
    r = as_array("r", r).ravel()
    if isinstance(model, ClosedLoopResult):
        if dt is not None and not math.isclose(dt, model.dt, rel_tol=1e-9):
            raise DataError(f"dt = {dt} s differs from the result's dt = {model.dt} s")
        if loop is not None:
            return loop.close(model.plant).simulate(r)
        if model.closed_loop is None:
            raise ModelError("this result has no loop: pass loop=FeedbackLoop(c, F)")
        rr = r
        lead = model.advance
        if not lead:
            return model.closed_loop.simulate(rr)
        # y(k) = H(q)·r(k + L): beyond the record the reference is taken as held
        extended = np.concatenate([rr, np.full(lead, rr[-1] if rr.size else 0.0)])
        return model.closed_loop.simulate(extended)[lead:]
    if loop is None or dt is None:
        raise ModelError("simulating from θ = (K, omega_hp, delta_hp) needs dt and loop")
    try:
        theta = as_array("model", model).ravel()
    except OptionTypeError:
        raise type_error("model", model, "a ClosedLoopResult or θ = (K, omega_hp, delta_hp)"
                         ) from None
    if theta.size != 3:
        raise DataError(f"θ must be (K, omega_hp, delta_hp), got {theta.tolist()}")
    h: TransferFunction = loop.close(c2d(reduced_plant(theta), dt, "tustin"))
    return h.simulate(r)
