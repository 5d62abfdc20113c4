"""Checks and helpers shared by the actuator models and simulators.

Private: the parameter sets (:mod:`._ehsa_params`, :mod:`._pneumatic_params`)
validate their fields and copy themselves through :func:`check_fields` and
:func:`replace_fields`; the simulators (:mod:`._ehsa_sim`,
:mod:`._pneumatic_sim`) check their inputs, pick the integration step and
freeze their responses with the rest.  Messages name the parameter, the
value and the expectation, so the callers' errors read the same.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from numbers import Real
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_int, type_error
from .._errors import DataError, ModelError, OptionTypeError

__all__ = [
    "Bounds",
    "check_bool",
    "check_fields",
    "check_finite",
    "check_instance",
    "check_period",
    "check_signal",
    "check_state",
    "freeze_arrays",
    "integer_field",
    "integration_step",
    "largest_step",
    "positive_field",
    "real_field",
    "replace_fields",
]

_T = TypeVar("_T")

#: name → (lower bound, strict?) of a parameter set; None = any finite value.
Bounds = Mapping[str, tuple[float, bool] | None]


def check_fields(obj: Any, bounds: Bounds) -> None:
    """Validate and convert to float every field of a frozen parameter dataclass.

    Raises TypeError for a non-real value, ModelError for a non-finite one
    or one below its bound; messages start ``ClassName.field``.
    """
    cls = type(obj).__name__
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise OptionTypeError(f"{cls}.{f.name} must be a real number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ModelError(f"{cls}.{f.name} must be finite, got {value}")
        bound = bounds[f.name]
        if bound is not None:
            low, strict = bound
            if (value <= low) if strict else (value < low):
                rel = ">" if strict else ">="
                raise ModelError(f"{cls}.{f.name} must be {rel} {low:g}, got {value:g}")
        object.__setattr__(obj, f.name, value)


def replace_fields(obj: _T, changes: Mapping[str, Any]) -> _T:
    """Return a validated copy of a parameter dataclass with `changes`."""
    names = {f.name for f in dataclasses.fields(obj)}  # type: ignore[arg-type]
    unknown = sorted(set(changes) - names)
    if unknown:
        raise OptionTypeError(f"{type(obj).__name__} has no parameter(s) {', '.join(unknown)}")
    return dataclasses.replace(obj, **changes)  # type: ignore[type-var]


def check_instance(name: str, value: object, cls: type[_T]) -> _T:
    """Return `value` if it is a `cls`, else raise TypeError."""
    if not isinstance(value, cls):
        raise OptionTypeError(f"{name} must be {cls.__name__}, got {type(value).__name__}")
    return value


def check_finite(name: str, value: object, error: type[Exception] = DataError) -> float:
    """Return a finite real scalar as float (TypeError, else `error`)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"{name} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise error(f"{name} must be finite, got {v}")
    return v


def check_period(name: str, value: object) -> float:
    """Return a finite time > 0 [s] as float."""
    v = check_finite(name, value)
    if v <= 0.0:
        raise DataError(f"{name} must be > 0 s, got {v:g}")
    return v


def check_bool(name: str, value: object) -> bool:
    """Return a Python or numpy bool as bool, else raise TypeError."""
    if not isinstance(value, (bool, np.bool_)):
        raise OptionTypeError(f"{name} must be a bool, got {value!r}")
    return bool(value)


def check_signal(name: str, x: ArrayLike, unit: str, n: int | None = None) -> NDArray[np.float64]:
    """Return a finite, non-empty 1-D float copy of samples `x` [unit]."""
    try:
        arr = np.array(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(f"{name} must be an array of real numbers: {exc}") from None
    if arr.ndim != 1 or arr.size == 0:
        raise DataError(f"{name} must be a non-empty 1-D array [{unit}], got shape {arr.shape}")
    if n is not None and arr.size != n:
        raise DataError(f"{name} must have {n} samples like the other inputs, got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise DataError(
            f"{name} must be finite, got {arr[bad[0]]} at sample {bad[0]} "
            f"({bad.size} non-finite sample(s))"
        )
    return arr


def check_state(x0: ArrayLike, names: tuple[str, ...]) -> NDArray[np.float64]:
    """Return a finite float copy of an initial state ordered as `names`."""
    state = np.array(as_array("x0", x0, finite=False), dtype=np.float64)
    if state.shape != (len(names),):
        raise DataError(f"x0 must have shape ({len(names)},) ({', '.join(names)}), "
                        f"got {state.shape}")
    if not np.all(np.isfinite(state)):
        raise DataError(f"x0 must be finite, got {state}")
    return state


def largest_step(dt: float, limit: float) -> float:
    """Return the largest ``dt/n`` (n integer) not above `limit` [s].

    The factor ``1 − 1e-12`` keeps a `dt` that is a multiple of `limit`
    from rounding up to one step more.
    """
    return dt / math.ceil(dt / limit * (1.0 - 1e-12))


def integration_step(dt: float, dt_int: object) -> float:
    """Check a requested integration step; return it as ``dt/decimation``.

    `dt` is already checked; `dt_int` must divide it into a whole number
    of steps (to 1e-9 relative).
    """
    h = check_period("dt_int", dt_int)
    if h > dt * (1.0 + 1e-12):
        raise DataError(f"dt_int must be <= the sample period dt = {dt:g} s, got {h:g} s")
    decimation = max(1, round(dt / h))
    if abs(decimation * h - dt) > 1e-9 * dt:
        raise DataError(
            f"dt/dt_int must be a whole number of steps, got dt = {dt:g} s, dt_int = {h:g} s "
            f"(ratio {dt / h:.6g}); try dt_int = {dt / decimation:.6g} s"
        )
    return dt / decimation


#: Most fixed integration steps a simulation may take: about 3 min of RK4 at 1e7 steps/s,
#: 30 times a 100 s EHSA record at its default 2 µs step.
MAX_STEPS = 2 * 10**9


def check_steps(n_samples: int, dt: float, h: float, what: str) -> int:
    """Return ``dt/h`` steps per sample, or refuse a simulation beyond :data:`MAX_STEPS`.

    An integration step orders of magnitude below the sample period comes from
    a parameter far outside its physical range (a stiffness of 1e300 gives
    steps of 1e-150 s): refuse it instead of starting a run that cannot end.
    """
    per_sample = dt / h
    if per_sample * n_samples > MAX_STEPS:
        raise ModelError(
            f"{what} would take {per_sample * n_samples:.3g} integration steps of {h:.3g} s "
            f"({per_sample:.3g} per sample of {dt:g} s), over the budget of {MAX_STEPS:.0e}; the "
            "fastest mode of the parameters is far beyond a real actuator's: check them "
            "(a stiffness, mass or volume off by orders of magnitude?), or pass a shorter input"
        )
    return max(1, round(per_sample))


def freeze_arrays(obj: object, names: Iterable[str], *, flags: tuple[str, ...] = (),
                  optional: tuple[str, ...] = ()) -> None:
    """Replace fields of a frozen dataclass by read-only array copies.

    `flags` are stored as bool arrays, the rest as float64; a field in
    `optional` may be None and is then left as it is.
    """
    for name in names:
        value = getattr(obj, name)
        if value is None and name in optional:
            continue
        if name in flags:
            arr = np.array(value, dtype=bool)
        else:
            arr = np.array(as_array(name, value, finite=False), dtype=np.float64)
        arr.setflags(write=False)
        object.__setattr__(obj, name, arr)


def real_field(name: str, value: object, unit: str) -> float:
    """``value`` as a float: a real number (not a bool) in ``unit``."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise type_error(name, value, f"a real number [{unit}]")
    return float(value)


def positive_field(name: str, value: object, unit: str) -> float:
    """``value`` as a finite float > 0 in ``unit``."""
    v = real_field(name, value, unit)
    if not (math.isfinite(v) and v > 0):
        raise DataError(f"{name} must be finite and > 0 [{unit}], got {v}")
    return v


def integer_field(name: str, value: object, low: int, high: int) -> int:
    """``value`` as an int within [low, high]."""
    return as_int(name, value, minimum=low, maximum=high)
