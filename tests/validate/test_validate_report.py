"""simulate_from_data, validate() and the ValidationReport."""

import json

import numpy as np
import pytest

from servoid import DataError, Experiment, OptionError
from servoid.estimate import fit_arx
from servoid.models import PolynomialModel, TransferFunction
from servoid.validate import ValidationReport, simulate_from_data, validate

DT = 1e-3
A = np.array([1.0, -1.5, 0.7])
B = np.array([1.0, 0.5])
MODEL = PolynomialModel.arx(A, B, 2, DT)  # longest lag: nk + nb − 1 = 3


def mid_record(n=800, seed=0, model=MODEL):
    """A noise-free window from the middle of a longer run: it does not start at rest."""
    u = np.random.default_rng(seed).normal(size=n + 500)
    y = model.simulate(u)
    return u[500:], y[500:]


def test_measured_initial_conditions_remove_the_transient():
    u, y = mid_record()
    y_sim, first = simulate_from_data(MODEL, y, u)
    assert first == 3
    np.testing.assert_array_equal(y_sim[:first], y[:first])  # copied, by definition
    # same difference equation from exact initial conditions: rounding only (|y| ~ 5)
    np.testing.assert_allclose(y_sim[first:], y[first:], rtol=0, atol=1e-12)
    # from rest instead, the start-up transient of the poles |z| = 0.84 lasts ~100 samples
    y_rest = MODEL.simulate(u)
    assert np.max(np.abs(y_rest[first:50] - y[first:50])) > 1e-2


def test_two_input_and_fir_models():
    rng = np.random.default_rng(1)
    u = rng.normal(size=(600, 2))
    two = PolynomialModel.arx(A, [B, [0.3, -0.2, 0.1]], [1, 2], DT)
    y = two.simulate(np.vstack([rng.normal(size=(300, 2)), u]))[300:]
    y_sim, first = simulate_from_data(two, y, u)
    assert first == 4  # nk + nb − 1 of the second input
    np.testing.assert_allclose(y_sim[first:], y[first:], atol=1e-12)  # exact ICs, rounding only
    fir = PolynomialModel.arx([1.0], [0.5, 0.25], 1, DT)
    y_fir = fir.simulate(u[:, 0])
    y_sim, first = simulate_from_data(fir, y_fir, u[:, 0])
    assert first == 2
    np.testing.assert_allclose(y_sim[first:], y_fir[first:], atol=1e-15)  # two products per sample


def test_non_arx_models_start_from_rest():
    tf = TransferFunction([0.5], [1.0, -0.5], DT)
    u = np.random.default_rng(2).normal(size=100)
    y_sim, first = simulate_from_data(tf, tf.simulate(u), u)
    assert first == 0
    np.testing.assert_allclose(y_sim, tf.simulate(u), rtol=1e-12)  # the same simulation


def test_validate_noise_free_data():
    u, y = mid_record(seed=3)
    exp = Experiment.from_arrays(DT, u=u, y=y, name="bench 7")
    report = validate(MODEL, exp)
    assert isinstance(report, ValidationReport)
    # exact model, exact initial conditions: the error is rounding, ~1e-14 of ‖y − ȳ‖
    assert report.fit_percent == pytest.approx(100.0, abs=1e-9)
    assert report.vaf == pytest.approx(100.0, abs=1e-9)  # same rounding
    assert report.rmse < 1e-12 and report.relative_error < 1e-9  # same rounding
    # the 5-step predictor of an ARX model is an FIR in y and u reaching back k − 1 + 3 samples:
    # scored from there on it is exact too, rounding only
    assert report.prediction_fit_percent == pytest.approx(100.0, abs=1e-9)
    assert report.first == 3 and report.horizon == 5 and report.experiment == "bench 7"
    assert report.prediction_first == 3 + 5 - 1
    assert report.residuals.n_samples == u.size - 3


def test_validate_an_estimated_model_on_fresh_data():
    u_e, y_e = mid_record(seed=4)
    est = fit_arx(Experiment.from_arrays(DT, u=u_e, y=y_e), 2, 2, 2)
    u_v, y_v = mid_record(seed=5)
    report = validate(est.model, Experiment.from_arrays(DT, u=u_v, y=y_v))
    # the estimate equals the truth to ~1e-12, so does its simulation
    assert report.fit_percent == pytest.approx(100.0, abs=1e-6)
    assert report.prediction_fit_percent == pytest.approx(100.0, abs=1e-6)  # same as the fit


def test_dt_mismatch_raises():
    u, y = mid_record()
    with pytest.raises(DataError, match=r"the model has dt = 0.001 s but the experiment 0.002 s"):
        validate(MODEL, Experiment.from_arrays(2e-3, u=u, y=y))
    # a fast rig: 1 µs vs 1.01 µs differs by 1 %, far beyond the 1e-9 relative tolerance
    fast = PolynomialModel.arx(A, B, 2, 1e-6)
    with pytest.raises(DataError, match="the model has dt = 1e-06 s"):
        validate(fast, Experiment.from_arrays(1.01e-6, u=u, y=y))


def test_bad_options():
    u, y = mid_record(n=200)
    exp = Experiment.from_arrays(DT, u=u, y=y)
    with pytest.raises(DataError, match="horizon must be >= 1 sample, got 0"):
        validate(MODEL, exp, horizon=0)
    with pytest.raises(OptionError, match="input must be one of 'u', 'r'; got 'x'"):
        validate(MODEL, exp, input="x")
    two_y = Experiment.from_arrays(DT, u=u, y=np.column_stack([y, y]))
    with pytest.raises(DataError, match=r"several outputs \(y0, y1\): pass output="):
        validate(MODEL, two_y)
    assert validate(MODEL, two_y, output="y1").output == "y1"


def test_summary_is_json_serialisable():
    rng = np.random.default_rng(6)
    u, y = mid_record(seed=6)
    exp = Experiment.from_arrays(DT, u=u, y=y + 0.1 * rng.normal(size=y.size))
    report = validate(MODEL, exp, max_lag=10)
    summary = json.loads(json.dumps(report.summary()))
    assert summary["n_samples"] == u.size - 3 and summary["prediction_horizon"] == 5
    assert set(summary) >= {"fit_percent", "nrmse", "rmse", "vaf", "relative_error_percent"}
    assert len(summary["residuals"]["autocorrelation"]) == 11
    assert summary["fit_percent"] == pytest.approx(report.fit_percent, rel=1e-15)  # a copy
    text = str(report)
    assert "fit" in text and ("white" in text)
