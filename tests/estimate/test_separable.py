"""Separable least squares: Type IV flow equation, joint covariance, flat profile, bad input."""

import warnings

import numpy as np
import pytest

from servoid import DataError, IdentifiabilityError, OptionError, ServoidWarning
from servoid.estimate import LeastSquaresResult, fit_separable

KAPPA = 1.4
PSI_MAX = (2 / (KAPPA + 1)) ** (1 / (KAPPA - 1)) * np.sqrt(KAPPA / (KAPPA + 1))
B_TRUE = 0.25
THETA = np.array([2.0, 0.5])
N = 800


def psi(ratio, b):
    """Ellipse flow function of spec §2 (local copy: the test owns its truth)."""
    r = np.clip(ratio, 0.0, 1.0)
    out = np.full_like(r, PSI_MAX)
    sub = r > b
    out[sub] = PSI_MAX * np.sqrt(1.0 - ((r[sub] - b) / (1.0 - b)) ** 2)
    return out


def record(seed, sigma=0.0, ratio_range=(0.02, 0.98), b=B_TRUE):
    rng = np.random.default_rng(seed)
    ratio = rng.uniform(*ratio_range, size=N)
    x = rng.normal(size=N)
    y = THETA[0] * psi(ratio, b) + THETA[1] * x + sigma * rng.normal(size=N)

    def build(beta):
        return np.column_stack([psi(ratio, beta), x]), y

    return build


def test_noise_free_flow_equation_recovers_b():
    est = fit_separable(
        record(0), (0.1, 0.6), grid=np.arange(0.10, 0.6001, 0.01), names=["a_d", "c"], beta_name="b"
    )
    assert est.names == ("b", "a_d", "c")
    # RSS is 0 at b and C¹ there; Brent's xatol 1e-8·0.5 bounds the error in b
    assert est["b"] == pytest.approx(B_TRUE, abs=1e-7)
    np.testing.assert_allclose(est.parameters[1:], THETA, rtol=1e-6)  # through b's error
    assert isinstance(est.model, LeastSquaresResult)
    assert est.options["covariance"].startswith("joint")
    assert est.method == "separable_ls"


def test_grid_alone_is_within_half_a_cell():
    est = fit_separable(record(0), (0.1, 0.6), grid=51, method="grid")
    assert abs(est["beta"] - B_TRUE) <= 0.005 + 1e-12  # spacing 0.01: half a cell


def test_golden_alone_on_a_unimodal_profile():
    est = fit_separable(record(0), (0.1, 0.6), method="golden")
    assert est["beta"] == pytest.approx(B_TRUE, abs=1e-6)  # xatol 5e-9, C¹ profile


def test_covariance_is_honest_and_matches_the_profile():
    sigma = 0.02
    for seed in range(4):
        est = fit_separable(record(10 + seed, sigma), (0.1, 0.6), beta_name="b")
        truth = np.concatenate([[B_TRUE], THETA])
        assert np.all(np.abs(est.parameters - truth) < 4 * est.std), seed  # 4σ
        # Gauss–Newton (joint J) and profile curvature agree to first order in the residual
        assert est.std[0] == pytest.approx(est.options["beta_std_profile"], rel=0.05)
        assert est.noise_variance == pytest.approx(sigma**2, rel=0.2)  # χ², N = 800: ±5 %·4


def test_flat_profile_is_refused():
    # every pressure ratio below the searched b: ψ_b = ψ_max throughout, b has no effect
    build = record(1, ratio_range=(0.01, 0.09))
    with pytest.raises(IdentifiabilityError, match=r"RSS\(b\) is flat"):
        fit_separable(build, (0.1, 0.6), beta_name="b")


def test_optimum_on_the_edge_warns():
    build = record(2, b=0.7)
    with pytest.warns(ServoidWarning, match="sits on an end of the search interval"):
        fit_separable(build, (0.1, 0.6))


def test_rows_that_depend_on_beta_give_a_block_diagonal_covariance():
    rng = np.random.default_rng(3)
    v = rng.uniform(-1, 1, size=N)
    y_all = 3.0 * v + np.sign(v) * 0.2 + 0.01 * rng.normal(size=N)

    def build(beta):
        keep = np.abs(v) >= beta  # a switching threshold: samples change with β
        x = np.abs(v[keep]) ** (1 + beta)  # and a smooth dependence too
        return np.column_stack([v[keep], np.sign(v[keep]), x]), y_all[keep]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        est = fit_separable(build, (0.1, 0.3), grid=21)
    assert est.options["covariance"].startswith("block diagonal")
    assert est.covariance[0, 1] == 0.0


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"bounds": (0.6, 0.1)}, DataError, "lower < upper"),
        ({"grid": 2}, DataError, "at least 3 points"),
        ({"grid": [0.1, 0.3, 0.2]}, DataError, "increasing points inside bounds"),
        ({"grid": [0.0, 0.3, 0.5]}, DataError, "inside bounds"),
        ({"method": "brent"}, OptionError, "method must be one of"),
        ({"names": ["only_one"]}, DataError, "names needs one entry per column"),
    ],
)
def test_bad_settings(kwargs, error, match):
    args = {"bounds": (0.1, 0.6)} | kwargs
    with pytest.raises(error, match=match):
        fit_separable(record(4), **args)


def test_bad_build():
    with pytest.raises(DataError, match="must return a tuple"):
        fit_separable(lambda b: np.zeros((10, 2)), (0.1, 0.6))
    with pytest.raises(DataError, match="non-finite"):
        fit_separable(lambda b: (np.full((10, 2), np.nan), np.zeros(10)), (0.1, 0.6))
