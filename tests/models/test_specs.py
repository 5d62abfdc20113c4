"""Spec numbers against closed forms: bandwidth, phase lag, resonance peak."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid import DataError, ModelError
from servoid.models import (
    FrequencyResponseData,
    StateSpace,
    TransferFunction,
    bandwidth,
    phase_lag,
    resonance_peak,
)

FN, ZETA = 40.0, 0.3
WN = 2 * np.pi * FN
SECOND = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])


def _bandwidth_2nd(zeta: float, level_db: float, ref_db: float = 0.0) -> float:
    """ω_n·r at which |1/(1 − r² + 2jζr)| = 10^((ref + level)/20), in Hz."""
    # (1 − r²)² + (2ζr)² = 10^(−(ref + level)/10): a quadratic in r²
    a = 1 - 2 * zeta**2
    r2 = a + math.sqrt(a * a - 1 + 10 ** (-(ref_db + level_db) / 10))
    return FN * math.sqrt(r2)


@pytest.mark.parametrize("zeta", [0.1, 0.3, 0.7071, 1.0, 2.0])
@pytest.mark.parametrize("level_db", [-3.0, -20 * math.log10(math.sqrt(2)), -6.0])
def test_bandwidth_of_a_second_order_system(zeta, level_db):
    g = TransferFunction([WN**2], [1.0, 2 * zeta * WN, WN**2])
    # Brent on the exact response: rounding only
    assert bandwidth(g, level_db) == pytest.approx(_bandwidth_2nd(zeta, level_db), rel=1e-9)


@pytest.mark.parametrize("f", [1.0, 20.0, 40.0, 80.0, 400.0])
def test_phase_lag_of_a_second_order_system(f):
    r = f / FN
    expected = math.degrees(math.atan2(2 * ZETA * r, 1 - r * r))  # in (0°, 180°)
    # exact evaluation: rounding only
    assert phase_lag(SECOND, f) == pytest.approx(expected, abs=1e-9)


def test_phase_lag_goes_past_180_degrees():
    lag3 = SECOND * TransferFunction([1.0], [1 / (2 * np.pi * 50.0), 1.0])
    f = 200.0
    r = f / FN
    expected = math.degrees(math.atan2(2 * ZETA * r, 1 - r * r) + math.atan(f / 50.0))
    assert expected > 180
    # unwrapped from low frequency: the lags of the factors add (rounding only)
    assert phase_lag(lag3, f) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("zeta", [0.05, 0.3, 0.6])
def test_resonance_peak_of_a_second_order_system(zeta):
    g = TransferFunction([WN**2], [1.0, 2 * zeta * WN, WN**2])
    peak = resonance_peak(g)
    # M_r = 1/(2ζ√(1 − ζ²)) at ω_r = ω_n·√(1 − 2ζ²): the height is exact to rounding; a
    # maximum is flat, so its place is found to ~√ε
    assert peak.peak_db == pytest.approx(-20 * math.log10(2 * zeta * math.sqrt(1 - zeta**2)),
                                         abs=1e-9)
    assert peak.frequency == pytest.approx(FN * math.sqrt(1 - 2 * zeta**2), rel=1e-6)
    assert peak.reference_db == pytest.approx(0.0, abs=1e-12)


def test_no_resonance_above_the_critical_damping():
    peak = resonance_peak(TransferFunction([WN**2], [1.0, 2 * 0.8 * WN, WN**2]))
    assert (peak.peak_db, peak.frequency) == (0.0, 0.0)


def test_discrete_first_order_against_its_closed_form():
    a, dt = 0.9, 1e-3
    g = TransferFunction([1 - a], [1.0, -a], dt=dt)
    # |G(e^{jθ})|² = (1 − a)²/(1 − 2a·cosθ + a²) = 10^(−3/10)·1 at the −3 dB point
    cos_theta = (1 + a * a - 10 ** 0.3 * (1 - a) ** 2) / (2 * a)
    expected = math.acos(cos_theta) / (2 * math.pi * dt)
    assert bandwidth(g) == pytest.approx(expected, rel=1e-9)  # rounding only
    # and its phase lag: ∠G = −θ − ∠(1 − a·e^{−jθ}) for θ = ω·dt
    theta = 2 * math.pi * 20.0 * dt
    lag = math.degrees(theta + math.atan2(a * math.sin(theta), 1 - a * math.cos(theta)))
    assert phase_lag(g, 20.0) == pytest.approx(lag, abs=1e-9)


def test_state_space_gives_the_same_numbers():
    ss = SECOND.to_ss()
    assert isinstance(ss, StateSpace)
    # two realisations of one response: rounding only
    assert bandwidth(ss) == pytest.approx(bandwidth(SECOND), rel=1e-9)
    assert phase_lag(ss, 50.0) == pytest.approx(phase_lag(SECOND, 50.0), abs=1e-9)
    assert resonance_peak(ss).peak_db == pytest.approx(resonance_peak(SECOND).peak_db, abs=1e-9)


def test_integrator_needs_a_reference_frequency():
    integ = TransferFunction([1.0], [1.0, 0.0])
    with pytest.raises(ModelError, match="pass reference_frequency=<Hz>"):
        bandwidth(integ)
    # |1/(jω)| falls 3 dB from 1 Hz at 10^(3/20) Hz (rounding only)
    assert bandwidth(integ, reference_frequency=1.0) == pytest.approx(10 ** (3 / 20), rel=1e-9)
    assert phase_lag(integ, 5.0) == pytest.approx(90.0, abs=1e-9)


def test_measured_lines():
    f = np.arange(1.0, 200.0, 0.25)
    frd = FrequencyResponseData(f, SECOND.freqresp(2 * np.pi * f))
    # the level is that of the lowest line, 1 Hz; log-linear interpolation between lines
    # 0.25 Hz apart puts the crossing within 1e-4 relative
    ref_db = float(frd.magnitude_db[0])
    assert bandwidth(frd) == pytest.approx(_bandwidth_2nd(ZETA, -3.0, ref_db), rel=1e-4)
    # the phase interpolated linearly between lines: error ≤ h²/8·|φ''| ≈ 1e-3 deg
    r = 33.1 / FN
    assert phase_lag(frd, 33.1) == pytest.approx(
        math.degrees(math.atan2(2 * ZETA * r, 1 - r * r)), abs=1e-2)
    # the peak is the highest line: its height within the curvature over half a line spacing
    peak = resonance_peak(frd)
    assert abs(peak.frequency - FN * math.sqrt(1 - 2 * ZETA**2)) <= 0.125
    assert peak.peak_db == pytest.approx(
        -20 * math.log10(2 * ZETA * math.sqrt(1 - ZETA**2)) - ref_db, abs=1e-3)
    assert peak.reference_db == ref_db


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: bandwidth(SECOND, 3.0), DataError, "level_db must be a finite number < 0"),
        (lambda: phase_lag(SECOND, 0.0), DataError, "frequency must be a finite number > 0"),
        (lambda: bandwidth(TransferFunction([0.1, 1.0], [0.01, 1.0])), ModelError,
         "does not fall 3 dB below"),
        (lambda: bandwidth(FrequencyResponseData([1.0, 2.0], [1.0, 0.9])), ModelError,
         r"measure to higher frequencies or fit a model"),
        (lambda: phase_lag(FrequencyResponseData([1.0, 2.0], [1.0, 0.9]), 5.0), DataError,
         "within the measured lines"),
        (lambda: bandwidth("not a model"), TypeError, "freqresp"),  # type: ignore[arg-type]
    ],
)
def test_bad_input(call, error, match):
    with pytest.raises(error, match=match):
        call()
