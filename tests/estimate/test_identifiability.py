"""Identifiability diagnostics of the grey-box fits: numbers, flags, warnings.

The issue's example: "Generic grey-box fits reported std 1e-8 and 1e5 on
parameters the data cannot pin down, silently."  Each way that happens is
reproduced here and must now raise or warn, naming the parameters:

* an exact product k1·k2 or a parameter without effect: the Jacobian is
  rank deficient → IdentifiabilityError;
* a nearly confounded pair (a parameter with a 1e-4 effect): std 1.5e6 on a
  value of 2e3 → warned as correlated and undetermined;
* a Jacobian spoilt by a discontinuity inside the difference step: std 40×
  below what the noise allows → warned below the Hammersley–Chapman–Robbins
  floor and as a non-quadratic cost;
* a second minimum that fits as well (two time constants that can swap):
  warned by the several-start search.
"""

from __future__ import annotations

import json
import math
import re
import warnings

import numpy as np
import pytest
from scipy import signal as sps

from servoid import DataError, IdentifiabilityError, ServoidWarning
from servoid.bench import simulate_lti
from servoid.estimate import (
    Identifiability,
    MultistartSummary,
    check_identifiability,
    fit_greybox,
    fit_tf_greybox,
)
from servoid.models import TransferFunction

DT = 1e-3
N = 2000
WN = 2 * math.pi * 5
SERVO = TransferFunction([2.0 * WN**2], [1.0, 0.4 * WN, WN**2])  # K = 2, ζ = 0.2


def zoh2(k: float, w: float, z: float) -> TransferFunction:
    """ZOH image of K ω²/(s² + 2ζωs + ω²) (scipy)."""
    num, den, _ = sps.cont2discrete(([k * w * w], [1.0, 2 * z * w, w * w]), DT, method="zoh")
    return TransferFunction(np.ravel(num)[1:], den, DT, "zoh")


@pytest.fixture(scope="module")
def servo_record():
    u = np.repeat(np.sign(np.random.default_rng(7).standard_normal(N // 5)), 5)
    return simulate_lti(SERVO, u, DT, noise_std=0.05, rng=3)


def quiet_fit(*args, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        est = fit_tf_greybox(*args, **kw)
    return est, [w for w in caught if issubclass(w.category, ServoidWarning)]


# -- the numbers match an independent computation ----------------------------------------------


def test_correlation_and_condition_of_a_linear_model_match_numpy():
    # FIR G(q, θ) = θ0 + θ1 q⁻¹ + θ2 q⁻²: the Jacobian is −[u(t), u(t−1), u(t−2)] exactly
    rng = np.random.default_rng(4)
    u = sps.lfilter([1.0], [1.0, -0.8], rng.standard_normal(1500))  # correlated regressors
    theta = np.array([1.0, -0.5, 0.25])
    y = sps.lfilter(theta, [1.0], u) + 0.1 * rng.standard_normal(u.size)
    from servoid.data import Experiment

    exp = Experiment.from_arrays(1.0, u=u, y=y)

    def fir(t):
        return TransferFunction(t, [1.0, 0.0, 0.0], 1.0)

    est = fit_tf_greybox(exp, fir, [0.0, 0.0, 0.0], ("b0", "b1", "b2"), covariance="white")
    phi = np.column_stack([u, np.r_[0, u[:-1]], np.r_[0, 0, u[:-2]]])
    cov = est.noise_variance * np.linalg.inv(phi.T @ phi)
    corr = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    ident = est.options["identifiability"]
    # forward differences of a linear model are exact up to rounding ε·‖r‖/h ≈ 1e-8
    np.testing.assert_allclose(np.array(ident["correlation"]), corr, rtol=1e-6, atol=1e-9)
    scaled = phi / np.linalg.norm(phi, axis=0)
    assert ident["condition_number"] == pytest.approx(np.linalg.cond(scaled), rel=1e-6)
    np.testing.assert_allclose(ident["singular_values"],
                               np.linalg.svd(scaled, compute_uv=False), rtol=1e-6)
    # a linear model's cost is exactly quadratic: the curvature ratio is 1 to rounding
    # (V differences of ~σ² out of V ≈ Nσ²: ε·N ≈ 3e-13 relative, divided by h² terms)
    np.testing.assert_allclose(list(ident["curvature_ratio"].values()), 1.0, rtol=1e-5)
    # the Cramér–Rao floor with the others known is σ/‖φ_k‖ (white, A_v = 1) as h → 0; at
    # h = σ_k the HCR bound is h²/(e^Δ − 1) with Δ = (h‖φ_k‖/σ)² (module notes), exactly
    s = np.sqrt(est.noise_variance)
    h = est.std
    delta = (h * np.linalg.norm(phi, axis=0) / s) ** 2
    order = est.options["covariance_ar_order"]
    assert order is None
    np.testing.assert_allclose(list(ident["std_floor"].values()),
                               np.sqrt(h**2 / np.expm1(delta)), rtol=1e-6)
    assert ident["identifiable"] and ident["flags"] == []


def test_nonlinear_correlation_matches_a_central_difference_jacobian(servo_record):
    est, caught = quiet_fit(servo_record, lambda t: zoh2(*t), [1.5, 25.0, 0.3],
                            ("K", "omega", "zeta"), covariance="white")
    assert not caught
    theta = est.parameters
    jac = np.empty((N, 3))
    for k in range(3):
        h = 1e-5 * theta[k]
        e = np.zeros(3)
        e[k] = h
        plus = zoh2(*(theta + e)).simulate(servo_record.u[:, 0])
        minus = zoh2(*(theta - e)).simulate(servo_record.u[:, 0])
        jac[:, k] = (plus - minus) / (2 * h)
    cov = np.linalg.inv(jac.T @ jac)
    corr = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    ident = est.options["identifiability"]
    # the fit's forward differences (step √ε ≈ 1.5e-8) vs central ones (step 1e-5):
    # cont2discrete rounds at ~1e-13, which the √ε step turns into 1e-5 of a Jacobian entry
    np.testing.assert_allclose(np.array(ident["correlation"]), corr, atol=1e-4)
    scaled = jac / np.linalg.norm(jac, axis=0)
    assert ident["condition_number"] == pytest.approx(np.linalg.cond(scaled), rel=1e-4)
    # a smooth model over ±1σ: curvature within a few % of Gauss–Newton, std above its floor
    np.testing.assert_allclose(list(ident["curvature_ratio"].values()), 1.0, atol=0.05)
    assert all(s >= f for s, f in zip(est.std, ident["std_floor"].values(), strict=True))


# -- not identifiable: errors and warnings that name the parameters ----------------------------


def test_an_exact_product_raises_naming_both(servo_record):
    with pytest.raises(IdentifiabilityError, match=r"rank deficient.*'k[12]', 'k[12]'"):
        fit_tf_greybox(servo_record, lambda t: zoh2(t[0] * t[1], t[2], t[3]),
                       [1.0, 1.5, 25.0, 0.3], ("k1", "k2", "omega", "zeta"))


def test_a_parameter_without_effect_raises_naming_it(servo_record):
    with pytest.raises(IdentifiabilityError, match=r"rank deficient, weakest direction mostly "
                                                   r"'c'\)"):
        fit_tf_greybox(servo_record, lambda t: zoh2(t[0], t[1], t[2] + 0.0 * t[3]),
                       [1.5, 25.0, 0.3, 1.0], ("K", "omega", "zeta", "c"))


def test_a_nearly_confounded_pair_warns_instead_of_a_silent_1e6_std(servo_record):
    # ζ_eff = ζ + 1e-4·c: the data fix ζ + 1e-4·c, not ζ and c — before, σ_c = 1.5e6 came
    # back without a word
    est, caught = quiet_fit(servo_record, lambda t: zoh2(t[0], t[1], t[2] + 1e-4 * t[3]),
                            [1.5, 25.0, 0.3, 1.0], ("K", "omega", "zeta", "c"))
    messages = " | ".join(str(w.message) for w in caught)
    assert "not separately identifiable" in messages and "zeta–c" in messages
    assert "standard deviation exceeds the value" in messages
    ident = est.options["identifiability"]
    kinds = {f["kind"]: f["parameters"] for f in ident["flags"]}
    assert set(kinds["correlated"]) == {"zeta", "c"}
    assert set(kinds["std_exceeds_value"]) == {"zeta", "c"}
    assert not ident["identifiable"]
    assert ident["condition_number"] > 1e5  # √(1/(1 − ρ)) with |ρ| → 1
    assert abs(ident["correlation"][2][3]) > 0.999
    # K and ω are untouched by the confounding: no flag names them
    assert not {"K", "omega"} & {p for f in ident["flags"] for p in f["parameters"]}


def test_a_combination_of_three_is_named():
    # r = y − Xθ with x3 = x1 + x2 + 1e-3·x4: one near-null direction (1, 1, −1)/√3
    rng = np.random.default_rng(5)
    x = rng.standard_normal((800, 4))
    design = np.column_stack([x[:, 0], x[:, 1], x[:, 0] + x[:, 1] + 1e-3 * x[:, 3]])
    y = design @ [1.0, 2.0, 3.0] + 0.01 * rng.standard_normal(800)
    theta, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ theta
    cov = resid @ resid / 797 * np.linalg.inv(design.T @ design)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        ident = check_identifiability(lambda t: y - design @ t, theta, cov, ("a", "b", "c"),
                                      jacobian=-design)
    messages = [str(w.message) for w in record if w.category is ServoidWarning]
    assert len(messages) == 2 and "a–b" in messages[0]
    assert re.match(r"parameters [abc], [abc], [abc] are not separately identifiable",
                    messages[1])
    assert set(ident.flagged("near_null")) == {"a", "b", "c"}
    assert set(ident.flagged("correlated")) == {"a", "b", "c"}
    # the weakest direction is the last right singular vector of the normalised columns
    scaled = design / np.linalg.norm(design, axis=0)
    v = np.linalg.svd(scaled)[2][-1]
    np.testing.assert_allclose(np.abs(ident.weakest_direction), np.abs(v), atol=1e-12)
    assert ident.condition_number == pytest.approx(np.linalg.cond(scaled), rel=1e-9)


def test_a_jacobian_spoilt_by_a_discontinuity_is_caught():
    # ŷ = (g + δ·[g > g_j])·x with a jump of δ = 3e-4 in the gain just above ĝ, inside the
    # central-difference step (6e-6): the Jacobian sees a slope 26× too steep and σ̂_g 26×
    # too small — the "std 1e-8" kind. Its effect δ‖x‖ = 0.01 is below the noise.
    rng = np.random.default_rng(1)
    x = rng.standard_normal(1000)
    y = x + 0.1 * rng.standard_normal(1000)
    g_hat = float(x @ y / (x @ x))
    jump = g_hat + 1e-7

    def residuals(t):
        return y - (t[0] + 3e-4 * (t[0] > jump)) * x

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ident = check_identifiability(residuals, [g_hat], np.eye(1), ["g"], warn=False)
    assert not caught  # warn=False
    # its own central-difference Jacobian → the spoilt covariance a fit would report
    jac_norm2 = np.sum(((residuals([g_hat + 6e-6]) - residuals([g_hat - 6e-6])) / 1.2e-5) ** 2)
    r0 = residuals([g_hat])
    spoilt = np.array([[r0 @ r0 / 999 / jac_norm2]])
    with pytest.warns(ServoidWarning) as record:
        ident = check_identifiability(residuals, [g_hat], spoilt, ["g"])
    kinds = [f.kind for f in ident.flags]
    assert kinds == ["std_below_floor", "not_smooth"], kinds
    assert len(record) == 2
    # the floor is the honest CR bound σ/‖x‖ = 3.2e-3 (the move −h crosses no jump)
    true_std = math.sqrt(r0 @ r0 / 999 / (x @ x))
    assert ident.std_floor[0] == pytest.approx(true_std, rel=0.01)  # HCR at Δ ≈ 1e-3
    assert ident.std[0] < true_std / 10


def test_white_identifiable_fit_has_no_flags(servo_record):
    est, caught = quiet_fit(servo_record, lambda t: zoh2(*t), [1.5, 25.0, 0.3],
                            ("K", "omega", "zeta"), transform=("log", "log", "none"))
    assert not caught
    ident = est.options["identifiability"]
    assert ident["identifiable"] and ident["multistart"] is None
    json.dumps(ident)


# -- several starts ----------------------------------------------------------------------------


def test_several_starts_escape_a_local_minimum_and_say_so():
    # a lightly damped resonance (ζ = 0.03) fitted from ω₀ = 15 rad/s (truth 31.4): the given
    # start stops in a local minimum; random starts find the global one
    wn, zeta = 2 * math.pi * 5, 0.03
    plant = TransferFunction([2 * wn**2], [1.0, 2 * zeta * wn, wn**2])
    u = np.random.default_rng(0).standard_normal(N)
    exp = simulate_lti(plant, u, DT, noise_std=0.05, rng=1)
    kw = {"transform": ("log", "log", "log"), "multistart": 4, "rng": 0, "max_nfev": 100}
    est, caught = quiet_fit(exp, lambda t: zoh2(*t), [2.0, 15.0, 0.05], ("K", "omega", "zeta"),
                            **kw)
    summary = est.options["multistart"]
    assert summary["starts"] == 5 and summary["best"] != 0
    assert 2 <= summary["same_minimum"] < 5  # several reach the best, not the given start
    assert summary["costs"][0] > 100 * min(c for c in summary["costs"] if c is not None)
    assert est["omega"] == pytest.approx(wn, rel=1e-3)  # 1e-3: ≫ its std (3e-5 relative)
    assert any("stopped in a local minimum" in str(w.message) for w in caught)
    assert est.options["identifiability"]["flags"][0]["kind"] == "local_minimum"
    # reproducible: the same seed gives the same starts
    again, _ = quiet_fit(exp, lambda t: zoh2(*t), [2.0, 15.0, 0.05], ("K", "omega", "zeta"),
                         **kw)
    assert again.options["multistart"]["costs"] == summary["costs"]


def test_two_time_constants_that_swap_are_flagged():
    # K/((τ1 s + 1)(τ2 s + 1)) is the same model with τ1 and τ2 swapped: locally identifiable,
    # globally not — only several starts can see it
    plant = TransferFunction([2.0], np.polymul([0.05, 1.0], [0.2, 1.0]))
    u = np.repeat(np.sign(np.random.default_rng(0).standard_normal(400)), 5)
    exp = simulate_lti(plant, u, DT, noise_std=0.02, rng=3)

    def lag2(t):
        num, den, _ = sps.cont2discrete(([t[0]], np.polymul([t[1], 1.0], [t[2], 1.0])), DT,
                                        method="zoh")
        return TransferFunction(np.ravel(num)[1:], den, DT, "zoh")

    with pytest.warns(ServoidWarning, match="different minimum that fits as well"):
        est = fit_tf_greybox(exp, lag2, [1.0, 0.1, 0.3], ("K", "tau1", "tau2"),
                             transform=("log", "log", "log"), multistart=6, rng=0)
    flags = est.options["identifiability"]["flags"]
    assert [f["kind"] for f in flags] == ["equivalent_minimum"]
    params = [p for p in est.options["multistart"]["parameters"] if p is not None]
    taus = {tuple(np.round(p[1:], 3)) for p in params}
    assert taus == {(0.049, 0.202), (0.202, 0.049)}  # both labellings reached


# -- fit_greybox -------------------------------------------------------------------------------


def test_fit_greybox_names_a_mass_split_in_two():
    # m = m1 + m2 enters only as the sum.  cont2discrete rounds at ~1e-13, which over the √ε
    # difference step leaves the two Jacobian columns 1e-5 apart — above the 1e-6 rank
    # tolerance — so this is the warned kind, not the rank error; either way both are named
    t = np.arange(600) * 0.01
    u = np.repeat(np.random.default_rng(2).normal(size=120), 5)

    def simulate(theta):
        m = theta[0] + theta[1]
        num, den, _ = sps.cont2discrete(([1.0], [m, theta[2], theta[3]]), 0.01, method="zoh")
        return sps.lfilter(np.ravel(num), den, u)

    y = simulate(np.array([1.0, 1.0, 3.0, 200.0]))
    y = y + 0.01 * np.std(y) * np.random.default_rng(3).normal(size=y.size)
    params = [("m1", 0.8, 0.1, 10.0), ("m2", 1.5, 0.1, 10.0), ("c", 2.0, 0.1, 50.0),
              ("k", 150.0, 1.0, 1e4)]
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        est = fit_greybox((t, u, y), None, None, params, simulate=simulate)
    messages = " | ".join(str(w.message) for w in record if w.category is ServoidWarning)
    assert "m1–m2" in messages and "standard deviation exceeds the value (m1" in messages
    ident = est.options["identifiability"]
    assert set(ident["weakest_direction"]) == {"m1", "m2", "c", "k"}
    assert abs(ident["weakest_direction"]["m1"]) > 0.7 and abs(
        ident["weakest_direction"]["m2"]) > 0.7  # (1, −1)/√2 of the normalised columns


def test_fit_greybox_multistart_and_identifiability_options():
    t = np.arange(600) * 0.01
    u = np.repeat(np.random.default_rng(2).normal(size=120), 5)

    def simulate(theta):
        num, den, _ = sps.cont2discrete(([1.0], list(theta)), 0.01, method="zoh")
        return sps.lfilter(np.ravel(num), den, u)

    y = simulate(np.array([2.0, 3.0, 200.0])) + 1e-4 * np.random.default_rng(3).normal(size=600)
    params = [("m", 1.5, 0.1, 10.0, "kg", False, "log"), ("c", 2.0, 0.1, 50.0, "N·s/m", False,
                                                          "log"),
              ("k", 150.0, 1.0, 1e4, "N/m", False, "log")]
    est = fit_greybox((t, u, y), None, None, params, simulate=simulate, multistart=3, rng=0)
    assert est.options["multistart"]["starts"] == 4
    assert est.options["identifiability"]["identifiable"]
    assert est.options["covariance"] == "robust" and est.options["covariance_ar_orders"] == {
        "y0": est.options["covariance_ar_order"]}


# -- the public function and its record --------------------------------------------------------


def test_identifiability_record_is_frozen_and_json_friendly():
    x = np.random.default_rng(0).standard_normal((200, 2))
    y = x @ [1.0, 2.0] + 0.1 * np.random.default_rng(1).standard_normal(200)
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    cov = 0.01 * np.linalg.inv(x.T @ x)
    summary = MultistartSummary(2, 2, 0, 0, (1.0, 1.0), ((1.0, 2.0), (1.0, 2.0)))
    ident = check_identifiability(lambda t: y - x @ t, theta, cov, ("a", "b"),
                                  multistart=summary)
    assert isinstance(ident, Identifiability) and ident.is_identifiable
    assert ident.condition_number == pytest.approx(np.linalg.cond(
        x / np.linalg.norm(x, axis=0)), rel=1e-6)  # central differences of a linear r: exact
    with pytest.raises(ValueError):
        ident.values[0] = 0.0  # read-only arrays
    data = json.loads(json.dumps(ident.to_dict()))
    assert data["multistart"]["same_minimum"] == 2 and set(data["std_floor"]) == {"a", "b"}


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"names": ("a",)}, "names has 1"),
        ({"groups": [[100]]}, "groups cover 100 residuals"),
        ({"jacobian": np.zeros((3, 2))}, "jacobian must have shape"),
    ],
)
def test_check_identifiability_bad_input(kwargs, match):
    x = np.random.default_rng(0).standard_normal((200, 2))
    args = {"names": ("a", "b")} | kwargs
    with pytest.raises(DataError, match=match):
        check_identifiability(lambda t: x @ t, [1.0, 1.0], np.eye(2), **args)
