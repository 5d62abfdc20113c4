"""fit_frf: continuous transfer functions fitted to measured frequency responses.

Known answers on exact responses, the statistics of the ML fit on responses with complex
Gaussian errors of known variance, and the whole chain rig → estimate_frf → fit_frf with
a band-limited periodic input (so that the sampled response is G(jω) itself, not the
zero-order-hold's) and a band-limited random input (Welch).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import fields

import numpy as np
import pytest
from scipy import signal as sps

from servoid import DataError, IdentifiabilityError, ModelError, OptionError, ServoidWarning
from servoid.bench import simulate_lti
from servoid.estimate import estimate_frf, fit_frf, fit_tf
from servoid.models import FrequencyResponseData, TransferFunction
from servoid.signals import multisine

# a servo valve-like 2nd-order loop at 800 Hz and a 3rd-order plant with a zero: lines at
# 1e2..4e4 rad/s, where unscaled power columns would span 1e-9..1e9
WN, ZETA = 2 * np.pi * 800.0, 0.35
SERVO = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
PLANT3 = TransferFunction(
    np.polymul([1 / (2 * np.pi * 1500.0), 1.0], [WN**2]),
    np.polymul([1 / (2 * np.pi * 2500.0), 1.0], SERVO.den),
)
F_LINES = np.geomspace(20.0, 6000.0, 80)


def _theta(g: TransferFunction) -> np.ndarray:
    return np.concatenate([g.num, g.den[1:]])


def _noisy(g: TransferFunction, rel: float, seed: int) -> FrequencyResponseData:
    """Exact response plus circular complex Gaussian errors of variance (rel·|G|)²."""
    rng = np.random.default_rng(seed)
    resp = g.freqresp(2 * np.pi * F_LINES)
    var = (rel * np.abs(resp)) ** 2
    noise = np.sqrt(var / 2) * (rng.standard_normal(resp.size)
                                + 1j * rng.standard_normal(resp.size))
    return FrequencyResponseData(F_LINES, resp + noise, variance=var, method="synthetic")


# -- known answers -------------------------------------------------------------------------------
@pytest.mark.parametrize(("g", "n_zeros"), [(SERVO, 0), (PLANT3, 1)])
def test_exact_response_is_recovered(g, n_zeros):
    frd = FrequencyResponseData(F_LINES, g.freqresp(2 * np.pi * F_LINES))
    est = fit_frf(frd, g.order, n_zeros)
    assert est.method == "frf" and est.options["weighting"] == "none"
    assert est.names == tuple([f"b{i}" for i in range(n_zeros, -1, -1)]
                              + [f"a{k}" for k in range(1, g.order + 1)])
    # noise-free data from a model inside the structure: rounding only (ε·cond of the scaled
    # problem ~1e4)
    np.testing.assert_allclose(est.parameters, _theta(g), rtol=1e-9)
    np.testing.assert_allclose(np.sort_complex(est.model.poles()), np.sort_complex(g.poles()),
                               rtol=1e-9)


def test_coefficients_are_named_as_fit_tf_names_them():
    # the same G(s) fitted from its response and from a noise-free record (fit_tf's ZOH
    # route is exact): the same names, units and values for the same coefficients
    frd = FrequencyResponseData(F_LINES, PLANT3.freqresp(2 * np.pi * F_LINES))
    by_frf = fit_frf(frd, 3, 1)
    dt = 1e-5
    u = np.repeat(np.sign(np.random.default_rng(3).standard_normal(600)), 10)
    by_tf = fit_tf(simulate_lti(PLANT3, u, dt), 3, 1, intersample="zoh")
    assert by_frf.names == by_tf.names == ("b1", "b0", "a1", "a2", "a3")
    # both noise-free, inside the structure: the ε·cond of each scaled problem (~1e4 · 1e-16)
    np.testing.assert_allclose(by_frf.parameters, by_tf.parameters, rtol=1e-6)
    assert by_frf["a3"] == pytest.approx(PLANT3.den[-1] / PLANT3.den[0], rel=1e-9)


def test_the_former_name_of_the_constant_term_reads_for_one_release():
    frd = FrequencyResponseData(F_LINES, SERVO.freqresp(2 * np.pi * F_LINES))
    est = fit_frf(frd, 2, 0)
    with pytest.warns(DeprecationWarning, match="'a0' is now 'a2'"):
        assert est["a0"] == est["a2"]


def test_default_zeros_follow_tfest():
    frd = FrequencyResponseData(F_LINES, PLANT3.freqresp(2 * np.pi * F_LINES))
    est = fit_frf(frd, 3)
    assert est.options["n_zeros"] == 2
    # the extra zero coefficient comes out zero: the model is the same (ε·cond)
    assert abs(est["b2"]) < 1e-9 * abs(est["b1"]) * WN
    np.testing.assert_allclose(est.model.freqresp([1e3, 1e4]), PLANT3.freqresp([1e3, 1e4]),
                               rtol=1e-9)


# -- statistics ----------------------------------------------------------------------------------
def test_ml_fit_statistics_over_seeds():
    runs = 20
    z, costs = [], []
    for seed in range(runs):
        est = fit_frf(_noisy(PLANT3, 0.02, seed), 3, 1)
        z.append((est.parameters - _theta(PLANT3)) / est.std)
        costs.append(est.noise_variance)
    z = np.array(z)
    # known variances: θ̂ is Gaussian with the returned covariance to first order, so every
    # error lies within 4σ (P(|z| > 4) = 6e-5; 100 coefficients)
    assert np.max(np.abs(z)) < 4.0
    # and the spread of z is 1 within 4 s.e. of a s.d. from 20 runs (1/√40 = 0.16)
    assert np.all(np.abs(z.std(axis=0) - 1) < 4 * 0.16)
    # the normalised cost V/(F − n/2) is χ²(2F − n)/(2F − n): mean 1, s.e. √(2/(2F − n))/√20
    dof = 2 * F_LINES.size - 5
    assert abs(np.mean(costs) - 1) < 4 * np.sqrt(2 / dof) / np.sqrt(runs)


# -- from the rig ---------------------------------------------------------------------------------
def _periodic_record(g: TransferFunction, seed: int, noise: float = 0.02):
    # a multisine generated at the rig's fast rate and sampled by the logger: band-limited,
    # so the logged lines carry G(jω) itself (no hold); 20 periods of 0.2 s at 10 kHz
    dt, os_, period = 1e-4, 20, 2000
    ex = multisine(period * os_, dt / os_, 5.0, 3000.0, periods=12, phases="random", rng=1)
    exp = simulate_lti(g, ex.values, dt, intersample="fast", oversample=os_, noise_std=noise,
                       rng=seed)
    return estimate_frf(exp, period=period)


def _pole_z_scores(est, truth: TransferFunction) -> np.ndarray:
    """(p̂ − p)/σ_p for the real and imaginary parts, σ_p by the delta method."""
    def poles(theta):
        return np.sort_complex(est.model_at(theta).poles())

    base = poles(est.parameters)
    step = 1e-7 * np.maximum(np.abs(est.parameters), 1e-12)
    jac = []
    for i in range(est.parameters.size):
        d = np.zeros_like(est.parameters)
        d[i] = step[i]
        jac.append((poles(est.parameters + d) - poles(est.parameters - d)) / (2 * step[i]))
    jac = np.array(jac).T  # (n_poles, n_theta), complex
    err = base - np.sort_complex(truth.poles())
    out = []
    for part in (np.real, np.imag):
        j = part(jac)
        sd = np.sqrt(np.einsum("ij,jk,ik->i", j, est.covariance, j))
        keep = sd > 0
        out.append(part(err)[keep] / sd[keep])
    return np.concatenate(out)


@pytest.mark.parametrize(("g", "n_zeros"), [(SERVO, 0), (PLANT3, 1)])
def test_rig_periodic_chain_recovers_poles_and_zeros(g, n_zeros):
    frd = _periodic_record(g, seed=3)
    assert frd.method == "periodic" and frd.n_averages == 11
    est = fit_frf(frd, g.order, n_zeros)
    # covariance grown by (M − 1)/(M − 3) for variances estimated from M = 11 periods
    assert est.options["covariance_factor"] == pytest.approx(10 / 8)
    # 4σ: θ, the poles, and the zero
    assert np.all(np.abs((est.parameters - _theta(g)) / est.std) < 4)
    assert np.all(np.abs(_pole_z_scores(est, g)) < 4)
    if n_zeros:
        zero_sd = abs(est["b0"] / est["b1"]) * np.hypot(est.std[0] / est["b1"],
                                                       est.std[1] / est["b0"])
        assert abs(est.model.zeros()[0] - g.zeros()[0]) < 4 * zero_sd  # delta method, 1st order
    # the normalised cost is F(2, 2(M − 1))-distributed per line: mean (M − 1)/(M − 2) = 1.11,
    # s.e. ≈ 1.24/√(F = 600) = 0.05
    assert abs(est.noise_variance - 10 / 9) < 4 * 0.05


def test_rig_welch_chain_with_a_band_limited_random_input():
    dt, os_ = 1e-4, 20
    rng = np.random.default_rng(4)
    # white noise at the fast rate through a 10th-order low-pass at 0.3·(1/dt): band-limited
    sos = sps.butter(10, 0.3 / (0.5 * os_), output="sos")
    u_fast = 5.0 * sps.sosfilt(sos, rng.standard_normal(2**15 * os_))
    exp = simulate_lti(SERVO, u_fast, dt, intersample="fast", oversample=os_, noise_std=0.02,
                       rng=5)
    frd = estimate_frf(exp, nperseg=2048, f_max=2000.0)
    est = fit_frf(frd, 2, 0)
    assert est.options["weighting"] == "variance" and est.options["frd_method"] == "welch"
    # 4σ with the coherence-based variance; the Hann window's leakage flattens the resonance
    # (a bias of ~1σ at this resolution, 4.9 Hz lines for a 2·ζ·800 = 560 Hz wide peak)
    assert np.all(np.abs((est.parameters - _theta(SERVO)) / est.std) < 4)


# -- the estimate --------------------------------------------------------------------------------
def test_estimate_carries_model_function_and_json_options():
    est = fit_frf(_noisy(SERVO, 0.01, 0), 2, 0)
    assert est.model.dt is None
    np.testing.assert_array_equal(est.model_at(est.parameters).den, est.model.den)
    shifted = est.model_at(est.parameters + np.array([0.0, 1.0, 0.0]))
    assert shifted.den[1] == pytest.approx(est.model.den[1] + 1.0)
    json.dumps(dict(est.options), allow_nan=False)
    assert est.n_samples == 2 * F_LINES.size and est.residuals.size == est.n_samples
    # normalised residuals: Σr² = 2V, so their mean square is V/(F − n/2)·(1 − n/(2F))
    assert np.mean(est.residuals**2) == pytest.approx(est.noise_variance * (1 - 3 / est.n_samples))
    assert est.units == ("1/s^2", "1/s", "1/s^2")


@pytest.mark.parametrize("weighting", ["relative", "none"])
def test_other_weightings_give_the_model_with_a_residual_scaled_covariance(weighting):
    est = fit_frf(_noisy(SERVO, 0.01, 1), 2, 0, weighting=weighting)
    # the same data: parameters within 4 of their own σ of the truth
    assert np.all(np.abs((est.parameters - _theta(SERVO)) / est.std) < 4)
    assert est.options["covariance_factor"] == pytest.approx(est.noise_variance)


def test_known_delay():
    tau = 2e-4
    if "delay" not in {f.name for f in fields(TransferFunction)}:
        frd = FrequencyResponseData(F_LINES, SERVO.freqresp(2 * np.pi * F_LINES))
        with pytest.raises(OptionError, match="delay"):
            fit_frf(frd, 2, 0, delay=tau)
        return
    late = TransferFunction(SERVO.num, SERVO.den, delay=tau)  # type: ignore[call-arg]
    frd = FrequencyResponseData(F_LINES, late.freqresp(2 * np.pi * F_LINES))
    est = fit_frf(frd, 2, 0, delay=tau)
    assert est.model.delay == tau
    # exact data: rounding only
    np.testing.assert_allclose(est.parameters, _theta(SERVO), rtol=1e-9)


# -- warnings and errors -------------------------------------------------------------------------
def test_rejected_structure_warns():
    with pytest.warns(ServoidWarning, match="rejected by the data"):
        fit_frf(_noisy(SERVO, 0.01, 2), 1, 0)


def test_unstable_fit_warns():
    unstable = TransferFunction([WN**2], [1.0, -0.2 * WN, WN**2])
    frd = FrequencyResponseData(F_LINES, unstable.freqresp(2 * np.pi * F_LINES))
    with pytest.warns(ServoidWarning, match="right half-plane"):
        est = fit_frf(frd, 2, 0)
    np.testing.assert_allclose(est.parameters, _theta(unstable), rtol=1e-9)


def test_auto_weighting_skips_zero_variances():
    # a noise-free periodic record has zero scatter across periods: equal weights instead
    frd = FrequencyResponseData(F_LINES, SERVO.freqresp(2 * np.pi * F_LINES),
                                variance=np.zeros(F_LINES.size))
    assert fit_frf(frd, 2, 0).options["weighting"] == "none"


def test_few_averages_warn():
    frd = _noisy(SERVO, 0.01, 3)
    frd = FrequencyResponseData(frd.frequency, frd.response, variance=frd.variance,
                                n_averages=3, method="periodic")
    with pytest.warns(ServoidWarning, match="fewer than 4"):
        fit_frf(frd, 2, 0)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"n_poles": 2, "n_zeros": 3}, ModelError, r"n_zeros must be <= n_poles = 2"),
        ({"n_poles": 0}, DataError, r"n_poles must lie in 1..30"),
        ({"n_poles": 2, "weighting": "log"}, OptionError, r"'auto', 'variance'"),
        ({"n_poles": 2, "weighting": "variance", "frd": "plain"}, OptionError,
         r"needs a response with a variance per line"),
        ({"n_poles": 2, "weighting": "variance", "frd": "zero-variance"}, DataError,
         r"zero variance.*weighting='relative'"),
        ({"n_poles": 30, "n_zeros": 30, "frd": "plain"}, IdentifiabilityError,
         r"61 parameters.*the response has 30"),
        ({"n_poles": 2, "delay": -1.0}, DataError, r"delay must be >= 0"),
    ],
)
def test_bad_input(kwargs, error, match):
    f = F_LINES[:30]
    resp = SERVO.freqresp(2 * np.pi * f)
    frds = {
        "default": FrequencyResponseData(f, resp, variance=np.full(f.size, 1e-4)),
        "plain": FrequencyResponseData(f, resp),
        "zero-variance": FrequencyResponseData(f, resp, variance=np.zeros(f.size)),
    }
    frd = frds[kwargs.pop("frd", "default")]
    with pytest.raises(error, match=match), warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        fit_frf(frd, **kwargs)


def test_frd_type_is_checked():
    with pytest.raises(TypeError, match="FrequencyResponseData"):
        fit_frf(np.ones(3), 1)  # type: ignore[arg-type]
