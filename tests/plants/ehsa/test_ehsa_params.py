"""Physical parameters of the EHSA: derived numbers and validation (spec §1.3)."""

import dataclasses
import math

import pytest

from servoid._errors import ModelError
from servoid.plants.ehsa import SET_B, SET_C, EhsaParameters, closed_loop_bandwidth, loop_margins

# Each tolerance is half a unit in the last digit the spec prints.


def test_set_b_is_the_default_and_set_c_differs_only_in_mass() -> None:
    assert EhsaParameters() == SET_B
    changed = [f.name for f in dataclasses.fields(SET_B)
               if getattr(SET_B, f.name) != getattr(SET_C, f.name)]
    assert changed == ["M_t"]
    assert SET_B.M_t == 1500.0 and SET_C.M_t == 0.5


def test_torque_motor_gain_gives_unit_tracking() -> None:
    assert SET_B.K_TM == pytest.approx(4.6e-3, abs=5e-5)  # printed 4.6e-3
    assert SET_B.K_driver == pytest.approx(2.1739, abs=5e-5)  # printed 2.1739
    assert SET_B.dc_gain == pytest.approx(1.0, rel=1e-15)  # K_TM = K_fb/K_driver exactly
    assert SET_B.K_TM / SET_B.K_fb == pytest.approx(0.46, abs=5e-3)  # y/i_c printed 0.46 m/A


def test_derived_valve_and_loop_gains() -> None:
    p = SET_B
    assert p.K_qs == pytest.approx(0.288, abs=5e-4)
    assert p.K_qs / p.A_p == pytest.approx(287.6, abs=0.05)
    assert p.K == pytest.approx(3452, abs=0.5)
    assert p.loop_gain == pytest.approx(34.5, abs=0.05)
    assert p.v_max == pytest.approx(0.115, abs=5e-4)
    assert p.stall_force == pytest.approx(21e3, rel=1e-12)  # A_p·P_s exactly


def test_set_b_hydraulics_margins_bandwidth() -> None:
    p = SET_B
    assert p.omega_hp == pytest.approx(163.3, abs=0.05)
    assert p.omega_hp / (2 * math.pi) == pytest.approx(26.0, abs=0.05)
    assert p.delta_hp == pytest.approx(0.249, abs=5e-4)
    assert p.routh_limit == pytest.approx(81.3, abs=0.05)
    assert loop_margins(p, "reduced").gain_margin_db == pytest.approx(7.4, abs=0.05)
    full = loop_margins(p, "full")
    assert full.gain_margin_db == pytest.approx(6.8, abs=0.05)
    # The spec's PM 80° and 7.3 Hz are the full-order loop's; the reduced loop
    # gives 83.4° and 6.67 Hz (its lightly damped pair peaks less).
    assert full.phase_margin_deg == pytest.approx(80.0, abs=0.5)
    assert closed_loop_bandwidth(p, "full") == pytest.approx(7.3, abs=0.05)
    red = loop_margins(p, "reduced")
    assert 80.0 < red.phase_margin_deg < 85.0  # "PM ≈ 80°" (reduced: 83.4°)
    assert 6.0 < closed_loop_bandwidth(p, "reduced") < 7.3


def test_reduced_gain_margin_is_the_routh_ratio() -> None:
    # Reduced loop: phase crosses −180° at ω_hp where |L| = FK/(2δω).
    m = loop_margins(SET_B, "reduced")
    assert m.phase_crossover == pytest.approx(SET_B.omega_hp, rel=1e-9)  # brentq xtol
    expected = 20 * math.log10(SET_B.routh_limit / SET_B.loop_gain)
    assert m.gain_margin_db == pytest.approx(expected, abs=1e-8)  # brentq xtol


def test_set_c_hydraulics() -> None:
    p = SET_C
    assert p.omega_hp == pytest.approx(8944, abs=0.5)
    assert p.omega_hp / (2 * math.pi) == pytest.approx(1420, rel=0.01)  # E7: 1.42 kHz ± 1 %
    assert p.delta_hp == pytest.approx(0.228, abs=5e-4)
    assert closed_loop_bandwidth(p, "full") == pytest.approx(5.8, abs=0.05)
    # ≈ first order: the reduced loop is close to FK/2π
    assert closed_loop_bandwidth(p, "reduced") == pytest.approx(
        p.loop_gain / (2 * math.pi), rel=0.01)


def test_with_returns_a_validated_copy() -> None:
    q = SET_B.with_(M_t=0.5)
    assert q == SET_C and SET_B.M_t == 1500.0
    with pytest.raises(TypeError, match="no parameter"):
        SET_B.with_(mass=1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        SET_B.M_t = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("changes", "error", "match"),
    [
        ({"M_t": -1.0}, ModelError, r"M_t must be > 0, got -1"),
        ({"M_t": 0.0}, ModelError, r"M_t must be > 0"),
        ({"beta_e": math.nan}, ModelError, r"beta_e must be finite"),
        ({"B_p": -1.0}, ModelError, r"B_p must be >= 0"),
        ({"P_T": 22e6}, ModelError, r"P_T must be < P_s"),
        ({"F_s": 100.0}, ModelError, r"F_s \(static friction\) must be >= F_c"),
        ({"u_0": 1e-3}, ModelError, r"u_0 \(overlap\) must be < x_s_max"),
        ({"T_d": -1e-3}, ModelError, r"T_d must be >= 0"),
        ({"A_p": "1e-3"}, TypeError, r"A_p must be a real number"),
        ({"K_fb": True}, TypeError, r"K_fb must be a real number"),
    ],
)
def test_bad_parameters_raise(changes: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        SET_B.with_(**changes)


def test_bad_parameters_are_value_errors() -> None:
    with pytest.raises(ValueError):
        EhsaParameters(M_t=-3.0)
