"""The start of the prediction-error search: scored starts, auto initial values.

Known answers come from scipy.signal.lfilter (not servoid's simulation),
with coloured output noise and several seeds.
"""

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import ServoidWarning
from servoid.data import Experiment
from servoid.datasets import load_daisy
from servoid.estimate import fit_oe
from servoid.estimate._pem_orders import PemOrders, prepare
from servoid.estimate._pem_start import iv_start
from servoid.validate import validate

N = 3000
#: output noise RMS over the noise-free output RMS: high enough that the IV start alone
#: misses the minimum on some records (seeds 0, 2, 4, 9 of the 6th order)
NOISE = 0.25


def modal(modes):
    """Numerator (coefficients of q⁻¹, q⁻²…) and denominator of Σ_k g_k G_k."""
    num, den = np.zeros(1), np.ones(1)
    for r, w, g in modes:
        d = np.array([1.0, -2.0 * r * np.cos(w), r * r])
        n = g * d.sum() * np.array([1.0, 0.0])  # DC gain g per mode
        num = np.polyadd(np.polymul(num, d), np.polymul(n, den)) if num.any() else n
        den = np.polymul(den, d)
    return np.trim_zeros(num, "b"), den


#: lightly damped modes (radii 0.93–0.98), each excited by a white binary input
SYSTEMS = {
    4: modal([(0.98, 0.3, 1.0), (0.95, 1.1, 0.7)]),
    6: modal([(0.98, 0.25, 1.0), (0.96, 0.8, 0.8), (0.93, 1.7, 1.5)]),
}


def record(order, seed):
    b, f = SYSTEMS[order]
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(N))
    x = lfilter(np.r_[0.0, b], f, u)  # from rest, delay 1
    v = lfilter([1.0, 0.5], [1.0, -0.8], rng.standard_normal(N))  # coloured output noise
    return Experiment.from_arrays(1.0, u=u, y=x + NOISE * np.std(x) / np.std(v) * v)


@pytest.mark.parametrize("order", [4, 6])
@pytest.mark.parametrize("seed", [0, 2, 4])
def test_oe_with_lightly_damped_poles_reaches_the_true_minimum(order, seed):
    b, f = SYSTEMS[order]
    truth = np.r_[b, f[1:]]
    exp = record(order, seed)
    est = fit_oe(exp, b.size, order, 1)
    # the record starts at rest: auto keeps zero initial values (coloured noise alone must
    # not switch it)
    assert est.options["initial"] == "zero"
    # the minimum next to the truth: the search started at the true θ ends at the same cost
    # (stop tolerance 1e-9 relative; 1e-6 leaves room for the two paths)
    at_truth = fit_oe(exp, b.size, order, 1, init=truth, initial="zero")
    assert est.options["cost"] == pytest.approx(at_truth.options["cost"], rel=1e-6)
    # and every parameter within 4σ of the robust (coloured-noise) standard error
    z = (est.parameters - truth) / np.sqrt(np.diag(est.covariance))
    assert np.max(np.abs(z)) < 4.0


def test_sixth_order_start_from_iv_alone_misses_the_minimum():
    # the reason for the scored starts: from the IV start alone this record's search
    # ends in a worse minimum (or stalls); the scored starts reach the one next to the truth
    b, _ = SYSTEMS[6]
    exp = record(6, 0)
    theta_iv, _ = iv_start(PemOrders(0, b.size, 0, 0, 6, 1, 1), prepare(exp, "u", None), 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # it may stop at max_iter
        from_iv = fit_oe(exp, b.size, 6, 1, init=theta_iv, initial="zero")
    est = fit_oe(exp, b.size, 6, 1)
    assert est.options["cost"] < 0.9 * from_iv.options["cost"]
    assert "Steiglitz-McBride" in est.options["start"] or "runner-up" in est.options["start"]


@pytest.fixture(scope="module")
def arm():
    exp = load_daisy("robot_arm").detrend("mean")
    half = exp.n_samples // 2
    return exp.slice(0, half), exp.slice(half, exp.n_samples)


def test_flexible_arm_oe_matches_the_block_models_linear_part(arm):
    est_half, held_back = arm
    est = fit_oe(est_half, 6, 6, 1)
    # the arm's poles at radius 0.996 ring for ~2000 samples, four times the 512-sample half:
    # the record does not start at rest and auto estimates the initial values
    assert est.options["initial"] == "estimate"
    assert validate(est, est_half).fit_percent >= 96.0
    assert validate(est, held_back).fit_percent >= 96.0
    # with zero initial values the criterion differs and so does its minimum (no local-minimum
    # trap: the IV-started and the scored-start searches agree to the stop tolerance)
    zero = fit_oe(est_half, 6, 6, 1, initial="zero")
    assert zero.options["initial"] == "zero"
    assert validate(zero, est_half).fit_percent < 95.0
