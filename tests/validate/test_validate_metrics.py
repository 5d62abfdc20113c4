"""Fit metrics: known answers and shape checks."""

import numpy as np
import pytest

from servoid import DataError
from servoid.validate import fit_percent, nrmse, relative_error, rmse, vaf

Y = np.sin(np.linspace(0.0, 6.0, 200)) + 0.3


def test_perfect_model_and_mean_model():
    assert fit_percent(Y, Y) == 100.0
    assert nrmse(Y, Y) == 0.0 and rmse(Y, Y) == 0.0 and vaf(Y, Y) == 100.0
    mean = np.full_like(Y, Y.mean())
    # ‖y − ȳ‖/‖y − ȳ‖ = 1 up to rounding
    assert fit_percent(Y, mean) == pytest.approx(0.0, abs=1e-12)
    assert nrmse(Y, mean) == pytest.approx(1.0, rel=1e-12)  # same
    assert vaf(Y, mean) == pytest.approx(0.0, abs=1e-12)  # var(y − ȳ) = var(y), rounding only


def test_closed_forms():
    # an offset: RMSE is the offset, VAF ignores it (variance of a constant error is 0)
    assert rmse(Y, Y + 0.5) == pytest.approx(0.5, rel=1e-12)  # rounding only
    assert vaf(Y, Y + 0.5) == pytest.approx(100.0, rel=1e-12)  # rounding only
    spread = np.linalg.norm(Y - Y.mean())
    # ‖0.5·1‖ = 0.5·√N; rounding only
    assert fit_percent(Y, Y + 0.5) == pytest.approx(
        100 * (1 - 0.5 * np.sqrt(Y.size) / spread), rel=1e-12
    )
    # a scaled model ŷ = 0.9 y: relative error 10 %, VAF 100·(1 − 0.01) = 99 %
    assert relative_error(Y, 0.9 * Y) == pytest.approx(10.0, rel=1e-12)  # rounding only
    assert vaf(Y, 0.9 * Y) == pytest.approx(99.0, rel=1e-12)  # rounding only
    assert nrmse(Y, 0.9 * Y) == pytest.approx(0.1 * np.linalg.norm(Y) / spread, rel=1e-12)  # same


def test_per_column():
    y = np.column_stack([Y, 2 * Y])
    got = fit_percent(y, np.column_stack([Y, 2 * Y.mean() * np.ones_like(Y)]))
    assert isinstance(got, np.ndarray) and got.shape == (2,)
    np.testing.assert_allclose(got, [100.0, 0.0], atol=1e-12)  # rounding only
    np.testing.assert_allclose(rmse(y, y + [0.1, 0.2]), [0.1, 0.2], rtol=1e-12)  # rounding only


@pytest.mark.parametrize("metric", [fit_percent, nrmse, rmse, vaf, relative_error])
def test_shape_mismatch_raises(metric):
    with pytest.raises(DataError, match=r"differ in shape: \(200,\) vs \(199,\)"):
        metric(Y, Y[:-1])


def test_too_few_samples():
    with pytest.raises(DataError, match="at least 2 samples, got 1"):
        rmse([1.0], [1.0])
