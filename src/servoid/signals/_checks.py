"""Argument checks shared by the excitation designers.

These run at the public boundary only; inner helpers trust their inputs.
Wrong types raise :class:`~servoid.OptionTypeError` (a ``TypeError``), wrong
values :class:`DataError`, and every message names the parameter, the value
received and the expectation.
"""

from __future__ import annotations

import math
from numbers import Integral, Real

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import DataError, OptionTypeError

__all__ = [
    "MAX_SAMPLES",
    "RngLike",
    "as_dt",
    "as_float",
    "as_int",
    "as_rng",
    "as_signal",
    "check_samples",
    "nyquist",
    "rng_label",
]

RngLike = np.random.Generator | int | np.integer

#: Longest signal a designer builds unless asked for more: 2e8 samples, 1.6 GB of float64.
MAX_SAMPLES = 200_000_000


def check_samples(n: int, what: str, max_samples: object) -> None:
    """Refuse a signal of ``n`` samples beyond the ``max_samples`` budget."""
    budget = as_int("max_samples", max_samples)
    if n > budget:
        raise DataError(
            f"{what} would have {n:,} samples ({8 * n / 1e9:.3g} GB as float64), over the "
            f"budget of {budget:,}; shorten it, or raise max_samples (--max-samples) if the "
            "machine has the memory"
        )


def as_int(name: str, value: object, minimum: int = 1, what: str = "") -> int:
    """Return ``value`` as an int >= ``minimum`` or raise."""
    kind = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise OptionTypeError(
            f"{name} must be {kind}{what}, got {value!r} ({type(value).__name__})"
        )
    if value < minimum:
        raise DataError(f"{name} must be {kind}{what}, got {value}")
    return int(value)


def as_float(
    name: str, value: object, *, positive: bool = False, nonneg: bool = False, unit: str = ""
) -> float:
    """Return ``value`` as a finite float, optionally > 0 or >= 0."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise OptionTypeError(f"{name} must be a real number{unit}, got {type(value).__name__}")
    try:
        out = float(value)
    except OverflowError:  # an integer past the largest float (10**400)
        raise DataError(f"{name} must be finite{unit} (within ±1.8e308), got an integer too "
                        "large for a float") from None
    if not math.isfinite(out):
        raise DataError(f"{name} must be finite{unit}, got {out}")
    if positive and out <= 0:
        raise DataError(f"{name} must be > 0{unit}, got {out:g}")
    if nonneg and out < 0:
        raise DataError(f"{name} must be >= 0{unit}, got {out:g}")
    return out


def as_dt(value: object) -> float:
    """Return the sample period [s] as a float > 0."""
    return as_float("dt", value, positive=True, unit=" s")


def as_rng(value: object, purpose: str) -> np.random.Generator:
    """Return a Generator from a Generator or an integer seed.

    ``None`` is refused on purpose: a test-bench excitation must be
    reproducible, so the caller states the seed.
    """
    if isinstance(value, np.random.Generator):
        return value
    if isinstance(value, Integral) and not isinstance(value, bool):
        if value < 0:
            raise DataError(f"rng seed must be >= 0, got {value}")
        return np.random.default_rng(int(value))
    raise OptionTypeError(
        f"{purpose} needs rng=, a numpy.random.Generator or an integer seed (so the design "
        f"can be reproduced), got {type(value).__name__}"
    )


def as_signal(name: str, value: ArrayLike, min_samples: int = 2) -> NDArray[np.float64]:
    """Return a finite 1-D float array with at least ``min_samples`` samples."""
    if value is None or isinstance(value, (str, bytes)):
        raise OptionTypeError(f"{name} must be an array of real numbers, got {value!r} "
                              f"({type(value).__name__})")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(f"{name} must be an array of real numbers, got {value!r} "
                              f"({type(value).__name__}): {exc}") from None
    if arr.ndim != 1:
        raise DataError(f"{name} must be 1-D, got an array of shape {arr.shape}")
    if arr.size < min_samples:
        raise DataError(f"{name} needs at least {min_samples} samples, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        first = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise DataError(f"{name} must be finite, got {arr[first]} at sample {first}")
    return arr


def nyquist(dt: float) -> float:
    """Nyquist frequency 1/(2·dt) [Hz]."""
    return 0.5 / dt


def rng_label(value: object) -> object:
    """How ``rng`` is recorded in a design: the seed, or ``"Generator"``."""
    if isinstance(value, np.random.Generator):
        return "Generator"
    return int(value)  # type: ignore[call-overload]
