"""acceptance_numbers / judge: the numbers' intervals cover the truth at their stated rate.

The plant is the issue's case: ω_n = 2π·8 rad/s, ζ = 0.4, whose resonance is 2.696 dB at
6.597 Hz.  Records come from the virtual rig (continuous plant at 20× the logging rate, a
multisine played at that rate, the same anti-alias filter on input and output): the periodic
FRF's truth is the continuous G(jω), so the truth of each number is the continuous plant's.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid import OptionError
from servoid.bench import simulate_lti
from servoid.frequency import (
    SpecNumber,
    acceptance_numbers,
    estimate_bla,
    fit_ml,
    judge,
)
from servoid.models import TransferFunction, bandwidth, phase_lag, resonance_peak
from servoid.signals import plan_multisine, random_multisine

DT, OS = 0.01, 20
WN, ZETA = 2 * np.pi * 8.0, 0.4
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
PLAN = plan_multisine(DT / OS, 0.1, 30.0, period=256 * OS, lines="odd", periods=4,
                      transient_periods=1)
U_FAST = random_multisine(PLAN, rng=1).values


def _numbers(seed):
    exp = simulate_lti(PLANT, U_FAST, DT, intersample="fast", oversample=OS, anti_alias=40.0,
                       noise_std=0.05, rng=seed)
    fit = fit_ml(estimate_bla(exp, PLAN), 2, 0)
    return {n.name: n for n in acceptance_numbers(fit, phase_frequency=5.0)}


def test_the_issue_resonance_is_read_from_the_model_not_the_grid():
    peak = resonance_peak(PLANT)
    # closed form: 1/(2ζ√(1 − ζ²)) at ω_n√(1 − 2ζ²)
    assert peak.peak_db == pytest.approx(20 * math.log10(1 / (2 * ZETA * math.sqrt(1 - ZETA**2))),
                                         abs=1e-9)
    assert peak.frequency == pytest.approx(8.0 * math.sqrt(1 - 2 * ZETA**2), rel=1e-7)
    nums = _numbers(0)
    f, pk = nums["resonance_frequency"], nums["resonance_peak"]
    # within 4σ of the truth, σ a few hundredths of a Hz and of a dB with these 77 lines
    assert abs(f.value - peak.frequency) < 4 * f.std and f.std < 0.1
    assert abs(pk.value - peak.peak_db) < 4 * pk.std and pk.std < 0.1
    # the lines are 0.39 Hz apart: the highest line misses the peak by up to half of that
    assert abs(f.measured - peak.frequency) < 0.2


@pytest.fixture(scope="module")
def many():
    return [_numbers(100 + s) for s in range(100)]


@pytest.mark.parametrize("name", ["dc_gain", "bandwidth", "phase_lag", "resonance_frequency",
                                  "resonance_peak"])
def test_intervals_cover_the_truth_at_their_stated_rate(many, name):
    truth = {"dc_gain": 1.0, "bandwidth": bandwidth(PLANT), "phase_lag": phase_lag(PLANT, 5.0),
             "resonance_frequency": resonance_peak(PLANT).frequency,
             "resonance_peak": resonance_peak(PLANT).peak_db}[name]
    inside = [n[name].ci_low <= truth <= n[name].ci_high for n in many]
    # 95 % intervals over 100 records: binomial(100, 0.95) lies in 90..99 with 98.9 %; the
    # issue's 90–98 % (a delta-method interval of a smooth number of a 3-parameter model)
    assert 0.90 <= float(np.mean(inside)) <= 0.99, np.mean(inside)


def _num(name, lo, hi):
    return SpecNumber(name, name, (lo + hi) / 2, (hi - lo) / 4, lo, hi, "Hz")


@pytest.mark.parametrize("interval, limits, passed", [
    ((9.0, 11.0), {"bandwidth_min": 8.0}, True),
    ((9.0, 11.0), {"bandwidth_min": 10.0}, False),  # straddles: not shown to be inside
    ((9.0, 11.0), {"bandwidth_min": 12.0}, False),
    ((9.0, 11.0), {"bandwidth_min": 8.0, "bandwidth_max": 10.5}, False),
    ((9.0, 11.0), {"bandwidth_min": 8.0, "bandwidth_max": 12.0}, True),
    ((math.nan, math.nan), {"bandwidth_min": 8.0}, False),  # no interval fails
])
def test_judge_passes_only_an_interval_inside_the_limit(interval, limits, passed):
    (check,) = judge((_num("bandwidth", *interval),), limits)
    assert check.passed is passed and check.name == "bandwidth"


def test_judge_refuses_unknown_keys_and_fails_a_number_not_computed():
    with pytest.raises(OptionError, match="bandwith_min"):
        judge((), {"bandwith_min": 1.0})
    (check,) = judge((_num("bandwidth", 1, 2),), {"phase_lag_max": 30.0})
    assert not check.passed and "phase_frequency" in check.reason


def test_the_distortion_number_of_a_linear_plant_is_its_noise_level_at_most():
    plan = plan_multisine(DT, 0.2, 25.0, period=256, lines="random-odd", rng=2, realisations=4,
                          periods=2)
    u = random_multisine(plan, rng=3).values
    exp = simulate_lti(PLANT, u, DT, noise_std=0.05, rng=4)
    frm = estimate_bla(exp, plan)
    nums = {n.name: n for n in acceptance_numbers(fit_ml(frm, 2, 0))}
    d = nums["distortion"]
    # a linear plant: the detection lines hold the noise (or a level below it, by chance);
    # the interval runs from the number to its upper bound, both finite
    assert math.isfinite(d.ci_low) and d.ci_low <= d.value <= d.ci_high
    assert d.value <= frm.distortion.noise_db + 3.0  # no distortion above the noise
    (ok,) = judge((d,), {"distortion_max": d.ci_high + 1.0})
    (bad,) = judge((d,), {"distortion_max": d.value - 1.0})
    assert ok.passed and not bad.passed
