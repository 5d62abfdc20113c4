"""Converter and bookkeeping steps shared by the EHSA and pneumatic rigs.

Private: :mod:`._run` and :mod:`._pneumatic` both quantise with clipping
like the same bipolar ADC/DAC, collect their warnings in the record's
notes while warning the caller, and take ``rng=`` as a generator or a
seed that is written into the record.
"""

from __future__ import annotations

from numbers import Integral

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, OptionTypeError, ServoidWarning
from .._warn import warn

__all__ = ["note_warning", "quantise", "resolve_rng"]


def quantise(v: NDArray[np.float64], bits: int,
             lsb: float) -> tuple[NDArray[np.float64], int]:
    """Round to the converter's codes, clip to its range; also count the clipped samples.

    The codes of a bipolar `bits`-bit converter run from ``−2^(bits−1)``
    to ``2^(bits−1) − 1``; `lsb` is one code [V].
    """
    top = 2 ** (bits - 1)
    codes = np.rint(v / lsb)
    clipped = int(np.count_nonzero((codes < -top) | (codes > top - 1)))
    return np.clip(codes, -top, top - 1) * lsb, clipped


def note_warning(notes: list[str], message: str) -> None:
    """Record `message` in a run's notes and warn (ServoidWarning, at the caller's line)."""
    notes.append(message)
    warn(message, ServoidWarning)


def resolve_rng(rng: object, caller: str) -> tuple[np.random.Generator, int | None]:
    """Return the generator and the seed (None for a given generator).

    `caller` names the public function in the TypeError.
    """
    if isinstance(rng, np.random.Generator):
        return rng, None
    if isinstance(rng, Integral) and not isinstance(rng, bool):
        if rng < 0:
            raise DataError(f"rng seed must be >= 0, got {rng}")
        return np.random.default_rng(int(rng)), int(rng)
    raise OptionTypeError(
        f"{caller} needs rng=, a numpy.random.Generator or an integer seed (so the record can "
        f"be reproduced), got {type(rng).__name__}")
