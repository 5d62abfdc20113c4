"""Maximum-length sequences from a Fibonacci LFSR, generated in blocks.

Convention (as in the Wikipedia "Linear-feedback shift register" article
and Xilinx XAPP052): taps ``(n, k, ...)`` name the feedback polynomial
``x^n + x^k + ... + 1``. The register holds ``n`` bits; bit ``i`` of the
state at step ``m`` is output bit ``a[m + i]``, the output is bit 0, and
the new top bit is the XOR of the tapped bits, so the sequence obeys

    a[i] = XOR over taps t of a[i - t]        (i >= n).

Generating bit by bit in Python would take seconds for n = 20. Over
GF(2), squaring a polynomial squares each term (Frobenius), so the same
sequence also obeys ``a[i] = XOR_t a[i - t·2^j]`` for every j with
``i >= n·2^j``. Once ``n·2^j`` bits exist, the next ``t_min·2^j`` bits
depend only on bits already known and are computed as one vector XOR.
The block length doubles as the sequence grows, so a period takes
O(log N) numpy operations and O(N·taps) work.
"""

from __future__ import annotations

from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

__all__ = ["PRBS_TAPS", "mls_bits"]

# Feedback taps of one primitive polynomial per register length. Source:
# Wikipedia, "Linear-feedback shift register", table "Example polynomials for
# maximal LFSRs" (n = 2..24), continued for 25..31 with Xilinx XAPP052 Table 3
# (the two agree on 2..11, 15, 17, 18, 20..23, 25..31). n = 7..12 also match
# models-spec §3.1. Every entry is proved primitive in tests/signals.
_TAPS: dict[int, tuple[int, ...]] = {
    2: (2, 1),
    3: (3, 2),
    4: (4, 3),
    5: (5, 3),
    6: (6, 5),
    7: (7, 6),
    8: (8, 6, 5, 4),
    9: (9, 5),
    10: (10, 7),
    11: (11, 9),
    12: (12, 11, 10, 4),
    13: (13, 12, 11, 8),
    14: (14, 13, 12, 2),
    15: (15, 14),
    16: (16, 15, 13, 4),
    17: (17, 14),
    18: (18, 11),
    19: (19, 18, 17, 14),
    20: (20, 17),
    21: (21, 19),
    22: (22, 21),
    23: (23, 18),
    24: (24, 23, 22, 17),
    25: (25, 22),
    26: (26, 6, 2, 1),
    27: (27, 5, 2, 1),
    28: (28, 25),
    29: (29, 27),
    30: (30, 6, 4, 1),
    31: (31, 28),
}
PRBS_TAPS = MappingProxyType(_TAPS)
"""Read-only map from register length n (2..31) to its feedback taps."""


def mls_bits(n: int, n_bits: int, state: int) -> NDArray[np.uint8]:
    """First ``n_bits`` output bits of the LFSR of length ``n``.

    ``state`` is the initial register (1 <= state < 2**n); its bit ``i`` is
    output bit ``i``. Arguments are trusted (checked by the caller).
    """
    taps = _TAPS[n]
    t_min = min(taps)
    bits = np.empty(max(n_bits, n), dtype=np.uint8)
    bits[:n] = (state >> np.arange(n)) & 1
    filled = n
    while filled < n_bits:
        scale = 1 << ((filled // n).bit_length() - 1)  # largest 2^j with n·2^j <= filled
        block = min(t_min * scale, n_bits - filled)
        out = bits[filled : filled + block]
        first, *rest = (filled - t * scale for t in taps)
        np.bitwise_xor(bits[first : first + block], bits[rest[0] : rest[0] + block], out=out)
        for start in rest[1:]:
            np.bitwise_xor(out, bits[start : start + block], out=out)
        filled += block
    return bits[:n_bits]
