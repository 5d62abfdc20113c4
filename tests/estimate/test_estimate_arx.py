"""fit_arx: noise-free recovery, solver routes, segments and bad input."""

import warnings

import numpy as np
import pytest

from servoid import (
    DataError,
    Experiment,
    ExperimentSet,
    IdentifiabilityError,
    OptionError,
    ServoidWarning,
)
from servoid.estimate import fit_arx, lstsq, solve_gram
from servoid.models import PolynomialModel, TransferFunction, c2d
from servoid.signals import prbs

DT = 1e-3
A = np.array([1.0, -1.5, 0.7])  # poles 0.75 ± 0.37j, well damped
B = np.array([1.0, 0.5])
NK = 1
TRUE = np.concatenate([A[1:], B])  # a1, a2, b0, b1


def arx_record(n, seed, sigma=0.0, a=A, b=B, nk=NK):
    """u white, y = B/A u (+ e/A): the record starts at rest."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    model = PolynomialModel.arx(a, b, nk, DT)
    e = sigma * rng.normal(size=n)
    y = model.simulate(u) + PolynomialModel.arx(a, [1.0], 0, DT).simulate(e)
    return Experiment.from_arrays(DT, u=u, y=y)


def rel_err(est, truth):
    return np.max(np.abs(np.asarray(est) - truth) / np.abs(truth))


def manual_regressor(u, y, na, nb, nk, start):
    """Φ row t: [−y(t−1) … −y(t−na), u(t−nk) … u(t−nk−nb+1)] for t = start … N−1."""
    n = len(y)
    rows = []
    for t in range(start, n):
        rows.append([-y[t - j] for j in range(1, na + 1)] + [u[t - nk - j] for j in range(nb)])
    return np.array(rows), np.asarray(y[start:])


# -- 1. noise-free recovery --------------------------------------------------------------------


@pytest.mark.parametrize("method", ["qr", "gram", "auto"])
def test_siso_noise_free_recovery(method):
    est = fit_arx(arx_record(1000, seed=1), 2, 2, NK, method=method)
    # noise-free data inside the structure: only rounding, ε·cond(Φ) with cond ≈ 5
    assert rel_err(est.parameters, TRUE) < 1e-9
    assert est.names == ("a1", "a2", "b0", "b1")
    np.testing.assert_allclose(est.model.a, A, rtol=1e-9)  # same rounding bound as above
    assert est.model.nk == (NK,)
    assert est.options["solver"] == ("qr" if method == "qr" else "gram")


@pytest.mark.parametrize("method", ["qr", "gram", "auto"])
def test_two_inputs_different_nb_nk(method):
    rng = np.random.default_rng(2)
    u = rng.normal(size=(1500, 2))
    b2, nk2 = np.array([0.3, -0.2, 0.1]), 2
    model = PolynomialModel.arx(A, [B, b2], [NK, nk2], DT)
    exp = Experiment.from_arrays(DT, u=u, y=model.simulate(u))
    est = fit_arx(exp, 2, [2, 3], [NK, nk2], method=method)
    assert est.names == ("a1", "a2", "u0:b0", "u0:b1", "u1:b0", "u1:b1", "u1:b2")
    # noise-free, inside the structure: rounding only (cond(Φ) ≈ 10)
    assert rel_err(est.parameters, np.concatenate([A[1:], B, b2])) < 1e-9
    assert est["u1:b2"] == pytest.approx(0.1, rel=1e-9)  # same rounding bound
    assert est.options["nb"] == [2, 3] and est.options["nk"] == [NK, nk2]


@pytest.mark.parametrize("method", ["qr", "gram", "auto"])
def test_experiment_set_noise_free_recovery(method):
    data = ExperimentSet(tuple(arx_record(n, seed=s) for n, s in ((400, 3), (250, 4), (600, 5))))
    est = fit_arx(data, 2, 2, NK, method=method)
    assert rel_err(est.parameters, TRUE) < 1e-9  # each segment starts at rest: exact, rounding only
    assert est.n_samples == (400 - 2) + (250 - 2) + (600 - 2)
    assert est.options["segments"] == 3
    # the residuals of a noise-free fit are rounding-level against |y| ~ 1
    assert np.max(np.abs(est.residuals)) < 1e-9


def test_gram_and_qr_agree_on_well_conditioned_noisy_data():
    exp = arx_record(3000, seed=6, sigma=0.3)
    qr = fit_arx(exp, 3, 3, 1, method="qr")
    gram = fit_arx(exp, 3, 3, 1, method="gram")
    assert gram.options["solver"] == "gram" and qr.options["condition"] < 1e2
    # Gram error ≈ ε·cond² ≈ 2e-16·1e4 = 2e-12, well inside 1e-8
    np.testing.assert_allclose(gram.parameters, qr.parameters, rtol=1e-8)
    np.testing.assert_allclose(gram.covariance, qr.covariance, rtol=1e-8)  # same ε·cond² bound
    assert gram.noise_variance == pytest.approx(qr.noise_variance, rel=1e-8)  # same bound


def ill_conditioned_record():
    """2nd-order 2 rad/s plant at 1 kHz (ZOH) driven by a slow PRBS: cond(Φ) > 1e3."""
    wn = 2.0
    model = c2d(TransferFunction([wn**2], [1.0, 1.4 * wn, wn**2]), DT, "zoh").to_polynomial()
    u = prbs(10, clock=100, periods=1, dt=DT).values
    return model, Experiment.from_arrays(DT, u=u, y=model.simulate(u))


def test_ill_conditioned_auto_falls_back_to_qr():
    model, exp = ill_conditioned_record()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # "auto" falls back silently
        est = fit_arx(exp, 2, 2, 1, method="auto")
    assert est.options["solver"] == "qr"
    assert est.options["condition"] > 1e3
    truth = np.concatenate([model.a[1:], model.b[0]])
    # QR error ≈ ε·cond ≈ 2e-16·1e3 relative to ‖θ‖; the b's are 1e-6 of the a's, so 1e-9·(a/b)
    assert np.max(np.abs(est.parameters - truth)) < 1e-9 * np.max(np.abs(truth))


def test_ill_conditioned_gram_warns_and_uses_qr():
    _, exp = ill_conditioned_record()
    with pytest.warns(ServoidWarning, match=r"too ill-conditioned .* solved by QR instead"):
        est = fit_arx(exp, 2, 2, 1, method="gram")
    assert est.options["solver"] == "qr"


# -- 2. segments -------------------------------------------------------------------------------


def test_experiment_set_stacks_regressors_per_segment():
    segs = [arx_record(n, seed=s, sigma=0.2) for n, s in ((300, 7), (200, 8), (350, 9))]
    na, nb, nk = 2, 3, 1
    start = 3  # the longest lag, nk + nb − 1
    parts = [manual_regressor(s["u"], s["y"], na, nb, nk, start) for s in segs]
    phi = np.vstack([p[0] for p in parts])
    target = np.concatenate([p[1] for p in parts])
    expected, *_ = np.linalg.lstsq(phi, target, rcond=None)  # Φ holds −y: θ = (a, b) directly
    for method in ("qr", "gram"):
        est = fit_arx(ExperimentSet(tuple(segs)), na, nb, nk, method=method)
        assert est.n_samples == phi.shape[0]
        # two least-squares solvers on cond(Φ) ≈ 10: ε·cond² at most
        np.testing.assert_allclose(est.parameters, expected, rtol=1e-10)
        resid = target - phi @ expected
        # σ̂² = RSS/(N − n) from the hand-built regression; rounding only
        assert est.noise_variance == pytest.approx(resid @ resid / (len(target) - 5), rel=1e-10)


def test_joining_segments_end_to_end_gives_a_different_answer():
    segs = [arx_record(n, seed=s) for n, s in ((300, 10), (300, 11), (300, 12))]
    separate = fit_arx(ExperimentSet(tuple(segs)), 2, 2, NK, method="qr")
    joined = Experiment.from_arrays(
        DT,
        u=np.concatenate([s["u"] for s in segs]),
        y=np.concatenate([s["y"] for s in segs]),
    )
    wrong = fit_arx(joined, 2, 2, NK, method="qr")
    assert rel_err(separate.parameters, TRUE) < 1e-9  # exact within segments, rounding only
    # across a boundary the lags mix two records: a few bad equations bias θ far above rounding
    assert rel_err(wrong.parameters, TRUE) > 1e-4
    assert wrong.n_samples == separate.n_samples + 2 * 2  # the 2 boundary-crossing rows per joint


@pytest.mark.parametrize("method", ["qr", "gram"])
def test_segment_shorter_than_the_start_contributes_nothing(method):
    segs = [arx_record(500, seed=13, sigma=0.1), arx_record(3, seed=14), arx_record(400, seed=15)]
    est = fit_arx(ExperimentSet(tuple(segs)), 2, 2, NK, method=method, start=5)
    ref = fit_arx(ExperimentSet((segs[0], segs[2])), 2, 2, NK, method="qr", start=5)
    # the 3-sample segment has no equation; QR vs Gram on cond ≈ 5: ε·cond²
    np.testing.assert_allclose(est.parameters, ref.parameters, rtol=1e-10)
    assert est.n_samples == ref.n_samples == 495 + 395


def test_start_sets_a_common_first_equation():
    exp = arx_record(500, seed=16, sigma=0.1)
    est = fit_arx(exp, 1, 1, 1, start=7)
    assert est.n_samples == 500 - 7 and est.options["start"] == 7
    with pytest.raises(DataError, match="start must be >= the longest lag 2, got 1"):
        fit_arx(exp, 2, 2, 1, start=1)


# -- 6. bad input ------------------------------------------------------------------------------


def test_constant_input_is_not_persistently_exciting():
    exp = Experiment.from_arrays(
        DT, u=np.full(200, 0.7), y=np.random.default_rng(0).normal(size=200)
    )
    with pytest.raises(
        IdentifiabilityError, match=r"input 'u' is constant .* persistently exciting"
    ):
        fit_arx(exp, 2, 2, 1)


def test_zero_input_is_not_persistently_exciting():
    exp = Experiment.from_arrays(DT, u=np.zeros(200), y=np.random.default_rng(0).normal(size=200))
    with pytest.raises(IdentifiabilityError, match=r"constant \(0 for all 200 samples\)"):
        fit_arx(exp, 2, 2, 1)


def test_too_few_samples_for_the_orders():
    exp = arx_record(6, seed=0)
    with pytest.raises(
        DataError, match=r"ARX\(na=2, nb=2, nk=1\) has 4 parameters and needs at least 7 samples"
    ):
        fit_arx(exp, 2, 2, 1)


def test_missing_input_role():
    with pytest.raises(DataError, match=r"no reference \('r'\) channel; it has: u \(u\), y \(y\)"):
        fit_arx(arx_record(100, seed=0), 2, 2, 1, input="r")


def test_several_outputs_need_output():
    rng = np.random.default_rng(0)
    exp = Experiment.from_arrays(DT, u=rng.normal(size=100), y=rng.normal(size=(100, 2)))
    with pytest.raises(DataError, match=r"2 outputs \(y0, y1\); the model fits one: pass output="):
        fit_arx(exp, 1, 1, 1)
    assert fit_arx(exp, 1, 1, 1, output="y1").options["output"] == "y1"


@pytest.mark.parametrize(
    ("orders", "error", "match"),
    [
        ((-1, 2, 1), DataError, "na must be >= 0, got -1"),
        ((2, 0, 1), DataError, "nb must be >= 1, got 0"),
        ((2, 2, -1), DataError, "nk must be >= 0, got -1"),
        ((1.5, 2, 1), TypeError, "na must be an integer, got 1.5"),
        ((2, 2.0, 1), TypeError, "nb must be an integer, got 2.0"),
        ((2, True, 1), TypeError, "nb must be an integer, got True"),
    ],
)
def test_bad_orders(orders, error, match):
    with pytest.raises(error, match=match):
        fit_arx(arx_record(100, seed=0), *orders)


def test_nb_per_input_of_the_wrong_length():
    rng = np.random.default_rng(0)
    exp = Experiment.from_arrays(DT, u=rng.normal(size=(100, 2)), y=rng.normal(size=100))
    with pytest.raises(DataError, match=r"nb needs one value per input \(2\), got \[1, 2, 3\]"):
        fit_arx(exp, 1, [1, 2, 3], 1)


def test_unknown_method_lists_the_valid_ones():
    with pytest.raises(OptionError, match="method must be one of 'auto', 'qr', 'gram'; got 'svd'"):
        fit_arx(arx_record(100, seed=0), 2, 2, 1, method="svd")


def test_unstable_estimate_warns():
    exp = arx_record(400, seed=17, a=np.array([1.0, -1.01]), b=np.array([1.0]))
    with pytest.warns(ServoidWarning, match=r"unstable: largest pole magnitude 1.01 > 1"):
        est = fit_arx(exp, 1, 1, 1)
    assert est["a1"] == pytest.approx(-1.01, rel=1e-9)  # noise-free, rounding only


# -- lstsq / solve_gram ------------------------------------------------------------------------


def test_lstsq_matches_numpy_and_reports_covariance():
    rng = np.random.default_rng(18)
    phi = rng.normal(size=(200, 3)) * [1.0, 1e3, 1e-3]  # units differ; equilibration hides it
    y = phi @ [1.0, 2.0, 3.0] + 0.1 * rng.normal(size=200)
    res = lstsq(phi, y, ("p", "q", "r"))
    theta, rss, *_ = np.linalg.lstsq(phi, y, rcond=None)
    np.testing.assert_allclose(res.theta, theta, rtol=1e-10)  # ε·cond of the scaled Φ ≈ 1
    assert res.rss == pytest.approx(float(rss[0]), rel=1e-10)  # same rounding bound
    cov = res.rss / 197 * np.linalg.inv(phi.T @ phi)
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-8)  # inv of ΦᵀΦ: ε·cond(Φ)² unscaled
    assert res.method == "qr" and res.dof == 197


def test_lstsq_rejects_rank_deficient_and_zero_columns():
    rng = np.random.default_rng(19)
    x = rng.normal(size=50)
    with pytest.raises(IdentifiabilityError, match=r"rank deficient .*columns: p, q"):
        lstsq(np.column_stack([x, 2 * x]), x, ("p", "q"))
    with pytest.raises(IdentifiabilityError, match="regressor q is identically zero"):
        lstsq(np.column_stack([x, np.zeros(50)]), x, ("p", "q"))
    with pytest.raises(
        DataError, match=r"need phi \(N, n\) and y \(N,\), got \(50, 1\) and \(49,\)"
    ):
        lstsq(x[:, None], x[:49])


def test_solve_gram_equals_lstsq_and_refuses_ill_conditioned():
    rng = np.random.default_rng(20)
    phi = rng.normal(size=(300, 3))
    y = phi @ [1.0, -1.0, 0.5] + 0.1 * rng.normal(size=300)
    aug = np.column_stack([phi, y])
    res = solve_gram(aug.T @ aug, 300)
    ref = lstsq(phi, y)
    assert res is not None and res.method == "gram"
    np.testing.assert_allclose(res.theta, ref.theta, rtol=1e-10)  # ε·cond² with cond ≈ 1.2
    t = np.linspace(0, 1, 300)
    mono = t[:, None] ** np.arange(7)  # monomials 1 … t⁶: nearly collinear
    assert lstsq(mono, y).condition > 1e3
    bad = np.column_stack([mono, y])
    assert solve_gram(bad.T @ bad, 300) is None
