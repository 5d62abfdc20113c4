"""Output error on coloured noise: the robust covariance covers, the white one does not.

An OE model fitted to y = G u + v with coloured v (independent of u) is
consistent, but its prediction errors are coloured, so σ̂²(ΨᵀΨ)⁻¹ is not
its covariance; the sandwich (ΨᵀΨ)⁻¹ Ψᵀ R_v Ψ (ΨᵀΨ)⁻¹ is (Ljung, *System
Identification*, 2nd ed., §9.3).  The records come from
:func:`servoid.bench.simulate_lti` — a continuous plant integrated exactly at
20× the logging rate with a held input, plus ARMA noise C/D·e at the logging
rate — so the true coefficients are those of ``c2d(plant, dt, "zoh")`` and
the generator shares no code with the estimator.
"""

import numpy as np
import pytest
import scipy.signal as sps
from scipy import linalg

from servoid import ExperimentSet, OptionError
from servoid.bench import simulate_lti
from servoid.estimate import fit_armax, fit_bj, fit_oe, fit_pem
from servoid.models import TransferFunction, c2d

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
G = c2d(PLANT, DT, "zoh")
B, F = np.asarray(G.num), np.asarray(G.den)  # num has 2 terms, den 3: nk = 1
TRUTH = np.concatenate([B, F[1:]])
# strongly coloured: a pole at 0.9 (low-frequency drift, where the plant's gain is) and a zero
COLOURED = (np.array([1.0, 0.5]), np.array([1.0, -0.9]))
SIGMA = 0.05
N = 2000
# b0/b1 (and f1/f2) of one record are strongly correlated, so 4 coefficients are worth about 2
# independent draws: 80 seeds make the pooled coverage's sd ≈ √(0.05·0.95/160) = 1.7 %
SEEDS = 80
SLOW_SEEDS = 200


def record(seed, noise_model):
    u = np.sign(np.random.default_rng(10_000 + seed).standard_normal(N))
    return simulate_lti(PLANT, u, DT, noise_std=SIGMA, noise_model=noise_model, rng=seed)


def study(seeds, noise_model):
    """Standardised errors and 95 % coverage under the robust (auto) and white covariance."""
    out = {"robust": ([], []), "white": ([], [])}
    orders = []
    for seed in range(seeds):
        exp = record(seed, noise_model)
        robust = fit_oe(exp, 2, 2, 1)
        white = fit_oe(exp, 2, 2, 1, covariance="white")
        assert robust.options["converged"] and robust.options["covariance"] == "robust"
        assert white.options["covariance"] == "white"
        # the covariance is computed after the search: the estimate itself is the same
        np.testing.assert_array_equal(robust.parameters, white.parameters)
        orders.append(robust.options["covariance_ar_order"])
        for est, (z, inside) in ((robust, out["robust"]), (white, out["white"])):
            z.append((est.parameters - TRUTH) / est.std)
            ci = est.confidence_intervals(0.95)
            inside.append((ci[:, 0] <= TRUTH) & (TRUTH <= ci[:, 1]))
    return ({k: (np.array(z), np.array(i)) for k, (z, i) in out.items()}, np.array(orders))


def check_calibrated(z, inside):
    seeds = z.shape[0]
    # P(|z| > 4) = 6.3e-5 per coefficient: 80 seeds × 4 coefficients expect 0.02 exceedances
    assert np.max(np.abs(z)) < 4.0, np.max(np.abs(z), axis=0)
    # unbiased (OE is consistent under coloured noise in open loop): mean z within 4/√seeds
    assert np.all(np.abs(z.mean(axis=0)) < 4 / np.sqrt(seeds)), z.mean(axis=0)
    # the band; the pooled coverage has sd ≈ 1.7 % (see SEEDS): 90–99 % is −3 … +2.4 sd
    assert 0.90 <= inside.mean() <= 0.99, inside.mean()


@pytest.fixture(scope="module")
def coloured():
    return study(SEEDS, COLOURED)


def test_robust_covariance_covers_on_coloured_noise(coloured):
    results, orders = coloured
    check_calibrated(*results["robust"])
    # the residual AR model is never white here: ε ≈ v, whose AR(∞) form (1 − 0.9q⁻¹)/(1 + 0.5q⁻¹)
    # has coefficients −1.4, 0.7, −0.35, … far above the ±2/√N noise of their estimates
    assert orders.min() >= 2, np.bincount(orders)


def test_white_covariance_undercovers_on_the_same_records(coloured):
    results, _ = coloured
    z, inside = results["white"]
    # the white formula ignores Σ_{τ≠0} r_v(τ)·Σψψᵀ: the z of b0, b1 spread ×1.4 and of f1, f2
    # ×2.2 (the ratio of the two covariances), so the expected coverage is ≈ 0.72; 0.85 is
    # 3.7 sd (3.5 % with ~160 independent draws) above that and 5 points below the band
    assert inside.mean() < 0.85, inside.mean()
    # a calibrated z has sd 1 within 4/√(2·80) = 0.32; f1 and f2 are expected at 2.2
    assert np.all(z.std(axis=0)[2:] > 1 + 4 / np.sqrt(2 * SEEDS)), z.std(axis=0)
    # and the "within 4σ" fails: P(|z| > 4) = P(|N(0, 1)| > 1.8) = 0.07 per f
    # coefficient, so 80 records with none beyond 4 would have probability 0.93⁸⁰ = 0.3 %
    assert np.max(np.abs(z)) > 4.0


def test_white_noise_oe_still_covers_and_mostly_uses_the_white_formula():
    results, orders = study(40, None)
    check_calibrated(*results["robust"])
    check_calibrated(*results["white"])
    # AIC keeps p = 0 on white residuals with probability ≈ 0.71 (Shibata 1976); Binomial(40,
    # 0.71) is 28 ± 2.9, so at least half the seeds is 2.9 sd below the mean
    assert np.sum(orders == 0) >= 20, np.bincount(orders)
    # with p = 0 the sandwich is σ̂²·H⁺HH⁺ = σ̂²·H⁺: the same covariance, not just close
    for seed in np.flatnonzero(orders == 0)[:3]:
        exp = record(int(seed), None)
        np.testing.assert_array_equal(fit_oe(exp, 2, 2, 1).covariance,
                                      fit_oe(exp, 2, 2, 1, covariance="white").covariance)


@pytest.mark.slow
def test_robust_covariance_covers_on_coloured_noise_200_seeds():
    results, _ = study(SLOW_SEEDS, COLOURED)
    z, inside = results["robust"]
    check_calibrated(z, inside)
    # each coefficient's own coverage: Binomial(200, 0.95) has sd 1.5 %, 90–99 % is −3.2 … +2.6 sd
    per_coefficient = inside.mean(axis=0)
    assert np.all((0.90 <= per_coefficient) & (per_coefficient <= 0.99)), per_coefficient
    # and the spread of z is 1 within 4 standard errors (≈ 1/√(2·200))
    assert np.all(np.abs(z.std(axis=0) - 1) < 4 / np.sqrt(2 * SLOW_SEEDS)), z.std(axis=0)
    assert results["white"][1].mean() < 0.85


# -- the sandwich against an independent computation --------------------------------------------


def brute_force_sandwich(est, u, dof):
    """(ΨᵀΨ)⁻¹ Ψᵀ R Ψ (ΨᵀΨ)⁻¹ with an explicit Ψ and Yule–Walker by a Toeplitz solve."""
    b, f = est.parameters[:2], np.r_[1.0, est.parameters[2:]]
    n = u.size
    uf = sps.lfilter([1.0], f, u)
    wf = sps.lfilter([1.0], f, sps.lfilter(np.r_[0.0, b], f, u))
    psi = np.column_stack([np.r_[0.0, uf[:-1]], np.r_[0.0, 0.0, uf[:-2]],
                           -np.r_[0.0, wf[:-1]], -np.r_[0.0, 0.0, wf[:-2]]])
    eps = np.asarray(est.residuals)
    p = est.options["covariance_ar_order"]
    r = np.array([eps[: n - k] @ eps[k:] for k in range(p + 1)]) / n
    a = np.r_[1.0, linalg.solve_toeplitz(r[:p], -r[1:])] if p else np.ones(1)
    innovation = float(a @ r)  # Yule–Walker: σ_η² = Σ_k a_k r(k)
    filtered = sps.lfilter([1.0], a, psi, axis=0)  # Ψ/A_v(q), from rest
    inv = np.linalg.inv(psi.T @ psi)
    return inv @ (innovation * n / dof * filtered.T @ filtered) @ inv


def test_robust_covariance_is_the_sandwich_with_the_residual_ar_model():
    exp = record(3, COLOURED)
    est = fit_oe(exp, 2, 2, 1)
    p = est.options["covariance_ar_order"]
    assert p >= 2
    expected = brute_force_sandwich(est, exp["u"], N - 4)
    # the same formula by another route (explicit Ψ, lfilter, Toeplitz solve): rounding only,
    # ε·cond(ΨᵀΨ)² ≈ 3e-11 (cond ≈ 400, the inverse applied twice) and ε·cond(T) ≈ 3e-13
    np.testing.assert_allclose(est.covariance, expected, rtol=1e-9)
    # and p minimises AIC = N ln σ_p² + 2p over p <= 10·log10 N (Yule–Walker σ_p² by solve)
    eps = np.asarray(est.residuals)
    p_max = int(10 * np.log10(N))
    r = np.array([eps[: N - k] @ eps[k:] for k in range(p_max + 1)]) / N
    aic = [N * np.log(r[0])]
    for q in range(1, p_max + 1):
        a = np.r_[1.0, linalg.solve_toeplitz(r[:q], -r[1: q + 1])]
        aic.append(N * np.log(a @ r[: q + 1]) + 2 * q)
    assert int(np.argmin(aic)) == p


def test_robust_covariance_is_positive_definite_with_segments_and_initial_values():
    exp = record(5, COLOURED)
    white = fit_oe(exp, 2, 2, 1, covariance="white")
    for kwargs in ({"initial": "estimate"}, {"start": 5}, {"initial": "estimate", "start": 5}):
        est = fit_oe(exp, 2, 2, 1, **kwargs)
        np.testing.assert_array_equal(est.covariance, est.covariance.T)
        assert np.linalg.eigvalsh(est.covariance).min() > 0
        # eliminating 2 initial values or dropping 5 samples barely changes the uncertainty;
        # the colour widens it as on the whole record (ratios 1.3–1.6 and 1.9–2.4, see above)
        ratio = est.std / white.std
        assert np.all(ratio[:2] > 1.2) and np.all(ratio[2:] > 1.8), ratio
    halves = ExperimentSet((exp.slice(0, N // 2), exp.slice(N // 2, N)))
    est = fit_oe(halves, 2, 2, 1)
    assert est.options["segments"] == 2 and est.options["covariance"] == "robust"
    assert np.linalg.eigvalsh(est.covariance).min() > 0
    assert np.all(est.std / fit_oe(halves, 2, 2, 1, covariance="white").std > 1.2)


# -- options -----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bj_record():
    return record(7, COLOURED)


@pytest.mark.parametrize(
    ("fit", "kind"),
    [
        (lambda e, **k: fit_oe(e, 2, 2, 1, **k), "robust"),
        (lambda e, **k: fit_pem(e, nb=2, nf=2, nk=1, **k), "robust"),
        (lambda e, **k: fit_bj(e, 2, 1, 1, 2, 1, **k), "white"),
        (lambda e, **k: fit_armax(e, 2, 2, 1, 1, **k), "white"),
        (lambda e, **k: fit_armax(e, 2, 2, 0, 1, **k), "white"),  # ARX: noise model 1/A
    ],
)
def test_auto_covariance_depends_on_the_noise_model(bj_record, fit, kind):
    est = fit(bj_record)
    assert est.options["covariance"] == kind
    assert (est.options["covariance_ar_order"] is None) == (kind == "white")
    assert fit(bj_record, covariance="white").options["covariance"] == "white"
    assert fit(bj_record, covariance="robust").options["covariance"] == "robust"


def test_robust_bj_with_the_right_noise_model_is_the_white_formula(bj_record):
    # BJ's residuals are white here, so AIC picks p = 0 and the two covariances coincide
    robust = fit_bj(bj_record, 2, 1, 1, 2, 1, covariance="robust")
    assert robust.options["covariance_ar_order"] == 0
    np.testing.assert_array_equal(robust.covariance, fit_bj(bj_record, 2, 1, 1, 2, 1).covariance)


def test_unknown_covariance_lists_the_valid_ones(bj_record):
    with pytest.raises(OptionError, match="covariance must be one of 'auto', 'white', 'robust'; "
                                          "got 'sandwich'"):
        fit_oe(bj_record, 2, 2, 1, covariance="sandwich")
