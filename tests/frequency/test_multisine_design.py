"""plan_multisine / random_multisine / the plan file: lines, plan arithmetic, crest factor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import DataError, FileFormatError
from servoid.signals import crest_factor, plan_multisine, random_multisine, read_plan


def test_odd_plan_excites_the_odd_harmonics_and_leaves_the_even_as_detection():
    plan = plan_multisine(1e-3, 1.0, 100.0, resolution=1.0, lines="odd", realisations=4,
                          periods=2)
    assert plan.period == 1000 and plan.resolution == pytest.approx(1.0)
    assert plan.excited == tuple(range(1, 100, 2))
    assert plan.detection_odd == () and plan.detection_even == tuple(range(2, 99, 2))
    # 4 realisations × (1 transient + 2 measured) periods of 1000 samples
    assert plan.n_samples == 12000 and plan.duration == pytest.approx(12.0)


def test_random_odd_leaves_one_odd_line_per_group():
    plan = plan_multisine(1e-3, 1.0, 200.0, period=1000, lines="random-odd", group=4, rng=3)
    odd = np.arange(1, 200, 2)
    # 100 odd lines in 25 groups of 4: one of each group is a detection line
    assert len(plan.detection_odd) == 25 and len(plan.excited) == 75
    groups = np.searchsorted(odd, plan.detection_odd) // 4
    np.testing.assert_array_equal(groups, np.arange(25))
    assert all(k % 2 == 1 for k in plan.excited)


def test_log_grid_spaces_lines_per_decade():
    plan = plan_multisine(1e-3, 1.0, 100.0, period=1000, lines="full", grid="log", per_decade=10)
    ratios = np.diff(np.log10(plan.frequencies))
    # 2 decades at 10 per decade, rounded to whole harmonics: 20 steps at most, none repeated
    assert 15 <= ratios.size <= 21 and np.all(ratios > 0)
    assert plan.band == pytest.approx((1.0, 100.0))


def test_test_time_and_settling_time_fill_the_realisations():
    # period 0.5 s; settling 0.7 s → 2 transient periods; 4 periods each → 10 s holds 5
    plan = plan_multisine(1e-3, 2.0, 50.0, resolution=2.0, lines="full", settling_time=0.7,
                          periods=2, test_time=10.0)
    assert plan.transient_periods == 2 and plan.realisations == 5
    assert plan.duration <= 10.0
    with pytest.raises(DataError, match="test_time"):
        plan_multisine(1e-3, 2.0, 50.0, resolution=2.0, lines="full", settling_time=0.7,
                       test_time=1.0)


def test_multisine_spectrum_is_flat_on_the_excited_lines_and_empty_elsewhere():
    plan = plan_multisine(1e-3, 1.0, 100.0, period=1000, lines="random-odd", rng=0,
                          realisations=3, periods=2)
    x = random_multisine(plan, rng=1)
    assert x.n_samples == plan.n_samples
    for m in range(3):
        one = x.values[plan.realisation_start(m) + plan.period:][:plan.period]
        spec = np.abs(np.fft.rfft(one))
        exc = np.asarray(plan.excited)
        # flat amplitude on the excited lines, zero elsewhere, to FFT round-off
        assert np.ptp(spec[exc]) < 1e-9 * spec[exc].max()
        rest = np.setdiff1d(np.arange(spec.size), exc)
        assert spec[rest].max() < 1e-9 * spec[exc].max()
    # periodic within a realisation, different phases between realisations
    a, b = (x.values[plan.realisation_start(m):][:2 * plan.period] for m in (0, 1))
    np.testing.assert_allclose(a[:1000], a[1000:], atol=1e-12)  # exact repetition
    assert not np.allclose(a, b)


def test_clipping_lowers_the_crest_factor_and_keeps_the_amplitude_spectrum():
    plan = plan_multisine(1e-3, 1.0, 200.0, period=2000, lines="odd", realisations=2)
    plain = random_multisine(plan, rng=5)
    low = random_multisine(plan, rng=5, crest="clip", crest_iterations=100)
    assert max(low.description["crest_factors"]) < 0.8 * min(plain.description["crest_factors"])
    # random phases give ≈ 3-4; clipping reaches < 2 on 100 lines (Van der Ouderaa et al.)
    assert max(low.description["crest_factors"]) < 2.0
    spec = np.abs(np.fft.rfft(low.values[plan.period:2 * plan.period]))
    exc = np.asarray(plan.excited)
    assert np.ptp(spec[exc]) < 1e-9 * spec[exc].max()  # amplitudes restored exactly
    assert crest_factor(low.values[:plan.period]) == pytest.approx(
        low.description["crest_factors"][0], rel=1e-9)


def test_plan_file_round_trips_and_refuses_other_json(tmp_path):
    plan = plan_multisine(1e-3, 1.0, 100.0, period=1000, lines="random-odd", rng=2,
                          realisations=3)
    path = plan.write(tmp_path / "ms.plan.json")
    again = read_plan(path)
    assert again == plan and again.detection == plan.detection
    (tmp_path / "other.json").write_text(json.dumps({"format": "x"}))
    with pytest.raises(FileFormatError, match="not a servoid multisine plan"):
        read_plan(tmp_path / "other.json")


@pytest.mark.parametrize("kwargs, match", [
    ({"f_max": 600.0}, "Nyquist"),
    ({"f_min": 80.0, "f_max": 50.0}, "f_min must be <="),
    ({"period": 1000, "resolution": 1.0}, "exactly one of period and resolution"),
    ({"lines": "even"}, "lines"),
    ({"lines": "random-odd"}, "rng"),
])
def test_bad_plans_are_refused(kwargs, match):
    args = {"f_min": 1.0, "f_max": 100.0, "period": 1000, "lines": "odd", **kwargs}
    with pytest.raises(Exception, match=match) as info:
        plan_multisine(1e-3, args.pop("f_min"), args.pop("f_max"), **args)
    from servoid import ServoidError

    assert isinstance(info.value, ServoidError)
