"""Preprocessing: calibration, detrending, filtering, decimation, splitting."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps

from servoid import DataError, Experiment, OptionError
from servoid.data import calibrate, decimate, detrend, lowpass, split, split_periods


def _amplitude(x: np.ndarray, t: np.ndarray, f: float) -> float:
    """Amplitude of the f-Hz component by least squares on sin and cos."""
    basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    coef = np.linalg.lstsq(basis, x, rcond=None)[0]
    return float(np.hypot(*coef))


def test_calibrate_gain_offset_units() -> None:
    exp = Experiment.from_arrays(0.01, u=[1.0, 2.0, 3.0], y=[0.0, 1.0, 2.0], units={"y": "V"})
    cal = calibrate(exp, {"y": (2.0, 0.5), "u": 3.0}, units={"y": "m"})
    np.testing.assert_array_equal(cal["y"], [0.5, 2.5, 4.5])
    np.testing.assert_array_equal(cal["u"], [3.0, 6.0, 9.0])
    assert cal.unit("y") == "m" and cal.unit("u") == ""
    assert exp.unit("y") == "V"  # the input is untouched
    with pytest.raises(DataError, match="finite non-zero gain"):
        calibrate(exp, {"y": 0.0})


def test_detrend_mean_linear_offset() -> None:
    t = np.arange(200) * 0.01
    exp = Experiment.from_arrays(0.01, u=3.0 + 0 * t, y=1.0 + 2.0 * t, side={"p": 5.0 + t})
    mean = detrend(exp, "mean")
    # Sums of 200 values of order 1: a few ulps of rounding.
    assert abs(mean["y"].mean()) < 1e-13
    np.testing.assert_array_equal(mean["p"], exp["p"])  # side channels keep their level
    lin = detrend(exp, "linear")
    np.testing.assert_allclose(lin["y"], 0.0, atol=1e-12)  # exact line, rounding only
    off = detrend(exp, "offset", offsets={"u": 3.0})
    np.testing.assert_array_equal(off["u"], 0.0)
    np.testing.assert_array_equal(off["y"], exp["y"])
    with pytest.raises(DataError, match="needs offsets"):
        detrend(exp, "offset")
    with pytest.raises(OptionError, match="'mean', 'linear', 'offset'"):
        detrend(exp, "quadratic")  # type: ignore[arg-type]


@pytest.mark.parametrize("q", [2, 5, 10])
def test_decimate_keeps_low_removes_high(q: int) -> None:
    dt = 1e-3
    t = np.arange(20000) * dt
    f_new_nyq = 0.5 / (q * dt)
    f_low, f_high = 0.1 * f_new_nyq, 1.8 * f_new_nyq
    f_alias = 2 * f_new_nyq - f_high  # where f_high would fold to
    exp = Experiment.from_arrays(dt, y=np.sin(2 * np.pi * f_low * t))
    high = Experiment.from_arrays(dt, y=np.sin(2 * np.pi * f_high * t))
    d_low, d_high = decimate(exp, q), decimate(high, q)
    assert d_low.dt == pytest.approx(q * dt, rel=1e-15)  # one product, one rounding
    assert d_low.n_samples == 20000 // q
    inner = slice(20, -20)  # the FIR's 10q-sample half length at each edge
    td = d_low.time[inner]
    # Hamming-window FIR passband ripple is below 0.03 dB (0.4 %).
    assert _amplitude(d_low["y"][inner], td, f_low) == pytest.approx(1.0, abs=5e-3)
    # 20q+1-tap Hamming FIR: >= 52 dB down beyond 1.2x the new Nyquist, 10**(-52/20) = 2.5e-3;
    # unfiltered, the tone would fold to f_alias with amplitude 1.
    assert _amplitude(d_high["y"][inner], td, f_alias) < 2.6e-3


def test_decimate_keeps_offset_and_ramp_at_the_edges() -> None:
    k = np.arange(1000)
    exp = Experiment.from_arrays(1e-3, y=2.5 + 0.01 * k)
    out = decimate(exp, 5)
    # A symmetric unit-DC-gain FIR passes a line unchanged, and the line padding continues
    # it past the ends: only rounding of ~100 products of order 10 remains.
    np.testing.assert_allclose(out["y"], 2.5 + 0.01 * k[::5], rtol=1e-12)


def test_decimate_checks() -> None:
    exp = Experiment.from_arrays(0.01, y=np.ones(50))
    assert decimate(exp, 1) is exp
    with pytest.raises(DataError, match="integer >= 1"):
        decimate(exp, 0)
    with pytest.raises(DataError, match="needs at least 28 samples"):
        decimate(Experiment.from_arrays(0.01, y=np.ones(27)), 2, ftype="iir")
    assert decimate(Experiment.from_arrays(0.01, y=np.ones(28)), 2, ftype="iir").n_samples == 14


def test_zero_phase_has_no_lag_causal_does() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal(4000)
    exp = Experiment.from_arrays(1e-3, u=x)
    lags = sps.correlation_lags(x.size, x.size)

    def peak_lag(zero_phase: bool) -> int:
        out = lowpass(exp, 50.0, zero_phase=zero_phase)["u"]
        return int(lags[np.argmax(sps.correlate(out, x))])

    assert peak_lag(True) == 0
    # A causal 4th-order Butterworth at 50 Hz has its impulse-response peak ~5 ms late.
    assert 2 <= peak_lag(False) <= 10
    with pytest.raises(DataError, match=r"cutoff must lie in \(0, 500\) Hz"):
        lowpass(exp, 600.0)


def test_split_fraction_index_periods() -> None:
    exp = Experiment.from_arrays(0.1, y=np.arange(100.0), t0=1.0)
    est, val = split(exp)
    assert (est.n_samples, val.n_samples) == (50, 50)
    assert val.t0 == pytest.approx(1.0 + 50 * 0.1, abs=1e-14)  # one rounding of 50·dt
    est, val = split(exp, 0.3)
    assert (est.n_samples, val.n_samples) == (30, 70)
    est, val = split(exp, 40)
    assert val["y"][0] == 40.0
    est, val = split(exp, 0.55, period=20)  # 55 -> 40, rest cut to 3 whole periods
    assert (est.n_samples, val.n_samples) == (40, 60)
    with pytest.raises(DataError, match=r"fraction must lie in \(0, 1\)"):
        split(exp, 1.5)
    with pytest.raises(DataError, match="need at least 2"):
        split(exp, 0.5, period=80)
    with pytest.raises(TypeError, match="fraction"):
        split(exp, "half")  # type: ignore[arg-type]


def test_split_periods() -> None:
    exp = Experiment.from_arrays(0.1, y=np.arange(105.0))
    parts = split_periods(exp, 25, skip=1)
    assert [p.n_samples for p in parts] == [25, 25, 25]
    assert parts[0]["y"][0] == 25.0
    with pytest.raises(DataError, match="cannot skip 4"):
        split_periods(exp, 25, skip=4)
    with pytest.raises(DataError, match="skip must be >= 0"):
        split_periods(exp, 25, skip=-1)
