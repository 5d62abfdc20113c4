"""frequency_band: the delta-method band agrees with the scatter over seeds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import DataError, Experiment, ModelError
from servoid.estimate import Estimate, fit_arx, frequency_band
from servoid.models import PolynomialModel

DT = 0.01
TRUE = PolynomialModel.arx([1.0, -1.5, 0.7], [0.0, 1.0, 0.5], 0, DT)
F = np.array([0.5, 2.0, 8.0, 20.0])


def _fit(seed: int) -> Estimate:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(1000)
    y = TRUE.simulate(u) + lfilter([1.0], TRUE.a, 0.2 * rng.standard_normal(1000))  # ARX noise
    return fit_arx(Experiment.from_arrays(DT, u=u, y=y), 2, 3, 0)


def test_band_matches_the_scatter_over_seeds():
    fits = [_fit(s) for s in range(60)]
    mags = np.array([frequency_band(f, F).magnitude_db for f in fits])
    phases = np.array([frequency_band(f, F).phase_deg for f in fits])
    band = frequency_band(fits[0], F)
    # 60 seeds: the sample std of a Gaussian is within ±25 % of σ at about 3 standard errors
    np.testing.assert_allclose(band.magnitude_std_db / mags.std(axis=0), 1.0, atol=0.3)
    np.testing.assert_allclose(band.phase_std_deg / phases.std(axis=0), 1.0, atol=0.3)
    g = TRUE.transfer_function().freqresp(2 * np.pi * F)
    assert np.allclose(band.response, fits[0].model.transfer_function().freqresp(2 * np.pi * F))
    assert np.all(np.abs(mags.mean(axis=0) - 20 * np.log10(np.abs(g))) < 4 * mags.std(axis=0))


def test_band_needs_a_model_function_and_positive_frequencies():
    est = _fit(0)
    bare = Estimate(est.model, est.parameters, est.names, est.covariance, 1.0, 10, "x")
    with pytest.raises(ModelError, match="does not say how its model depends"):
        frequency_band(bare, F)
    with pytest.raises(DataError, match="> 0 Hz"):
        frequency_band(est, [0.0, 1.0])


def test_arx_model_function_round_trips():
    rng = np.random.default_rng(5)
    u = rng.standard_normal((500, 2))
    two = PolynomialModel.arx([1.0, -0.5], [[1.0, 0.2], [0.3, 0.0, -0.1]], [1, 2], DT)
    exp = Experiment.from_arrays(DT, u=u, y=two.simulate(u) + 0.01 * rng.standard_normal(500))
    est = fit_arx(exp, 1, [2, 3], [1, 2])
    again = est.model_at(est.parameters)
    np.testing.assert_array_equal(again.a, est.model.a)
    for b_again, b in zip(again.b, est.model.b, strict=True):
        np.testing.assert_array_equal(b_again, b)
    assert again.nk == est.model.nk
