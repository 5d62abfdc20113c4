"""Every model type through one door: bode, freqresp, simulate and validate.

The references are scipy.signal's own evaluations of the same coefficients
(freqz / freqs / dlsim), so servoid's evaluation is checked against code it
does not share.  Tolerances are round-off (1e-9 relative): both sides
evaluate the same rational function.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from servoid import DataError, Experiment, ModelError, OptionTypeError
from servoid.estimate import fit_armax, fit_arx, fit_bj, fit_n4sid, fit_oe, fit_tf
from servoid.models import (
    FrequencyResponseData,
    StateSpace,
    TransferFunction,
    as_lti,
    bode,
    freqresp,
    simulate,
    to_control,
    to_scipy,
)
from servoid.validate import compare, validate

DT = 0.01
# scipy warns about its own normalisation of near-zero leading numerator terms
pytestmark = pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(7)
    u = np.repeat(np.sign(rng.standard_normal(750)), 2)
    y = ss.lfilter([0.0, 0.2, 0.1], [1.0, -1.2, 0.5], u) + 0.01 * rng.standard_normal(u.size)
    return Experiment.from_arrays(dt=DT, u=u, y=y)


@pytest.fixture(scope="module")
def estimates(record):
    return {
        "arx": fit_arx(record, 2, 2, 1),
        "oe": fit_oe(record, 2, 2, 1),
        "armax": fit_armax(record, 2, 2, 2, 1),
        "bj": fit_bj(record, 2, 2, 2, 2, 1),
        "n4sid": fit_n4sid(record, 2),
        "tf": fit_tf(record, 2, 1),
    }


def _reference_response(model, f):
    """scipy's evaluation of the model at f [Hz] (freqresp / dfreqresp)."""
    sys = to_scipy(model)
    if model.dt is None:
        return ss.freqresp(sys, w=2 * np.pi * f)[1]
    return ss.dfreqresp(sys, w=2 * np.pi * f * model.dt)[1]


@pytest.mark.parametrize("name", ["arx", "oe", "armax", "bj", "n4sid", "tf"])
def test_bode_of_every_model_matches_scipy(estimates, name):
    est = estimates[name]
    f = np.array([0.1, 1.0, 5.0, 20.0, 49.0])
    expected = _reference_response(est.model, f)
    for given in (est, est.model, to_control(est.model), to_scipy(est.model)):
        b = bode(given, f)
        assert isinstance(b, FrequencyResponseData)
        np.testing.assert_allclose(b.response, expected, rtol=1e-9)
        np.testing.assert_allclose(freqresp(given, 2 * np.pi * f), expected, rtol=1e-9)


@pytest.mark.parametrize("name", ["arx", "oe", "armax", "bj", "n4sid", "tf"])
def test_simulate_of_every_model_matches_scipy(estimates, record, name):
    est = estimates[name]
    u = record["u"]
    model = est.model
    if model.dt is None:  # continuous: scipy's own ZOH discretisation and simulation
        expected = ss.dlsim(to_scipy(model).to_discrete(DT, method="zoh"), u)[1].ravel()
    else:
        expected = ss.dlsim(to_scipy(model), u)[1].ravel()
    for given in (est, model, to_control(model), to_scipy(model)):
        np.testing.assert_allclose(simulate(given, u, dt=DT), expected, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("name", ["arx", "oe", "n4sid", "tf"])
def test_validate_and_compare_take_foreign_systems(estimates, record, name):
    model = estimates[name].model
    ours = validate(model, record, initial="zero")
    reports = compare({"control": to_control(model), "scipy": to_scipy(model)}, record,
                      initial="zero")
    for r in reports.values():
        assert r.fit_percent == pytest.approx(ours.fit_percent, abs=1e-6)


def test_default_grid_spans_the_dynamics():
    g = TransferFunction([100.0], [1.0, 2.0, 100.0])  # 10 rad/s ≈ 1.6 Hz
    b = bode(g)
    assert b.frequency[0] < 1.6 / 5 and b.frequency[-1] > 1.6 * 5
    d = bode(TransferFunction([0.5], [1.0, -0.5], dt=0.01))
    assert d.frequency[-1] == pytest.approx(50.0)  # stops at Nyquist


def test_state_space_channels():
    m = StateSpace([[-1.0, 0.0], [0.0, -2.0]], [[1.0, 0.0], [0.0, 1.0]],
                   [[1.0, 0.0], [0.0, 3.0]], [[0.0, 0.0], [0.0, 0.0]])
    g = freqresp(m, [0.0], input=1, output=1)
    assert g[0] == pytest.approx(1.5)
    with pytest.raises(DataError, match="2 input"):
        freqresp(m, [0.0], input=2)


def test_refusals_name_the_fix():
    frd = FrequencyResponseData(np.array([1.0, 2.0]), np.array([1.0 + 0j, 0.5 + 0j]))
    assert bode(frd) is frd
    with pytest.raises(ModelError, match="fit_frf"):
        simulate(frd, np.ones(10), dt=0.1)
    with pytest.raises(DataError, match="pass dt"):
        simulate(TransferFunction([1.0], [1.0, 1.0]), np.ones(10))
    with pytest.raises(DataError, match="Nyquist"):
        bode(TransferFunction([0.5], [1.0, -0.5], dt=0.01), [1.0, 80.0])
    with pytest.raises(ModelError, match="integrator|infinite"):
        bode(TransferFunction([1.0], [1.0, 0.0]), [0.0, 1.0])
    with pytest.raises(OptionTypeError, match="TransferFunction"):
        as_lti("abc")


def test_estimates_and_innovation_models_convert(estimates):
    import control

    for name in ("arx", "n4sid"):
        est = estimates[name]
        g = control.frequency_response(to_control(est), [3.0]).complex.ravel()
        np.testing.assert_allclose(g, freqresp(est.model, [3.0]), rtol=1e-9)
        assert isinstance(to_scipy(est), (ss.TransferFunction, ss.StateSpace))
    from servoid.estimate import InnovationModel

    m = StateSpace([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=1.0)
    innovation = InnovationModel(m, np.array([[0.5]]), np.array([[0.01]]))
    assert to_scipy(innovation).A.tolist() == [[0.9]]  # its deterministic part
    assert bode(innovation, [0.0]).response[0] == pytest.approx(10.0)  # 1/(1 − 0.9)
