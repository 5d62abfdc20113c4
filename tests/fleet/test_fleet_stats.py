"""Population statistics: robust control limits, robust z-scores, drift slope and its interval."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.fleet import control_limits, drift, robust_z


def test_control_limits_ignore_the_outliers_they_flag():
    gen = np.random.default_rng(1)
    x = gen.normal(10.0, 0.5, 200)
    clean = control_limits(x)
    x[:10] = 100.0  # 5 % gross outliers
    dirty = control_limits(x)
    # median and MAD move by far less than the plain mean ± 3 std would (mean +4.5, std ×40)
    assert abs(dirty.centre - clean.centre) < 0.1
    assert dirty.spread / clean.spread == pytest.approx(1.0, abs=0.15)
    assert clean.low == pytest.approx(10.0 - 1.5, abs=0.3)
    z = robust_z(x)
    assert np.all(np.abs(z[:10]) > 3.5)
    assert np.mean(np.abs(z[10:]) > 3.5) < 0.01


def test_robust_z_with_too_few_or_identical_values():
    assert np.isnan(robust_z([1.0, 2.0])).all()
    np.testing.assert_array_equal(robust_z([3.0, 3.0, 3.0, 3.0]), 0.0)
    z = robust_z([1.0, np.nan, 2.0, 3.0, 2.0])
    assert np.isnan(z[1]) and np.isfinite(z[[0, 2, 3, 4]]).all()


def test_drift_interval_covers_the_true_slope_95_percent():
    """200 seeds of a linear trend with unit scatter and known per-unit std: coverage ≈ 0.95.

    The binomial 99 % band for 200 trials at p = 0.95 is about 0.915..0.985.
    """
    t = np.arange(30.0)
    hits = 0
    for seed in range(200):
        gen = np.random.default_rng(seed)
        stds = gen.uniform(0.05, 0.2, t.size)
        y = 2.0 + 0.03 * t + gen.normal(0, 0.3, t.size) + gen.normal(0, stds)
        d = drift(t, y, stds, "day")
        hits += d.ci_low <= 0.03 <= d.ci_high
    assert 0.915 <= hits / 200 <= 0.985


def test_drift_without_trend_is_rarely_significant():
    t = np.arange(40.0)
    significant = sum(drift(t, np.random.default_rng(s).normal(0, 1, t.size)).significant
                      for s in range(200))
    assert significant / 200 < 0.09  # 5 % expected; 99 % binomial upper bound ≈ 0.09


def test_drift_needs_three_points_and_a_spread_axis():
    assert drift([1.0, 2.0], [1.0, 2.0]) is None
    assert drift([1.0, 1.0, 1.0], [1.0, 2.0, 3.0]) is None
