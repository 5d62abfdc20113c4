"""validate() on every model type: continuous models, initial state, limits, verdicts."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import DataError, Experiment, ModelError, OptionError
from servoid.bench import simulate_lti
from servoid.models import PolynomialModel, StateSpace, TransferFunction, c2d
from servoid.validate import compare, discrete_model, simulate_model, validate

DT = 0.01
WN, ZETA = 2 * np.pi * 3, 0.2
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])


def _binary(n: int, seed: int) -> np.ndarray:
    return np.repeat(np.sign(np.random.default_rng(seed).standard_normal(n // 5 + 1)), 5)[:n]


def _window(model, n=600, seed=0):
    """A noise-free window from the middle of a run: the plant is not at rest at its start."""
    u = _binary(n + 400, seed)
    y = np.asarray(model.simulate(u), dtype=float)
    return Experiment.from_arrays(DT, u=u[400:], y=y[400:], name="window")


def test_continuous_model_on_a_rig_record_is_exact():
    u = _binary(1500, 1)
    exp = simulate_lti(PLANT, u, DT)  # ZOH input, exact analog simulation
    report = validate(PLANT, exp)
    # the ZOH equivalent of the true plant on the rig's exact ZOH record: rounding only
    assert report.fit_percent == pytest.approx(100.0, abs=1e-6)
    assert report.initial == "estimate" and report.first == 0


def test_estimated_initial_state_removes_the_start_up_transient():
    oe = c2d(PLANT, DT).to_polynomial("oe")
    exp = _window(oe)
    est = validate(oe, exp, initial="estimate")
    zero = validate(oe, exp, initial="zero")
    # the exact model from its least-squares initial state: rounding of the n-column LS only
    assert est.fit_percent == pytest.approx(100.0, abs=1e-6)
    # from rest, the lightly damped poles (ζ = 0.2) ring for ~50 samples and cost fit points
    assert zero.fit_percent < 99.0
    # excluding that ringing as a transient brings most of it back
    late = validate(oe, exp, initial="zero", transient=200)
    assert late.first == 200 and late.fit_percent > zero.fit_percent


def test_state_space_with_two_outputs_is_validated_row_by_row():
    ss = c2d(PLANT, DT).to_ss()
    two = StateSpace(ss.A, ss.B, np.vstack([ss.C, 2 * ss.C]), np.vstack([ss.D, 2 * ss.D]), DT)
    u = _binary(800, 2)
    y = two.simulate(u)
    exp = Experiment.from_arrays(DT, u=u, y=y, names={"y": ["pos", "pos2"]})
    for name in ("pos", "pos2"):
        report = validate(two, exp, output=name)
        assert report.fit_percent == pytest.approx(100.0, abs=1e-6)  # rounding only


def test_declared_limits_clip_the_simulation():
    oe = c2d(PLANT, DT).to_polynomial("oe")
    exp = _window(oe)
    top = 0.8 * float(np.max(exp["y"][100:]))
    clipped_exp = Experiment.from_arrays(DT, u=exp["u"], y=np.minimum(exp["y"], top))
    plain = validate(oe, clipped_exp, initial="zero", transient=100)
    limited = validate(oe, clipped_exp, initial="zero", transient=100, limits=(-10.0, top))
    assert limited.clipped > 0 and limited.fit_percent > plain.fit_percent
    assert any("clipped" in n for n in limited.notes())


def test_a_wrong_model_is_rejected_in_words():
    oe = c2d(PLANT, DT).to_polynomial("oe")
    exp = _window(oe)
    wrong = PolynomialModel([1.0], ([0.0, -3.0],), 1, DT, f=([1.0, -0.5],))
    report = validate(wrong, exp, initial="zero")
    assert report.fit_percent < 0
    text = " ".join(report.notes())
    assert "rejected by the data" in text and "negative" in text
    assert report.summary()["notes"] == list(report.notes())


def test_compare_validates_each_model():
    oe = c2d(PLANT, DT).to_polynomial("oe")
    exp = _window(oe)
    reports = compare({"true": oe, "continuous": PLANT}, exp)
    assert list(reports) == ["true", "continuous"]
    # both describe the same system: the continuous one is discretised with the ZOH
    assert reports["continuous"].fit_percent == pytest.approx(100.0, abs=1e-6)


def test_discrete_model_checks():
    assert discrete_model(PLANT, DT).dt == DT
    with pytest.raises(DataError, match="resample the data or discretise"):
        discrete_model(c2d(PLANT, 0.02), DT)
    with pytest.raises(OptionError, match="intersample"):
        discrete_model(PLANT, DT, "cubic")
    with pytest.raises(TypeError, match="TransferFunction, StateSpace, PolynomialModel"):
        discrete_model("G", DT)


def test_bad_initial_and_transient():
    oe = c2d(PLANT, DT).to_polynomial("oe")
    exp = _window(oe, n=100)
    with pytest.raises(ModelError, match="only an ARX model"):
        validate(oe, exp, initial="measured")
    with pytest.raises(DataError, match="transient must lie"):
        validate(oe, exp, transient=99)
    with pytest.raises(OptionError, match="initial"):
        simulate_model(oe, exp["y"], exp["u"], initial="guess")
    with pytest.raises(DataError, match="low < high"):
        validate(oe, exp, limits=(1.0, -1.0))
