"""Delays on continuous transfer functions, and the first-order (triangle) hold."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from servoid import ModelError
from servoid.models import StateSpace, TransferFunction, c2d, d2c, to_control, to_scipy

DT = 0.01
WN, ZETA = 2 * math.pi * 5, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
LEAD = TransferFunction([3.0, WN**2], [1.0, 2 * ZETA * WN, WN**2])  # one zero


def delayed(g: TransferFunction, tau: float) -> TransferFunction:
    return dataclasses.replace(g, delay=tau)


def fine_reference(g: TransferFunction, u: np.ndarray, tau: float, hold: str,
                   fine: int = 10) -> np.ndarray:
    """Samples of g driven by the held, delayed u, from scipy on a grid fine enough to be exact.

    τ is a whole number of fine steps, so the delayed staircase (or polyline) is again a
    staircase (polyline) on the fine grid, which scipy's own ZOH/FOH discretises exactly.
    """
    shift = round(tau / (DT / fine))
    assert math.isclose(shift * DT / fine, tau, rel_tol=1e-12)
    if hold == "zoh":
        u_fine = np.repeat(u, fine)
    else:
        u_fine = np.interp(np.arange(u.size * fine) / fine, np.arange(u.size), u)
    u_fine = np.concatenate([np.zeros(shift), u_fine[: u_fine.size - shift]])
    ss = g.to_ss()
    ad, bd, cd, dd, _ = signal.cont2discrete((ss.A, ss.B, ss.C, ss.D), DT / fine, hold)
    _, y, _ = signal.dlsim((ad, bd, cd, dd, DT / fine), u_fine)
    return y[::fine, 0]


def test_default_delay_is_zero():
    assert PLANT.delay == 0.0
    assert c2d(PLANT, DT).delay == 0.0 and d2c(c2d(PLANT, DT)).delay == 0.0


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"delay": -0.1}, ModelError, "finite and >= 0"),
        ({"delay": math.nan}, ModelError, "finite and >= 0"),
        ({"delay": math.inf}, ModelError, "finite and >= 0"),
        ({"delay": True}, TypeError, "delay must be a float"),
        ({"delay": "0.1"}, TypeError, "delay must be a float"),
        ({"delay": 0.02, "dt": DT}, ModelError, "takes no delay"),
    ],
)
def test_bad_delay_raises(kwargs, error, match):
    with pytest.raises(error, match=match):
        TransferFunction([1.0], [1.0, 1.0], **kwargs)


def test_frequency_response_is_multiplied_by_the_delay():
    w = np.geomspace(0.1, 300.0, 50)
    tau = 0.037
    g, gd = PLANT.freqresp(w), delayed(PLANT, tau).freqresp(w)
    # the same complex numbers times e^{−jωτ}: rounding of one complex product
    np.testing.assert_allclose(gd, g * np.exp(-1j * w * tau), rtol=1e-14)
    _, phase = delayed(PLANT, tau).bode(w)
    _, phase0 = PLANT.bode(w)
    np.testing.assert_allclose(phase - phase0, -np.degrees(w * tau), atol=1e-9)  # unwrap: exact


def test_rational_part_is_unchanged():
    g = delayed(LEAD, 0.05)
    assert np.array_equal(g.poles(), LEAD.poles()) and np.array_equal(g.zeros(), LEAD.zeros())
    assert g.dc_gain() == LEAD.dc_gain() and g.is_stable()


@pytest.mark.parametrize("method", ["zoh", "foh", "tustin"])
def test_whole_sample_delay_is_poles_at_zero(method):
    gd = c2d(delayed(PLANT, 3 * DT), DT, method)
    ref = c2d(PLANT, DT, method)
    # z^-3·G_d(z): the same coefficients, three exact zeros appended to the denominator
    np.testing.assert_array_equal(gd.num, ref.num)
    np.testing.assert_array_equal(gd.den, np.concatenate([ref.den, np.zeros(3)]))
    assert gd.method == method and gd.delay == 0.0


@pytest.mark.parametrize("hold", ["zoh", "foh"])
@pytest.mark.parametrize("tau", [0.3 * DT, 2.7 * DT])
@pytest.mark.parametrize("plant", [PLANT, LEAD], ids=["strictly-proper", "with-zero"])
def test_fractional_delay_is_exact_for_its_hold(hold, tau, plant):
    rng = np.random.default_rng(0)
    u = rng.standard_normal(400)
    u[0] = 0.0  # the triangle hold ramps into u[0] from rest; start there for both
    y = c2d(delayed(plant, tau), DT, hold).simulate(u)
    ref = fine_reference(plant, u, tau, hold)
    # both exact: rounding over 400 (4000 fine) steps of well-conditioned recursions
    assert np.max(np.abs(y - ref)) < 1e-11 * np.max(np.abs(ref))


def test_continuous_simulate_and_step_include_the_delay():
    k, t_c, tau = 2.0, 0.08, 0.035  # first order K/(T s + 1), delay 3.5 samples
    g = TransferFunction([k], [t_c, 1.0], delay=tau)
    t = np.arange(60) * DT
    step = g.step(t).y
    exact = np.where(t >= tau, k * (1.0 - np.exp(-(t - tau) / t_c)), 0.0)
    assert np.max(np.abs(step - exact)) < 1e-13  # closed form at the samples, rounding only
    imp = g.impulse(t).y
    exact_imp = np.where(t >= tau, k / t_c * np.exp(-(t - tau) / t_c), 0.0)
    assert np.max(np.abs(imp - exact_imp)) < 1e-12 * k / t_c  # closed form, rounding only


def test_impulse_with_a_delay_on_the_grid():
    g = TransferFunction([1.0], [1.0, 5.0], delay=4 * DT)
    t = np.arange(20) * DT
    y = g.impulse(t).y
    assert np.all(y[:4] == 0.0)
    np.testing.assert_allclose(y[4:], np.exp(-5.0 * t[:16]), rtol=1e-13)  # e^{−5(t−τ)}


def test_tustin_refuses_a_fractional_delay():
    with pytest.raises(ModelError, match="whole-sample delays"):
        c2d(delayed(PLANT, 0.5 * DT), DT, "tustin")


@pytest.mark.parametrize("method", ["zoh", "foh"])
def test_d2c_keeps_a_whole_sample_delay(method):
    back = d2c(c2d(delayed(LEAD, 2 * DT), DT, method))
    assert back.delay == pytest.approx(2 * DT, rel=1e-15)
    # logm round trip of a 2nd-order model: ~1e-12 relative seen; 1e-9 leaves room for ε·cond
    np.testing.assert_allclose(back.den, LEAD.den, rtol=1e-9)
    np.testing.assert_allclose(back.num, LEAD.num, rtol=1e-9)


def test_zoh_d2c_of_a_fractional_delay_matches_every_sample():
    gd = c2d(delayed(PLANT, 1.4 * DT), DT, "zoh")
    back = d2c(gd)
    # the only preimage d2c can see: a biproper model with the next whole-sample delay
    assert back.delay == pytest.approx(2 * DT) and back.num.size == back.den.size
    again = c2d(back, DT, "zoh")
    np.testing.assert_allclose(again.den, gd.den, rtol=0, atol=1e-12)  # ε·cond(logm)
    np.testing.assert_allclose(again.num, gd.num, rtol=0, atol=1e-12 * np.abs(gd.num).max())


def test_foh_d2c_refuses_a_fractional_delay():
    with pytest.raises(ModelError, match="improper"):
        d2c(c2d(delayed(PLANT, 1.4 * DT), DT, "foh"))


def test_foh_matches_scipy_and_round_trips():
    gd = c2d(PLANT, DT, "foh")
    num, den, _ = signal.cont2discrete((PLANT.num, PLANT.den), DT, "foh")
    # same formulas, different rounding order
    np.testing.assert_allclose(gd.den, den, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gd.num, np.ravel(num) / den[0], rtol=0, atol=1e-12)
    back = d2c(gd)  # remembers "foh"
    assert gd.method == "foh" and back.method is None
    np.testing.assert_allclose(back.den, PLANT.den, rtol=1e-9)  # logm round trip, ε·cond
    np.testing.assert_allclose(back.num[-1], PLANT.num[-1], rtol=1e-9)
    # strictly proper again: the rounding-level feed-through (~1e-17 here) is dropped
    assert back.num.size < back.den.size
    # the s¹ coefficient is rounding of the logm round trip (ε·cond, ~1e-14 of 987) or, when
    # the state-space-to-polynomial step trims it, absent: compare by power of s
    num = np.concatenate([np.zeros(back.den.size - back.num.size), back.num])
    want = np.concatenate([np.zeros(back.den.size - PLANT.num.size), PLANT.num])
    np.testing.assert_allclose(num, want, rtol=0, atol=1e-9 * abs(PLANT.num[-1]))  # ε·cond


def test_foh_state_space_round_trip():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 3)) - 3 * np.eye(3)
    b, c, d = rng.normal(size=(3, 2)), rng.normal(size=(2, 3)), rng.normal(size=(2, 2))
    ss = StateSpace(a, b, c, d)
    ssd = c2d(ss, 0.05, "foh")
    ref = signal.cont2discrete((a, b, c, d), 0.05, "foh")
    for mine, theirs in zip((ssd.A, ssd.B, ssd.C, ssd.D), ref[:4], strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)  # same formulas
    back = d2c(ssd)
    for mine, theirs in zip((back.A, back.B, back.C, back.D), (a, b, c, d), strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-10)  # logm + solve, ε·cond


def test_algebra_with_delays():
    g1, g2 = delayed(PLANT, 0.01), delayed(LEAD, 0.02)
    assert (g1 * g2).delay == pytest.approx(0.03) and (2.0 * g1).delay == 0.01
    assert (g1 + delayed(LEAD, 0.01)).delay == 0.01 and (-g1).delay == 0.01
    assert g1.minreal().delay == 0.01
    with pytest.raises(ModelError, match="different delays"):
        g1 + g2
    with pytest.raises(ModelError, match="different delays"):
        1.0 - g1
    with pytest.raises(ModelError, match="loop around a delay"):
        g1.feedback(1.0)


def test_conversions_refuse_to_drop_a_delay():
    g = delayed(PLANT, 0.01)
    with pytest.raises(ModelError, match="no delay"):
        g.to_ss()
    with pytest.raises(ModelError, match="no delay"):
        to_scipy(g)
    with pytest.raises(ModelError, match="no delay"):
        to_control(g)
    assert dataclasses.replace(g, delay=0.0).to_ss().n_states == 2  # dropped on purpose
