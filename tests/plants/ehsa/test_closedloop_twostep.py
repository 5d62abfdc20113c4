"""Two-step indirect and direct approaches: spec §4 E2, E3, E8 and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from loop_records import DT, LOOP, TRUTH, halves, record, reference
from scipy.signal import lfilter

from servoid import DataError, ServoidWarning
from servoid.data import Experiment
from servoid.models import TransferFunction, d2c
from servoid.plants.ehsa import FeedbackLoop, fit_direct, fit_indirect, simulate_closed_loop


@pytest.fixture(scope="module")
def clean(r, y_clean):
    return halves(record(y_clean, r))[0]


def test_e2_indirect_equals_direct_and_truth(clean):
    ind = fit_indirect(clean, LOOP)
    direct = fit_direct(clean, LOOP)  # u formed as c·r − F·y
    p_ind, p_dir = ind.estimate.parameters, direct.estimate.parameters
    # spec E2: 1e-6 relative; noise-free ARX is exact to rounding (observed ~1e-9)
    np.testing.assert_allclose(p_ind, p_dir, rtol=1e-6)
    np.testing.assert_allclose(p_ind, TRUTH, rtol=1e-6)
    np.testing.assert_allclose(p_dir, TRUTH, rtol=1e-6)
    assert abs(ind.integrator) < 1e-4 and abs(direct.integrator) < 1e-4  # spec E2, rad/s
    assert ind.is_physical and direct.is_physical
    assert ind.estimate.names == ("K", "omega_hp", "delta_hp")
    assert ind.estimate.units == ("1/s", "rad/s", "-")


def test_e2_discrete_then_d2c_equals_d2c_then_indirect(clean):
    res = fit_indirect(clean, LOOP)
    h_c = d2c(res.closed_loop, "tustin")
    g_c = LOOP.plant_from(h_c)  # continuous indirect
    w = np.logspace(0, np.log10(3000), 60)
    # Tustin is an exact substitution (spec §1.5): equal to rounding of the d2c sums
    np.testing.assert_allclose(g_c.freqresp(w), res.plant_continuous.freqresp(w), rtol=1e-6)
    np.testing.assert_allclose(np.sort_complex(g_c.poles()),
                               np.sort_complex(res.plant_continuous.poles()), atol=1e-4)


def test_direct_with_measured_u_equals_formed_u(r, y_clean):
    exp = halves(record(y_clean, r))[0]
    u = LOOP.plant_input(exp["r"], exp["y"], DT)
    with_u = Experiment.from_arrays(DT, u=u, y=exp["y"])
    a = fit_direct(with_u)  # no loop: plant only
    b = fit_direct(exp, LOOP)
    np.testing.assert_allclose(a.estimate.parameters, b.estimate.parameters, rtol=1e-9)
    assert a.closed_loop is None and a.loop is None


def test_e3_equation_noise(r, y_clean):
    res0 = fit_indirect(halves(record(y_clean, r))[0], LOOP)
    a_cl = res0.closed_loop.den  # true A_cl (noise-free ARX is exact)
    rng = np.random.default_rng(3)
    e = rng.normal(0.0, 5e-6, r.size)  # σ = 5 µm (spec E3)
    y = y_clean + lfilter([1.0], a_cl, e)
    est = halves(record(y, r))[0]
    res = fit_indirect(est, LOOP)
    k, w, d = res.estimate.parameters
    assert abs(w / TRUTH[1] - 1) < 0.03  # spec E3
    assert abs(d / TRUTH[2] - 1) < 0.12  # spec E3
    assert abs(k / TRUTH[0] - 1) < 0.15  # spec E3
    # delta-method covariance: errors within 4σ (ARX consistent under equation error)
    err = np.abs(res.estimate.parameters - TRUTH)
    assert np.all(err < 4 * res.estimate.std), (err, res.estimate.std)
    lo, hi = res.estimate.confidence_intervals(0.95).T
    assert np.all(lo < res.estimate.parameters) and np.all(res.estimate.parameters < hi)


def test_e8_three_b_coefficients_miss_the_integrator(clean):
    with pytest.warns(ServoidWarning, match="integrator came out at s0 = .*nb = na \\+ 1 = 4"):
        res = fit_indirect(clean, LOOP, nb=3)
    assert abs(res.integrator) > 0.1  # spec E8
    flagged = [p for p in res.poles if p.role == "integrator" and p.domain == "continuous"]
    assert flagged and not flagged[0].is_physical


def test_dynamic_feedback_noise_free():
    f = TransferFunction([0.01], [1 / 300, 1.0])  # first-order sensor lag, 300 rad/s
    loop = FeedbackLoop(0.01, f)
    r = reference()
    y = simulate_closed_loop(TRUTH, r, DT, loop)
    est = halves(record(y, r))[0]
    # closed loop has 3 + 1 poles: ARX(4, 5, 0); the F pole cancels in G0 = B/(cA − FB)
    res = fit_indirect(est, loop, na=4, nb=5)
    np.testing.assert_allclose(res.estimate.parameters, TRUTH, rtol=1e-6)
    assert any(p.role == "cancelled" for p in res.poles)
    direct = fit_direct(est, loop)  # u = c·r − F·y with F applied by Tustin
    np.testing.assert_allclose(direct.estimate.parameters, TRUTH, rtol=1e-6)


def test_unstable_identified_closed_loop_warns():
    k, w, d = TRUTH
    f_unstable = 1.1 * 2 * d * w / k  # 10 % beyond the Routh limit FK < 2δω (spec E6)
    loop = FeedbackLoop(0.01, f_unstable)
    r = reference()[:3000]
    y = simulate_closed_loop(TRUTH, r, DT, loop)
    with pytest.warns(ServoidWarning, match="outside the unit circle: the identified closed "
                                            "loop is unstable"):
        res = fit_indirect(record(y, r), loop)
    assert not res.is_physical


def test_missing_reference_for_indirect():
    exp = Experiment.from_arrays(DT, u=np.arange(100.0), y=np.arange(100.0))
    with pytest.raises(DataError, match="indirect approach fits the closed loop from the "
                                        "reference r to y.*no reference"):
        fit_indirect(exp, LOOP)


def test_direct_without_u_and_loop():
    exp = Experiment.from_arrays(DT, r=np.arange(100.0), y=np.arange(100.0))
    with pytest.raises(DataError, match="pass loop=FeedbackLoop"):
        fit_direct(exp)


def test_loop_type_checked(clean):
    with pytest.raises(TypeError, match="FeedbackLoop"):
        fit_indirect(clean, 0.01)  # type: ignore[arg-type]
