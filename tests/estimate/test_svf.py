"""State-variable filters: spec P1, every order, products, a known-answer regression, bad input."""

import math

import numpy as np
import pytest
from scipy import integrate

from servoid import DataError, OptionError
from servoid.estimate import FilteredSignal, filter_product, lstsq, state_variable_filter

DT = 1e-4
OMEGA = 2 * np.pi * 20  # test tone [rad/s]
OMEGA_F = 2 * np.pi * 100  # filter bandwidth [rad/s]
T = np.arange(0.0, 0.5, DT)
AFTER = T >= 0.2  # spec P1: compare after 0.2 s


def tone_filters(hold):
    x = np.sin(OMEGA * T)
    xd = OMEGA * np.cos(OMEGA * T)
    xdd = -(OMEGA**2) * np.sin(OMEGA * T)
    return [state_variable_filter(s, DT, OMEGA_F, hold=hold) for s in (x, xd, xdd)]


@pytest.mark.parametrize("hold", ["cubic", "foh", "tustin"])
def test_spec_p1_sine(hold):
    fx, fxd, fxdd = tone_filters(hold)
    h = fx.frequency_response(OMEGA)
    steady = np.abs(h) * OMEGA * np.cos(OMEGA * T + np.angle(h))
    e1 = np.max(np.abs(fx.derivative(1) - fxd.derivative(0))[AFTER])
    e2 = np.max(np.abs(fx.derivative(2) - fxdd.derivative(0))[AFTER])
    e3 = np.max(np.abs(fx.derivative(1) - steady)[AFTER])
    assert e1 <= 1e-4 * OMEGA  # spec P1
    assert e2 <= 1e-3 * OMEGA**2  # spec P1
    assert e3 <= 1e-4 * OMEGA  # spec P1


def test_cubic_hold_is_far_inside_p1():
    fx, _, fxdd = tone_filters("cubic")
    e2 = np.max(np.abs(fx.derivative(2) - fxdd.derivative(0))[AFTER])
    # cubic interpolation error O((ωT)⁴) ≈ 2.5e-8, amplified by (ω_f/ω)² = 25 in s²F x
    assert e2 <= 1e-6 * OMEGA**2


def test_zoh_on_a_smooth_signal_is_a_half_sample_delay():
    fx, _, _ = tone_filters("zoh")
    h = fx.frequency_response(OMEGA)
    steady = np.abs(h) * OMEGA * np.cos(OMEGA * T + np.angle(h))
    e3 = np.max(np.abs(fx.derivative(1) - steady)[AFTER])
    # ZOH of a sine lags by T/2: relative error ≈ ωT/2 = 6.3e-3 ≫ P1's 1e-4
    assert 3e-3 * OMEGA < e3 < 1e-2 * OMEGA


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_every_derivative_matches_the_steady_state(order):
    f = state_variable_filter(np.sin(OMEGA * T), DT, OMEGA_F, order=order)
    assert f.values.shape == (T.size, order + 1)
    for k in range(order + 1):
        h = f.frequency_response(OMEGA, k)
        steady = np.abs(h) * np.sin(OMEGA * T + np.angle(h))
        err = np.max(np.abs(f.derivative(k) - steady)[AFTER]) / np.abs(h)
        # O((ωT)⁴) hold error times the feed-through gain (ω_f/ω)^k ≤ 625: < 1e-6
        assert err < 1e-6, (order, k, err)


def test_order_two_with_zeta_is_the_spec_filter():
    f = state_variable_filter(np.sin(OMEGA * T), DT, OMEGA_F, order=2, zeta=0.7)
    h = f.frequency_response(OMEGA)
    expected = OMEGA_F**2 / (-(OMEGA**2) + 2j * 0.7 * OMEGA_F * OMEGA + OMEGA_F**2)
    assert h == pytest.approx(expected, rel=1e-12)  # same formula, rounding only
    steady = np.abs(h) * np.sin(OMEGA * T + np.angle(h))
    assert np.max(np.abs(f.derivative(0) - steady)[T >= 0.3]) < 1e-6  # hold error
    # slowest decay 0.7 ω_f: the rule (n + 3)/σ gives 5/(0.7 ω_f)
    assert f.first_valid == math.ceil(5 / (0.7 * OMEGA_F) / DT)


@pytest.mark.parametrize(("order", "expected"), [(1, 4), (2, 5), (3, 6)])
def test_first_valid_rule(order, expected):
    f = state_variable_filter(np.zeros(1000), DT, OMEGA_F, order=order)
    assert f.first_valid == math.ceil(expected / OMEGA_F / DT)


def test_steady_start_leaves_a_constant_untouched():
    f = state_variable_filter(np.full(500, 3.0), DT, OMEGA_F, order=3, initial="steady")
    np.testing.assert_allclose(f.derivative(0), 3.0, rtol=1e-12)  # exact equilibrium
    for k in (1, 2, 3):  # feed-through rounding: a few ε·|x|·ω_f^k
        np.testing.assert_allclose(f.derivative(k), 0.0, atol=100 * 3.0 * 2.2e-16 * OMEGA_F**k)


def test_product_is_filtered_as_one_signal():
    volume = 1.0 + 0.3 * np.sin(2 * np.pi * 3 * T)
    pressure = 2.0 + np.cos(2 * np.pi * 7 * T)
    fp = filter_product(volume, pressure, dt=DT, omega_f=OMEGA_F, settle=0.05)
    ref = state_variable_filter(volume * pressure, DT, OMEGA_F, settle=0.05)
    np.testing.assert_array_equal(fp.values, ref.values)
    # derivative-free form: s F[V p] = F[V̇ p + V ṗ] (same filter on both sides)
    v_dot = 0.3 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * T)
    p_dot = -2 * np.pi * 7 * np.sin(2 * np.pi * 7 * T)
    rhs = filter_product(v_dot, pressure, dt=DT, omega_f=OMEGA_F).derivative(0) + filter_product(
        volume, p_dot, dt=DT, omega_f=OMEGA_F
    ).derivative(0)
    scale = np.max(np.abs(rhs))
    # the product starts at V p = 3 from a filter at rest: settle = 0.05 s = 31/ω_f leaves
    # e^-31·31 ≈ 1e-12 of that step; the rest is the cubic hold error
    assert fp.first_valid == 500
    assert np.max(np.abs(fp.derivative(1, valid=True) - rhs[fp.first_valid :])) < 1e-7 * scale


def test_first_order_system_recovered_by_svf_and_ls():
    # τ ẏ + y = K u with a smooth multisine u; y integrated to 1e-12
    tau, gain = 0.02, 3.0
    freqs = np.array([2.0, 7.0, 19.0, 41.0])

    def u(t):
        return np.sum(np.sin(2 * np.pi * np.outer(np.atleast_1d(t), freqs)), axis=1)

    sol = integrate.solve_ivp(
        lambda t, y: (gain * u(t) - y) / tau, (0, T[-1]), [0.0], t_eval=T, rtol=1e-12, atol=1e-14
    )
    fy = state_variable_filter(sol.y[0], DT, OMEGA_F)
    fu = state_variable_filter(u(T), DT, OMEGA_F)
    # y = −τ ẏ + K u  →  F y = [−sF y, F u]·[τ, K]
    phi = np.column_stack([-fy.derivative(1, valid=True), fu.derivative(0, valid=True)])
    est = lstsq(phi, fy.derivative(0, valid=True))
    np.testing.assert_allclose(est.theta, [tau, gain], rtol=1e-6)  # cubic hold error ~1e-8


def test_result_is_frozen():
    f = state_variable_filter(np.sin(OMEGA * T), DT, OMEGA_F)
    assert isinstance(f, FilteredSignal)
    assert f.n_samples == T.size and f.hold == "cubic" and f.order == 2
    with pytest.raises(ValueError):
        f.values[0, 0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"order": 3, "zeta": 0.7}, "zeta != 1 is only defined for order 2"),
        ({"omega_f": 2 * np.pi * 6000}, r"omega_f must lie in \(0, π/dt\)"),
        ({"omega_f": -1.0}, "omega_f must lie"),
        ({"dt": 0.0}, "dt must be > 0"),
        ({"order": 0}, "order must be an integer >= 1"),
        ({"zeta": 0.0}, "zeta must be > 0"),
    ],
)
def test_bad_settings(kwargs, match):
    args = {"dt": DT, "omega_f": OMEGA_F} | kwargs
    with pytest.raises(DataError, match=match):
        state_variable_filter(np.zeros(1000), **args)


def test_bad_signals_and_options():
    with pytest.raises(DataError, match="NaN or inf"):
        state_variable_filter(np.array([0.0, np.nan] * 500), DT, OMEGA_F)
    with pytest.raises(DataError, match="shorter than the filter's start-up"):
        state_variable_filter(np.zeros(50), DT, OMEGA_F)
    with pytest.raises(DataError, match="must be 1-D"):
        state_variable_filter(np.zeros((100, 2)), DT, OMEGA_F)
    with pytest.raises(OptionError, match="hold must be one of"):
        state_variable_filter(np.zeros(1000), DT, OMEGA_F, hold="linear")
    with pytest.raises(DataError, match="equal 1-D shapes"):
        filter_product(np.zeros(1000), np.zeros(999), dt=DT, omega_f=OMEGA_F)
    f = state_variable_filter(np.zeros(1000), DT, OMEGA_F)
    with pytest.raises(DataError, match=r"k must be an integer in \[0, 2\]"):
        f.derivative(3)
