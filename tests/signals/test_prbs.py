"""PRBS: taps table, period, balance, autocorrelation, spectrum, clock."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.signals import PRBS_TAPS, power_spectrum, prbs

# Published primitive polynomials, transcribed as exponent tuples (constant term implied).
# n = 2..24: Wikipedia, "Linear-feedback shift register", table "Example polynomials for
# maximal LFSRs" (revision of 2024). n = 25..31: Xilinx XAPP052 (P. Alfke, 1996), Table 3.
PUBLISHED = {
    2: (2, 1), 3: (3, 2), 4: (4, 3), 5: (5, 3), 6: (6, 5), 7: (7, 6), 8: (8, 6, 5, 4),
    9: (9, 5), 10: (10, 7), 11: (11, 9), 12: (12, 11, 10, 4), 13: (13, 12, 11, 8),
    14: (14, 13, 12, 2), 15: (15, 14), 16: (16, 15, 13, 4), 17: (17, 14), 18: (18, 11),
    19: (19, 18, 17, 14), 20: (20, 17), 21: (21, 19), 22: (22, 21), 23: (23, 18),
    24: (24, 23, 22, 17), 25: (25, 22), 26: (26, 6, 2, 1), 27: (27, 5, 2, 1), 28: (28, 25),
    29: (29, 27), 30: (30, 6, 4, 1), 31: (31, 28),
}  # fmt: skip
# models-spec §3.1 lists these taps with their periods checked
SPEC = {7: (7, 6), 8: (8, 6, 5, 4), 9: (9, 5), 10: (10, 7), 11: (11, 9), 12: (12, 11, 10, 4)}


def _bits(n: int, **kwargs: object) -> np.ndarray:
    """0/1 bits of one period at clock 1."""
    return (prbs(n, **kwargs).values > 0).astype(np.uint8)  # type: ignore[arg-type]


# -- GF(2) arithmetic for the primitivity proof ---------------------------------------------


def _mulmod(a: int, b: int, poly: int, n: int) -> int:
    """a·b mod poly over GF(2); polynomials as bit masks, deg poly = n."""
    out = 0
    while b:
        if b & 1:
            out ^= a
        b >>= 1
        a <<= 1
        if (a >> n) & 1:
            a ^= poly
    return out


def _x_power(e: int, poly: int, n: int) -> int:
    """x**e mod poly over GF(2), by square and multiply."""
    result, base = 1, 2
    while e:
        if e & 1:
            result = _mulmod(result, base, poly, n)
        base = _mulmod(base, base, poly, n)
        e >>= 1
    return result


def _prime_factors(m: int) -> set[int]:
    factors, d = set(), 2
    while d * d <= m:
        while m % d == 0:
            factors.add(d)
            m //= d
        d += 1
    if m > 1:
        factors.add(m)
    return factors


def _is_primitive(taps: tuple[int, ...]) -> bool:
    """True if 1 + sum x**t (degree n = max tap) is primitive over GF(2).

    x has order exactly 2**n - 1 modulo p iff x**(2**n - 1) = 1 and
    x**((2**n - 1)/q) != 1 for each prime q dividing 2**n - 1. An element of
    that order makes every non-zero residue a unit, so p is also irreducible.
    """
    n = max(taps)
    poly = 1
    for t in taps:
        poly |= 1 << t
    order = (1 << n) - 1
    if _x_power(order, poly, n) != 1:
        return False
    return all(_x_power(order // q, poly, n) != 1 for q in _prime_factors(order))


def _naive_lfsr(n: int, n_bits: int, state: int) -> np.ndarray:
    """Bit-by-bit Fibonacci LFSR, as in Wikipedia's C example."""
    taps, out = PRBS_TAPS[n], []
    for _ in range(n_bits):
        out.append(state & 1)
        feedback = 0
        for t in taps:
            feedback ^= (state >> (n - t)) & 1
        state = (state >> 1) | (feedback << (n - 1))
    return np.array(out, dtype=np.uint8)


# -- taps table -----------------------------------------------------------------------------


def test_taps_table_matches_published_tables() -> None:
    assert dict(PRBS_TAPS) == PUBLISHED
    assert {n: PRBS_TAPS[n] for n in SPEC} == SPEC


def test_taps_table_is_read_only() -> None:
    with pytest.raises(TypeError):
        PRBS_TAPS[5] = (5, 2)  # type: ignore[index]


@pytest.mark.parametrize("n", range(2, 32))
def test_every_feedback_polynomial_is_primitive(n: int) -> None:
    assert _is_primitive(PRBS_TAPS[n])


def test_primitivity_check_rejects_non_primitive() -> None:
    # x^4+x^3+x^2+x+1 is irreducible with order 5, x^4+x^2+1 = (x^2+x+1)^2 is reducible
    assert not _is_primitive((4, 3, 2, 1))
    assert not _is_primitive((4, 2))
    assert _is_primitive((4, 1))


# -- generated sequences --------------------------------------------------------------------


@pytest.mark.parametrize("n", range(2, 13))
def test_fast_generator_matches_bit_by_bit_lfsr(n: int) -> None:
    n_bits = (1 << n) - 1
    state = 0b1011 % n_bits or 1
    fast = _bits(n, periods=2, seed_state=state)
    assert np.array_equal(fast, _naive_lfsr(n, 2 * n_bits, state))


@pytest.mark.parametrize("n", range(2, 21))
def test_period_is_exactly_2n_minus_1(n: int) -> None:
    n_bits = (1 << n) - 1
    two = _bits(n, periods=2)
    assert two.size == 2 * n_bits
    assert np.array_equal(two[:n_bits], two[n_bits:])
    # All N circular n-bit windows distinct <=> no shorter period (a period p < N
    # would make the windows at i and i + p equal)
    one = two[:n_bits]
    windows = np.zeros(n_bits, dtype=np.int64)
    for k in range(n):
        windows |= np.roll(one, -k).astype(np.int64) << k
    assert np.unique(windows).size == n_bits
    assert windows.min() >= 1  # the all-zero state never occurs


@pytest.mark.parametrize("n", [2, 3, 7, 11, 16, 20])
def test_balance_one_more_high_than_low(n: int) -> None:
    x = prbs(n).values
    assert np.count_nonzero(x == 1.0) == 2 ** (n - 1)
    assert np.count_nonzero(x == -1.0) == 2 ** (n - 1) - 1


@pytest.mark.parametrize("n", [3, 6, 10, 14])
def test_circular_autocorrelation_is_two_valued(n: int) -> None:
    x = prbs(n).values
    big_n = x.size
    acf = np.array([np.dot(x, np.roll(x, k)) for k in range(big_n)]) / big_n
    np.testing.assert_allclose(acf[0], 1.0, rtol=1e-15)  # integer sum / N: one rounding
    np.testing.assert_allclose(acf[1:], -1.0 / big_n, rtol=1e-12)  # integer sum / N: rounding


def test_seed_state_gives_a_circular_shift() -> None:
    a = prbs(9).values
    b = prbs(9, seed_state=0b101100111).values
    shifts = [k for k in range(a.size) if np.array_equal(np.roll(a, -k), b)]
    assert len(shifts) == 1


def test_levels_offset_amplitude_and_clock() -> None:
    x = prbs(6, clock=4, amplitude=0.5, offset=2.0, periods=3, dt=1e-3)
    assert set(np.unique(x.values)) == {1.5, 2.5}
    assert (x.period, x.clock, x.n_samples) == (63 * 4, 4, 63 * 4 * 3)
    bits = x.values.reshape(-1, 4)
    assert np.all(bits == bits[:, :1])  # every bit is held for exactly `clock` samples
    assert np.array_equal(bits[:, 0], prbs(6, amplitude=0.5, offset=2.0, periods=3).values)
    assert x.description["taps"] == (6, 5)
    assert x.description["bit_time"] == pytest.approx(4e-3, rel=1e-15)  # one product


def test_n20_full_length() -> None:
    # speed is measured in benchmarks/bench_signals.py, never asserted in a unit test
    x = prbs(20)
    assert x.n_samples == 2**20 - 1


# -- spectrum -------------------------------------------------------------------------------


def _envelope(f: np.ndarray, clock: int, dt: float) -> np.ndarray:
    """Zero-order-hold power envelope, 1 at f -> 0 (sinc² for a long clock)."""
    x = f * clock * dt
    return (np.sin(np.pi * x) / (clock * np.sin(np.pi * x / clock))) ** 2


@pytest.mark.parametrize("clock", [1, 2, 5, 10])
def test_line_spectrum_matches_theory(clock: int) -> None:
    n, dt = 8, 1e-3
    big_n = 2**n - 1
    x = prbs(n, clock=clock, dt=dt)
    s = power_spectrum(x)
    k = np.arange(1, s.frequency.size)
    on_grid = k % big_n != 0
    # |DFT of a ±1 m-sequence|² is N + 1 off DC; the hold multiplies by the envelope
    theory = 2 * (big_n + 1) / big_n**2 * _envelope(s.frequency[1:], clock, dt)
    if clock * big_n % 2 == 0:
        theory[-1] /= 2  # the Nyquist line is not doubled
    np.testing.assert_allclose(s.power[1:][on_grid], theory[on_grid], rtol=1e-9)  # FFT rounding
    assert np.all(s.power[1:][~on_grid] < 1e-25)  # hold nulls at multiples of 1/T_b: rounding
    np.testing.assert_allclose(s.power[0], 1 / big_n**2, rtol=1e-9)  # DC: one more high bit


@pytest.mark.parametrize("clock", [1, 3, 10, 25])
def test_spectrum_flat_within_3db_over_the_band(clock: int) -> None:
    dt = 1e-3
    x = prbs(10, clock=clock, dt=dt)
    s = power_spectrum(x)
    lo, hi = x.band
    assert lo == pytest.approx(1 / x.duration, rel=1e-12)  # one division
    in_band = (s.frequency >= lo) & (s.frequency <= hi * (1 + 1e-12))
    assert in_band.sum() >= 100
    flat = 2 * (2**10) / (2**10 - 1) ** 2  # low-frequency limit of the line power
    # 3 dB: the band edge is where the hold's sinc²-like envelope reaches half power
    assert np.all(s.power[in_band] >= flat / 2 * (1 - 1e-9))
    assert np.all(s.power[in_band] <= flat * (1 + 1e-9))
    # spec §3.1 rule of thumb: flat to 0.44/T_b for every clock
    rule = (s.frequency > 0) & (s.frequency <= 0.44 / (clock * dt))
    assert np.all(s.power[rule] >= flat / 2 * (1 - 1e-9))


@pytest.mark.parametrize(
    ("clock", "edge"),
    [(1, 0.5), (2, 0.5), (5, 0.4508), (10, 0.4449), (100, 0.4430)],
)
def test_band_edge_is_the_half_power_point(clock: int, edge: float) -> None:
    dt = 1e-3
    x = prbs(5, clock=clock, dt=dt)
    assert x.band[1] * clock * dt == pytest.approx(edge, abs=1e-4)  # edge quoted to 4 digits
    if clock > 1:
        half = _envelope(np.array([x.band[1]]), clock, dt)[0]
        assert half == pytest.approx(0.5, rel=1e-9)  # brentq xtol 1e-14 on a smooth function
