"""residual_analysis: whiteness and independence tests, bands, rejection rates."""

import json

import numpy as np
import pytest
from scipy import signal as sps
from scipy import stats

from servoid import DataError
from servoid.signals import prbs
from servoid.validate import residual_analysis

N = 2000
RUNS = 200
# Binomial(200, 0.01): mean 2; P(X ≥ 9) ≈ 2e-4, so ≤ 8 rejections is the 1 % band
MAX_REJECTIONS = 8


def test_white_gaussian_noise_is_white_in_about_99_percent_of_runs():
    p = np.array(
        [
            residual_analysis(np.random.default_rng(seed).normal(size=N)).whiteness_pvalue
            for seed in range(RUNS)
        ]
    )
    assert np.sum(p <= 0.01) <= MAX_REJECTIONS
    # under the null the p-values are uniform; KS at 1e-3 fails a correct test once in 1000
    assert stats.kstest(p, "uniform").pvalue > 1e-3


@pytest.mark.parametrize(
    "u",
    [
        pytest.param(np.random.default_rng(12345).normal(size=N), id="white input"),
        pytest.param(prbs(11, clock=10, periods=1).values[:N], id="PRBS held 10 samples"),
        pytest.param(np.random.default_rng(54321).normal(size=(N, 2)), id="two inputs"),
    ],
)
def test_independent_noise_is_independent_in_about_99_percent_of_runs(u):
    # the null holds (ε white, independent of u); a coloured input must not inflate the
    # false-alarm rate (N·Σr² ~ χ²(2M+1) alone rejects ~15 % of runs for the PRBS)
    results = [residual_analysis(np.random.default_rng(s).normal(size=N), u) for s in range(RUNS)]
    assert sum(not r.is_independent for r in results) <= MAX_REJECTIONS
    # uniform p-values under the null: neither liberal nor conservative (KS at 1e-3)
    p = np.array([r.independence_pvalue for r in results])
    assert stats.kstest(p, "uniform").pvalue > 1e-3


def test_ar1_residual_is_not_white():
    e = sps.lfilter([1.0], [1.0, -0.5], np.random.default_rng(1).normal(size=N))
    res = residual_analysis(e)
    # r(1) ≈ 0.5 ≫ the band 2.58/√N = 0.058: Q ≈ N·(0.25 + 0.0625 + …) ≈ 670 vs χ²₀.₉₉(25) = 44
    assert not res.is_white
    assert res.whiteness_pvalue < 1e-10
    assert res.autocorrelation[1] == pytest.approx(0.5, abs=4 * 0.866 / np.sqrt(N))  # 4 sd of r̂(1)
    assert res.fraction_outside > 0


def test_residual_with_a_delayed_input_is_not_independent():
    rng = np.random.default_rng(2)
    u = rng.normal(size=N)
    e = 0.3 * np.concatenate([np.zeros(3), u[:-3]]) + rng.normal(size=N)
    res = residual_analysis(e, u)
    assert res.is_white  # the delayed input part is white too
    assert not res.is_independent
    # r_εu peaks at lag +3 (input leads the residual): 0.3/√1.09 ≈ 0.29 ≫ 2.58/√N
    peak = res.cross_lags[np.argmax(np.abs(res.cross_correlation[0]))]
    assert peak == 3
    assert res.cross_correlation.shape == (1, 2 * 25 + 1)


@pytest.mark.parametrize(("confidence", "z"), [(0.99, 2.5758293035489), (0.95, 1.959963984540054)])
def test_bound(confidence, z):
    res = residual_analysis(np.random.default_rng(3).normal(size=N), confidence=confidence)
    assert res.bound == pytest.approx(z / np.sqrt(N), rel=1e-12)  # normal quantile, rounding only
    if confidence == 0.99:
        assert res.bound == pytest.approx(2.58 / np.sqrt(N), rel=2e-3)  # 2.58 is 2.5758 to 3 digits


def test_layout_and_json():
    rng = np.random.default_rng(4)
    res = residual_analysis(rng.normal(size=500), rng.normal(size=500), max_lag=10)
    np.testing.assert_array_equal(res.lags, np.arange(11))
    np.testing.assert_array_equal(res.cross_lags, np.arange(-10, 11))
    assert res.autocorrelation[0] == pytest.approx(1.0, rel=1e-12)  # normalised, rounding only
    d = json.loads(json.dumps(res.to_dict()))
    assert d["n_samples"] == 500 and isinstance(d["is_white"], bool)
    assert (
        json.loads(json.dumps(residual_analysis(rng.normal(size=500)).to_dict()))[
            "independence_pvalue"
        ]
        is None
    )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"max_lag": 0}, r"max_lag must lie in \[1, 49\] for 100 residuals, got 0"),
        ({"max_lag": 50}, r"max_lag must lie in \[1, 49\] for 100 residuals, got 50"),
        ({"confidence": 1.0}, r"confidence must lie in \(0, 1\), got 1.0"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(DataError, match=match):
        residual_analysis(np.random.default_rng(5).normal(size=100), **kwargs)


def test_coloured_independent_residuals_are_not_called_correlated():
    # an output-error model leaves the noise colour in its residuals; independent of the input
    # they must still pass (the null covariance includes their own correlation, Ljung eq. 16.69)
    u = prbs(11, clock=10, periods=1).values[:N]
    results = [residual_analysis(sps.lfilter([1.0], [1.0, -0.8],
                                             np.random.default_rng(s).normal(size=N)), u)
               for s in range(RUNS)]
    assert all(not r.is_white for r in results)  # AR(0.8): the switch to the coloured null is on
    # the truncated, Bartlett-weighted covariance is approximate: allow twice the white band
    assert sum(not r.is_independent for r in results) <= 2 * MAX_REJECTIONS
    p = np.array([r.independence_pvalue for r in results])
    assert 0.35 < np.mean(p) < 0.65  # uniform p-values have mean 1/2; ±0.15 is > 7 sd for 200


def test_coloured_residuals_with_an_input_leak_are_still_caught():
    rng = np.random.default_rng(9)
    u = rng.normal(size=N)
    e = sps.lfilter([1.0], [1.0, -0.8], rng.normal(size=N)) + 0.5 * np.roll(u, 2)
    assert not residual_analysis(e, u).is_independent
