"""The simulator against independent generators, and its bad inputs."""

from __future__ import annotations

import numpy as np
import pytest
from reference_loop import simulate_linear, simulate_ode

from servoid import DataError, ModelError, OptionError, OptionTypeError
from servoid.plants.ema import TVC_CONTROLLER, TVC_EMA, EmaController, simulate_ema

DT = 1e-4


def _multisine(n, amplitude, seed=0):
    t = DT * np.arange(n)
    rng = np.random.default_rng(seed)
    r = sum(amplitude / f * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f in (1.3, 3.7, 9.1, 17.0, 31.0))
    return r - r[0]


def _columns(out):
    return np.column_stack([out.current, out.angle, out.speed, out.position, out.velocity,
                            out.voltage])


def test_linear_loop_matches_exact_discretisation():
    # no Coulomb friction, no limits, exact encoder: the loop is linear and sampled exactly
    p = TVC_EMA.with_(T_cm=0.0, F_cL=0.0)
    c = EmaController(u_max=np.inf, i_max=np.inf, w_max=np.inf, encoder_counts=0, ki_x=20.0)
    r = _multisine(4000, 2e-3)
    f = 500.0 * np.sin(2 * np.pi * 5.0 * DT * np.arange(r.size))
    x0 = np.zeros(5)
    ref = simulate_linear(p, c, r, DT, f, x0)
    out = _columns(simulate_ema(p, r, DT, controller=c, f_ext=f, x0=x0, dt_int=DT / 10))
    scale = np.max(np.abs(ref), axis=0)
    # RK4 at 1e-5 s against the matrix exponential: local error (h·|λ|max)^5 ~ 1e-12 per step
    assert np.max(np.abs(out - ref) / scale) < 1e-8


def test_linear_loop_fails_with_the_wrong_stiffness():
    # the comparison above can fail: a 1 % stiffer screw is seen
    p = TVC_EMA.with_(T_cm=0.0, F_cL=0.0)
    c = EmaController(u_max=np.inf, i_max=np.inf, w_max=np.inf, encoder_counts=0)
    r = _multisine(2000, 2e-3)
    ref = simulate_linear(p.with_(k_s=1.01 * p.k_s), c, r, DT, np.zeros(r.size), np.zeros(5))
    out = _columns(simulate_ema(p, r, DT, controller=c, x0=np.zeros(5)))
    assert np.max(np.abs(out - ref) / np.max(np.abs(ref), axis=0)) > 1e-5


def test_nonlinear_loop_matches_solve_ivp_with_limits_and_encoder():
    # Coulomb friction on both sides while moving one way (no sticking), encoder counts,
    # current and voltage limits reached by a ramp that steepens, outer loops at 2.5 kHz
    p = TVC_EMA
    c = EmaController(outer_every=4, i_max=12.0, u_max=90.0)
    n = 1500
    t = DT * np.arange(n)
    v0 = 0.05
    r = v0 * t + 0.5 * 3.0 * np.clip(t - 0.05, 0.0, None) ** 2
    x0 = np.array([0.0, 0.0, v0 * p.transmission, 0.0, v0])
    # the screw carries the friction of the load at the start
    f_ext = np.full(n, 800.0)
    ref = simulate_ode(p, c, r, DT, f_ext, x0)
    out = simulate_ema(p, r, DT, controller=c, f_ext=f_ext, x0=x0)
    assert np.min(out.speed) > 0 and np.min(out.velocity) > 0  # no reversal: sign is smooth
    assert out.saturation_fraction()["current"] > 0.05  # the limit was reached
    got = _columns(out)
    scale = np.max(np.abs(ref), axis=0)
    # solve_ivp at rtol 1e-11; the encoder floor() can flip a count where the two differ by
    # rounding, a 1e-4 rad jump of the speed estimate: allow that much
    assert np.max(np.abs(got - ref) / scale) < 1e-6


def test_motor_sticks_after_a_step_without_chatter():
    # a step settles: the motor sticks (speed exactly zero from then on) and the load stops
    # where the screw force balances its Coulomb friction
    r = np.r_[0.0, np.full(9999, 1e-3)]
    out = simulate_ema(TVC_EMA, r, DT, controller=TVC_CONTROLLER)
    assert np.all(out.stuck_motor[7000:]) and np.all(out.speed[7000:] == 0.0)
    assert np.max(np.abs(out.velocity[7000:])) < 1e-12
    assert abs(out.screw_force[-1] - TVC_EMA.F_cL) < 1e-6  # the load rests on its friction
    assert abs(out.position[-1] - 1e-3) < 1e-7


def test_backlash_dead_zone_carries_no_force():
    p = TVC_EMA.with_(backlash=20e-6)
    r = np.zeros(100)
    x0 = np.array([0.0, 5e-6 * p.transmission, 0.0, 0.0, 0.0])  # nut 5 µm ahead: inside the play
    out = simulate_ema(p, r, DT, x0=x0)
    assert out.screw_force[0] == 0.0
    x0[1] = 15e-6 * p.transmission  # 15 µm: 5 µm beyond the half play
    out = simulate_ema(p, r, DT, x0=x0)
    assert out.screw_force[0] == pytest.approx(p.k_s * 5e-6, rel=1e-9)


def test_response_is_read_only_and_has_time():
    out = simulate_ema(TVC_EMA, np.zeros(10), DT, analog=True)
    assert out.analog.shape == (100, 5)
    assert out.time[3] == pytest.approx(3 * DT)
    with pytest.raises(ValueError):
        out.position[0] = 1.0


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"reference": [0.0]}, DataError, "at least 2"),
    ({"reference": [0.0, np.nan]}, DataError, "non-finite"),
    ({"dt": -1e-4}, DataError, "dt must be > 0"),
    ({"dt_int": 3e-5}, DataError, "whole multiple"),
    ({"f_ext": [1.0, 2.0]}, DataError, "one value per reference sample"),
    ({"x0": [0.0, 0.0]}, DataError, "x0 must hold 5"),
    ({"measurement_noise": {"voltage": np.zeros(4)}}, OptionError, "unknown key"),
    ({"params": "tvc"}, OptionTypeError, "params must be EmaParameters"),
    ({"controller": {}}, OptionTypeError, "controller must be an EmaController"),
])
def test_bad_inputs_are_refused(kwargs, error, match):
    args = {"params": TVC_EMA, "reference": np.zeros(4), "dt": DT}
    args.update(kwargs)
    with pytest.raises(error, match=match):
        simulate_ema(args.pop("params"), args.pop("reference"), args.pop("dt"), **args)


@pytest.mark.parametrize(("make", "error", "match"), [
    (lambda: TVC_EMA.with_(k_s=0.0), ModelError, r"k_s must be > 0"),
    (lambda: TVC_EMA.with_(F_cL=-1.0), ModelError, r"F_cL must be >= 0"),
    (lambda: TVC_EMA.with_(J_m=float("inf")), ModelError, "finite"),
    (lambda: TVC_EMA.with_(gear=2.0), OptionTypeError, "no parameter"),
    (lambda: EmaController(kp_i=True), OptionTypeError, "real number"),
    (lambda: EmaController(outer_every=0), ModelError, "outer_every must be >= 1"),
    (lambda: EmaController(feedback="rod"), OptionError, "feedback"),
])
def test_bad_parameters_are_refused(make, error, match):
    with pytest.raises(error, match=match):
        make()
