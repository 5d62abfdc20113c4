"""fit_n4sid: noise-free recovery, pole scatter over seeds, the order rule, bad input.

Data come from generators the estimator does not share:

- SISO: :func:`servoid.bench.simulate_lti` integrates a continuous plant exactly at 20× the
  logging rate under a ZOH (staircase) input, so the sampled system is exactly the ZOH
  equivalent :func:`servoid.models.c2d` gives, of the plant's order.
- MIMO: a continuous 2-input 2-output plant, discretised at the fast rate dt/20 by the rig's
  own ``bench._analog.discretise`` (the route simulate_lti takes for one path) and simulated on
  the held input, then sampled every 20th step.
"""

import json
import warnings

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from servoid import (
    ChannelError,
    DataError,
    Experiment,
    ExperimentSet,
    IdentifiabilityError,
    OptionError,
    ServoidWarning,
)
from servoid.bench import simulate_lti
from servoid.bench._analog import discretise
from servoid.estimate import fit_n4sid
from servoid.models import StateSpace, TransferFunction, c2d

DT = 2e-3
OVERSAMPLE = 20
WEIGHTINGS = ["moesp", "cva", "n4sid"]
# A servo-like plant: 20 Hz resonance (ζ = 0.2) behind a 5 Hz lag; discrete |z| = 0.951, 0.939.
W_RES, W_LAG = 2 * np.pi * 20, 2 * np.pi * 5
PLANT = TransferFunction(
    [W_RES**2 * W_LAG], np.polymul([1, 2 * 0.2 * W_RES, W_RES**2], [1, W_LAG])
)
TRUTH = c2d(PLANT, DT)  # exact ZOH equivalent, order 3
OMEGA = np.linspace(1.0, 0.95 * np.pi / DT, 60)  # up to 95 % of Nyquist [rad/s]

# 2×2, order 4: a 12 Hz resonance driven by u0 and by a 4 Hz lag from u1; a 25 Hz lag from u0
# and the lag state to y1. Discrete |z| = 0.963 (pair), 0.951, 0.730.
_W = 2 * np.pi * 12
MIMO_PLANT = StateSpace(
    [[0, 1, 0, 0], [-_W**2, -2 * 0.25 * _W, 0.3 * _W**2, 0],
     [0, 0, -2 * np.pi * 4, 0], [0, 0, 5.0, -2 * np.pi * 25]],
    [[0, 0], [_W**2, 0], [0, 2 * np.pi * 4], [2 * np.pi * 25, 0]],
    [[1.0, 0, 0, 0], [0, 0, 0, 1.0]],
    np.zeros((2, 2)),
)
MIMO_TRUTH = c2d(MIMO_PLANT, DT)
_MIMO_FAST = discretise(MIMO_PLANT, DT / OVERSAMPLE, "zoh")


def siso_record(n, noise_std=0.0, seed=0):
    u = np.random.default_rng(1000 + seed).standard_normal(n)
    return simulate_lti(PLANT, u, DT, oversample=OVERSAMPLE, noise_std=noise_std, rng=seed)


def mimo_record(n, noise_std=0.0, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 2))
    y = _MIMO_FAST.simulate(np.repeat(u, OVERSAMPLE, axis=0))[::OVERSAMPLE]
    return Experiment.from_arrays(DT, u=u, y=y + noise_std * rng.standard_normal(y.shape))


def rel_tf_error(model, truth):
    g, gt = model.freqresp(OMEGA), truth.freqresp(OMEGA)
    return float(np.max(np.abs(g - gt)) / np.max(np.abs(gt)))


def matched_pole_errors(poles, truth):
    """Estimated minus true poles, paired by the assignment of least total distance."""
    cost = np.abs(poles[:, None] - truth[None, :])
    rows, cols = linear_sum_assignment(cost)
    order = np.argsort(cols)
    return (poles[rows] - truth[cols])[order], rows[order]


def pole_std(est):
    """σ of Re and Im of each pole, by the delta method through the roots of F (last n θ)."""
    n = est.options["order"]
    f = np.concatenate([[1.0], est.parameters[-n:]])
    poles = np.roots(f)
    slope = np.polyval(np.polyder(f), poles)
    jac = np.array([[-p ** (n - k) / s for k in range(1, n + 1)] for p, s in zip(poles, slope)])
    cov = est.covariance[-n:, -n:]
    var_re = np.einsum("ik,kl,il->i", jac.real, cov, jac.real)
    var_im = np.einsum("ik,kl,il->i", jac.imag, cov, jac.imag)
    return poles, np.sqrt(var_re), np.sqrt(var_im)


# -- noise-free recovery ---------------------------------------------------------------------


@pytest.mark.parametrize("weighting", WEIGHTINGS)
def test_noise_free_siso_recovers_order_and_transfer_function(weighting):
    est = fit_n4sid(siso_record(2000), weighting=weighting)
    assert est.options["order"] == 3
    # Gram route: the subspace error is about ε·‖G‖/σ_n² ≈ 1e-12 here; 1e-8 leaves room for
    # the rig's 20 composed fast steps and the conditioning of the poles near z = 1
    assert rel_tf_error(est.model, TRUTH) < 1e-8
    err, _ = matched_pole_errors(est.model.poles(), TRUTH.poles())
    assert np.max(np.abs(err)) < 1e-8  # same rounding bound, on the eigenvalues
    # θ is the OE form of the same model: its realisation has the same response (rounding)
    assert rel_tf_error(est.model_at(est.parameters), TRUTH) < 1e-8
    assert est.names == ("b0", "b1", "b2", "f1", "f2", "f3")
    assert np.all(est.std < 1e-9)  # noise-free: the covariance is at the rounding level
    assert est.options["kalman_gain"] is None and "noise-free" in est.options["kalman_note"]


@pytest.mark.parametrize("weighting", WEIGHTINGS)
def test_noise_free_mimo_recovers_order_and_transfer_matrix(weighting):
    est = fit_n4sid(mimo_record(3000), weighting=weighting)
    assert est.options["order"] == 4
    assert est.model.n_inputs == 2 and est.model.n_outputs == 2
    assert rel_tf_error(est.model, MIMO_TRUTH) < 1e-8  # rounding, as in the SISO case
    err, _ = matched_pole_errors(est.model.poles(), MIMO_TRUTH.poles())
    assert np.max(np.abs(err)) < 1e-8  # same bound
    # the common-denominator OE realisation (order n·ny) has the same transfer matrix
    assert rel_tf_error(est.model_at(est.parameters), MIMO_TRUTH) < 1e-8
    assert est.names[:5] == ("u0->y0:b0", "u0->y0:b1", "u0->y0:b2", "u0->y0:b3", "u1->y0:b0")
    assert est.names[-4:] == ("f1", "f2", "f3", "f4")


def test_experiment_set_estimates_each_initial_state():
    """The second segment starts mid-record (x0 ≠ 0): no window crosses the join."""
    exp = siso_record(3000)
    data = ExperimentSet((exp.slice(0, 1400), exp.slice(1600, 3000)))
    est = fit_n4sid(data, 3)
    assert rel_tf_error(est.model, TRUTH) < 1e-8  # rounding, as above
    x0 = [np.asarray(x) for x in est.options["x0"]]
    assert np.max(np.abs(x0[0])) < 1e-8 * np.max(np.abs(x0[1]))  # the record starts at rest
    resid = est.residuals
    assert resid.shape == (2800,)
    # with the estimated x0 the simulation matches the data from the first sample (rounding)
    assert np.max(np.abs(resid)) < 1e-8 * np.max(np.abs(exp["y"]))


def test_feedthrough_recovers_d():
    true = StateSpace([[0.8, 0.3], [-0.3, 0.8]], [[1.0], [0.5]], [[1.0, -0.4]], [[0.7]], dt=DT)
    u = np.random.default_rng(3).standard_normal(1500)
    exp = Experiment.from_arrays(DT, u=u, y=true.simulate(u))
    est = fit_n4sid(exp, 2, feedthrough=True)
    assert est.model.D[0, 0] == pytest.approx(0.7, rel=1e-9)  # noise-free: rounding only
    assert rel_tf_error(est.model, true) < 1e-9  # same
    assert est.names == ("b0", "b1", "b2", "f1", "f2") and est.options["nk"] == 0


def test_unstable_plant_uses_the_state_sequences():
    """An unstable estimate cannot be fitted by simulation: B, D from the state sequences."""
    true = StateSpace([[1.01, 0.2], [0.0, 0.6]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=DT)
    u = np.random.default_rng(4).standard_normal(600)
    exp = Experiment.from_arrays(DT, u=u, y=true.simulate(u))
    with pytest.warns(ServoidWarning, match="unstable.*state sequences"):
        est = fit_n4sid(exp, 2, horizon=10)
    assert rel_tf_error(est.model, true) < 1e-7  # noise-free, exact projections; y grows 400×
    assert np.all(np.isnan(est.covariance))
    assert est.options["solver"].startswith("state sequences")


# -- noisy data: poles over seeds -------------------------------------------------------------


def _pole_study(record, truth, weighting, seeds):
    """Fit each record with the order chosen by the rule (the same fit as with order given:
    the first-pass horizon is 2·max_order = 20 either way)."""
    errors, predicted, orders = [], [], []
    for seed in seeds:
        with warnings.catch_warnings():
            warnings.simplefilter("error", ServoidWarning)  # a clear gap: no warning
            est = fit_n4sid(record(seed), weighting=weighting)
        orders.append(est.options["order"])
        if est.options["order"] != truth.poles().size:
            continue
        poles, s_re, s_im = pole_std(est)
        err, idx = matched_pole_errors(poles, truth.poles())
        errors.append(np.concatenate([err.real, err.imag]))
        predicted.append(np.concatenate([s_re[idx], s_im[idx]]))
    return np.array(errors), np.array(predicted), orders


def _check_scatter(errors, predicted):
    r = errors.shape[0]
    sd = errors.std(axis=0, ddof=1)
    real = sd > 0  # the imaginary part of a real pole is exactly zero
    # unbiased: each mean error within 4 standard errors of the scatter over seeds
    assert np.all(np.abs(errors.mean(axis=0)[real]) < 4 * sd[real] / np.sqrt(r))
    # honest covariance: the scatter is within 2× of the returned PEM σ (20 seeds estimate an
    # sd to ±16 %; a 30-seed study found ratios 0.7–1.4 for these plants and horizons)
    ratio = sd[real] / predicted.mean(axis=0)[real]
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


@pytest.mark.parametrize("weighting", ["moesp", "cva"])
def test_noisy_siso_poles_unbiased_and_scatter_matches_covariance(weighting):
    # N = 3000, white measurement noise σ = 0.05 (SNR ≈ 12 dB); order chosen in every seed
    errors, predicted, orders = _pole_study(
        lambda s: siso_record(3000, 0.05, s), TRUTH, weighting, range(20)
    )
    assert orders == [3] * 20
    _check_scatter(errors, predicted)


def test_noisy_mimo_poles_unbiased_and_scatter_matches_covariance():
    # MOESP here; CVA and N4SID with 40 seeds in the slow study below
    errors, predicted, orders = _pole_study(
        lambda s: mimo_record(3000, 0.05, s), MIMO_TRUTH, "moesp", range(12)
    )
    assert orders == [4] * 12
    _check_scatter(errors, predicted)


def test_noise_variance_and_innovation_covariance_match_the_noise():
    est = fit_n4sid(siso_record(20000, 0.05, 1), 3)
    sigma2 = 0.05**2
    # σ̂² of N = 2e4 white residuals: relative sd √(2/N) = 1 %; 4σ
    assert est.noise_variance == pytest.approx(sigma2, rel=4 * np.sqrt(2 / 20000))
    # output noise that is white is its own innovation (K → 0): same variance within 4σ
    # (plus a few per cent for the finite-horizon Kalman-state estimate)
    (re,), = est.options["innovation_covariance"]
    assert re == pytest.approx(sigma2, rel=0.06)
    json.dumps(est.to_dict())  # options are JSON-friendly


# -- the order rule ------------------------------------------------------------------------------


def test_order_rule_counts_a_weak_fast_mode():
    """10 Hz resonance and a 40 Hz lag (|z| = 0.60): the lag's singular value is 25× below
    the resonance's but 10× above the noise; the largest-gap rule would choose order 2."""
    w, p = 2 * np.pi * 10, 2 * np.pi * 40
    plant = TransferFunction([w**2 * p], np.polymul([1, 2 * 0.3 * w, w**2], [1, p]))
    u = np.random.default_rng(105).standard_normal(20000)
    exp = simulate_lti(plant, u, DT, noise_std=0.03, rng=5)  # SNR ≈ 20 dB
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)
        est = fit_n4sid(exp)
    sv = est.options["singular_values"]
    assert est.options["order"] == 3
    assert sv[1] / sv[2] > sv[2] / sv[3]  # the largest drop is after order 2


@pytest.mark.filterwarnings("ignore:the estimated model is unstable")
def test_order_rule_warns_without_a_gap():
    """Output noise unrelated to the input: the singular values only decay slowly."""
    rng = np.random.default_rng(6)
    exp = Experiment.from_arrays(DT, u=rng.standard_normal(3000), y=rng.standard_normal(3000))
    with pytest.warns(ServoidWarning, match="no clear gap"):
        fit_n4sid(exp)


def test_order_rule_warns_at_max_order():
    with pytest.warns(ServoidWarning, match="largest max_order considers"):
        est = fit_n4sid(siso_record(2000), max_order=2)
    assert est.options["order"] == 2 and est.options["max_order"] == 2


def test_options_record_the_choices():
    est = fit_n4sid(siso_record(2000, 0.05, 2))
    opts = est.options
    assert opts["weighting"] == "moesp" and opts["inputs"] == ["u"] and opts["outputs"] == ["y"]
    past, future = opts["horizon"]
    # first pass 2·max_order = 20; then as long as the slowest pole takes to decay to 25 %
    assert opts["horizon_first_pass"] == 20
    radius = opts["slowest_pole_first_pass"]
    assert radius == pytest.approx(0.951, abs=0.01)  # the true slowest |z|, noisy estimate
    assert past == future == int(np.ceil(np.log(0.25) / np.log(radius)))
    assert len(opts["singular_values"]) == future  # one output: f·ny singular values
    assert opts["singular_values"] == sorted(opts["singular_values"], reverse=True)
    assert opts["order_rule"].startswith("last log singular-value gap")


def test_output_selects_channels():
    exp = mimo_record(3000)
    est = fit_n4sid(exp, 4, output=["y1"])  # y1 sees the 25 Hz lag and the 4 Hz lag: order 2
    assert est.model.n_outputs == 1 and est.options["outputs"] == ["y1"]
    g = est.model.freqresp(OMEGA)  # (N, 1, 2)
    assert np.max(np.abs(g[:, 0, :] - MIMO_TRUTH.freqresp(OMEGA)[:, 1, :])) < 1e-8  # rounding


# -- bad input -----------------------------------------------------------------------------------


def test_order_larger_than_the_horizons_allow():
    with pytest.raises(DataError, match=r"order 12 .* horizon=\(past, future\) with future >= 13"):
        fit_n4sid(siso_record(2000), 12, horizon=(10, 10))


def test_record_too_short_for_the_horizons():
    with pytest.raises(DataError, match=r"too short for horizons past=20.*Use shorter horizons"):
        fit_n4sid(siso_record(150), 3, horizon=20)


def test_record_too_short_for_the_order():
    with pytest.raises(DataError, match="too short for order 8.*longer record or a lower order"):
        fit_n4sid(siso_record(40), 8)


def test_constant_input():
    exp = Experiment.from_arrays(DT, u=np.ones(500), y=np.random.default_rng(0).normal(size=500))
    with pytest.raises(IdentifiabilityError, match="constant.*PRBS, multisine or chirp"):
        fit_n4sid(exp)


def test_input_not_persistently_exciting():
    t = np.arange(2000) * DT
    exp = Experiment.from_arrays(DT, u=np.sin(2 * np.pi * 7 * t), y=np.cos(2 * np.pi * 7 * t))
    with pytest.raises(IdentifiabilityError, match="not persistently exciting.*PRBS or multisine"):
        fit_n4sid(exp, 2)


def test_unknown_weighting():
    with pytest.raises(OptionError, match="weighting must be one of 'moesp', 'cva', 'n4sid'"):
        fit_n4sid(siso_record(500), 3, weighting="pca")


def test_unknown_output_channel():
    with pytest.raises(ChannelError, match="no channel named 'z'"):
        fit_n4sid(siso_record(500), 3, output="z")


def test_zero_output():
    exp = Experiment.from_arrays(DT, u=np.random.default_rng(0).normal(size=500), y=np.zeros(500))
    with pytest.raises(IdentifiabilityError, match="identically zero"):
        fit_n4sid(exp)


# -- a longer study --------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("weighting", WEIGHTINGS)
def test_pole_scatter_study(weighting):
    """The full version of the scatter tests: 40 seeds each, SISO and MIMO."""
    for record, truth in ((lambda s: siso_record(3000, 0.05, s), TRUTH),
                          (lambda s: mimo_record(3000, 0.05, s), MIMO_TRUTH)):
        errors, predicted, orders = _pole_study(record, truth, weighting, range(40))
        assert orders == [truth.poles().size] * 40
        _check_scatter(errors, predicted)
