"""Closed-loop ARX on the Set-B reduced EHSA (models-spec §1.1, §1.5, §3.3–3.4, §4 E2/E8).

Truth: ``G_simple = K/(s(s²/ω² + 2δs/ω + 1))``, closed with c = F = 0.01 into
``H = c·G/(1 + F·G)``, discretised by Tustin at 1 ms, driven by a ±1 mm PRBS, noise free.
"""

import numpy as np
import pytest

from servoid import Experiment
from servoid.estimate import fit_arx
from servoid.models import TransferFunction, c2d, d2c
from servoid.signals import prbs

K, OMEGA, DELTA = 3451.7, 163.3, 0.249
C = F = 0.01
DT = 1e-3


@pytest.fixture(scope="module")
def loop():
    g = TransferFunction([K], [1 / OMEGA**2, 2 * DELTA / OMEGA, 1.0, 0.0])
    h = (C * g).feedback(F / C)  # c·G/(1 + (F/c)·c·G) = c·G/(1 + F·G)
    hd = c2d(h, DT, "tustin")
    r = prbs(11, clock=10, amplitude=1e-3, periods=1, dt=DT).values  # 20 470 samples
    # den and num of a Tustin image have equal degree: descending z = ascending q⁻¹
    y = TransferFunction(hd.num, hd.den, DT).simulate(r)
    return hd, Experiment.from_arrays(DT, r=r, y=y)


def indirect(est, nb):
    """G0 = B/(c·A − F·B) in q⁻¹ (spec §1.5), as a Tustin z-domain transfer function."""
    a = np.concatenate([[1.0], est.parameters[:3]])
    b = np.concatenate([est.parameters[3 : 3 + nb], np.zeros(4 - nb)])  # b_j multiplies q⁻ʲ
    den = np.polysub(C * a, F * b)
    return TransferFunction(b, den, DT, "tustin")  # ×z³: ascending q⁻¹ = descending z


def test_arx_340_recovers_the_closed_loop_tustin_coefficients(loop):
    hd, exp = loop
    est = fit_arx(exp, 3, 4, 0, input="r")
    truth = np.concatenate([hd.den[1:], hd.num])
    # E2: 1e-6 relative (spec §4); noise-free inside the structure, cond(Φ) ≈ 5e2 gives ≈ 1e-10
    np.testing.assert_allclose(est.parameters, truth, rtol=1e-6)
    assert est.options["input"] == "r" and est.options["inputs"] == ["r"]


def test_indirect_then_d2c_recovers_k_omega_delta(loop):
    _, exp = loop
    g0 = d2c(indirect(fit_arx(exp, 3, 4, 0, input="r"), nb=4))
    num, den = g0.num, g0.den  # den monic: s³ + 2δω s² + ω² s + s₀-term
    poles = np.roots(den)
    s0 = poles[np.argmin(np.abs(poles))]
    assert abs(s0) < 1e-4  # E2: the integrator within 1e-4 rad/s
    omega = np.sqrt(den[2])
    # E2: K, ω, δ within 1e-6 relative; K = numerator constant / s¹ coefficient (spec §3.4 step 4)
    assert omega == pytest.approx(OMEGA, rel=1e-6)
    assert den[1] / (2 * omega) == pytest.approx(DELTA, rel=1e-6)  # same E2 bound
    assert num[-1] / den[2] == pytest.approx(K, rel=1e-6)  # same E2 bound


def test_three_b_coefficients_cannot_represent_the_data(loop):
    _, exp = loop
    est = fit_arx(exp, 3, 3, 0, input="r")
    y = exp["y"]
    # the right structure leaves rounding (≈1e-15 of |y|); the wrong one ≈ 1e-4 of std(y)
    rms = np.sqrt(np.mean(est.residuals**2))
    assert rms > 1e-6 * np.std(y)
    # E8: the continuous model misses the integrator: a spurious pole near +0.64 rad/s (spec §1.2)
    poles = d2c(indirect(est, nb=3)).poles()
    assert np.min(np.abs(poles)) > 0.1


def test_indirect_equals_direct(loop):
    _, exp = loop
    u = C * exp["r"] - F * exp["y"]  # the plant input the loop computed
    direct = fit_arx(Experiment.from_arrays(DT, u=u, y=exp["y"]), 3, 4, 0)
    g0 = indirect(fit_arx(exp, 3, 4, 0, input="r"), nb=4)
    # E2: indirect (Eq. 8) and direct ARX agree within 1e-6 relative
    np.testing.assert_allclose(g0.den[1:], direct.parameters[:3], rtol=1e-6)
    np.testing.assert_allclose(g0.num, direct.parameters[3:], rtol=1e-6)  # same E2 bound
