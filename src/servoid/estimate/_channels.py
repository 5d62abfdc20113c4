"""Channel checks the estimators share: the output to fit, an input that excites."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, IdentifiabilityError
from ..data import Experiment

__all__ = ["check_magnitude", "check_not_constant", "output_name"]

#: Largest signal magnitude accepted: squares and sums of squares of larger
#: numbers overflow double precision (1e308) on records of up to ~1e8 samples.
LARGEST_VALUE = 1e150
#: Smallest non-zero peak accepted: squares of smaller numbers underflow to 0,
#: so such a signal looks identically zero to a least-squares solver.
SMALLEST_VALUE = 1e-150


def output_name(exp: Experiment, output: str | None) -> str:
    """The output channel to fit: ``output`` (checked) or the only ``y`` channel."""
    if output is not None:
        exp.channel(output)
        return output
    outputs = exp.names_of("y")
    if not outputs:
        exp.signal("y")  # a DataError naming what the experiment has
    if len(outputs) > 1:
        raise DataError(
            f"the experiment has {len(outputs)} outputs ({', '.join(outputs)}); the model fits "
            "one: pass output=<name>"
        )
    return outputs[0]


def check_magnitude(label: str, pieces: Sequence[NDArray[np.float64]]) -> None:
    """Refuse a channel whose values overflow or underflow when squared."""
    peak = max((float(np.max(np.abs(p))) for p in pieces if p.size), default=0.0)
    if peak > LARGEST_VALUE:
        raise DataError(
            f"the {label} reaches {peak:.3g}: values beyond {LARGEST_VALUE:g} overflow "
            "double precision when squared. Rescale the channel (calibrate it to SI units)"
        )
    if 0 < peak < SMALLEST_VALUE:
        raise DataError(
            f"the {label} peaks at {peak:.3g}: values below {SMALLEST_VALUE:g} underflow to "
            "zero when squared. Rescale the channel (calibrate it to SI units)"
        )


def check_not_constant(name: str, pieces: Sequence[NDArray[np.float64]]) -> None:
    """Refuse a channel that is constant over every segment: it excites nothing."""
    low = min(float(p.min()) for p in pieces)
    high = max(float(p.max()) for p in pieces)
    if high - low <= 1e-12 * max(abs(low), abs(high), 1e-300):
        count = sum(p.size for p in pieces)
        raise IdentifiabilityError(
            f"input {name!r} is constant ({low:.6g} for all {count} samples): it "
            "is not persistently exciting, so no dynamics can be identified. Excite the "
            "system with a PRBS, multisine or chirp (servoid excite)"
        )
