"""Validation helpers shared by the LTI model classes.

These run at the model boundary (constructors, conversion entry points);
inner numerical helpers trust their inputs.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ModelError, OptionError, OptionTypeError, check_option

__all__ = [
    "METHODS",
    "Method",
    "as_coefficients",
    "as_input_matrix",
    "at_sample_time",
    "check_delay",
    "check_dt",
    "check_method",
    "common_dt",
    "readonly",
]

Method = Literal["zoh", "tustin", "foh"]
METHODS: tuple[Method, ...] = ("zoh", "tustin", "foh")


def readonly(values: ArrayLike, dtype: type = np.float64, name: str = "values") -> NDArray:
    """Return a read-only copy of ``values`` (text or None: an OptionTypeError naming ``name``)."""
    if dtype is np.float64:
        values = as_array(name, values, finite=False)
    out = np.array(values, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


def check_dt(dt: object, *, owner: str, allow_none: bool = True) -> float | None:
    """Validate a sample period [s]; None means continuous time."""
    if dt is None:
        if not allow_none:
            raise ModelError(f"{owner} is discrete-time only: dt must be > 0 s, got None")
        return None
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"{owner}: dt must be a float [s] or None for continuous time, "
                              f"got {dt!r}")
    value = _real(dt)
    if not math.isfinite(value) or value <= 0.0:
        raise ModelError(f"{owner}: dt must be > 0 s (None for continuous time), got {dt!r}")
    return value


def check_delay(delay: object, dt: float | None, *, owner: str) -> float:
    """Validate an input/output delay [s]: finite, >= 0, continuous models only.

    A discrete model carries a delay of k samples as k poles at z = 0
    (``c2d`` puts them there), so it takes no separate delay.
    """
    if isinstance(delay, bool) or not isinstance(delay, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"{owner}: delay must be a float [s], got {delay!r}")
    value = _real(delay)
    if not math.isfinite(value) or value < 0.0:
        raise ModelError(f"{owner}: delay must be finite and >= 0 s, got {delay!r}")
    if value and dt is not None:
        raise ModelError(
            f"{owner}: a discrete model (dt = {dt} s) takes no delay [s]; its delay is k poles "
            f"at z = 0 (build the continuous model with delay={value!r} and use c2d), got "
            f"delay={delay!r}"
        )
    return value


def check_method(
    method: object, prewarp: object, dt: float | None, *, owner: str
) -> tuple[Method | None, float | None]:
    """Validate the remembered discretisation method and prewarp [rad/s]."""
    if method is None:
        if prewarp is not None:
            raise OptionError(f"{owner}: prewarp applies only to method='tustin', got method=None")
        return None, None
    check_option("method", method, METHODS)
    if dt is None:
        raise ModelError(
            f"{owner}: a continuous-time model (dt=None) has no discretisation method, "
            f"got method={method!r}"
        )
    if prewarp is None:
        return method, None  # type: ignore[return-value]
    if method != "tustin":
        raise OptionError(f"{owner}: prewarp applies only to method='tustin', got {method!r}")
    if isinstance(prewarp, bool) or not isinstance(prewarp, (int, float, np.integer, np.floating)):
        raise OptionTypeError(f"{owner}: prewarp must be a float [rad/s] or None, got {prewarp!r}")
    wp = _real(prewarp)
    if not (math.isfinite(wp) and 0.0 < wp < math.pi / dt):
        raise ModelError(
            f"{owner}: prewarp must lie in (0, pi/dt) = (0, {math.pi / dt:.6g}) rad/s, "
            f"got {prewarp!r}"
        )
    return "tustin", wp


def as_coefficients(name: str, values: ArrayLike, *, owner: str) -> NDArray[np.float64]:
    """Return ``values`` as a finite, non-empty 1-D float array."""
    try:
        arr = np.array(values, dtype=np.float64)
    except OverflowError:  # an integer past the largest float (10**400)
        raise ModelError(f"{owner}: {name} must hold numbers within ±1.8e308, got an integer "
                         "too large for a float") from None
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(
            f"{owner}: {name} must be a 1-D array of real numbers, got {values!r}"
        ) from exc
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise ModelError(f"{owner}: {name} must be a non-empty 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{owner}: {name} must be finite, got {arr}")
    return arr


def as_input_matrix(u: ArrayLike, n_inputs: int, *, owner: str) -> NDArray[np.float64]:
    """Return an input signal as an (N, n_inputs) float array, never transposing."""
    arr = as_array("u", u, finite=False, where=f"{owner}:")
    if arr.ndim == 1 and n_inputs == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != n_inputs:
        want = "(N,) or (N, 1)" if n_inputs == 1 else f"(N, {n_inputs})"
        raise DataError(f"{owner}: u must have shape {want}, got {arr.shape}")
    if not _all_finite(arr):
        raise DataError(f"{owner}: u must be finite")
    return arr


def _all_finite(arr: NDArray[np.float64]) -> bool:
    """Whether every value is finite; one compiled pass for a long contiguous array."""
    if arr.size < 1 << 16 or not arr.flags.c_contiguous:
        return bool(np.all(np.isfinite(arr)))
    from ._kernels import all_finite  # (compiled: loaded on first use)

    return bool(all_finite(arr.reshape(-1)))


def common_dt(dt1: float | None, dt2: float | None, *, what: str) -> float | None:
    """Return the shared time base of two models or raise ModelError."""
    if dt1 is None and dt2 is None:
        return None
    if dt1 is None or dt2 is None:
        raise ModelError(f"cannot {what} a continuous-time and a discrete-time model")
    if not math.isclose(dt1, dt2, rel_tol=1e-12, abs_tol=0.0):
        raise ModelError(f"cannot {what} models with different dt ({dt1} s and {dt2} s)")
    return dt1


def at_sample_time(model, dt: float | None, owner: str):  # type: ignore[no-untyped-def]
    """The discrete model to simulate at ``dt``: ZOH of a continuous one, else itself."""
    if model.dt is None:
        if dt is None:
            raise ModelError(
                f"{owner}.simulate of a continuous model needs dt [s] (ZOH discretisation)"
            )
        from ._discretize import c2d

        return c2d(model, dt, "zoh")
    if dt is not None and not math.isclose(dt, model.dt, rel_tol=1e-9):
        raise ModelError(f"dt = {dt} s differs from the model's dt = {model.dt} s")
    return model


def _real(value: object) -> float:
    """``float(value)``, with an integer past the largest float (10**400) as ±inf."""
    try:
        return float(value)  # type: ignore[arg-type]
    except OverflowError:
        return math.inf if value > 0 else -math.inf  # type: ignore[operator]
