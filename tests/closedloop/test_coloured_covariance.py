"""Closed-loop IV and two-stage covariances on coloured noise in the loop.

fit_cliv solves ``θ̂ = (Σ ζφᵀ)⁻¹ Σ ζ y`` with instruments ζ built from the
reference, so its error is ``M⁻¹ Σ ζ(t) w(t)`` and its covariance the
sandwich ``M⁻¹ [Σ_τ r_w(τ) Σ_t ζ(t) ζ(t−τ)ᵀ] M⁻ᵀ`` (Söderström & Stoica,
*Instrumental Variable Methods*, 1983, §4.3), w the prefiltered equation
error.  The refined IV prefilters with an AR model of fixed order, which
whitens w when the noise has a short AR(∞) form and not otherwise; the
robust covariance (the default) estimates r_w itself and is the white
formula exactly when w looks white.  Records: :func:`servoid.bench.simulate_lti_loop`
(a continuous servo integrated exactly at 20× the logging rate under a PI
controller the estimators do not know, ARMA noise inside the loop).
"""

from __future__ import annotations

import numpy as np
import pytest

from servoid import OptionError
from servoid.bench import simulate_lti_loop
from servoid.closedloop import fit_cliv, fit_two_stage
from servoid.models import TransferFunction, c2d

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.4
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])  # a 2nd-order servo, 2 Hz
PI = TransferFunction([0.5 + 3.0 * DT, -0.5], [1.0, -1.0], DT)  # kp = 0.5, ki = 3 /s
TRUE = c2d(PLANT, DT, "zoh").to_polynomial("oe")
THETA_ARX = np.concatenate([TRUE.f[0][1:], TRUE.b[0]])  # a1, a2, b0, b1
THETA_OE = np.concatenate([TRUE.b[0], TRUE.f[0][1:]])  # b0, b1, f1, f2
ARMA = ([1.0, 0.5], [1.0, -0.9])  # (1 + 0.5q⁻¹)/(1 − 0.9q⁻¹) e: AR(∞) form decays as 0.5^k
# (1 − 0.9q⁻¹) e: its AR(∞) form decays as 0.9^k, which the AR(10) prefilter cannot follow
SLOW_ZERO = ([1.0, -0.9], [1.0])
N = 2000
# the four coefficients of a fit are correlated (a1/a2 and b0/b1 pairs), so 4 × 40 intervals
# are worth ~80 independent ones: the pooled coverage has sd ≈ √(0.05·0.95/80) = 2.4 %
SEEDS = 40
SLOW_SEEDS = 200


def record(seed: int, noise_model, n: int = N):
    g = np.random.default_rng(1000 + seed)
    r = np.repeat(np.sign(g.standard_normal(n // 2)), 2)
    return simulate_lti_loop(PLANT, PI, r, DT, noise_std=0.1, noise_model=noise_model, rng=seed)


def study(noise_model, seeds: int, **kw) -> dict[str, tuple[np.ndarray, np.ndarray, list]]:
    """z, 95 % interval hits and residual AR orders of fit_cliv, auto and white covariance."""
    out: dict[str, tuple[list, list, list]] = {"robust": ([], [], []), "white": ([], [], [])}
    for seed in range(seeds):
        exp = record(seed, noise_model)
        robust = fit_cliv(exp, 2, 2, 1, **kw)
        white = fit_cliv(exp, 2, 2, 1, covariance="white", **kw)
        assert robust.options["covariance"] == "robust"
        assert white.options["covariance"] == "white"
        np.testing.assert_array_equal(robust.parameters, white.parameters)
        for est, (z, inside, orders) in ((robust, out["robust"]), (white, out["white"])):
            z.append((est.parameters - THETA_ARX) / est.std)
            ci = est.confidence_intervals(0.95)
            inside.append((ci[:, 0] <= THETA_ARX) & (THETA_ARX <= ci[:, 1]))
            orders.append(est.options["covariance_ar_order"])
    return {k: (np.array(z), np.array(i), o) for k, (z, i, o) in out.items()}


def check_calibrated(z: np.ndarray, inside: np.ndarray) -> None:
    # P(|z| > 4) = 6.3e-5 per coefficient: 40 seeds × 4 coefficients expect 0.01 exceedances
    assert np.max(np.abs(z)) < 4.0, np.max(np.abs(z), axis=0)
    # the band; the pooled coverage has sd ≈ 2.4 % (see SEEDS): −2 … +1.7 sd
    assert 0.90 <= inside.mean() <= 0.99, inside.mean()


@pytest.fixture(scope="module")
def arma():
    return study(ARMA, SEEDS)


@pytest.fixture(scope="module")
def slow_zero():
    return study(SLOW_ZERO, SEEDS)


def test_cliv_robust_covariance_covers_on_arma_noise(arma):
    z, inside, _ = arma["robust"]
    check_calibrated(z, inside)
    # consistent (instruments from r): mean z within 4 standard errors 4/√40
    assert np.all(np.abs(z.mean(axis=0)) < 4 / np.sqrt(SEEDS)), z.mean(axis=0)


def test_cliv_prefilter_whitens_arma_noise_so_white_agrees(arma):
    # the refined IV's AR(10) prefilter whitens this noise: AIC mostly finds the prefiltered
    # residual white (p = 0 with probability ≈ 0.71, Shibata 1976: Binomial(40, 0.71) is
    # 28 ± 2.9, at least half is 2.9 sd below), where robust *is* white
    orders = np.array(arma["robust"][2])
    assert np.sum(orders == 0) >= SEEDS // 2, np.bincount(orders)
    z, inside, _ = arma["white"]
    check_calibrated(z, inside)


def test_cliv_white_covariance_misstates_noise_the_prefilter_cannot_whiten(slow_zero):
    z, inside, orders = slow_zero["robust"]
    check_calibrated(z, inside)
    # the prefiltered residual is still coloured, and AIC sees it on every record
    assert min(orders) >= 1, orders
    zw, inside_w, _ = slow_zero["white"]
    # the white formula overstates σ of a1 and a2 about ×2 (measured z spread 0.40–0.44): a
    # calibrated spread is 1 within 4/√(2·40) = 0.45, so < 0.55 is outside it
    assert np.all(zw.std(axis=0)[:2] < 0.55), zw.std(axis=0)
    assert inside_w.mean() > 0.99, inside_w.mean()  # measured 1.000: no interval misses
    # robust's spread is 1 within those 4 standard errors
    assert np.all(np.abs(z.std(axis=0) - 1) < 4 / np.sqrt(2 * SEEDS)), z.std(axis=0)


def test_basic_cliv_without_prefilter_uses_the_sandwich():
    # iterations=0: no prefilter at all; the equation error A·v is coloured, and the robust
    # covariance sees it (the white formula would assume it white)
    exp = record(3, ARMA)
    robust = fit_cliv(exp, 2, 2, 1, iterations=0)
    white = fit_cliv(exp, 2, 2, 1, iterations=0, covariance="white")
    assert robust.options["covariance"] == "robust"
    assert robust.options["covariance_ar_order"] >= 2  # A·v: far from white
    np.testing.assert_array_equal(robust.covariance, robust.covariance.T)
    assert np.linalg.eigvalsh(robust.covariance).min() > 0
    # the colour moves σ by more than rounding in every coefficient (measured ×0.8–1.2)
    assert np.all(np.abs(robust.std / white.std - 1) > 0.02), robust.std / white.std


def test_two_stage_covariance_counts_stage_1():
    exp = record(5, ARMA)
    est = fit_two_stage(exp, 2, 2, 1)
    assert est.options["covariance"].startswith("two-step sandwich: stage-1 FIR error counted")
    np.testing.assert_array_equal(est.covariance, est.covariance.T)
    assert np.linalg.eigvalsh(est.covariance).min() > 0
    assert np.all(np.abs((est.parameters - THETA_OE) / est.std) < 4)  # 4σ, one record


def test_unknown_covariance_lists_the_valid_ones():
    with pytest.raises(OptionError, match="covariance must be one of 'auto', 'white', 'robust'; "
                                          "got 'hac'"):
        fit_cliv(record(0, ARMA, 600), 2, 2, 1, covariance="hac")  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize("noise_model", [ARMA, SLOW_ZERO], ids=["arma", "slow-zero"])
def test_cliv_robust_covariance_covers_200_seeds(noise_model):
    results = study(noise_model, SLOW_SEEDS)
    z, inside, _ = results["robust"]
    assert np.max(np.abs(z)) < 4.0  # 200 × 4 coefficients expect 0.05 beyond 4σ
    # ~400 independent intervals: sd 1.1 %; 92–98 % is ±2.7 sd
    assert 0.92 <= inside.mean() <= 0.98, inside.mean()
    # the spread of z is 1 within 15 % (standard error 1/√400 = 5 %; the sandwich's own
    # finite-sample error takes the rest)
    assert np.all(np.abs(z.std(axis=0) - 1) < 0.15), z.std(axis=0)
