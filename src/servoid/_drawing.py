"""Drawing helpers every figure uses: user text shown as typed, long records thinned.

Matplotlib reads ``$…$`` as math text and fails on an unbalanced or unknown
expression (a unit written ``$m/s``); every string that comes from the
user's data or experiment file goes through :func:`plain` first.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BUCKETS", "plain", "thinned"]


def plain(text: object) -> str:
    """Return ``text`` with matplotlib's math-text markers escaped."""
    return str(text).replace("$", r"\$")


#: Buckets a long plotted signal is thinned to: wider than the figures in pixels.
BUCKETS = 2000


def thinned(t: NDArray[np.float64], y: NDArray[np.float64],
            buckets: int = BUCKETS) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The samples of y a line plot of ``buckets`` pixels can show.

    For each of ``buckets`` equal runs of samples, the first, the last, the
    smallest and the largest, in time order (the M4 aggregation of Jugel et
    al., VLDB 2014): drawn at that width the line is the same picture as
    every sample, and a 1e7-sample record no longer makes matplotlib hold
    several N × 2 copies (1.4 GB).  Records up to 4 × ``buckets`` samples
    are drawn whole.
    """
    n = y.size
    if n <= 4 * buckets:
        return t, y
    size = n // buckets
    rows = y[: size * buckets].reshape(buckets, size)
    start = np.arange(buckets) * size
    keep = np.concatenate([start, start + size - 1, start + np.argmin(rows, axis=1),
                           start + np.argmax(rows, axis=1), np.arange(size * buckets, n)])
    keep = np.unique(keep)  # sorted: time order
    return t[keep], y[keep]
