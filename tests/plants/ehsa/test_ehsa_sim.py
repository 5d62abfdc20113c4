"""Nonlinear EHSA simulator (spec §1.4, E7)."""

import math

import numpy as np
import pytest

from servoid._errors import DataError
from servoid.models import c2d
from servoid.plants.ehsa import (
    SET_B,
    SET_C,
    STATE_NAMES,
    EhsaParameters,
    ReducedEhsa,
    default_dt_int,
    full_order_closed_loop,
    simulate_ehsa,
)

DT = 1e-3
STEP = 0.5e-3


def _e7(p: EhsaParameters) -> EhsaParameters:
    # E7 runs "as checked": no dead time, no overlap (friction off per call)
    return p.with_(T_d=0.0, u_0=0.0)


def _reduced_step(p: EhsaParameters, n: int, size: float) -> np.ndarray:
    cl = ReducedEhsa.from_parameters(p).closed_loop(p.reference_gain, p.K_fb)
    return cl.simulate(np.full(n, size), dt=DT)


def _exact_linear(p: EhsaParameters, u: np.ndarray) -> np.ndarray:
    # state space keeps the 8th-order ZOH model well conditioned
    ss = c2d(full_order_closed_loop(p, exact=True).to_ss(), DT, "zoh")
    return np.ravel(ss.simulate(u))


@pytest.mark.parametrize(("params", "spec_dev"), [(SET_B, 0.08), (SET_C, 0.045)])
def test_e7_small_step_follows_reduced_model(params: EhsaParameters, spec_dev: float) -> None:
    p = _e7(params)
    n = 400  # 0.4 s ≈ 14 closed-loop time constants 1/FK
    res = simulate_ehsa(p, np.full(n, STEP), DT, friction=False)
    dev = np.max(np.abs(res.y - _reduced_step(p, n, STEP))) / STEP
    assert dev < 0.10  # E7: within 10 % of the step size
    assert dev < spec_dev + 0.005  # spec "checked": 8 % (B) / 4.5 % (C)
    assert abs(res.y[-1] - STEP) / STEP < 0.01  # E7: steady-state error < 1 %


def test_e7_large_step_is_rate_limited() -> None:
    p = _e7(SET_B)
    res = simulate_ehsa(p, np.full(300, 10e-3), DT, friction=False)
    peak = float(np.max(res.y_dot))
    assert 0.10 <= peak <= 0.13  # E7
    assert peak <= p.v_max * 1.1  # at most the no-load speed, plus P_L < 0 on deceleration
    assert np.max(np.abs(res.x_s)) <= p.x_s_max  # spool travel limit holds exactly
    assert np.max(np.abs(res.x_f)) <= p.x_f_max  # flapper meets the nozzle


def test_e7_set_c_resonance() -> None:
    assert SET_C.omega_hp / (2 * math.pi) == pytest.approx(1420.0, rel=0.01)  # E7


@pytest.mark.parametrize("params", [SET_B, SET_C])
def test_linear_mode_matches_full_order_model(params: EhsaParameters) -> None:
    p = params.with_(T_d=0.0)
    rng = np.random.default_rng(7)
    u = np.repeat(rng.choice([-1e-3, 1e-3], size=30), 10)  # a PRBS-like ±1 mm input
    res = simulate_ehsa(p, u, DT, linear=True)
    ref = _exact_linear(p, u)
    # RK4 at ω_max·dt_int ≈ 0.018: truncation ~ (ω h)^4/120 ≈ 1e-9 per radian,
    # far below 1e-8 of the amplitude; what remains is rounding
    assert np.max(np.abs(res.y - ref)) < 1e-8 * 1e-3
    assert res.linear and not res.friction
    # the spec's Merritt form drops K_ce·B_p/A_p² = 0.4 % of the gain
    spec = full_order_closed_loop(p).simulate(u, dt=DT)
    assert np.max(np.abs(res.y - spec)) < 0.01 * 1e-3


def test_rk4_error_is_fourth_order() -> None:
    p = SET_C.with_(T_d=0.0)
    u = np.full(60, STEP)
    ref = _exact_linear(p, u)
    err = [np.max(np.abs(simulate_ehsa(p, u, DT, linear=True, dt_int=h).y - ref))
           for h in (40e-6, 20e-6)]
    # halving h divides a 4th-order global error by 16 (±40 % for the
    # asymptotic regime not yet reached at ω·h = 0.36)
    assert 16 / 1.4 < err[0] / err[1] < 16 * 1.4


def test_friction_holds_below_breakaway() -> None:
    # 350 N external force < F_s = 400 N: the piston never moves
    for p in (SET_B, SET_C):
        res = simulate_ehsa(p.with_(F_ext=350.0), np.zeros(200), DT)
        assert np.all(res.y_dot == 0.0) and np.all(res.y == 0.0)


@pytest.mark.parametrize("params", [SET_B, SET_C])
def test_friction_breakaway_then_sticks_without_chatter(params: EhsaParameters) -> None:
    # 450 N > F_s breaks the piston away; the loop builds pressure and it sticks again.
    p = params.with_(F_ext=450.0)
    res = simulate_ehsa(p, np.zeros(20000), 1e-5)  # 0.2 s at 10 µs (5 RK4 steps a sample)
    still = res.y_dot == 0.0
    assert still[0] and not still[1] and still[-1]
    moving = ~still
    # one slip phase, no sample-to-sample velocity sign flips (chatter)
    assert np.count_nonzero(moving[1:] & ~moving[:-1]) == 1
    v = res.y_dot[moving]
    assert np.count_nonzero(np.diff(np.sign(v)) != 0) <= 2
    # while stuck, y is exactly constant and the force is within the breakaway force
    stuck_pairs = still[1:] & still[:-1]
    assert np.all(np.diff(res.y)[stuck_pairs] == 0.0)
    # (sample 0 is the initial rest state, from which 450 N breaks away)
    force = p.A_p * res.P_L - p.F_ext
    assert abs(force[0]) > p.F_s
    assert np.all(np.abs(force[1:][still[1:]]) <= p.F_s * (1 + 1e-12))


def test_friction_step_settles_within_leakage_band() -> None:
    # Stuck at rest the valve flow equals the leakage K_ce·P_L with |A_p P_L| ≤ F_s,
    # so the position error is at most K_ce F_s/(A_p K_qs K_s2 K_fb) = 23 µm.
    p = SET_B
    band = p.K_ce * p.F_s / (p.A_p * p.K_qs * p.K_s2 * p.K_fb)
    res = simulate_ehsa(p, np.full(600, STEP), DT)
    assert np.all(res.y_dot[-300:] == 0.0)  # at rest for the last 0.3 s
    assert abs(res.y[-1] - STEP) <= band * 1.01  # band from the static balance


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_end_stops_hold(sign: float) -> None:
    p = SET_B
    res = simulate_ehsa(p, np.full(500, sign * 0.030), DT)  # command beyond the 25 mm stop
    assert np.max(np.abs(res.y)) <= p.stroke  # exactly: the stop clamps y
    assert res.y[-1] == sign * p.stroke
    assert np.all(res.y_dot[-50:] == 0.0)
    assert sign * res.P_L[-1] > 0.5 * p.P_s  # the valve keeps pushing into the stop
    # back off: leaves the stop
    back = simulate_ehsa(p, np.zeros(400), DT, x0=res.final_state, y_r_past=sign * 0.030)
    assert abs(back.y[-1]) < 1e-4


@pytest.mark.parametrize("linear", [True, False])
def test_dead_time_shifts_the_response(linear: bool) -> None:
    u = np.full(200, STEP)
    base = simulate_ehsa(SET_C.with_(T_d=0.0), u, DT, linear=linear)
    late = simulate_ehsa(SET_C.with_(T_d=3e-3), u, DT, linear=linear)
    assert late.dead_time == pytest.approx(3e-3, rel=1e-12)
    assert np.all(late.y[:4] == 0.0)
    # same floating-point operations three samples later
    assert np.array_equal(late.y[3:], base.y[:-3])
    # a dead time of half a sample, resolved on the integration grid
    u2 = np.full(400, STEP)
    half = simulate_ehsa(SET_C.with_(T_d=0.5e-3), u2, DT / 2, linear=linear)
    fine = simulate_ehsa(SET_C.with_(T_d=0.0), u2, DT / 2, linear=linear)
    assert np.array_equal(half.y[1:], fine.y[:-1])


def test_response_layout_and_continuation() -> None:
    p = SET_B.with_(T_d=0.0)
    u = np.concatenate([np.full(150, STEP), np.full(150, -STEP)])
    res = simulate_ehsa(p, u, DT)
    assert res.t == pytest.approx(np.arange(300) * DT, rel=1e-15)
    assert res.dt == DT and res.dt_int == default_dt_int(p, DT) == pytest.approx(2e-6)
    assert np.all(res.P_s == p.P_s) and np.all(res.P_T == p.P_T)
    assert res.final_state.shape == (len(STATE_NAMES),)
    with pytest.raises(ValueError):
        res.y[0] = 1.0  # read-only
    first = simulate_ehsa(p, u[:150], DT)
    second = simulate_ehsa(p, u[150:], DT, x0=first.final_state, y_r_past=u[149])
    assert np.array_equal(np.concatenate([first.y, second.y]), res.y)


def test_default_step_respects_fast_modes() -> None:
    assert default_dt_int(SET_B, 1e-3) == pytest.approx(2e-6, rel=1e-12)
    fast = SET_C.with_(M_t=1e-3)  # ω_hp = 2·10⁵ rad/s
    h = default_dt_int(fast, 1e-3)
    assert h * fast.omega_hp <= 0.05 * (1 + 1e-12)
    assert (1e-3 / h) == pytest.approx(round(1e-3 / h), abs=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"y_r": [0.0, math.nan]}, DataError, r"y_r must be finite, got nan at sample 1"),
        ({"y_r": np.zeros((3, 2))}, DataError, r"y_r must be a non-empty 1-D array"),
        ({"y_r": []}, DataError, r"non-empty"),
        ({"dt": -1e-3}, DataError, r"dt must be > 0 s, got -0.001"),
        ({"dt": math.inf}, DataError, r"dt must be finite"),
        ({"dt_int": 2e-3}, DataError, r"dt_int must be <= the sample period"),
        ({"dt_int": 3e-6}, DataError, r"whole number of steps.*try dt_int"),
        ({"dt_int": 0.0}, DataError, r"dt_int must be > 0 s"),
        ({"x0": np.zeros(7)}, DataError, r"x0 must have shape \(8,\)"),
        ({"x0": np.full(8, np.inf)}, DataError, r"x0 must be finite"),
        ({"linear": 1}, TypeError, r"linear must be a bool"),
        ({"params": "SET_B"}, TypeError, r"params must be EhsaParameters"),
        ({"y_r_past": math.nan}, DataError, r"y_r_past must be finite"),
    ],
)
def test_bad_inputs_raise(kwargs: dict, error: type, match: str) -> None:
    args = {"params": SET_B, "y_r": np.zeros(5), "dt": 1e-3} | kwargs
    with pytest.raises(error, match=match):
        simulate_ehsa(args.pop("params"), args.pop("y_r"), args.pop("dt"), **args)
