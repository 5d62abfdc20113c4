"""The choices of a subspace fit: horizons and the order from singular values.

Functions here return the messages they would warn with, so that
:func:`~servoid.estimate.fit_n4sid` warns only about the pass it keeps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import DataError

__all__ = [
    "DEFAULT_MAX_ORDER",
    "adaptive_horizon",
    "check_order",
    "choose_order",
    "default_horizon",
    "given_horizons",
    "largest_order",
]

#: Largest order searched when neither `order` nor `max_order` is given.
DEFAULT_MAX_ORDER = 10
#: Shortest first-pass horizon [samples].
MIN_HORIZON = 20
#: Adaptive rule: the future horizon should let the slowest mode decay to this fraction.
#: Studied on a 2×2 4th-order plant (slowest |z| = 0.963, N = 2e4, 20 seeds): with future
#: horizons 10 / 20 / 40 (0.963^f = 0.69 / 0.47 / 0.22) the pole scatter was 10× / 3× / 1×
#: the asymptotic PEM standard deviation; the past horizon hardly mattered.
DECAY = 0.25
#: The adaptive horizon is at most this many times the first one.
MAX_GROWTH = 4
#: Hankel columns required per row of the data matrix: below this the Gram is barely full rank.
COLUMNS_PER_ROW = 2
#: Order rule: the last log-gap log(σ_n/σ_{n+1}) at least this fraction of the largest one.
#: Noise singular values decay slowly (ratios ~1.1–1.5), a mode's drop to the noise floor is
#: sharp; a weak fast mode can drop less than a dominant one, so "the last large drop" and not
#: "the largest drop" counts the weak mode.
GAP_KEEP = 0.5
#: A drop is clear when its log-ratio is at least this many times every later one (the
#: noise floor's own ratios, 1.1–1.3 at N = 3000, are log 0.1–0.26).
GAP_CLEAR = 3.0
#: Largest ratio σ_n/σ_{n+1} below which there is no gap at all (log 2): warn.
GAP_MIN = math.log(2.0)


def fits(past: int, future: int, m: int, ny: int, lengths: Sequence[int]) -> bool:
    """True when the segments give enough Hankel columns for these horizons."""
    rows = (past + future) * (m + ny)
    columns = sum(max(n - past - future + 1, 0) for n in lengths)
    return columns >= COLUMNS_PER_ROW * rows


def largest_order(past: int, future: int, m: int, ny: int) -> int:
    """min((future − 1)·ny, past·(m + ny)): the shift and the rank limits."""
    return min((future - 1) * ny, past * (m + ny))


def default_horizon(n_ref: int | None, m: int, ny: int, lengths: Sequence[int]) -> int:
    """First-pass horizon ``max(2·n_ref, 20)``, shortened to fit the record."""
    wanted = max(2 * (DEFAULT_MAX_ORDER if n_ref is None else n_ref), MIN_HORIZON)
    shortest = 2 if n_ref is None else max(-(-n_ref // ny) + 1, -(-n_ref // (m + ny)), 2)
    # Horizons beyond half the longest segment leave no Hankel column: start the search
    # there, not at 2·n_ref (an absurd order would count down for ever).
    s = min(wanted, max(max(lengths) // 2, shortest))
    while s > shortest and not fits(s, s, m, ny, lengths):
        s -= 1
    if not fits(s, s, m, ny, lengths):
        what = "" if n_ref is None else f" for order {n_ref}"
        raise DataError(
            f"the record ({_describe(lengths)}) is too short{what}: horizons past = future = "
            f"{s} need at least {_samples_needed(s, s, m, ny)} samples in one segment. Use a "
            "longer record or a lower order"
        )
    return s


def adaptive_horizon(radius: float, first: int, m: int, ny: int, lengths: Sequence[int]) -> int:
    """Horizon over which a pole of magnitude `radius` decays to DECAY.

    At least `first`, at most MAX_GROWTH·first, and no longer than the record allows.
    """
    if not 0.0 < radius < 1.0:
        return first
    wanted = min(math.ceil(math.log(DECAY) / math.log(radius)), MAX_GROWTH * first)
    s = first
    while s < wanted and fits(s + 1, s + 1, m, ny, lengths):
        s += 1
    return s


def given_horizons(horizon: int | tuple[int, int] | list[int], m: int, ny: int,
                   lengths: Sequence[int]) -> tuple[int, int]:
    """Check a user's horizon (an int or (past, future)) against the record."""
    if isinstance(horizon, (tuple, list)):
        if len(horizon) != 2:
            raise DataError(f"horizon must be an int or (past, future), got {horizon!r}")
        past = as_int("horizon past", horizon[0], minimum=1)
        future = as_int("horizon future", horizon[1], minimum=2)
    else:
        past = future = as_int("horizon", horizon, minimum=2)
    if not fits(past, future, m, ny, lengths):
        raise DataError(
            f"the record ({_describe(lengths)}) is too short for horizons past={past}, "
            f"future={future}: the block-Hankel matrix has {(past + future) * (m + ny)} rows and "
            f"needs {COLUMNS_PER_ROW}× as many columns, i.e. at least "
            f"{_samples_needed(past, future, m, ny)} samples in one segment. Use shorter horizons "
            "(horizon=(past, future)) or a longer record"
        )
    return past, future


def check_order(order: int, past: int, future: int, m: int, ny: int) -> None:
    """Raise DataError naming the horizons an order needs."""
    n_max = largest_order(past, future, m, ny)
    if order > n_max:
        need_f = -(-order // ny) + 1
        need_p = -(-order // (m + ny))
        raise DataError(
            f"order {order} is larger than horizons past={past}, future={future} allow: at most "
            f"min((future − 1)·outputs, past·(inputs + outputs)) = {n_max}. Pass "
            f"horizon=(past, future) with future >= {need_f} and past >= {need_p}, or a lower "
            "order"
        )


def choose_order(sv: NDArray[np.float64], cap: int, cap_is_horizon: bool
                 ) -> tuple[int, list[str]]:
    """The last large log-gap, and the warnings it calls for (see :func:`fit_n4sid`).

    A drop is *clear* when its log-ratio is at least GAP_CLEAR times every later one; the
    choice is ambiguous when there is no drop of 2 at all, or when a later order up to
    `cap` also ends in a clear drop (a weak mode standing out of the noise floor).
    """
    size = max(sv.size, cap + 1)
    s = np.zeros(size)
    s[: sv.size] = sv
    s = np.maximum(s, sv[0] * np.finfo(float).eps)  # below ε·σ₁ nothing is resolved
    gaps = np.log(s[:-1]) - np.log(s[1:])  # gaps[i − 1] = log σ_i/σ_{i+1}
    largest = float(gaps[:cap].max())
    n = int(np.flatnonzero(gaps[:cap] >= GAP_KEEP * largest)[-1]) + 1
    later = [j for j in range(n + 1, cap + 1) if _is_clear(gaps, j)]
    if largest < GAP_MIN or later:
        also = (f"; order {later[0]} (σ_{later[0]}/σ_{later[0] + 1} = "
                f"{math.exp(gaps[later[0] - 1]):.3g}) is also plausible" if later else "")
        message = (
            f"the singular values show no clear gap: chose order {n} (σ_{n}/σ_{n + 1} = "
            f"{math.exp(gaps[n - 1]):.3g}){also}. Inspect options['singular_values'] on a log "
            "scale, validate neighbouring orders, and pass order="
        )
        return n, [message]
    if n == cap and cap > 1:
        limit = "the horizons allow (lengthen horizon=)" if cap_is_horizon else "max_order"
        message = (
            f"the chosen order {n} is the largest {limit} considers: the true order may be "
            "higher. Raise it and check options['singular_values']"
        )
        return n, [message]
    return n, []


def _is_clear(gaps: NDArray[np.float64], order: int) -> bool:
    after = gaps[order:]
    return gaps[order - 1] >= GAP_MIN and (
        not after.size or gaps[order - 1] >= GAP_CLEAR * after.max()
    )


def _describe(lengths: Sequence[int]) -> str:
    if len(lengths) == 1:
        return f"{lengths[0]} samples"
    return f"{len(lengths)} segments of {', '.join(str(n) for n in lengths)} samples"


def _samples_needed(past: int, future: int, m: int, ny: int) -> int:
    return COLUMNS_PER_ROW * (past + future) * (m + ny) + past + future - 1
