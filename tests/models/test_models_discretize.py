"""c2d / d2c: known answers, round trips (spec E1) and agreement with scipy."""

import math

import numpy as np
import pytest
from scipy import signal

from servoid import ModelError, OptionError
from servoid.models import StateSpace, TransferFunction, c2d, d2c

K, W_HP, D_HP = 3451.7, 163.3, 0.249
DT = 1e-3


def quad(w, d):
    """Return s²/ω² + 2δs/ω + 1."""
    return np.array([1.0 / w**2, 2.0 * d / w, 1.0])


def quad_roots(w, d):
    return np.roots(quad(w, d))


def g_simple():
    return TransferFunction([K], np.polymul([1.0, 0.0], quad(W_HP, D_HP)))


def g_simple_poles():
    return np.concatenate([quad_roots(W_HP, D_HP), [0.0]])


# Set-B full-order plant, spec §1.1/§1.3: G_f·G_s2·G_h
W_F, D_F = 2 * math.pi * 600, 0.5
K_S2, W_S1, W_SP, D_SP = 12.0, 1000.0, 2 * math.pi * 800, 0.6
K_H = 287.6


def plant_factors():
    g_f = TransferFunction([1.0], quad(W_F, D_F))
    g_s2 = TransferFunction([K_S2 * W_S1], np.polymul([1.0, W_S1], quad(W_SP, D_SP)))
    g_h = TransferFunction([K_H], np.polymul([1.0, 0.0], quad(W_HP, D_HP)))
    return g_f, g_s2, g_h


def g_plant():
    g_f, g_s2, g_h = plant_factors()
    return g_f * g_s2 * g_h


def g_plant_poles():
    return np.concatenate(
        [quad_roots(W_F, D_F), [-W_S1], quad_roots(W_SP, D_SP), quad_roots(W_HP, D_HP), [0.0]]
    )


def plant_ss():
    """Series realisation of the plant (factor by factor, better scaled than a companion)."""
    g_f, g_s2, g_h = (g.to_ss() for g in plant_factors())
    a = np.zeros((8, 8))
    b = np.zeros((8, 1))
    a[:2, :2] = g_f.A
    b[:2] = g_f.B
    a[2:5, 2:5] = g_s2.A
    a[2:5, :2] = g_s2.B @ g_f.C
    a[5:, 5:] = g_h.A
    a[5:, 2:5] = g_h.B @ g_s2.C
    c = np.zeros((1, 8))
    c[:, 5:] = g_h.C
    return StateSpace(a, b, c, [[0.0]])


def velocity_gain(g):
    """K = b0/a1: numerator constant over the s¹ coefficient of den (one integrator)."""
    return g.num[-1] / g.den[-2]


def match_error(p, q):
    """Largest distance of each pole in p to its partner in q, relative to max(|q|, 1)."""
    q = list(q)
    worst = 0.0
    for x in p:
        j = int(np.argmin([abs(x - y) for y in q]))
        y = q.pop(j)
        worst = max(worst, abs(x - y) / max(abs(y), 1.0))
    assert not q
    return worst


def integrator(poles):
    return poles[np.argmin(np.abs(poles))]


# -- E1: round trips ----------------------------------------------------------
@pytest.mark.parametrize("method", ["tustin", "zoh"])
def test_e1_round_trip_third_order(method):
    g = g_simple()
    back = d2c(c2d(g, DT, method))
    assert back.dt is None and back.method is None
    # spec E1: 1e-6 relative on poles and gain, 1e-6 rad/s on the integrator
    assert match_error(back.poles(), g_simple_poles()) < 1e-6
    assert velocity_gain(back) == pytest.approx(K, rel=1e-6)
    assert abs(integrator(back.poles())) < 1e-6


def test_e1_tustin_round_trip_eighth_order_plant_by_coefficients():
    g = g_plant()
    gd = c2d(g, DT, "tustin")
    back = d2c(gd)
    # spec E1 bounds; exact substitution plus rounding clean-up reaches ~1e-11 here
    assert match_error(back.poles(), g_plant_poles()) < 1e-6
    assert velocity_gain(back) == pytest.approx(velocity_gain(g), rel=1e-6)
    assert abs(integrator(back.poles())) < 1e-6
    assert back.den[-1] == 0.0  # the integrator survives as an exact zero coefficient


def test_e1_zoh_round_trip_eighth_order_plant():
    # At dt = 1 ms the plant's 600 Hz and 800 Hz pairs lie above the 500 Hz Nyquist
    # frequency, so no ZOH inverse can recover them (see the aliasing test); at
    # 0.5 ms every pole is below Nyquist and the coefficient route is accurate.
    g = g_plant()
    back = d2c(c2d(g, 5e-4, "zoh"))
    # spec E1 bounds
    assert match_error(back.poles(), g_plant_poles()) < 1e-6
    assert velocity_gain(back) == pytest.approx(velocity_gain(g), rel=1e-6)
    assert abs(integrator(back.poles())) < 1e-6


def test_e1_zoh_round_trip_eighth_order_plant_in_state_space():
    # At 0.1 ms the eight discrete poles cluster within 0.5 of z = 1 and a degree-8
    # coefficient vector no longer fixes them to 1e-6 (observed ~1e-3); a state-space
    # model keeps them, which is why high-order ZOH work belongs in state space.
    ss = plant_ss()
    back = d2c(c2d(ss, 1e-4, "zoh"))
    assert match_error(back.poles(), g_plant_poles()) < 1e-6  # spec E1 bound
    assert np.allclose(back.A, ss.A, rtol=0, atol=1e-6 * np.abs(ss.A).max())  # same coordinates
    assert velocity_gain(back.to_tf()) == pytest.approx(velocity_gain(g_plant()), rel=1e-6)


def test_zoh_inverse_aliases_poles_above_nyquist():
    back = d2c(c2d(plant_ss(), DT, "zoh"))
    nyquist = math.pi / DT
    assert np.all(np.abs(back.poles().imag) <= nyquist * (1 + 1e-9))  # principal logarithm
    assert (
        match_error(back.poles(), g_plant_poles()) > 0.1
    )  # the 600/800 Hz pairs come back aliased


@pytest.mark.parametrize("method", ["tustin", "zoh"])
def test_state_space_round_trip_is_exact(method):
    ss = g_simple().to_ss()
    back = d2c(c2d(ss, DT, method))
    scale = np.abs(ss.A).max()
    assert np.allclose(back.A, ss.A, rtol=0, atol=1e-9 * scale)  # ε·cond of expm/logm
    assert np.allclose(back.B, ss.B, rtol=1e-9, atol=1e-12)
    assert np.allclose(back.C, ss.C, rtol=1e-9, atol=1e-9 * np.abs(ss.C).max())
    assert np.allclose(back.D, ss.D, atol=1e-9)


def test_prewarped_tustin_round_trip_and_match_at_prewarp_frequency():
    g = g_simple()
    wp = 2 * math.pi * 26.0
    gd = c2d(g, DT, "tustin", prewarp=wp)
    assert gd.method == "tustin" and gd.prewarp == wp
    # the prewarp frequency is mapped exactly, so the responses agree to rounding
    assert gd.freqresp([wp])[0] == pytest.approx(g.freqresp([wp])[0], rel=1e-9)
    back = d2c(gd)  # uses the remembered prewarp
    assert match_error(back.poles(), g_simple_poles()) < 1e-9  # exact substitution
    wrong = d2c(gd, prewarp=None, method="zoh")
    assert wrong.method is None
    assert match_error(wrong.poles(), g_simple_poles()) > 1e-4  # different inverse, different model


def test_d2c_uses_remembered_method_else_zoh():
    g = g_simple()
    gd = c2d(g, DT, "tustin")
    assert match_error(d2c(gd).poles(), g_simple_poles()) < 1e-9  # remembered: tustin
    plain = TransferFunction(gd.num, gd.den, DT)
    assert match_error(d2c(plain).poles(), g_simple_poles()) > 1e-6  # no memory: zoh


# -- agreement with scipy -------------------------------------------------------
@pytest.mark.parametrize("method, scipy_method", [("zoh", "zoh"), ("tustin", "bilinear")])
def test_tf_c2d_matches_scipy(method, scipy_method):
    g = g_simple()
    gd = c2d(g, DT, method)
    num, den, _ = signal.cont2discrete((g.num, g.den), DT, scipy_method)
    num = np.trim_zeros(np.ravel(num), "f")
    # 1e-10 relative to the coefficient scale: both are backward-stable, rounding differs
    assert np.allclose(gd.den, den, rtol=0, atol=1e-10 * np.abs(den).max())
    assert np.allclose(gd.num, num / den[0], rtol=0, atol=1e-10 * np.abs(num).max())


@pytest.mark.parametrize("method, scipy_method", [("zoh", "zoh"), ("tustin", "bilinear")])
def test_ss_c2d_matches_scipy(method, scipy_method):
    rng = np.random.default_rng(1)
    a = rng.normal(size=(4, 4)) - 3 * np.eye(4)
    b, c, d = rng.normal(size=(4, 2)), rng.normal(size=(3, 4)), rng.normal(size=(3, 2))
    ssd = c2d(StateSpace(a, b, c, d), 0.05, method)
    ref = signal.cont2discrete((a, b, c, d), 0.05, scipy_method)
    for mine, theirs in zip((ssd.A, ssd.B, ssd.C, ssd.D), ref[:4], strict=True):
        # 1e-10 relative: same formulas, different rounding order
        assert np.allclose(mine, theirs, rtol=0, atol=1e-10 * np.abs(theirs).max())


def test_tustin_image_of_strictly_proper_third_order_has_numerator_prop_to_z_plus_1_cubed():
    gd = c2d(g_simple(), DT, "tustin")
    assert gd.num.size == 4  # b0..b3: the "ARX(3,4,0)" structure of spec §1.2
    ref = np.poly([-1.0, -1.0, -1.0]) * gd.num[0]
    assert np.allclose(gd.num, ref, rtol=1e-12, atol=0)  # exact substitution, rounding only


def test_zoh_maps_poles_by_exponential():
    gd = c2d(g_simple(), DT, "zoh")
    # ε·cond of the degree-3 root problem
    assert match_error(gd.poles(), np.exp(g_simple_poles() * DT)) < 1e-10


# -- errors ------------------------------------------------------------------------
def test_zoh_d2c_refuses_negative_real_pole():
    gd = TransferFunction([1.0], [1.0, 0.5], DT)
    with pytest.raises(ModelError, match="negative real axis or at 0"):
        d2c(gd, "zoh")
    with pytest.raises(ModelError, match="negative real axis or at 0"):
        d2c(TransferFunction([1.0, 0.0], [1.0, 0.0], DT), "zoh")
    # Tustin has a preimage: the -7104 rad/s case of spec §1.2
    assert d2c(gd, "tustin").poles()[0].real == pytest.approx(-2 / DT * 1.5 / 0.5, rel=1e-12)


def test_tustin_d2c_refuses_pole_at_minus_one():
    with pytest.raises(ModelError, match="z = -1"):
        d2c(TransferFunction([1.0], [1.0, 1.0], DT), "tustin")
    with pytest.raises(ModelError, match="z = -1"):
        d2c(StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.0]], DT), "tustin")


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: c2d(g_simple(), DT, "matched"), OptionError, "'zoh', 'tustin'"),
        (lambda: c2d(g_simple(), -1.0), ModelError, "dt must be > 0"),
        (lambda: c2d(g_simple(), DT, "zoh", prewarp=10.0), OptionError, "prewarp"),
        (lambda: c2d(g_simple(), DT, "tustin", prewarp=1e4), ModelError, r"\(0, pi/dt\)"),
        (lambda: c2d(c2d(g_simple(), DT), DT), ModelError, "continuous-time model"),
        (lambda: d2c(g_simple()), ModelError, "discrete-time model"),
        (lambda: c2d("G", DT), TypeError, "TransferFunction or StateSpace"),
        (lambda: d2c(c2d(g_simple(), DT), "bilinear"), OptionError, "method must be one of"),
    ],
)
def test_bad_arguments_raise(call, error, match):
    with pytest.raises(error, match=match):
        call()
