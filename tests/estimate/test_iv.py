"""fit_iv: exact on noise-free data, consistent where least squares is biased, closed loop.

Open-loop records come from :func:`servoid.bench.simulate_lti` (exact ZOH
sampling of a continuous plant), closed-loop ones from
:func:`servoid.bench.simulate_lti_loop` (a digital PI controller the
estimator does not know, coloured noise inside the loop).  The truth is
``c2d(plant, dt, "zoh")`` written as ARX coefficients ``a1, a2, b0, b1``.
"""

import numpy as np
import pytest

from servoid import (
    DataError,
    Experiment,
    ExperimentSet,
    IdentifiabilityError,
    OptionError,
    OptionTypeError,
)
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.estimate import fit_arx, fit_iv
from servoid.models import PolynomialModel, TransferFunction, c2d

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
G = c2d(PLANT, DT, "zoh")
TRUE = np.concatenate([G.den[1:], G.num])  # a1, a2, b0, b1 with nk = 1
NOISE = ([1.0, 0.5], [1.0, -0.9])  # C/D of the output noise
PI = TransferFunction([0.8, -0.6], [1.0, -1.0], dt=DT)  # the "unknown" controller


def binary(n, seed, width=1):
    u = np.sign(np.random.default_rng(seed).standard_normal((n, width)))
    return u[:, 0] if width == 1 else u


def test_noise_free_record_is_recovered_exactly():
    exp = simulate_lti(PLANT, binary(1000, 1), DT)
    est = fit_iv(exp, 2, 2, 1)
    # exact sampling (generator error ~1e-12) and an exact solve: rounding × cond ≈ 1e-9
    np.testing.assert_allclose(est.parameters, TRUE, rtol=1e-8)
    assert est.names == ("a1", "a2", "b0", "b1")
    assert est.method == "iv" and isinstance(est.model, PolynomialModel)
    assert est.model.structure == "arx"
    opts = est.options
    assert opts["instrument"] == "auto" and opts["iterations"] == 2 and opts["start"] == 2
    assert opts["inputs"] == ["u"] and opts["output"] == "y" and opts["noise_order"] >= 1
    assert est.n_samples == 998 and est.residuals.size == 998
    np.testing.assert_array_equal(est.model_at(est.parameters).a, est.model.a)


def test_two_inputs_and_segments():
    lag = TransferFunction([1.0], [0.1, 1.0])
    # a common denominator: y = (B1 u1 + B2 u2)/A is ARX with two inputs
    a = np.asarray(G.den)
    b2 = np.array([0.2, -0.1])
    segs = []
    for seed in (2, 3):
        u = binary(800, seed, width=2)
        model = PolynomialModel(a, (np.asarray(G.num), b2), (1, 2), DT)
        segs.append(Experiment.from_arrays(DT, u=u, y=model.simulate(u)))
    est = fit_iv(ExperimentSet(tuple(segs)), 2, [2, 2], [1, 2])
    truth = np.concatenate([a[1:], G.num, b2])
    np.testing.assert_allclose(est.parameters, truth, rtol=1e-8)  # noise-free: rounding only
    assert est.names == ("a1", "a2", "u0:b0", "u0:b1", "u1:b0", "u1:b1")
    assert est.options["segments"] == 2 and est.n_samples == 2 * (800 - 3)
    del lag


@pytest.fixture(scope="module")
def open_loop_study():
    z_iv, z_ls, inside = [], [], []
    for seed in range(30):
        exp = simulate_lti(PLANT, binary(3000, 100 + seed), DT, noise_std=0.1,
                           noise_model=NOISE, rng=seed)
        iv = fit_iv(exp, 2, 2, 1)
        ls = fit_arx(exp, 2, 2, 1)
        z_iv.append((iv.parameters - TRUE) / iv.std)
        z_ls.append((ls.parameters - TRUE) / ls.std)
        ci = iv.confidence_intervals(0.95)
        inside.append((ci[:, 0] <= TRUE) & (TRUE <= ci[:, 1]))
    return np.array(z_iv), np.array(z_ls), np.array(inside)


def test_iv_is_consistent_where_least_squares_is_biased(open_loop_study):
    z_iv, z_ls, inside = open_loop_study
    # coloured output noise makes the ARX equation error correlated with −y lags: LS is biased,
    # by many of its own standard errors
    assert np.max(np.abs(z_ls.mean(axis=0))) > 4
    # IV: every error within 4σ (30 × 4 draws, P(|z| > 4) = 6.3e-5 each); mean 0 within
    # 4 standard errors of a mean of 30
    assert np.max(np.abs(z_iv)) < 4
    assert np.all(np.abs(z_iv.mean(axis=0)) < 4 / np.sqrt(30))
    # the documented covariance is calibrated: pooled 95 % coverage of 120 intervals,
    # Binomial(120, 0.95) sd 2 %: 88–100 % is ±3 sd
    assert 0.88 <= inside.mean() <= 1.0


def test_closed_loop_iv_with_the_reference_as_instrument():
    z_r, z_ls = [], []
    for seed in range(25):
        r = np.repeat(binary(600, 200 + seed), 5)  # a reference held for 5 samples
        exp = simulate_lti_loop(PLANT, PI, r, DT, noise_std=0.1, noise_model=NOISE, rng=seed)
        est = fit_iv(exp, 2, 2, 1, instrument="r")
        z_r.append((est.parameters - TRUE) / est.std)
        ls = fit_arx(exp, 2, 2, 1)
        z_ls.append((ls.parameters - TRUE) / ls.std)
    z_r, z_ls = np.array(z_r), np.array(z_ls)
    assert est.options["instrument"] == "r" and est.options["references"] == ["r"]
    assert est.options["auxiliary_order"] >= 6
    # least squares on closed-loop data with coloured noise is biased (feedback + colour) ...
    assert np.max(np.abs(z_ls.mean(axis=0))) > 4
    # ... the reference-driven instruments are not: 4σ per run (25 × 4 draws), and the mean
    # error is 0 within 4 standard errors of a mean of 25
    assert np.max(np.abs(z_r)) < 4
    assert np.all(np.abs(z_r.mean(axis=0)) < 4 / np.sqrt(25))


def test_basic_iv_without_refinement():
    # ARX data (white equation error), where the documented covariance of the basic IV holds
    rng = np.random.default_rng(5)
    u = binary(3000, 5)
    model = PolynomialModel.arx(G.den, G.num, 1, DT)
    noise = PolynomialModel.arx(G.den, [1.0], 0, DT)
    exp = Experiment.from_arrays(DT, u=u, y=model.simulate(u) + noise.simulate(
        0.01 * rng.standard_normal(u.size)))
    est = fit_iv(exp, 2, 2, 1, iterations=0)
    assert est.options["noise_order"] == 0 and est.options["iterations"] == 0
    assert np.all(np.abs(est.parameters - TRUE) < 4 * est.std)  # 4σ, one seed


@pytest.fixture(scope="module")
def record():
    return simulate_lti(PLANT, binary(400, 9), DT, noise_std=0.05, rng=9)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda e: fit_iv(e, 2, 2, instrument="u"), OptionError,
         "instrument must be one of 'auto', 'r'; got 'u'"),
        (lambda e: fit_iv(e, 2, 2, instrument="r"), DataError,
         "needs a reference channel .* use instrument='auto'"),
        (lambda e: fit_iv(e, 2, 2, iterations=-1), DataError, "iterations must be >= 0"),
        (lambda e: fit_iv(e, 2, 2, iterations=1.0), OptionTypeError, "iterations must be an integer"),
        (lambda e: fit_iv(e, 2, 2, input="r", instrument="r"), OptionError, "instrument='auto'"),
        (lambda e: fit_iv(e, 2, 2, start=1), DataError, "start must be >= 2"),
        (lambda e: fit_iv(e, 150, 150), DataError, "Use a longer record or lower orders"),
        (lambda e: fit_iv(e, -1, 2), DataError, "na must be >= 0"),
    ],
)
def test_bad_input_names_the_fix(record, call, error, match):
    with pytest.raises(error, match=match):
        call(record)


def test_constant_input_raises():
    exp = Experiment.from_arrays(DT, u=np.ones(300), y=np.random.default_rng(0).normal(size=300))
    with pytest.raises(IdentifiabilityError, match="not persistently exciting"):
        fit_iv(exp, 2, 2)


def test_reference_that_does_not_excite_the_input():
    rng = np.random.default_rng(1)
    u = binary(500, 1)
    exp = Experiment.from_arrays(DT, r=rng.normal(size=500) * 1e-3 + 1.0, u=u,
                                 y=np.convolve(u, [0.0, 0.5, 0.3])[:500])
    est = fit_iv(exp, 2, 2, instrument="r")  # a weak but valid instrument still runs
    assert est.options["instrument"] == "r"
    flat = Experiment.from_arrays(DT, r=np.ones(500), u=u, y=exp["y"])
    with pytest.raises(IdentifiabilityError, match="constant"):
        fit_iv(flat, 2, 2, instrument="r")
