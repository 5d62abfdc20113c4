"""The LTI virtual rig: exact sampling, anti-alias lag, noise colour, closed loop."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sps

from servoid import DataError, ModelError
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.models import TransferFunction, c2d

DT = 0.01
WN, ZETA = 2 * np.pi * 5, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])


def _prbs_like(n: int, seed: int = 0) -> np.ndarray:
    return np.sign(np.random.default_rng(seed).standard_normal(n))


def test_zoh_record_equals_the_exact_sampled_plant():
    u = _prbs_like(2000)
    exp = simulate_lti(PLANT, u, DT, rng=1)
    # the fast rate integrates exactly, so only rounding separates it from c2d(zoh): ε·n_steps
    assert np.max(np.abs(exp["y"] - c2d(PLANT, DT, "zoh").simulate(u))) < 1e-10
    assert exp.names == ("u", "y") and exp.notes["seed"] == "1"


def test_fast_input_samples_a_smooth_signal():
    t_fast = np.arange(500 * 20) * DT / 20
    u_fast = np.sin(2 * np.pi * 1.0 * t_fast)
    exp = simulate_lti(PLANT, u_fast, DT, intersample="fast")
    assert exp.n_samples == 500
    np.testing.assert_allclose(exp["u"], u_fast[::20])
    # steady state of a 1 Hz sine through the plant: gain |G(j2π)|; 2 % covers the fast FOH step
    g = abs(PLANT.freqresp([2 * np.pi])[0])
    assert abs(np.max(np.abs(exp["y"][300:])) / g - 1) < 0.02


def test_a_filtered_fast_input_is_logged_as_applied_not_as_the_plant_delays_it():
    t_fast = np.arange(500 * 20) * DT / 20
    u_fast = np.sin(2 * np.pi * 1.0 * t_fast)
    delayed = TransferFunction(PLANT.num, PLANT.den, delay=5 * DT)
    with_delay = simulate_lti(delayed, u_fast, DT, intersample="fast", anti_alias=20.0)
    without = simulate_lti(PLANT, u_fast, DT, intersample="fast", anti_alias=20.0)
    # the rig logs the input it applies: the plant's delay shows in y only (same filter, same u)
    np.testing.assert_array_equal(with_delay["u"], without["u"])
    lag = np.argmax(sps.correlate(with_delay["y"], without["y"], "full")) - (500 - 1)
    assert lag == 5


def test_anti_alias_filter_adds_its_lag():
    u = _prbs_like(3000)
    plain = simulate_lti(PLANT, u, DT)
    filtered = simulate_lti(PLANT, u, DT, anti_alias=10.0)
    lag = np.argmax(sps.correlate(filtered["y"], plain["y"], "full")) - (u.size - 1)
    # a 4th-order Butterworth at 10 Hz delays by about 2.6/(2π·10) s ≈ 4 samples
    assert 2 <= lag <= 6


def test_noise_has_the_requested_colour():
    u = np.zeros(20000)
    exp = simulate_lti(PLANT, u, DT, noise_std=0.1, noise_model=([1.0], [1.0, -0.9]), rng=3)
    v = exp["y"]
    # AR(1) with pole 0.9: variance σ²/(1 − 0.81), lag-1 correlation 0.9 (5 % for N = 2e4)
    assert abs(v.var() / (0.01 / 0.19) - 1) < 0.1
    assert abs(np.corrcoef(v[1:], v[:-1])[0, 1] - 0.9) < 0.02


def test_closed_loop_without_noise_matches_the_discrete_loop():
    r = _prbs_like(1500)
    ctl = TransferFunction([0.4, -0.3], [1.0, -1.0], dt=DT)
    exp = simulate_lti_loop(PLANT, ctl, r, DT)
    g = c2d(PLANT, DT, "zoh")
    loop = (ctl * g).feedback(1.0)
    # rounding of two different realisations over 1500 steps
    assert np.max(np.abs(exp["y"] - loop.simulate(r))) < 1e-8
    assert exp.names == ("r", "u", "y")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"plant": TransferFunction([1.0], [1.0, -0.5], dt=DT)}, ModelError, "continuous"),
        ({"dt": -1.0}, DataError, "dt must be > 0"),
        ({"anti_alias": 60.0}, DataError, "Nyquist"),
        ({"noise_model": ([2.0], [1.0])}, ModelError, "monic"),
        ({"noise_std": -1.0}, DataError, "noise_std"),
    ],
)
def test_bad_input(kwargs, error, match):
    args = {"plant": PLANT, "u": np.ones(50), "dt": DT, **kwargs}
    with pytest.raises(error, match=match):
        simulate_lti(args.pop("plant"), args.pop("u"), args.pop("dt"), **args)


def test_a_plant_delay_reaches_the_record():
    import dataclasses

    u = _prbs_like(800, 4)
    delayed = dataclasses.replace(PLANT, delay=0.025)  # 2.5 samples: 50 fast steps
    exp = simulate_lti(delayed, u, DT)
    # the exact ZOH map of a fractional delay (modified z-transform): rounding only
    assert np.max(np.abs(exp["y"] - c2d(delayed, DT, "zoh").simulate(u))) < 1e-10
    ctl = TransferFunction([0.3], [1.0], dt=DT)  # a proportional controller: a static gain
    whole = dataclasses.replace(PLANT, delay=0.02)
    loop = (ctl * c2d(whole, DT, "zoh")).feedback(1.0)
    assert np.max(np.abs(simulate_lti_loop(whole, ctl, u, DT)["y"] - loop.simulate(u))) < 1e-9
    with pytest.raises(DataError, match="whole steps of dt"):
        simulate_lti_loop(delayed, ctl, u, DT)
