"""fit_arx under white equation noise: covariance, confidence intervals, σ̂² (200 seeded runs).

The truth is ARX(2, 2, 1), ``A y = B u + e`` (y = B/A u + e/A), white Gaussian u and e.
Least squares is then consistent and √N(θ̂ − θ) is asymptotically Gaussian with the
covariance σ²(ΦᵀΦ/N)⁻¹ that ``fit_arx`` reports, so each standardised error
z = (θ̂ − θ)/σ̂_θ is ≈ N(0, 1) (Ljung, *System Identification*, 2nd ed., §9.2).
"""

import numpy as np
import pytest
from scipy import stats

from servoid import Experiment
from servoid.estimate import fit_arx
from servoid.models import PolynomialModel

DT = 1e-3
A = np.array([1.0, -1.5, 0.7])
B = np.array([1.0, 0.5])
TRUE = np.concatenate([A[1:], B])
SIGMA = 0.2
N = 2000
RUNS = 200


def _runs():
    plant = PolynomialModel.arx(A, B, 1, DT)
    noise = PolynomialModel.arx(A, [1.0], 0, DT)
    z, inside95, var_ratio = [], [], []
    for seed in range(RUNS):
        rng = np.random.default_rng(1000 + seed)
        u = rng.normal(size=N)
        e = SIGMA * rng.normal(size=N)
        exp = Experiment.from_arrays(DT, u=u, y=plant.simulate(u) + noise.simulate(e))
        est = fit_arx(exp, 2, 2, 1)
        z.append((est.parameters - TRUE) / est.std)
        ci = est.confidence_intervals(0.95)
        inside95.append((ci[:, 0] <= TRUE) & (TRUE <= ci[:, 1]))
        var_ratio.append(est.noise_variance / SIGMA**2)
    return np.array(z), np.array(inside95), np.array(var_ratio), est.n_samples


@pytest.fixture(scope="module")
def runs():
    return _runs()


def test_errors_within_4_sigma_in_every_run(runs):
    z, *_ = runs
    # P(|z| > 4) = 6.3e-5 per coefficient ⇒ 200 runs × 4 coefficients expect 0.05 exceedances
    assert np.max(np.abs(z)) < 4.0
    # the standardised errors are ≈ N(0, 1): their spread is 1 within 4 s.e. (s.e. ≈ 1/√(2·200) = 0.05)
    assert np.all(np.abs(z.std(axis=0) - 1.0) < 4 * 0.05)
    # and their mean is 0 within 4 s.e. (s.e. = 1/√200 = 0.071)
    assert np.all(np.abs(z.mean(axis=0)) < 4 / np.sqrt(RUNS))


def test_95_percent_intervals_cover_the_truth(runs):
    _, inside, *_ = runs
    coverage = inside.mean(axis=0)
    # Binomial(200, 0.95): mean 190, sd 3.1; 90–99 % (180…198) is −3.2 sd … +2.6 sd,
    # P(outside) ≈ 1e-3 per coefficient
    assert np.all((0.90 <= coverage) & (coverage <= 0.99)), coverage


def test_noise_variance_estimate(runs):
    *_, ratio, n_eq = runs
    rel_sd = np.sqrt(2.0 / (n_eq - 4))  # σ̂²/σ² ~ χ²(N − n)/(N − n): relative sd √(2/(N − n))
    # 4 sd per run: P = 6.3e-5 each, 200 runs expect 0.013 exceedances
    assert np.max(np.abs(ratio - 1.0)) < 4 * rel_sd
    # the mean of 200 runs is unbiased within 4 standard errors
    assert abs(ratio.mean() - 1.0) < 4 * rel_sd / np.sqrt(RUNS)


def test_confidence_interval_width_uses_student_t():
    # a single run: the 95 % half-width is t_{0.975}(N − n)·σ̂_θ (here ≈ 1.961)
    rng = np.random.default_rng(1)
    u = rng.normal(size=N)
    y = PolynomialModel.arx(A, B, 1, DT).simulate(u) + rng.normal(size=N)
    est = fit_arx(Experiment.from_arrays(DT, u=u, y=y), 2, 2, 1)
    half = np.diff(est.confidence_intervals(0.95), axis=1)[:, 0] / 2
    t = stats.t.ppf(0.975, est.n_samples - 4)
    np.testing.assert_allclose(half, t * est.std, rtol=1e-12)  # same arithmetic, rounding only
