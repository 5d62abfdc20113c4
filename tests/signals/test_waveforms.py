"""Multisine, chirp, steps and random binary signals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps
from scipy.signal import hilbert

from servoid.signals import (
    chirp,
    crest_factor,
    multisine,
    power_spectrum,
    random_binary,
    steps,
)

# -- multisine ------------------------------------------------------------------------------


@pytest.mark.parametrize("harmonics", ["all", "odd", "log"])
@pytest.mark.parametrize("phases", ["schroeder", "zero", "random"])
def test_multisine_power_only_on_chosen_lines(harmonics: str, phases: str) -> None:
    period, dt = 2000, 1e-3  # line spacing 0.5 Hz
    x = multisine(
        period, dt, 2.0, 80.0, amplitude=0.3, offset=1.0, periods=3,
        phases=phases, harmonics=harmonics, rng=7,
    )  # fmt: skip
    s = power_spectrum(x)
    lines = np.array(x.description["harmonics"])
    assert lines.min() >= 4 and lines.max() <= 160  # 2 Hz and 80 Hz are lines 4 and 160
    if harmonics == "odd":
        assert np.all(lines % 2 == 1)
    if harmonics == "log":
        assert 16 <= lines.size <= 21  # ~10 per decade over 1.6 decades, low ones merge
    other = np.ones(s.power.size, dtype=bool)
    other[lines] = False
    other[0] = False
    on = s.power[lines]
    np.testing.assert_allclose(on, on[0], rtol=1e-9)  # equal amplitudes: FFT rounding
    assert on.sum() == pytest.approx(x.description["rms"] ** 2, rel=1e-9)  # Parseval
    assert np.all(s.power[other] < 1e-12 * on[0])  # exactly periodic: rounding only
    assert s.power[0] == pytest.approx(1.0, rel=1e-12)  # DC line is offset²
    assert x.band == pytest.approx((lines[0] * 0.5, lines[-1] * 0.5), rel=1e-12)  # one product


def test_multisine_peak_scaling_and_rms_scaling() -> None:
    x = multisine(1024, 1e-3, 2.0, 200.0, amplitude=2.5, offset=-1.0)
    assert np.max(np.abs(x.values - x.offset)) == pytest.approx(2.5, rel=1e-12)  # one scaling
    assert x.amplitude == pytest.approx(2.5, rel=1e-12)  # one scaling
    y = multisine(1024, 1e-3, 2.0, 200.0, amplitude=0.5, scale="rms")
    assert np.sqrt(np.mean(y.values**2)) == pytest.approx(0.5, rel=1e-12)  # one scaling
    assert y.amplitude == pytest.approx(np.max(np.abs(y.values)), rel=1e-15)  # one product


def test_multisine_schroeder_phases_follow_the_formula() -> None:
    x = multisine(1000, 1e-3, 10.0, 30.0)
    k_count = len(x.description["harmonics"])
    index = np.arange(1, k_count + 1)
    expected = -np.pi * index * (index - 1) / k_count
    np.testing.assert_array_equal(x.description["phases"], expected)  # same float formula


@pytest.mark.parametrize("n_lines", [20, 50, 200])
def test_schroeder_crest_factor_far_below_zero_phase(n_lines: int) -> None:
    # Zero phases line every cosine up at t = 0: peak K, RMS sqrt(K/2), crest sqrt(2K).
    # Schroeder's quadratic phase makes the instantaneous frequency sweep the band once
    # per period like a chirp, so the envelope is nearly constant and the crest factor
    # stays near a single sine's sqrt(2), independent of K.
    period, dt = 4096, 1e-3
    f_max = n_lines / (period * dt)
    zero = crest_factor(multisine(period, dt, 0.0, f_max, phases="zero"))
    schroeder = crest_factor(multisine(period, dt, 0.0, f_max, phases="schroeder"))
    assert zero == pytest.approx(np.sqrt(2 * n_lines), rel=1e-9)  # closed form, FFT rounding
    assert schroeder < 2.0  # Schroeder (1970) reports about 1.6-1.7 for flat spectra
    assert schroeder < 0.45 * zero  # "markedly": sqrt(2·20) = 6.3 gives 0.32 at the least


def test_multisine_random_phases_reproducible() -> None:
    a = multisine(512, 1e-2, 0.5, 20.0, phases="random", rng=3)
    b = multisine(512, 1e-2, 0.5, 20.0, phases="random", rng=np.random.default_rng(3))
    c = multisine(512, 1e-2, 0.5, 20.0, phases="random", rng=4)
    assert np.array_equal(a.values, b.values)
    assert not np.array_equal(a.values, c.values)
    assert a.description["rng"] == 3 and b.description["rng"] == "Generator"


def test_multisine_periods_repeat_exactly() -> None:
    x = multisine(300, 1e-3, 5.0, 100.0, periods=4)
    assert x.n_samples == 1200 and x.period == 300
    parts = x.values.reshape(4, 300)
    assert np.all(parts == parts[0])


# -- chirp ----------------------------------------------------------------------------------


def _instantaneous_frequency(x: np.ndarray, dt: float) -> np.ndarray:
    phase = np.unwrap(np.angle(hilbert(x)))
    return np.diff(phase) / (2 * np.pi * dt)


@pytest.mark.parametrize("method", ["linear", "logarithmic"])
def test_chirp_instantaneous_frequency_endpoints(method: str) -> None:
    f0, f1, dt = 2.0, 40.0, 1e-3
    x = chirp(dt=dt, f0=f0, f1=f1, duration=20.0, amplitude=2.0, offset=1.0, method=method)
    sweep = x.description["sweep_time"]
    assert sweep == pytest.approx((x.n_samples - 1) * dt, rel=1e-15)  # one product
    inst = _instantaneous_frequency(x.values - x.offset, dt)
    mid = x.time[:-1] + dt / 2
    keep = slice(inst.size // 10, 9 * inst.size // 10)  # Hilbert edge effects at the ends
    if method == "linear":
        fit = np.polyfit(mid[keep], inst[keep], 1)
        ends = np.polyval(fit, [0.0, sweep])
    else:
        fit = np.polyfit(mid[keep], np.log(inst[keep]), 1)
        ends = np.exp(np.polyval(fit, [0.0, sweep]))
    # the fit over 16 000 samples averages the Hilbert ripple (about 1.5% pointwise)
    np.testing.assert_allclose(ends, [f0, f1], rtol=5e-3)


@pytest.mark.parametrize("method", ["linear", "logarithmic"])
def test_chirp_matches_scipy(method: str) -> None:
    f0, f1, dt, n = 1.0, 25.0, 2e-3, 3001
    x = chirp(dt=dt, f0=f0, f1=f1, n_samples=n, amplitude=0.5, offset=0.1, method=method)
    reference = sps.chirp(x.time, f0, (n - 1) * dt, f1, method=method, phi=-90.0)
    np.testing.assert_allclose(x.values, 0.1 + 0.5 * reference, atol=1e-9)  # phase ~1e3 rad
    assert x.values[0] == 0.1  # sin(0): starts at the operating point, no jump
    assert x.band == (1.0, 25.0) and x.period is None


def test_chirp_down_sweep_and_duration_rounding() -> None:
    x = chirp(dt=1e-3, f0=50.0, f1=5.0, duration=2.0004)
    assert x.n_samples == 2000
    assert x.band == (5.0, 50.0)


# -- steps ----------------------------------------------------------------------------------


def _runs(values: np.ndarray) -> tuple[list[float], list[int]]:
    edges = np.flatnonzero(np.diff(values)) + 1
    starts = np.concatenate([[0], edges])
    lengths = np.diff(np.concatenate([starts, [values.size]]))
    return values[starts].tolist(), lengths.tolist()


def test_steps_staircase_lengths() -> None:
    x = steps([0.0, 0.5, 1.0, 1.5], hold_samples=[10, 20, 30, 40], dt=0.01)
    assert _runs(x.values) == ([0.0, 0.5, 1.0, 1.5], [10, 20, 30, 40])
    assert x.n_samples == 100
    assert x.duration == pytest.approx(1.0, rel=1e-15)  # one product
    assert (x.offset, x.amplitude) == (0.75, 0.75)
    assert x.band == pytest.approx((1.0, 5.0), rel=1e-12)  # 1/duration, 1/(2·10·dt)


def test_steps_up_down_mirror() -> None:
    x = steps([0.0, 1.0, 2.0], hold_samples=[5, 6, 7], mirror=True)
    assert _runs(x.values) == ([0.0, 1.0, 2.0, 1.0, 0.0], [5, 6, 7, 6, 5])
    assert x.description["levels"] == (0.0, 1.0, 2.0, 1.0, 0.0)


def test_steps_single_hold_for_all_levels() -> None:
    x = steps([3.0, -3.0], hold_samples=4)
    assert x.values.tolist() == [3.0] * 4 + [-3.0] * 4


# -- random binary --------------------------------------------------------------------------


def test_random_binary_levels_clock_and_reproducibility() -> None:
    x = random_binary(1001, clock=4, amplitude=0.2, offset=5.0, dt=1e-3, rng=11)
    assert x.n_samples == 1001 and x.period is None and x.clock == 4
    assert set(np.unique(x.values)) == {4.8, 5.2}
    held = x.values[:1000].reshape(-1, 4)
    assert np.all(held == held[:, :1])  # held for exactly `clock` samples
    assert np.array_equal(x.values, random_binary(1001, 4, 0.2, 5.0, 1e-3, rng=11).values)


def test_random_binary_is_roughly_balanced() -> None:
    x = random_binary(40_000, rng=np.random.default_rng(2))
    assert abs(x.values.mean()) < 4 / 200  # 4σ: the mean of 40 000 fair ±1 coins has σ 1/200


def test_multisine_warns_when_f_min_is_off_the_grid():
    from servoid import ServoidWarning
    from servoid.signals import multisine

    with pytest.warns(ServoidWarning, match=r"lowest excited line is 1 Hz, not f_min = 0.1 Hz.*period of 10000 samples"):
        multisine(1000, 0.001, 0.1, 10.0)


def test_multisine_warns_on_a_single_line():
    from servoid import ServoidWarning
    from servoid.signals import multisine

    with pytest.warns(ServoidWarning, match="only 1 line"):
        multisine(1000, 0.001, 2.5, 3.5)
