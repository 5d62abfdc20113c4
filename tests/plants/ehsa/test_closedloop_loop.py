"""FeedbackLoop validation and loop algebra; the fast Tustin map."""

from __future__ import annotations

import numpy as np
import pytest
from loop_records import DT, LOOP, TRUTH

import servoid.closedloop as cl
import servoid.plants.ehsa as ehsa_package
from servoid import ModelError
from servoid.models import TransferFunction, c2d, d2c
from servoid.plants.ehsa import FeedbackLoop, reduced_plant
from servoid.plants.ehsa._loop import tustin


def test_exports_cover_the_ehsa_study_and_any_loop():
    # not a verbatim copy of __all__ (tests/test_public_api.py checks its shape): the EHSA's
    # approaches live with the actuator, the methods for any plant in servoid.closedloop
    ehsa = {"FeedbackLoop", "fit_direct", "fit_indirect", "fit_one_step", "identify_closed_loop"}
    any_loop = {"feedback_test", "fit_cliv", "fit_indirect_tf", "fit_two_stage"}
    assert ehsa <= set(ehsa_package.__all__) and any_loop <= set(cl.__all__)


def test_feedback_zero_is_refused_with_the_fix():
    with pytest.raises(ModelError, match=r"F = 0\.0: with F = 0 the loop is open.*FeedbackLoop"):
        FeedbackLoop(c=0.01, F=0.0)


def test_feedback_negative_is_refused_with_the_fix():
    with pytest.raises(ModelError, match=r"wrong sign.*1 \+ F·G0.*pass F = 0\.01"):
        FeedbackLoop(c=0.01, F=-0.01)


def test_dynamic_feedback_of_wrong_sign_is_refused():
    with pytest.raises(ModelError, match="wrong sign.*static gain -0.01"):
        FeedbackLoop(c=0.01, F=TransferFunction([-0.01], [1 / 300, 1.0]))


@pytest.mark.parametrize(
    ("c", "F", "error"),
    [(0.0, 0.01, ModelError), (float("nan"), 0.01, ModelError), ("1", 0.01, TypeError),
     (0.01, "x", TypeError), (True, 0.01, TypeError)],
)
def test_bad_gains(c, F, error):
    with pytest.raises(error):
        FeedbackLoop(c=c, F=F)


def test_close_then_plant_from_round_trip():
    g = c2d(reduced_plant(TRUTH), DT, "tustin")
    h = LOOP.close(g)
    g_back = LOOP.plant_from(h)
    w = np.logspace(0, 3, 50)
    # pure polynomial algebra on 4-term polynomials: rounding only
    np.testing.assert_allclose(g_back.freqresp(w), g.freqresp(w), rtol=1e-9)
    # DC gain of the closed loop is c/F (spec §1.1)
    assert h.dc_gain() == pytest.approx(LOOP.c / LOOP.F, rel=1e-9)


def test_closed_loop_denominator_matches_spec():
    h = LOOP.close(reduced_plant(TRUTH))
    k, w, d = TRUTH
    # cK/(s³/ω² + 2δs²/ω + s + FK), spec §1.1 Eq. 11; coefficients to rounding
    np.testing.assert_allclose(h.den, [1.0, 2 * d * w, w * w, 0.01 * k * w * w], rtol=1e-12)


def test_plant_input_static_and_dynamic():
    rng = np.random.default_rng(0)
    r, y = rng.normal(size=100), rng.normal(size=100)
    np.testing.assert_allclose(LOOP.plant_input(r, y, DT), 0.01 * r - 0.01 * y)
    dyn = FeedbackLoop(0.01, TransferFunction([0.01], [1 / 300, 1.0]))
    f = c2d(dyn.F, DT, "tustin")
    expected = 0.01 * r - f.simulate(y)
    np.testing.assert_allclose(dyn.plant_input(r, y, DT), expected, rtol=1e-12, atol=1e-15)


def test_discrete_feedback_must_match_dt():
    dyn = FeedbackLoop(0.01, TransferFunction([0.01], [1.0], dt=2e-3))
    with pytest.raises(ModelError, match="dt = 0.002 s but the data have dt = 0.001 s"):
        dyn.feedback_at(DT)


def test_fast_tustin_equals_c2d():
    g = reduced_plant(TRUTH)
    a, b = tustin(g, DT), c2d(g, DT, "tustin")
    # same substitution; only summation order may differ
    np.testing.assert_allclose(a.num, b.num, rtol=1e-13)
    np.testing.assert_allclose(a.den, b.den, rtol=1e-13, atol=1e-15)


def test_reduced_plant_round_trip_keeps_the_integrator():
    g = reduced_plant(TRUTH)
    back = d2c(c2d(g, DT, "tustin"), "tustin")
    assert np.min(np.abs(back.poles())) < 1e-6  # E1: integrator within 1e-6 rad/s
