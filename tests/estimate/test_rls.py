"""Recursive least squares: spec P3 (= batch LS, tracking), covariance, windup guard, bad input."""

import warnings

import numpy as np
import pytest

from servoid import DataError, IdentifiabilityError, OptionError, ServoidWarning
from servoid.estimate import RecursiveLeastSquaresResult, fit_rls, lstsq

N = 4000
TRUE = np.array([2e-3, 4e2, 1.0])


def regressors(seed, n=N):
    # columns of very different size (1e3, 1e-3, 5): normalisation is what makes P₀ = p₀·I fair
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [1e3 * rng.normal(size=n), 1e-3 * (rng.normal(size=n) + 0.5), np.full(n, 5.0)]
    )


def test_spec_p3_final_rls_equals_batch_ls():
    rng = np.random.default_rng(0)
    phi = regressors(1)
    y = phi @ TRUE + 0.01 * rng.normal(size=N)
    rls = fit_rls(phi, y, forgetting=1.0, p0=1e8)
    batch = lstsq(phi, y)
    # prior I/p₀ against a unit-diagonal ΦᵀΦ: ~cond²/p₀ ≈ 1e-8, plus the recursion's rounding
    np.testing.assert_allclose(rls.theta, batch.theta, rtol=1e-6)
    np.testing.assert_allclose(rls.covariance, batch.covariance, rtol=1e-6)  # same formula
    assert rls.estimate.noise_variance == pytest.approx(batch.noise_variance, rel=1e-6)
    assert isinstance(rls, RecursiveLeastSquaresResult)
    assert rls.estimate.method == "rls" and rls.guard_events == 0


def test_without_normalisation_the_prior_is_visible():
    phi = regressors(1)
    y = phi @ TRUE
    raw = fit_rls(phi, y, normalise=False)
    # raw columns: the small one (norm ≈ 0.07) sees a prior of weight 1/p₀ against 5e-3;
    # so the raw run is worse than the normalised one, which is the point of normalising
    scaled = fit_rls(phi, y)
    err_raw = np.max(np.abs(raw.theta - TRUE) / TRUE)
    err_scaled = np.max(np.abs(scaled.theta - TRUE) / TRUE)
    assert err_scaled < 1e-7 < err_raw


@pytest.mark.parametrize("lam", [0.99, 0.995])
def test_tracks_a_parameter_step_with_memory_one_over_one_minus_lambda(lam):
    phi = regressors(2)
    after = TRUE * np.array([2.0, 1.0, 1.0])
    half = N // 2
    y = np.where(np.arange(N) < half, phi @ TRUE, phi @ after)
    res = fit_rls(phi, y, forgetting=lam, history=True)
    err = np.abs(res.history[:, 0] - after[0]) / (after[0] - TRUE[0])
    memory = 1.0 / (1.0 - lam)
    # weighted LS over white regressors: error ≈ λ^k = e^{−k(1−λ)}; a factor 2 for the
    # sample fluctuation of the weighted Gram matrix
    for k in (memory, 3 * memory):
        assert err[half + int(k)] < 2 * lam ** int(k)
    assert err[half + int(memory)] > 0.5 * lam ** int(memory)  # not faster either
    assert res.estimate.options["memory_samples"] == pytest.approx(memory)


def test_covariance_is_honest_over_seeds():
    sigma = 0.01
    phi = regressors(3)
    for seed in range(4):
        rng = np.random.default_rng(100 + seed)
        y = phi @ TRUE + sigma * rng.normal(size=N)
        est = fit_rls(phi, y).estimate
        assert np.all(np.abs(est.parameters - TRUE) < 4 * est.std)  # 4σ
        # σ̂² is χ²/(N − n): relative spread √(2/N) ≈ 2.2 %, 4σ ≈ 9 %
        assert est.noise_variance == pytest.approx(sigma**2, rel=0.09)


def test_residuals_and_history():
    phi = regressors(4, n=500)
    y = phi @ TRUE
    res = fit_rls(phi, y, history=True)
    assert res.history.shape == (500, 3) and res.trace_history.shape == (500,)
    np.testing.assert_array_equal(res.history[-1], res.theta)
    assert abs(res.prior_residuals[0]) == pytest.approx(abs(y[0]))  # θ₀ = 0
    # noise-free: after n samples the a posteriori errors vanish (to the prior's 1/p₀)
    assert np.max(np.abs(res.posterior_residuals[10:])) < 1e-6 * np.max(np.abs(y))
    assert np.all(np.diff(res.trace_history) <= 1e-9 * res.trace_history[:-1])  # λ = 1: P shrinks
    assert fit_rls(phi, y).history is None


def test_theta0_is_in_parameter_units():
    phi = regressors(5, n=300)
    res = fit_rls(phi, phi @ TRUE, theta0=TRUE, history=True)
    np.testing.assert_allclose(res.history[0], TRUE, rtol=1e-12)  # zero innovation: no move


def windup_record():
    # both columns excited for 500 samples, then only the first for 3000
    rng = np.random.default_rng(6)
    phi = rng.normal(size=(3500, 2))
    phi[500:, 1] = 0.0
    return phi, phi @ np.array([1.0, -2.0])


@pytest.mark.filterwarnings("ignore:rls. the final memory window")
def test_windup_guard_bounds_the_trace_and_warns():
    phi, y = windup_record()
    with pytest.warns(ServoidWarning, match="covariance guard"):
        res = fit_rls(phi, y, forgetting=0.95, p0=1e4, history=True)
    assert res.guard_events > 0
    assert np.max(res.trace_history) <= 2e4 * (1 + 1e-12)  # the cap p₀·n, rounding only
    np.testing.assert_allclose(res.theta, [1.0, -2.0], rtol=1e-6)  # noise-free: still exact


def test_without_guard_the_covariance_winds_up():
    phi, y = windup_record()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # the final window misses a column
        res = fit_rls(phi, y, forgetting=0.95, p0=1e4, guard="none", history=True)
    # P grows like λ^−k in the unexcited direction: 0.95^−3000 overflows any cap
    assert res.guard_events == 0 and np.max(res.trace_history) > 1e10


@pytest.mark.filterwarnings("ignore:rls. the final memory window")
def test_reset_guard():
    phi, y = windup_record()
    with pytest.warns(ServoidWarning, match="'reset'"):
        res = fit_rls(phi, y, forgetting=0.95, p0=1e4, guard="reset")
    assert res.guard_events > 0


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"forgetting": 0.0}, DataError, r"forgetting must lie in \(0, 1\]"),
        ({"forgetting": 1.01}, DataError, "forgetting must lie"),
        ({"p0": -1.0}, DataError, "p0 must be > 0"),
        ({"theta0": [1.0]}, DataError, "theta0 must be 3 finite values"),
        ({"guard": "clip"}, OptionError, "guard must be one of"),
        ({"names": ["a"]}, DataError, "names needs one entry per column"),
        ({"max_trace": 0.0}, DataError, "max_trace must be > 0"),
    ],
)
def test_bad_settings(kwargs, error, match):
    phi = regressors(7, n=100)
    with pytest.raises(error, match=match):
        fit_rls(phi, phi @ TRUE, **kwargs)


def test_bad_data():
    phi = regressors(8, n=100)
    with pytest.raises(DataError, match="need phi"):
        fit_rls(phi, np.zeros(99))
    with pytest.raises(DataError, match="more than 3 equations"):
        fit_rls(phi[:3], np.zeros(3))
    bad = phi.copy()
    bad[5, 0] = np.nan
    with pytest.raises(DataError, match="finite"):
        fit_rls(bad, np.zeros(100))
    zero = phi.copy()
    zero[:, 1] = 0.0
    with pytest.raises(IdentifiabilityError, match="regressor b is identically zero"):
        fit_rls(zero, np.zeros(100), names=["a", "b", "c"])
    twin = phi.copy()
    twin[:, 2] = 2 * twin[:, 0]
    with pytest.raises(IdentifiabilityError, match="rank deficient"):
        fit_rls(twin, np.zeros(100))
