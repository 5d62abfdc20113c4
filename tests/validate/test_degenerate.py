"""Degenerate validation inputs: NaN never passes as white, constants warn."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import DataError, ServoidWarning
from servoid.validate import fit_percent, relative_error, residual_analysis, vaf


def test_nan_residuals_are_an_error_not_white():
    e = np.tile([1.0, np.nan], 50)
    with pytest.raises(DataError, match="non-finite.*whiteness test would be meaningless"):
        residual_analysis(e, u=np.ones(100))


def test_nan_input_for_cross_correlation():
    with pytest.raises(DataError, match="input .* non-finite"):
        residual_analysis(np.random.default_rng(0).standard_normal(100),
                          u=np.r_[np.nan, np.ones(99)])


def test_diverged_model_output_is_an_error():
    with pytest.raises(DataError, match="diverged"):
        fit_percent(np.arange(10.0), np.r_[np.arange(9.0), np.inf])


@pytest.mark.parametrize("metric", [fit_percent, vaf])
def test_constant_measured_output_warns(metric):
    with pytest.warns(ServoidWarning, match="constant measured output"):
        metric(np.ones(10), np.ones(10))


def test_zero_output_relative_error_warns():
    with pytest.warns(ServoidWarning, match="all-zero"):
        relative_error(np.zeros(10), np.ones(10))
