"""The residual figure draws the band the independence test uses."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps
from scipy import stats

from servoid.data import Experiment
from servoid.models import TransferFunction
from servoid.report import plot_residuals
from servoid.signals import prbs
from servoid.validate import validate
from servoid.validate._figures import _cross_bands

DT = 1e-3


def _report(coloured: bool, closed_loop: bool = False):
    u = prbs(10, clock=10, amplitude=1.0, dt=DT).values  # a slow input: ρ_u(1) = 0.9
    model = TransferFunction([0.1], [1.0, -0.9], dt=DT)
    rng = np.random.default_rng(4)
    e = rng.standard_normal(u.size) * 0.05
    if coloured:
        e = sps.lfilter([1.0], [1.0, -0.9], e)  # AR(1) output noise: an OE model keeps it
    y = model.simulate(u) + e
    exp = Experiment.from_arrays(DT, u=u, y=y)
    return validate(model, exp, initial="zero", closed_loop=closed_loop), u


def test_white_residuals_give_the_z_over_root_n_band():
    report, u = _report(coloured=False)
    assert report.residuals.is_white
    bands, how = _cross_bands(report, u, 1)
    n = u.size
    # Σ x(s − τ)²/‖x‖² = 1 − (the τ samples shifted out): within M/N of 1
    np.testing.assert_allclose(bands[0], report.residuals.bound, rtol=25 / n * 2)
    assert "independence test" in how and "colour" not in how


def test_coloured_residuals_widen_the_band_as_the_test_does():
    report, u = _report(coloured=True)
    res = report.residuals
    assert not res.is_white
    bands, how = _cross_bands(report, u, 1)
    # AR(1) noise with a = 0.9 and an input with ρ_u(k) ≈ 0.9^… : Σ ρ_ε ρ_u ≫ 1, so the band the
    # test uses is several times ±z/√N
    assert np.all(bands[0] > 2.0 * res.bound)
    assert "widened for the residuals' colour" in how
    # the same variance the test builds: with it, a lag at the band edge is a 1 % event
    z = stats.norm.ppf(0.5 + res.confidence / 2)
    assert bands[0][0] / z * np.sqrt(res.n_samples) > 2.0


def test_without_the_input_the_band_says_so():
    report, _ = _report(coloured=True)
    bands, how = _cross_bands(report, None, 1)
    assert np.all(bands[0] == report.residuals.bound) and "white-residual approximation" in how


def test_causal_test_leaves_negative_lags_untested(tmp_path):
    report, u = _report(coloured=False, closed_loop=True)
    assert report.residuals.causal
    plot_residuals(report, tmp_path / "res.png", u=u)
    assert (tmp_path / "res.png").stat().st_size > 0
    with pytest.raises(ValueError, match="inputs but the report"):
        _cross_bands(report, np.column_stack([u, u]), 1)
