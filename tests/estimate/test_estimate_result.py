"""The Estimate returned by fit_arx: intervals, table, dict, access, immutability."""

import json

import numpy as np
import pytest
from scipy import stats

from servoid import Experiment
from servoid.estimate import Estimate, ParameterRow, fit_arx
from servoid.models import PolynomialModel

DT = 1e-3


@pytest.fixture(scope="module")
def est():
    rng = np.random.default_rng(0)
    u = rng.normal(size=300)
    y = PolynomialModel.arx([1.0, -0.8], [0.5, 0.2], 1, DT).simulate(u) + 0.1 * rng.normal(size=300)
    return fit_arx(Experiment.from_arrays(DT, u=u, y=y), 1, 2, 1)


@pytest.mark.parametrize("level", [0.5, 0.9, 0.95, 0.99])
def test_confidence_intervals_use_student_t(est, level):
    ci = est.confidence_intervals(level)
    assert ci.shape == (3, 2)
    assert est.dof == 300 - 2 - 3
    half = stats.t.ppf((1 + level) / 2, df=est.dof) * np.sqrt(np.diag(est.covariance))
    np.testing.assert_allclose(ci[:, 0], est.parameters - half, rtol=1e-12)  # same arithmetic
    np.testing.assert_allclose(ci[:, 1], est.parameters + half, rtol=1e-12)  # same arithmetic
    # with 295 dof the t quantile exceeds the normal one (heavier tails)
    assert stats.t.ppf((1 + level) / 2, est.dof) > stats.norm.ppf((1 + level) / 2)


@pytest.mark.parametrize("level", [0.0, 1.0, 1.5])
def test_confidence_level_outside_the_unit_interval(est, level):
    with pytest.raises(ValueError, match=r"level must lie in \(0, 1\)"):
        est.confidence_intervals(level)


def test_table_rows(est):
    rows = est.table(0.9)
    ci = est.confidence_intervals(0.9)
    assert [r.name for r in rows] == ["a1", "b0", "b1"]
    for row, value, std, (lo, hi) in zip(rows, est.parameters, est.std, ci, strict=True):
        assert isinstance(row, ParameterRow)
        assert (row.value, row.std, row.ci_low, row.ci_high, row.unit) == (value, std, lo, hi, "")


def test_to_dict_is_json_serialisable(est):
    d = json.loads(json.dumps(est.to_dict()))
    assert d["method"] == "arx" and d["n_samples"] == 298 and d["confidence_level"] == 0.95
    assert [p["name"] for p in d["parameters"]] == ["a1", "b0", "b1"]
    assert (
        d["options"]["na"] == 1 and d["options"]["nb"] == [2] and d["options"]["solver"] == "gram"
    )
    assert "a1" in str(est) and "σ̂²" in str(est)


def test_access_by_name(est):
    assert est["a1"] == est.parameters[0]
    assert est["b1"] == est.parameters[2]
    with pytest.raises(KeyError, match="no parameter 'a2'; parameters are a1, b0, b1"):
        est["a2"]


def test_arrays_are_read_only(est):
    with pytest.raises(ValueError, match="read-only"):
        est.parameters[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        est.covariance[0, 0] = 1.0
    with pytest.raises(AttributeError):
        est.noise_variance = 1.0
    with pytest.raises(ValueError, match="read-only"):
        est.residuals[0] = 1.0
    with pytest.raises(TypeError):
        est.options["na"] = 5


def test_estimate_copies_its_inputs():
    theta = np.array([1.0, 2.0])
    e = Estimate(None, theta, ("p", "q"), np.eye(2), 0.1, 10, "test")
    theta[0] = 5.0
    assert e.parameters[0] == 1.0
    assert e.units == ("", "") and e.residuals.size == 0
    np.testing.assert_array_equal(e.std, [1.0, 1.0])
