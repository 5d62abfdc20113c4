"""A test the actuator can run: the amplitude rule against an independent generator."""

from __future__ import annotations

import warnings

import pytest
from merritt_rig import Rig, peak_load_pressure

from servoid._errors import DataError, ServoidWarning
from servoid.plants.ehsa import (
    PRESSURE_FRACTION,
    SET_B,
    SET_C,
    EhsaBench,
    excitation_limits,
    run,
    within_limits,
)
from servoid.signals import prbs


def test_load_pressure_matches_an_independent_generator():
    # Merritt's linearised rig (scipy, its own PRBS n = 10): a ±0.2 mm PRBS on Set B drives
    # |P_L| to 0.334·P_s; the rule's full-order model, read between samples, predicts it
    # within 3 % (the generator has no valve dynamics and reads at 5 kHz).
    rig = Rig(amplitude=0.2e-3, register=10, flow_law=False)
    plan = excitation_limits(SET_B, prbs(10, clock=10, amplitude=0.2e-3, dt=1e-3))
    assert plan.load_pressure / SET_B.P_s == pytest.approx(peak_load_pressure(rig), rel=0.03)


def test_spec_prbs_is_not_a_test_set_b_can_run():
    plan = excitation_limits(SET_B, prbs(11, clock=10, amplitude=1e-3, dt=1e-3))
    assert not plan.feasible and plan.rule.binding == "load pressure"
    assert plan.load_pressure == pytest.approx(35.2e6, rel=0.01)  # from a 21 MPa supply
    note = plan.note()
    assert "load pressure 35.2 MPa" in note and "±0.199 mm" in note
    assert plan.to_dict()["limits"][0]["quantity"] == "load pressure"
    # the default test: the largest amplitude within every limit, rounded down
    ex = within_limits(SET_B, prbs(11, clock=10, amplitude=1e-3, dt=1e-3))
    assert ex.amplitude == pytest.approx(0.19e-3)
    again = excitation_limits(SET_B, ex)
    assert again.feasible and again.note() == ""
    assert again.load_pressure <= PRESSURE_FRACTION * SET_B.P_s
    feasible = prbs(11, clock=10, amplitude=0.1e-3, dt=1e-3)
    assert within_limits(SET_B, feasible) is feasible


def test_set_c_is_bound_by_the_spool_rate():
    plan = excitation_limits(SET_C, prbs(9, clock=10, amplitude=1e-3, dt=1e-3))
    assert plan.rule.binding == "spool rate"  # a light load needs little pressure
    assert plan.load_pressure < 0.01 * SET_C.P_s


def test_bench_says_where_a_test_saturates_before_it_runs():
    with pytest.warns(ServoidWarning, match=r"asks more than the actuator can do: load "
                      r"pressure .*MPa.*the 'reduced' model stays linear"):
        rec = run(EhsaBench(), prbs(7, clock=10, amplitude=1e-3, dt=1e-3), rng=0)
    assert any("asks more than the actuator" in w for w in rec.warnings)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)  # the default amplitude is feasible
        run(EhsaBench(), within_limits(SET_B, prbs(7, clock=10, amplitude=1e-3, dt=1e-3)),
            rng=0)


def test_bad_fraction_and_zero_amplitude():
    ex = prbs(7, clock=10, amplitude=1e-3, dt=1e-3)
    with pytest.raises(DataError, match="pressure_fraction must lie in"):
        excitation_limits(SET_B, ex, pressure_fraction=1.5)
    with pytest.raises(DataError, match="offset"):
        excitation_limits(SET_B, prbs(7, clock=10, amplitude=1e-3, offset=0.03, dt=1e-3))
