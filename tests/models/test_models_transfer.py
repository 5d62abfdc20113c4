"""TransferFunction: normalisation, responses, algebra and validation."""

import math
import sys

import numpy as np
import pytest
from scipy import signal

from servoid import ModelError, OptionError
from servoid.models import TransferFunction, c2d

K, W, D = 3451.7, 163.3, 0.249
C, F = 0.01, 0.01


def g_simple():
    return TransferFunction([K], [1 / W**2, 2 * D / W, 1.0, 0.0])


def test_normalises_and_stores_read_only():
    g = TransferFunction([0.0, 4.0, 2.0], [0.0, 2.0, 2.0, 0.5])
    assert np.array_equal(g.den, [1.0, 1.0, 0.25]) and np.array_equal(g.num, [2.0, 1.0])
    with pytest.raises(ValueError, match="read-only"):
        g.num[0] = 1.0
    assert g.dt is None and g.method is None and g.prewarp is None


def test_feedback_gives_spec_closed_loop():
    # spec §1.1 Eq. 11: c·G/(1 + F·G) = cK/(s³/ω² + 2δs²/ω + s + FK)
    closed = C * g_simple().feedback(F)
    expected = TransferFunction([C * K], [1 / W**2, 2 * D / W, 1.0, F * K])
    assert np.allclose(closed.den, expected.den, rtol=1e-12)  # a few roundings per coefficient
    assert np.allclose(closed.num, expected.num, rtol=1e-12)
    assert closed.dc_gain() == pytest.approx(C / F, rel=1e-12)
    positive = g_simple().feedback(F, sign=1)
    assert positive.den[-1] == pytest.approx(-F * K * W**2, rel=1e-12)


def test_series_and_parallel():
    g1 = TransferFunction([1.0], [1.0, 1.0])
    g2 = TransferFunction([2.0], [1.0, 3.0])
    w = np.array([0.1, 1.0, 10.0])
    # the algebra is exact on the coefficients; rounding only
    assert np.allclose((g1 * g2).freqresp(w), g1.freqresp(w) * g2.freqresp(w), rtol=1e-13)
    assert np.allclose((g1 + g2).freqresp(w), g1.freqresp(w) + g2.freqresp(w), rtol=1e-13)
    assert np.allclose((g1 - g2).freqresp(w), g1.freqresp(w) - g2.freqresp(w), rtol=1e-13)
    assert np.allclose((3 * g1).num, [3.0]) and np.allclose((1 - g1).num, [1.0, 0.0])
    with pytest.raises(ModelError, match="continuous-time and a discrete-time"):
        g1 * c2d(g2, 0.1)
    with pytest.raises(ModelError, match="different dt"):
        c2d(g1, 0.1) + c2d(g2, 0.2)


def test_discretised_models_keep_their_method_through_algebra():
    g1 = c2d(TransferFunction([1.0], [1.0, 1.0]), 0.1, "tustin")
    assert (2.0 * g1).method == "tustin"
    assert (g1 * c2d(TransferFunction([1.0], [1.0, 2.0]), 0.1, "zoh")).method is None


@pytest.mark.parametrize("dt", [None, 1e-3])
def test_freqresp_matches_scipy(dt):
    g = g_simple() if dt is None else c2d(g_simple(), dt, "tustin")
    w = np.logspace(0, 3, 50)
    if dt is None:
        _, ref = signal.freqs(g.num, g.den, worN=w)
    else:
        _, ref = signal.freqz(g.num, g.den, worN=w * dt)
    # same polynomials; near z = 1 evaluating A(e^{jωdt}) cancels: ε·Σ|a_i|/|A| ≈ 1e-11 at 1 rad/s
    assert np.allclose(g.freqresp(w), ref, rtol=1e-9, atol=0)
    mag, phase = g.bode(w)
    assert np.allclose(mag, 20 * np.log10(np.abs(ref)), rtol=0, atol=1e-10)
    assert phase[0] == pytest.approx(-90.0, abs=1.0)  # integrator at 1 rad/s ≪ ω = 163 rad/s


def test_step_final_value_equals_dc_gain_and_matches_scipy():
    closed = C * g_simple().feedback(F)
    t = np.arange(0.0, 1.2, 1e-3)
    resp = closed.step(t)
    # slowest decay: the closed-loop pair at Re p = −22.3 rad/s, e^{−22.3·1.2} ≈ 2e-12 remains
    assert resp.y[-1] == pytest.approx(closed.dc_gain(), rel=1e-8)
    _, ref = signal.step((closed.num, closed.den), T=t)
    # scipy integrates with lsim's interpolation; on a step both are exact up to 1e-9
    assert np.allclose(resp.y, ref, rtol=0, atol=1e-9)
    _, ref_imp = signal.impulse((closed.num, closed.den), T=t)
    assert np.allclose(closed.impulse(t).y, ref_imp, rtol=0, atol=1e-9 * np.abs(ref_imp).max())
    d = c2d(closed, 1e-3, "zoh")
    assert d.step(1200).y[-1] == pytest.approx(d.dc_gain(), rel=1e-8)  # as above
    assert np.allclose(d.step(1200).y, resp.y, rtol=0, atol=1e-12)  # ZOH is exact on a step


def test_dc_gain_of_integrator_is_inf_and_cancellation_is_handled():
    assert g_simple().dc_gain() == math.inf
    assert c2d(g_simple(), 1e-3, "tustin").dc_gain() == math.inf
    assert TransferFunction([2.0, 0.0], [1.0, 3.0, 0.0]).dc_gain() == pytest.approx(2 / 3)
    assert TransferFunction([1.0, -1.0], [1.0, -1.5, 0.5], 0.1).dc_gain() == pytest.approx(2.0)


def test_poles_zeros_zpk_and_minreal():
    g = TransferFunction.from_zpk([-2.0], [-1.0, -3.0 + 4j, -3.0 - 4j], 5.0)
    assert np.allclose(np.sort_complex(g.poles()), [-3 - 4j, -3 + 4j, -1], rtol=1e-12)
    assert np.allclose(g.zeros(), [-2.0]) and g.num[0] == 5.0
    assert g.is_stable() and not g_simple().is_stable()
    cancelled = (g * TransferFunction([1.0, 1.0], [1.0, 2.0])).minreal()
    assert cancelled.order == 2  # the zero at −1 cancels the pole at −1, the zero at −2 the pole
    with pytest.raises(ModelError, match="conjugate pairs"):
        TransferFunction.from_zpk([], [-1.0 + 1j], 1.0)


def test_simulate_continuous_needs_dt_and_matches_zoh_model():
    u = np.sin(np.arange(200) * 0.05)
    g = g_simple()
    assert np.allclose(g.simulate(u, dt=1e-3), c2d(g, 1e-3).simulate(u), rtol=0, atol=1e-12)
    with pytest.raises(ModelError, match="needs dt"):
        g.simulate(u)
    with pytest.raises(ModelError, match="differs from the model's dt"):
        c2d(g, 1e-3).simulate(u, dt=2e-3)


def test_to_ss_and_back():
    g = C * g_simple().feedback(F)
    back = g.to_ss().to_tf()
    assert np.allclose(back.den, g.den, rtol=1e-10)  # poly of eigenvalues: ε·cond
    assert np.allclose(back.num[-1], g.num[-1], rtol=1e-10)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"num": [1.0, 0.0, 0.0], "den": [1.0, 1.0]}, ModelError, "proper"),
        ({"den": [0.0, 0.0]}, ModelError, "all zero"),
        ({"dt": 0}, ModelError, "dt must be > 0"),
        ({"dt": True}, TypeError, "dt must be a float"),
        ({"dt": None, "method": "zoh"}, ModelError, "no discretisation method"),
        ({"dt": 0.1, "method": "matched"}, OptionError, "'zoh', 'tustin'"),
        ({"dt": 0.1, "method": "zoh", "prewarp": 1.0}, OptionError, "prewarp"),
        ({"num": [np.inf]}, ModelError, "finite"),
        ({"num": [[1.0]]}, ModelError, "1-D"),
    ],
)
def test_bad_construction_raises(kwargs, error, match):
    args = {"num": [1.0], "den": [1.0, 1.0]} | kwargs
    with pytest.raises(error, match=match):
        TransferFunction(**args)


def test_other_bad_calls_raise():
    with pytest.raises(OptionError, match="sign must be one of"):
        g_simple().feedback(1.0, sign=0)
    with pytest.raises(ModelError, match="needs a time grid"):
        g_simple().step(10)
    with pytest.raises(ModelError, match="discrete-time model"):
        g_simple().to_polynomial()
    with pytest.raises(OptionError, match="structure must be one of"):
        c2d(g_simple(), 1e-3).to_polynomial("bj")
    assert "servoid" in sys.modules
