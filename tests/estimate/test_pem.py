"""fit_oe / fit_armax / fit_bj / fit_pem: known answers, search behaviour and bad input.

The data come from :func:`servoid.bench.simulate_lti`, which integrates a
continuous plant exactly at 20× the logging rate: with a held (ZOH) input the
logged record is exactly the ZOH-sampled plant ``c2d(plant, dt, "zoh")``, so
the true B and F are known without sharing any code with the estimators.
"""


import numpy as np
import pytest
import scipy.signal as sps

from servoid import (
    ConvergenceError,
    DataError,
    Experiment,
    ExperimentSet,
    IdentifiabilityError,
    ModelError,
    OptionError,
    OptionTypeError,
    ServoidWarning,
)
from servoid.bench import simulate_lti
from servoid.estimate import fit_armax, fit_arx, fit_bj, fit_oe, fit_pem
from servoid.estimate._pem_orders import PemOrders, prepare
from servoid.estimate._pem_start import iv_start
from servoid.models import PolynomialModel, TransferFunction, c2d

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])  # 2 Hz, ζ = 0.3
LAG = TransferFunction([1.0], [0.1, 1.0])  # first order, τ = 0.1 s


def true_bf(plant, dt=DT):
    """(b, f, nk) of the ZOH-sampled plant in q⁻¹: num/den in z, num strictly shorter."""
    g = c2d(plant, dt, "zoh")
    return np.asarray(g.num), np.asarray(g.den), g.den.size - g.num.size


B, F, NK = true_bf(PLANT)
TRUE_OE = np.concatenate([B, F[1:]])


def binary(n, seed, width=1):
    u = np.sign(np.random.default_rng(seed).standard_normal((n, width)))
    return u[:, 0] if width == 1 else u


def rel_err(a, b):
    return float(np.max(np.abs(np.asarray(a) - b) / np.abs(b)))


# -- known answers: noise-free data inside the structure ----------------------------------------


def test_oe_recovers_the_sampled_plant_from_noise_free_data():
    exp = simulate_lti(PLANT, binary(1500, 1), DT)
    est = fit_oe(exp, 2, 2, NK)
    # the generator matches c2d to ~1e-12 (exact fast-rate integration); cond(Ψ) ~ 1e3 → 1e-8
    assert rel_err(est.parameters, TRUE_OE) < 1e-8
    assert est.names == ("b0", "b1", "f1", "f2")
    assert est.method == "oe" and est.status == "ok" and est.options["converged"]
    assert isinstance(est.model, PolynomialModel) and est.model.structure == "oe"
    assert est.model.nk == (NK,)


def test_two_input_oe_recovers_both_plants():
    u = binary(2000, 2, width=2)
    y = simulate_lti(PLANT, u[:, 0], DT)["y"] + simulate_lti(LAG, u[:, 1], DT)["y"]
    exp = Experiment.from_arrays(DT, u=u, y=y)
    b2, f2, nk2 = true_bf(LAG)
    est = fit_oe(exp, [2, 1], [2, 1], [NK, nk2])
    assert est.names == ("u0:b0", "u0:b1", "u0:f1", "u0:f2", "u1:b0", "u1:f1")
    truth = np.concatenate([B, F[1:], b2, f2[1:]])
    assert rel_err(est.parameters, truth) < 1e-8  # rounding only, as in the SISO case
    assert est.options["nb"] == [2, 1] and est.options["inputs"] == ["u0", "u1"]


def test_segments_are_never_joined():
    segs = [simulate_lti(PLANT, binary(700, s), DT) for s in (3, 4)]
    est = fit_oe(ExperimentSet(tuple(segs)), 2, 2, NK)
    assert rel_err(est.parameters, TRUE_OE) < 1e-8  # each segment starts at rest: exact
    assert est.n_samples == 1400 and est.options["segments"] == 2
    # joined end to end, the second segment's start-up would be predicted from the first's end
    joined = Experiment.from_arrays(DT, u=np.concatenate([s["u"] for s in segs]),
                                    y=np.concatenate([s["y"] for s in segs]))
    assert rel_err(fit_oe(joined, 2, 2, NK).parameters, TRUE_OE) > 1e-6


def test_estimated_initial_conditions_remove_the_start_up_transient():
    # a short record cut from the middle of a run: the plant is not at rest at its start
    full = simulate_lti(PLANT, binary(600, 5), DT)
    exp = full.slice(450, 600)
    zero = fit_oe(exp, 2, 2, NK, initial="zero")
    est = fit_oe(exp, 2, 2, NK, initial="estimate")
    # the free response lies exactly in the span of the eliminated initial values
    assert rel_err(est.parameters, TRUE_OE) < 1e-8
    assert rel_err(zero.parameters, TRUE_OE) > 1e-3  # zero IC mistakes the transient for dynamics
    assert est.options["initial"] == "estimate" and est.options["initial_values"] == 2
    # and on noisy data it still beats zero initial conditions
    noisy = simulate_lti(PLANT, binary(600, 6), DT, noise_std=0.01, rng=6).slice(450, 600)
    err_zero = np.abs(fit_oe(noisy, 2, 2, NK, initial="zero").parameters - TRUE_OE)
    est_noisy = fit_oe(noisy, 2, 2, NK, initial="estimate")
    err_est = np.abs(est_noisy.parameters - TRUE_OE)
    assert np.linalg.norm(err_est) < 0.2 * np.linalg.norm(err_zero)
    # the default ("auto") sees the transient and estimates the initial values by itself;
    # it reaches the same minimum from another start (zero-start minimum): tolerance of the stop
    auto = fit_oe(noisy, 2, 2, NK)
    assert auto.options["initial"] == "estimate" and auto.options["initial_requested"] == "auto"
    np.testing.assert_allclose(auto.parameters, est_noisy.parameters, rtol=0, atol=1e-6)


# -- structure, names and the Estimate ------------------------------------------------------------


@pytest.fixture(scope="module")
def bj_record():
    return simulate_lti(PLANT, binary(2000, 7), DT, noise_std=0.05,
                        noise_model=([1.0, 0.5], [1.0, -0.85]), rng=7)


def test_bj_estimate_fields(bj_record):
    est = fit_bj(bj_record, 2, 1, 1, 2, NK)
    assert est.names == ("b0", "b1", "f1", "f2", "c1", "d1")
    assert est.method == "bj" and est.model.structure == "bj"
    assert est.covariance.shape == (6, 6)
    np.testing.assert_allclose(est.covariance, est.covariance.T, rtol=0, atol=0)
    assert np.all(np.linalg.eigvalsh(est.covariance) > 0)
    opts = est.options
    assert opts["nb"] == [2] and opts["nf"] == [2] and opts["nk"] == [NK]
    assert (opts["nc"], opts["nd"], opts["na"]) == (1, 1, 0)
    assert opts["input"] == "u" and opts["inputs"] == ["u"] and opts["output"] == "y"
    assert opts["start"].startswith("IV") and opts["reflected"] == 0
    assert est.n_samples == 2000 and est.residuals.size == 2000
    assert est.model.noise_variance == pytest.approx(est.noise_variance)
    # model_function gives the model at any θ; at θ̂ it is the returned model
    again = est.model_at(est.parameters)
    np.testing.assert_array_equal(again.c, est.model.c)
    np.testing.assert_array_equal(again.f[0], est.model.f[0])
    assert est.model_at(est.parameters + 0.01).d[1] == pytest.approx(est.model.d[1] + 0.01)


@pytest.mark.parametrize("fit", ["oe", "armax", "bj"])
def test_residuals_are_the_models_own_prediction_errors(fit, bj_record):
    est = {"oe": lambda: fit_oe(bj_record, 2, 2, NK),
           "armax": lambda: fit_armax(bj_record, 2, 2, 1, NK),
           "bj": lambda: fit_bj(bj_record, 2, 1, 1, 2, NK)}[fit]()
    # PolynomialModel.residuals is an independent predictor (scipy lfilter, zero past):
    # the two agree to rounding
    own = est.model.residuals(bj_record["y"], bj_record["u"])
    np.testing.assert_allclose(est.residuals, own, rtol=0, atol=1e-10)


def test_the_estimate_is_a_stationary_point_of_the_prediction_error_cost(bj_record):
    est = fit_bj(bj_record, 2, 1, 1, 2, NK)

    def cost(theta):
        return float(np.sum(est.model_at(theta).residuals(bj_record["y"], bj_record["u"]) ** 2))

    v0 = cost(est.parameters)
    for i, s in enumerate(est.std):
        step = np.zeros_like(est.parameters)
        step[i] = 0.01 * s
        up, down = cost(est.parameters + step), cost(est.parameters - step)
        # ±0.01σ out the cost rises by r ∝ 0.01²; a gradient g left by the search makes the
        # sides differ by 2·g·0.01σ: |up − down| < 1 % of r means θ̂ is within 5e-5 σ of the
        # stationary point (cubic terms add ~0.05 % at this step)
        assert abs(up - down) < 0.01 * (up + down - 2 * v0)
        assert up > v0 and down > v0


def test_fit_pem_is_the_general_entry(bj_record):
    bj = fit_bj(bj_record, 2, 1, 1, 2, NK)
    pem = fit_pem(bj_record, nb=2, nc=1, nd=1, nf=2, nk=NK)
    np.testing.assert_allclose(pem.parameters, bj.parameters, rtol=1e-12)  # the same computation
    assert pem.method == "pem" and pem.names == bj.names


def test_pem_without_c_d_f_is_least_squares_arx(bj_record):
    # ε = A y − B u is linear in θ: one Gauss–Newton step is the least-squares solution, and
    # σ̂²(ΨᵀΨ)⁻¹ is fit_arx's covariance (same equations from the same first sample)
    pem = fit_armax(bj_record, 2, 2, 0, NK, start=2)
    arx = fit_arx(bj_record, 2, 2, NK, start=2)
    np.testing.assert_allclose(pem.parameters, arx.parameters, rtol=1e-9)  # ε·cond(Φ)
    np.testing.assert_allclose(pem.covariance, arx.covariance, rtol=1e-6)  # Gram vs QR route
    assert pem.noise_variance == pytest.approx(arx.noise_variance, rel=1e-9)


def test_general_structure_with_a_and_f():
    # A y = B/F u + C e in discrete time: y = B/(A F) u + C/A e
    a, c = np.array([1.0, -0.5]), np.array([1.0, 0.4])
    rng = np.random.default_rng(11)
    u = binary(3000, 11)
    e = 0.05 * rng.standard_normal(u.size)
    y = sps.lfilter(np.r_[0.0, B], np.convolve(a, F), u) + sps.lfilter(c, a, e)
    est = fit_pem(Experiment.from_arrays(DT, u=u, y=y), na=1, nb=2, nf=2, nc=1, nk=NK)
    assert est.names == ("a1", "b0", "b1", "f1", "f2", "c1")
    assert est.model.structure == "general"
    truth = np.concatenate([a[1:], B, F[1:], c[1:]])
    assert np.all(np.abs(est.parameters - truth) < 4 * est.std)  # 4σ, one fixed seed


# -- stability, multistart, convergence -------------------------------------------------------------


def test_an_unstable_start_is_reflected_into_the_unit_circle(bj_record):
    ref = fit_armax(bj_record, 2, 2, 1, NK)
    init = np.array(ref.parameters)
    init[-1] = 1.0 / 0.6  # C root at −1/0.6: the predictor 1/C would blow up
    est = fit_armax(bj_record, 2, 2, 1, NK, init=init)
    assert est.options["reflected"] == 1
    assert "reflected 1 root" in est.status and "unit circle" in est.status
    assert est.options["start"] == "user"
    # the reflected C describes the same noise spectrum: the search ends at the same minimum,
    # up to where tol = 1e-9 stops it (θ within ~1e-3 σ of the stationary point)
    assert np.all(np.abs(est.parameters - ref.parameters) < 0.01 * ref.std)
    # an OE start with F roots at 1.25 and 0.5 is reflected too and still converges
    init_oe = np.concatenate([B, np.real(np.poly([1.25, 0.5]))[1:]])
    oe = fit_oe(bj_record, 2, 2, NK, init=init_oe)
    assert oe.options["reflected"] >= 1 and "reflected" in oe.status
    assert np.all(np.abs(np.roots(oe.model.f[0])) < 1)


def two_resonances(seed=3):
    """A 4th-order system; an OE(2, 2) fits one resonance: two local minima."""
    pa, pb = 0.97 * np.exp(0.25j), 0.95 * np.exp(1.6j)
    fa, fb = (np.real(np.poly([p, np.conj(p)])) for p in (pa, pb))
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(4000)
    y = sps.lfilter([0, 0.02, 0.02], fa, u) + sps.lfilter([0, 0.15], fb, u)
    return Experiment.from_arrays(1.0, u=u, y=y + 0.02 * rng.standard_normal(u.size)), fa, fb


def test_multistart_finds_the_global_minimum_a_single_start_misses():
    exp, fa, _ = two_resonances()
    # the IV start alone (the default before the scored starts of _pem_start.sm_starts)
    iv = iv_start(PemOrders(0, 2, 0, 0, 2, 1, 1), prepare(exp, "u", None), 0)[0]
    single = fit_oe(exp, 2, 2, 1, init=iv)
    multi = fit_oe(exp, 2, 2, 1, init=iv, multistart=6, rng=1)
    near_a = fit_oe(exp, 2, 2, 1, init=[0.02, 0.02, *fa[1:]])
    # the IV start locks onto the weaker resonance (a local minimum, about twice the cost)
    assert single.options["cost"] > 1.5 * multi.options["cost"]
    # the default start, scored among IV and Steiglitz-McBride candidates, finds the deeper one
    assert fit_oe(exp, 2, 2, 1).options["cost"] == pytest.approx(near_a.options["cost"],
                                                                 rel=1e-9)
    # the random starts reach the deeper minimum, the one a start near it converges to
    assert multi.options["cost"] == pytest.approx(near_a.options["cost"], rel=1e-9)
    # the same minimum up to where tol = 1e-9 stops each search (~1e-3 σ)
    assert np.all(np.abs(multi.parameters - near_a.parameters) < 0.01 * near_a.std)
    ms = multi.options["multistart"]
    assert ms["starts"] == 7 and ms["best"] != 0 and 1 <= ms["same_minimum"] <= 7
    assert len(ms["costs"]) == 7 and multi.options["start"].startswith("random start")
    # reproducible with the same seed
    again = fit_oe(exp, 2, 2, 1, init=iv, multistart=6, rng=1)
    np.testing.assert_array_equal(again.parameters, multi.parameters)


def test_multistart_agrees_with_a_single_start_when_the_minimum_is_unique(bj_record):
    single = fit_oe(bj_record, 2, 2, NK)
    multi = fit_oe(bj_record, 2, 2, NK, multistart=4, rng=np.random.default_rng(0))
    assert multi.options["cost"] == pytest.approx(single.options["cost"], rel=1e-9)
    assert multi.options["multistart"]["same_minimum"] == 5


def test_stopping_at_max_iter_warns(bj_record):
    with pytest.warns(ServoidWarning, match="stopped at max_iter=0 .* increase max_iter"):
        est = fit_bj(bj_record, 2, 1, 1, 2, NK, max_iter=0)
    assert not est.options["converged"] and "max_iter" in est.status


def test_a_divergent_start_raises_a_convergence_error(bj_record):
    with pytest.raises(ConvergenceError, match="diverged.*Rescale the data.*multistart"):
        fit_oe(bj_record, 2, 2, NK, init=[1e200, 1e200, -1.5, 0.7])


# -- bad input ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small():
    return simulate_lti(PLANT, binary(300, 9), DT, noise_std=0.01, rng=9)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda e: fit_oe(e.slice(0, 12), 6, 6), DataError,
         r"needs at least \d+ samples .*Use a longer record or lower orders"),
        (lambda e: fit_oe(e, 300, 2), DataError, "Use a longer record or lower orders"),
        (lambda e: fit_oe(e, 2, -1), DataError, "nf must be >= 0, got -1"),
        (lambda e: fit_oe(e, 0, 2), DataError, "nb must be >= 1, got 0"),
        (lambda e: fit_oe(e, 2.5, 2), OptionTypeError, "nb must be an integer, got 2.5"),
        (lambda e: fit_armax(e, "2", 2, 1), OptionTypeError, "na must be an integer"),
        (lambda e: fit_oe(e, [2, 2], 2), DataError, r"nb needs one value per input \(1\)"),
        (lambda e: fit_oe(e, 2, 2, initial="backcast"), OptionError,
         "initial must be one of 'auto', 'zero', 'estimate'; got 'backcast'"),
        (lambda e: fit_oe(e, 2, 2, input="x"), OptionError, "input must be one of"),
        (lambda e: fit_oe(e, 2, 2, tol=2.0), DataError, r"tol .* must lie in \(0, 1\)"),
        (lambda e: fit_oe(e, 2, 2, tol=0.0), DataError, "tol must be > 0"),
        (lambda e: fit_oe(e, 2, 2, multistart=-1), DataError, "multistart must be >= 0"),
        (lambda e: fit_oe(e, 2, 2, max_iter=1.5), OptionTypeError, "max_iter must be an integer"),
        (lambda e: fit_oe(e, 2, 2, init=[0.1, 0.1]), DataError, "init must have 4 values"),
        (lambda e: fit_oe(e, 2, 2, init="iv"), OptionTypeError, "init must be a PolynomialModel"),
        (lambda e: fit_oe(e, 2, 2, init=PolynomialModel.arx([1.0, 0.5], [1.0], 1, DT)),
         ModelError, "init has orders"),
        (lambda e: fit_oe(e, 2, 2, multistart=1, rng="seed"), OptionTypeError,
         "rng must be a numpy.random.Generator"),
        (lambda e: fit_oe(e, 2, 2, output="nope"), Exception, "no channel named 'nope'"),
    ],
)
def test_bad_input_names_the_fix(small, call, error, match):
    with pytest.raises(error, match=match):
        call(small)


def test_constant_input_is_not_persistently_exciting():
    exp = Experiment.from_arrays(DT, u=np.full(200, 0.5), y=np.random.default_rng(0).normal(size=200))
    with pytest.raises(IdentifiabilityError, match="not persistently exciting.*PRBS"):
        fit_oe(exp, 2, 2)


@pytest.mark.parametrize("scale", [1e160, 1e-10])
def test_absurd_magnitudes(small, scale):
    exp = Experiment.from_arrays(DT, u=small["u"] * scale, y=small["y"] * scale)
    if scale > 1:
        with pytest.raises(DataError, match="overflow double precision.*Rescale"):
            fit_oe(exp, 2, 2, NK)
    else:
        # tiny but representable numbers are fine: every criterion is relative
        est = fit_oe(exp, 2, 2, NK)
        ref = fit_oe(small, 2, 2, NK)
        np.testing.assert_allclose(est.parameters, ref.parameters, rtol=1e-6)  # scale-free search


def test_noise_free_data_with_a_noise_model_still_give_the_exact_plant():
    exp = simulate_lti(PLANT, binary(400, 10), DT)
    est = fit_bj(exp, 2, 1, 1, 2, NK)
    assert rel_err(est.parameters[:4], TRUE_OE) < 1e-8  # rounding only, as for OE
    # C and D are fitted to rounding noise: the covariance says they are undetermined
    assert est.std[4:].min() > 1e6 * est.std[:4].max()
