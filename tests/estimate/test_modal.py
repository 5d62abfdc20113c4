"""modal_parameters: gain, time constants, ω_n and ζ with delta-method uncertainty."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from servoid import Experiment, ModelError
from servoid.bench import simulate_lti
from servoid.estimate import Estimate, fit_oe, fit_tf, modal_parameters
from servoid.models import StateSpace, TransferFunction, c2d

DT = 1e-3
WN, ZETA = 2 * math.pi * 5, 0.2
SERVO = TransferFunction([2.0 * WN**2], [1.0, 2 * ZETA * WN, WN**2])  # gain 2, 5 Hz, ζ = 0.2
THIRD = TransferFunction.from_zpk([-60.0], [-15.0, -40 + 80j, -40 - 80j], 15.0 * 8000.0 / 60.0)


def binary(seed: int, n: int = 1500, clock: int = 5) -> np.ndarray:
    rng = np.random.default_rng(1000 + seed)
    return np.repeat(np.sign(rng.standard_normal(n // clock)), clock)


def rows_by_name(est: Estimate, **kw) -> dict:
    return {row.name: row for row in modal_parameters(est, **kw)}


def test_rows_names_and_units():
    est = fit_tf(simulate_lti(THIRD, binary(0), DT), 3, 1)
    rows = modal_parameters(est, output_unit="mm", input_unit="V")
    assert [r.name for r in rows] == ["dc_gain", "T1", "wn1", "zeta1"]
    assert [r.unit for r in rows] == ["mm/V", "s", "rad/s", ""]
    values = {r.name: r.value for r in rows}
    # noise-free data: SRIVC recovers θ to ~1e-12, and these are smooth functions of θ
    assert values["dc_gain"] == pytest.approx(1.0, rel=1e-9)
    assert values["T1"] == pytest.approx(1 / 15.0, rel=1e-9)
    assert values["wn1"] == pytest.approx(math.hypot(40, 80), rel=1e-9)
    assert values["zeta1"] == pytest.approx(40 / math.hypot(40, 80), rel=1e-9)
    assert all(r.std < 1e-6 * max(abs(r.value), 1.0) for r in rows)  # σ̂² ≈ rounding


@pytest.mark.parametrize("seeds", [range(40), pytest.param(range(40, 240),
                                                            marks=pytest.mark.slow)],
                         ids=["40", "200"])
def test_uncertainty_matches_the_scatter_over_seeds(seeds):
    truth = {"dc_gain": 2.0, "wn1": WN, "zeta1": ZETA}
    values, stds = {k: [] for k in truth}, {k: [] for k in truth}
    for seed in seeds:
        exp = simulate_lti(SERVO, binary(seed), DT, noise_std=0.05, rng=seed)
        rows = rows_by_name(fit_tf(exp, 2, 0))
        for key, true_value in truth.items():
            values[key].append(rows[key].value)
            stds[key].append(rows[key].std)
            # 4σ: a 1-in-16000 event for a correct standard deviation
            assert abs(rows[key].value - true_value) < 4 * rows[key].std
    n = len(seeds)
    for key in truth:
        scatter = np.std(values[key], ddof=1)
        # the sample sd of n estimates has a relative sd of 1/√(2(n − 1)) (11 % for 40):
        # 30 % is 2.7 of those; the delta method's own error is O(σ/θ) ≈ 1e-3 here
        assert abs(np.mean(stds[key]) / scatter - 1) < 0.3 * math.sqrt(39 / (n - 1))


def _continuous_estimate() -> Estimate:
    exp = simulate_lti(THIRD, binary(3), DT, noise_std=0.05, rng=3)
    return fit_tf(exp, 3, 1)


@pytest.mark.parametrize("kind", ["discrete-tf", "polynomial", "state-space"])
def test_discrete_models_give_the_same_rows(kind):
    est = _continuous_estimate()
    cont = est.model_function

    def discrete(theta):
        g = c2d(cont(theta), DT, "zoh")
        if kind == "polynomial":
            return g.to_polynomial("oe")
        if kind == "state-space":
            return g.to_ss()
        return g

    other = dataclasses.replace(est, model=discrete(est.parameters), model_function=discrete)
    a, b = modal_parameters(est), modal_parameters(other)
    assert [r.name for r in a] == [r.name for r in b]
    for ra, rb in zip(a, b, strict=True):
        # s = ln(z)/dt inverts z = e^{s·dt} exactly: values to the rounding of c2d and roots
        assert rb.value == pytest.approx(ra.value, rel=1e-8)
        # the same Jacobian through another path: central differences agree to ~1e-6
        assert rb.std == pytest.approx(ra.std, rel=1e-4)


def test_integrator_and_unstable_poles():
    def model(theta):
        return TransferFunction([theta[0]], [1.0, theta[1], theta[2]])

    integrating = Estimate(model([5.0, 2.0, 0.0]), np.array([5.0, 2.0, 0.0]), ("b0", "a1", "a2"),
                           np.diag([0.01, 0.001, 0.0]), 1.0, 500, "demo", model_function=model)
    rows = rows_by_name(integrating)
    assert rows["dc_gain"].value == math.inf and math.isnan(rows["dc_gain"].std)
    assert rows["T1"].value == math.inf and math.isnan(rows["T1"].ci_low)
    assert rows["T2"].value == pytest.approx(0.5)  # 1/2 s, the finite one
    unstable = Estimate(model([1.0, -1.0, -2.0]), np.array([1.0, -1.0, -2.0]),
                        ("b0", "a1", "a2"), np.eye(3) * 1e-4, 1.0, 500, "demo",
                        model_function=model)
    taus = sorted(r.value for r in modal_parameters(unstable) if r.name.startswith("T"))
    assert taus == pytest.approx([-0.5, 1.0])  # poles +2 (negative T) and −1


def test_a_negative_real_discrete_pole_is_a_nyquist_mode():
    def model(theta):
        return TransferFunction([theta[0]], [1.0, theta[1]], dt=DT)

    est = Estimate(model([1.0, 0.5]), np.array([1.0, 0.5]), ("b1", "f1"), np.eye(2) * 1e-6,
                   1.0, 500, "demo", model_function=model)
    rows = rows_by_name(est)
    assert rows["wn1"].value == pytest.approx(abs(complex(math.log(0.5), math.pi)) / DT)


def test_bad_input():
    est = _continuous_estimate()
    with pytest.raises(ModelError, match="does not say how its model depends"):
        modal_parameters(dataclasses.replace(est, model_function=None))
    mimo = StateSpace(-np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2)))
    with pytest.raises(ModelError, match="SISO"):
        modal_parameters(dataclasses.replace(est, model=mimo))
    with pytest.raises(TypeError, match="TransferFunction, PolynomialModel or StateSpace"):
        modal_parameters(dataclasses.replace(est, model="G"))
    with pytest.raises(ValueError, match="level"):
        modal_parameters(est, level=1.5)


def test_printed_as_a_table_with_the_gain_unit_of_the_data():
    # the units come from the record: fit_tf carries them to b0 (mm/V/s^3 here)
    exp = simulate_lti(THIRD, binary(0), DT)
    exp = Experiment.from_arrays(DT, u=exp["u"], y=exp["y"], units={"u": "V", "y": "mm"})
    modal = modal_parameters(fit_tf(exp, 3, 1))
    assert modal["dc_gain"].unit == "mm/V" and modal["T1"].unit == "s"
    text = str(modal)
    assert "ParameterRow" not in text and "ParameterRow" not in repr(modal)
    assert text.splitlines()[1].split()[0] == "dc_gain" and text.splitlines()[1].endswith("mm/V")
    assert modal.names == ("dc_gain", "T1", "wn1", "zeta1") and len(modal) == 4
    assert modal[-1] is modal["zeta1"] and list(modal)[0] is modal["dc_gain"]
    assert modal._repr_html_().startswith("<div")
    with pytest.raises(KeyError, match="no quantity 'wn2'; there are dc_gain, T1, wn1, zeta1"):
        modal["wn2"]


def test_given_units_override_and_a_discrete_fit_has_none_of_its_own():
    exp = simulate_lti(SERVO, binary(1), DT, noise_std=0.05, rng=1)
    exp = Experiment.from_arrays(DT, u=exp["u"], y=exp["y"], units={"u": "V", "y": "mm"})
    est = fit_tf(exp, 2, 0)
    assert modal_parameters(est, output_unit="m", input_unit="A")["dc_gain"].unit == "m/A"
    oe = fit_oe(exp, 2, 2, 1)  # discrete coefficients carry no units to read the gain's from
    assert modal_parameters(oe)["dc_gain"].unit == ""
    assert modal_parameters(oe, output_unit="mm", input_unit="V")["dc_gain"].unit == "mm/V"
