"""power_spectrum and crest_factor."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.signals import Spectrum, crest_factor, power_spectrum, prbs, random_binary


def test_dft_power_of_a_sine_on_the_grid() -> None:
    dt, period = 1e-3, 500
    t = dt * np.arange(3 * period)
    x = 0.7 + 2.0 * np.sin(2 * np.pi * 10.0 * t)  # 10 Hz = line 5 of 1/(500 dt)
    s = power_spectrum(x, dt, period=period)
    assert s.method == "dft"
    assert s.frequency[1] == pytest.approx(2.0, rel=1e-12)  # 1/(P·dt), one division
    assert s.power[5] == pytest.approx(2.0**2 / 2, rel=1e-12)  # A²/2, FFT rounding
    assert s.power[0] == pytest.approx(0.7**2, rel=1e-12)  # offset², FFT rounding
    assert s.power.sum() == pytest.approx(np.mean(x**2), rel=1e-12)  # Parseval


def test_dft_cuts_to_whole_periods_and_averages() -> None:
    dt, period = 1.0, 64
    y = np.tile(np.cos(2 * np.pi * 3 * np.arange(period) / period), 5)[:-10]
    s = power_spectrum(y, dt, period=period)  # 4 whole periods kept
    assert s.frequency.size == period // 2 + 1
    assert s.power[3] == pytest.approx(0.5, rel=1e-12)  # A²/2 with A = 1


def test_nyquist_line_not_doubled() -> None:
    x = np.array([1.0, -1.0] * 8)
    s = power_spectrum(x, 1.0)
    assert s.frequency[-1] == 0.5
    assert s.power[-1] == pytest.approx(1.0, rel=1e-12)  # mean square of ±1 lies on one line


def test_excitation_defaults_choose_the_method() -> None:
    per = prbs(7, clock=2, periods=2, dt=1e-3)
    s = power_spectrum(per)
    assert s.method == "dft" and s.frequency.size == 127 + 1  # one period of 254 samples
    rbs = random_binary(4096, rng=5, dt=1e-3)
    w = power_spectrum(rbs, nperseg=512)
    assert w.method == "welch"
    assert w.frequency[1] == pytest.approx(1 / (512e-3), rel=1e-12)  # 1/(nperseg·dt)
    # PSD × bin width sums to each segment's windowed mean square, and x² = 1 for a ±1
    # signal, so the total is exactly the mean square 1 whatever the random bits
    assert w.power.sum() == pytest.approx(1.0, rel=1e-12)  # rounding only


def test_white_random_binary_spectrum_is_flat_by_welch() -> None:
    x = random_binary(2**16, rng=9)
    w = power_spectrum(x, periodic=False, nperseg=256)
    inner = w.power[2:-2]
    # 511 Hann segments at 50 % overlap: each bin scatters by ~1/sqrt(0.9·511) = 4.7 %;
    # 0.25 is about 5 sigma for the worst of 125 bins
    assert np.all(np.abs(inner / inner.mean() - 1) < 0.25)


def test_spectrum_arrays_are_read_only() -> None:
    s = power_spectrum(np.arange(8.0), 1.0)
    assert isinstance(s, Spectrum)
    with pytest.raises(ValueError, match="read-only"):
        s.power[0] = 1.0
    db = power_spectrum(np.cos(np.arange(8) * np.pi / 2), 1.0).power_db
    assert db[2] == pytest.approx(10 * np.log10(0.5), rel=1e-12)  # A²/2 with A = 1


@pytest.mark.parametrize(
    ("x", "expected"),
    [
        (np.sin(2 * np.pi * np.arange(1000) / 100), np.sqrt(2)),  # sine
        (prbs(9).values * 3 + 10, np.sqrt(512 / 510)),  # ±1, mean 1/N: sqrt((N+1)/(N-1))
        (np.array([0.0, 0.0, 0.0, 4.0]), 3 / np.sqrt(3)),  # spike: peak 3, rms sqrt(3)
    ],
)
def test_crest_factor_about_the_mean(x: np.ndarray, expected: float) -> None:
    assert crest_factor(x) == pytest.approx(expected, rel=1e-9)  # closed forms, rounding


def test_crest_factor_accepts_an_excitation() -> None:
    x = prbs(5, amplitude=2.0, offset=1.0)
    assert crest_factor(x) == crest_factor(x.values)
