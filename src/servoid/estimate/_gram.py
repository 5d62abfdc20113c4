"""Gram matrix of lagged signals in one pass over the data.

For a regressor whose columns are delayed copies of a few signals,
φ_p(t) = z_{s_p}(t − l_p), the Gram matrix entry of columns p and q is a
lagged product Σ_t z_a(t − l_p)·z_b(t − l_q): it depends on the pair of
signals and the lag difference d = l_p − l_q, up to a few terms at the ends
of the record. So ΦᵀΦ needs only one full-length dot product per distinct
(a, b, d) — 15 instead of 36 for ARX(3, 4, 0) — plus O(lag) end corrections,
and Φ itself is never formed. The kernel walks the record in cache-sized
blocks so the data are read from memory once, and each inner loop is a
contiguous dot product the compiler vectorises.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["lagged_gram"]

_BLOCK = 4096  # samples per block: a few signals × 32 KB stay in the L1/L2 cache


def lagged_gram(
    z: Sequence[NDArray[np.float64]],
    signal: NDArray[np.int64],
    lag: NDArray[np.int64],
    start: int,
) -> NDArray[np.float64]:
    """Σ_{t=start}^{N−1} z_{s_p}(t − l_p)·z_{s_q}(t − l_q) for every column pair.

    Parameters
    ----------
    z : sequence of ndarray, each shape (N,)
        The signals (used in place, not copied).
    signal, lag : ndarray of int, shape (n,)
        Signal index and delay [samples] of each column.
    start : int
        First time index; must be ≥ max(lag).
    """
    z = tuple(np.ascontiguousarray(x, dtype=np.float64) for x in z)
    signal = np.asarray(signal, dtype=np.int64)
    lag = np.asarray(lag, dtype=np.int64)
    key_arr, pair_key = _pair_keys(tuple(signal.tolist()), tuple(lag.tolist()))
    n = signal.size
    gram = np.empty((n, n))
    _gram_kernel(z, key_arr, signal, lag, int(start), pair_key, gram)
    return gram


def lagged_gram_ranges(
    z: Sequence[NDArray[np.float64]],
    signal: NDArray[np.int64],
    lag: NDArray[np.int64],
    start: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`lagged_gram` and the (min, max) of each signal, in one compiled call.

    The ranges have the caveat of :func:`value_range` (unspecified with NaN).
    """
    z = tuple(np.ascontiguousarray(x, dtype=np.float64) for x in z)
    signal = np.asarray(signal, dtype=np.int64)
    lag = np.asarray(lag, dtype=np.int64)
    key_arr, pair_key = _pair_keys(tuple(signal.tolist()), tuple(lag.tolist()))
    n = signal.size
    gram = np.empty((n, n))
    ranges = np.empty((len(z), 2))
    _gram_ranges_kernel(z, key_arr, signal, lag, int(start), pair_key, gram, ranges)
    return gram, ranges


def _lagged_gram_ranges(
    z: tuple[NDArray[np.float64], ...],
    signal: NDArray[np.int64],
    lag: NDArray[np.int64],
    start: int,
    key_arr: NDArray[np.int64],
    pair_key: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`lagged_gram_ranges` with the structure's :func:`_pair_keys` given.

    For a caller that has cached them (ARX): the same compiled call, without
    re-deriving the keys or converting channels that are already contiguous
    float arrays.
    """
    if not all(type(x) is np.ndarray and x.dtype == np.float64 and x.flags.c_contiguous
               for x in z):
        z = tuple(np.ascontiguousarray(x, dtype=np.float64) for x in z)
    n = signal.size
    gram = np.empty((n, n))
    ranges = np.empty((len(z), 2))
    _gram_ranges_kernel(z, key_arr, signal, lag, start, pair_key, gram, ranges)
    return gram, ranges


@functools.lru_cache(maxsize=256)
def _pair_keys(
    signal: tuple[int, ...], lag: tuple[int, ...]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The distinct (a, b, d) lagged products and the one each column pair uses.

    Depends only on the regressor's structure, so it is built once per structure
    (a fit at 1e4 samples spent as long on this as on the sums). The arrays are
    read-only: every caller shares them.
    """
    n = len(signal)
    keys: dict[tuple[int, int, int], int] = {}
    pair_key = np.zeros((n, n), dtype=np.int64)
    for p in range(n):
        for q in range(p, n):
            a, b, d = signal[p], signal[q], lag[p] - lag[q]
            if d < 0:  # canonical orientation: non-negative lag, same set of products
                a, b, d = b, a, -d
            pair_key[p, q] = keys.setdefault((a, b, d), len(keys))
    key_arr = np.array(list(keys), dtype=np.int64).reshape(-1, 3)
    key_arr.setflags(write=False)
    pair_key.setflags(write=False)
    return key_arr, pair_key


@numba.njit(cache=True, nogil=True)
def _gram_kernel(z, keys, signal, lag, start, pair_key, gram):  # type: ignore[no-untyped-def]  # pragma: no cover
    # the full lagged sums, then the end corrections: one call from Python instead of two
    full = np.zeros(keys.shape[0])
    _full_sums(z, keys, full)
    _assemble(z, signal, lag, start, pair_key, full, gram)


@numba.njit(cache=True, nogil=True)
def _gram_ranges_kernel(z, keys, signal, lag, start, pair_key, gram, ranges):  # type: ignore[no-untyped-def]  # pragma: no cover
    full = np.zeros(keys.shape[0])
    _full_sums(z, keys, full)
    _assemble(z, signal, lag, start, pair_key, full, gram)
    for k in range(len(z)):
        lo, hi = _range_kernel(z[k])
        ranges[k, 0] = lo
        ranges[k, 1] = hi


@numba.njit(cache=True, fastmath=True, nogil=True)
def _full_sums(z, keys, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    # out[k] = Σ_{s=0}^{N−1−d} z_a(s)·z_b(s + d) for key k = (a, b, d), d ≥ 0.
    n_total = z[0].shape[0]
    for lo in range(0, n_total, _BLOCK):
        for k in range(keys.shape[0]):
            a, b, d = keys[k, 0], keys[k, 1], keys[k, 2]
            hi = min(lo + _BLOCK, n_total - d)
            if hi <= lo:
                continue
            xa = z[a][lo:hi]
            xb = z[b][lo + d : hi + d]
            acc = 0.0
            for i in range(hi - lo):
                acc += xa[i] * xb[i]
            out[k] += acc


@numba.njit(cache=True, nogil=True)
def _assemble(z, signal, lag, start, pair_key, full, gram):  # type: ignore[no-untyped-def]  # pragma: no cover
    # Pair (p, q) sums s = t − l_p over [start − l_p, N − 1 − l_p]; the full sum runs
    # over [max(0, −d), min(N − 1, N − 1 − d)]. Subtract the terms outside the pair's range.
    n_total = z[0].shape[0]
    n = signal.size
    for p in range(n):
        for q in range(p, n):
            a, b = signal[p], signal[q]
            d = lag[p] - lag[q]
            s = full[pair_key[p, q]]
            for i in range(max(0, -d), start - lag[p]):
                s -= z[a][i] * z[b][i + d]
            for i in range(n_total - lag[p], min(n_total - 1, n_total - 1 - d) + 1):
                s -= z[a][i] * z[b][i + d]
            gram[p, q] = s
            gram[q, p] = s


def value_range(x: NDArray[np.float64]) -> tuple[float, float]:
    """(min, max) of a signal in one vectorised pass, without temporaries.

    Exact for data without NaN; with NaN the values are unspecified (the
    compiled loop assumes none), so a caller must only use them to *skip*
    a check that NaN makes pass anyway (``check_magnitude`` and
    ``check_not_constant`` do not raise when NaN is present).
    """
    lo, hi = _range_kernel(np.ascontiguousarray(x, dtype=np.float64))
    return float(lo), float(hi)


@numba.njit(cache=True, nogil=True, fastmath={"nnan", "nsz"})
def _range_kernel(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    lo = np.inf
    hi = -np.inf
    for v in x:
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi
