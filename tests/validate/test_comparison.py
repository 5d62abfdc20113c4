"""compare(models, data): a Comparison with a table, an HTML view and a plot."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid.data import Experiment
from servoid.estimate import fit_arx, fit_oe
from servoid.validate import Comparison, ValidationReport, compare


@pytest.fixture(scope="module")
def records():
    rng = np.random.default_rng(4)
    out = []
    for _ in range(2):
        u = rng.standard_normal(2000)
        y = lfilter([0.0, 0.2, 0.1], [1.0, -1.3, 0.5], u) + 0.05 * rng.standard_normal(2000)
        out.append(Experiment.from_arrays(0.01, u=u, y=y))
    return out


def test_compare_returns_a_comparison_ranked_by_fit(records):
    est, val = records
    models = {"arx1": fit_arx(est, 1, 1, 1), "oe2": fit_oe(est, 2, 2, 1)}
    result = compare(models, val)
    assert isinstance(result, Comparison) and isinstance(result, dict)
    assert list(result) == ["arx1", "oe2"] and isinstance(result["oe2"], ValidationReport)
    assert result.best == "oe2"  # the true structure beats a first-order ARX
    table = result.table
    assert table[0][0] == "oe2" and table[0][1] == "4" and table[1][1] == "2"
    assert "oe2" in str(result).splitlines()[1]
    html = result._repr_html_()
    assert "<table" in html and "oe2" in html


def test_compare_plots_the_overlay(records):
    import matplotlib.pyplot as plt

    est, val = records
    fig = compare({"oe2": fit_oe(est, 2, 2, 1)}, val).plot()
    try:
        assert len(fig.axes[0].lines) == 2  # measured and one model
    finally:
        plt.close(fig)
