"""The feedback test: residuals against future inputs (Ljung §16.6, Sims 1972)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import stats

from servoid import DataError, IdentifiabilityError, ModelError, OptionTypeError, ServoidWarning
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.closedloop import FeedbackTest, feedback_test, warn_if_feedback
from servoid.data import Experiment, ExperimentSet
from servoid.datasets import load_daisy
from servoid.estimate import fit_oe
from servoid.models import TransferFunction

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.4
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
PI = TransferFunction([0.5 + 3.0 * DT, -0.5], [1.0, -1.0], DT)  # kp = 0.5, ki = 3 /s, backward
NOISE = ([1.0, 0.3], [1.0, -0.9])  # coloured: (1 + 0.3 q⁻¹)/(1 − 0.9 q⁻¹)
N = 2000
SEEDS = range(24)


def _binary(n: int, seed: int, clock: int = 2) -> np.ndarray:
    return np.repeat(np.sign(np.random.default_rng(seed).standard_normal(n // clock)), clock)


def closed(seed: int, n: int = N) -> Experiment:
    return simulate_lti_loop(PLANT, PI, _binary(n, 1000 + seed), DT, noise_std=0.1,
                             noise_model=NOISE, rng=seed)


def open_(seed: int, n: int = N) -> Experiment:
    return simulate_lti(PLANT, _binary(n, 2000 + seed), DT, noise_std=0.1, noise_model=NOISE,
                        rng=seed)


@pytest.fixture(scope="module")
def pvalues() -> dict[str, np.ndarray]:
    return {
        "closed": np.array([feedback_test(closed(s)).pvalue for s in SEEDS]),
        "open": np.array([feedback_test(open_(s)).pvalue for s in SEEDS]),
    }


def test_fires_on_every_closed_loop_record(pvalues):
    # the noise reaches u through the PI controller; measured p <= 1e-4 on these seeds
    assert np.all(pvalues["closed"] < 0.01)


def test_false_alarm_rate_matches_the_level(pvalues):
    p = pvalues["open"]
    # without feedback p is uniform: the count below α is Binomial(24, α)
    assert np.sum(p < 0.01) <= 2  # P(≥ 3) = 0.002 at α = 1 %
    assert np.sum(p < 0.10) <= 7  # P(≥ 8) = 0.004 at α = 10 %
    # the mean of 24 uniform p-values has sd 0.059: 0.2 is 3.4 sd
    assert abs(p.mean() - 0.5) < 0.2


def test_fires_on_the_real_ball_and_beam_record():
    # the DaISy ball and beam ran under an undocumented controller (open-loop unstable plant)
    test = feedback_test(load_daisy("ballbeam"))
    assert test.has_feedback
    assert test.pvalue < 0.01
    assert "closed loop" in test.message and "fit_bj" in test.message


def test_quiet_on_the_real_open_loop_dryer_record():
    test = feedback_test(load_daisy("dryer"))
    assert not test.has_feedback
    assert test.pvalue > 0.1  # measured 0.54
    assert "no evidence of feedback" in test.message


def test_residuals_of_a_given_model():
    # an OE model leaves coloured residuals; the ARX part of the test regression whitens them
    exp_open, exp_closed = open_(3, 4000), closed(3, 4000)
    quiet = feedback_test(exp_open, model=fit_oe(exp_open, 2, 2, 1))
    loud = feedback_test(exp_closed, model=fit_oe(exp_closed, 2, 2, 1).model)
    assert quiet.residuals == "model" and not quiet.has_feedback
    assert loud.has_feedback


def test_result_fields_and_band():
    test = feedback_test(closed(0), max_lag=10, confidence=0.95)
    assert isinstance(test, FeedbackTest)
    np.testing.assert_array_equal(test.lags, np.arange(1, 11))
    assert test.cross_correlation.shape == (10,)
    assert test.bound == pytest.approx(stats.norm.ppf(0.975) / np.sqrt(test.n_samples))
    assert test.dof[0] == 10 and test.level == pytest.approx(0.05)
    assert 0.0 <= test.fraction_outside <= 1.0
    assert test.input == "u" and test.output == "y" and test.residuals == "arx"
    assert json.loads(json.dumps(test.to_dict()))["has_feedback"] is True
    with pytest.raises(AttributeError):
        test.pvalue = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        test.cross_correlation[0] = 1.0


def test_given_order_and_segments():
    exp = closed(1)
    fixed = feedback_test(exp, order=4)
    assert fixed.order == 4 and fixed.has_feedback
    halves = ExperimentSet((exp.slice(0, N // 2), exp.slice(N // 2, None)))
    assert feedback_test(halves).has_feedback


def test_warn_if_feedback_names_the_method():
    with pytest.warns(ServoidWarning, match="oe is an open-loop method, but feedback detected"):
        warn_if_feedback(closed(2), "oe")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)
        assert not warn_if_feedback(open_(2), "oe").has_feedback


def test_a_noiseless_sine_leaves_nothing_to_test():
    # u(t + 1) = 2cos(ω)u(t) − u(t − 1): the future input is its own past
    t = np.arange(1000)
    u = np.sin(2 * np.pi * t / 50)
    exp = Experiment.from_arrays(DT, u=u, y=np.roll(u, 1) + 0.01 * np.cos(0.3 * t))
    with pytest.raises(IdentifiabilityError, match="random or noisy input"):
        feedback_test(exp)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"max_lag": 0}, DataError, "max_lag must be >= 1"),
        ({"max_lag": 400}, DataError, "smaller max_lag"),
        ({"confidence": 1.5}, DataError, r"confidence must lie in \(0, 1\)"),
        ({"input": "valve"}, Exception, "no channel named 'valve'"),
        ({"model": "arx"}, OptionTypeError, "model must be a PolynomialModel"),
        ({"model": TransferFunction([1.0], [1.0, -0.5], 0.1)}, ModelError, "dt = 0.1 s"),
        ({"model": TransferFunction([1.0], [1.0, 2.0])}, ModelError, "c2d"),
    ],
)
def test_bad_arguments_name_the_fix(kwargs, error, match):
    exp = closed(0, 600)
    with pytest.raises(error, match=match):
        feedback_test(exp, **kwargs)


def test_bad_records_name_the_fix():
    with pytest.raises(DataError, match="no plant input"):
        feedback_test(Experiment.from_arrays(DT, r=np.ones(500), y=np.arange(500.0)))
    flat = Experiment.from_arrays(DT, u=np.ones(500), y=np.random.default_rng(0).normal(size=500))
    with pytest.raises(IdentifiabilityError, match="not persistently exciting"):
        feedback_test(flat)
