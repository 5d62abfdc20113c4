"""Reduced and full-order linear EHSA models (spec §1.1, E6)."""

import math

import numpy as np
import pytest

from servoid._errors import ModelError, OptionError
from servoid.plants.ehsa import (
    SET_A,
    SET_B,
    SET_C,
    ReducedEhsa,
    closed_loop_bandwidth,
    full_order_closed_loop,
    full_order_plant,
    loop_margins,
)


def _routh_stable(den: np.ndarray) -> bool:
    """Routh–Hurwitz for a cubic a3 s³ + a2 s² + a1 s + a0 (independent check)."""
    a3, a2, a1, a0 = den
    return bool(a3 > 0 and a2 > 0 and a1 > 0 and a0 > 0 and a2 * a1 > a3 * a0)


def test_reduced_plant_and_closed_loop_forms() -> None:
    g = ReducedEhsa.from_parameters(SET_B)
    assert (g.K, g.omega_hp, g.delta_hp) == (SET_B.K, SET_B.omega_hp, SET_B.delta_hp)
    plant = g.plant()
    assert plant.dt is None and plant.order == 3
    w = np.array([1.0, 10.0, 100.0, 1000.0])
    s = 1j * w
    expected = g.K / (s * (s**2 / g.omega_hp**2 + 2 * g.delta_hp * s / g.omega_hp + 1))
    assert plant.freqresp(w) == pytest.approx(expected, rel=1e-12)  # rounding
    c, F = SET_B.reference_gain, SET_B.K_fb
    cl = g.closed_loop(c, F)
    via_feedback = plant.feedback(F) * c
    assert cl.freqresp(w) == pytest.approx(via_feedback.freqresp(w), rel=1e-12)  # rounding
    assert cl.dc_gain() == pytest.approx(c / F, rel=1e-12)  # DC gain = c/F


@pytest.mark.parametrize("model", [ReducedEhsa.from_parameters(SET_B),
                                   ReducedEhsa.from_parameters(SET_C), SET_A.model])
def test_e6_stability_boundary(model: ReducedEhsa) -> None:
    f_lim = 2 * model.delta_hp * model.omega_hp / model.K
    assert model.routh_limit == pytest.approx(model.K * f_lim, rel=1e-15)
    for factor, stable in ((0.9, True), (1.1, False)):
        F = factor * f_lim
        cl = model.closed_loop(1.0, F)
        assert model.is_stable(F) is stable
        assert bool(np.all(cl.poles().real < 0)) is stable
        assert cl.is_stable() is stable
        assert _routh_stable(cl.den) is stable
    # at the boundary the pair sits on the imaginary axis at ±jω_hp
    cl = model.closed_loop(1.0, f_lim)
    assert np.max(np.abs(cl.poles())) >= model.omega_hp * (1 - 1e-6)  # roots of a cubic
    assert np.min(np.abs(np.abs(cl.poles()) - model.omega_hp)) < 1e-6 * model.omega_hp
    assert not model.is_stable(-0.1) and not model.is_stable(0.0)


def test_from_real_poles() -> None:
    g = ReducedEhsa.from_real_poles(100.0 * 10.0 * 40.0, 10.0, 40.0)
    assert g.K == pytest.approx(100.0, rel=1e-15)
    assert g.omega_hp == pytest.approx(20.0, rel=1e-15)
    assert g.delta_hp == pytest.approx(50.0 / 40.0, rel=1e-15)
    assert np.sort(g.plant().poles().real) == pytest.approx([-40.0, -10.0, 0.0], abs=1e-9)


def test_full_order_plant_structure() -> None:
    for p in (SET_B, SET_C):
        g = full_order_plant(p)
        assert g.dt is None and g.order == 8
        poles = g.poles()
        assert np.min(np.abs(poles)) < 1e-6  # one integrator
        assert np.sum(np.abs(poles) < 1e-6) == 1
        expected = sorted([p.omega_f, p.omega_sp, p.omega_s1, p.omega_hp, p.omega_hp,
                           p.omega_f, p.omega_sp])
        got = sorted(np.abs(poles[np.abs(poles) > 1e-6]))
        assert got == pytest.approx(expected, rel=1e-6)  # roots of an 8th-order polynomial
        # static velocity gain of G_plant equals the reduced K
        w = 1e-3
        assert abs(g.freqresp(w) * 1j * w) == pytest.approx(p.K, rel=1e-6)  # (w/ω)² terms


def test_full_order_closed_loop_tracks_and_is_stable() -> None:
    for p in (SET_B, SET_C):
        cl = full_order_closed_loop(p)
        assert cl.order == 8 and cl.is_stable()
        assert cl.dc_gain() == pytest.approx(p.dc_gain, rel=1e-9)  # unit tracking
        # at low frequency the full and reduced loops agree (fast lags ≥ 1000 rad/s)
        red = ReducedEhsa.from_parameters(p).closed_loop(p.reference_gain, p.K_fb)
        assert abs(cl.freqresp(1.0) - red.freqresp(1.0)) < 2e-3


def test_exact_piston_differs_by_kce_bp() -> None:
    # Merritt drops K_ce·B_p/A_p² (= 0.4 %) against 1 in the velocity gain
    p = SET_B
    w = 1e-3
    approx = abs(full_order_plant(p).freqresp(w) * 1j * w)
    exact = abs(full_order_plant(p, exact=True).freqresp(w) * 1j * w)
    assert approx / exact == pytest.approx(1 + p.K_ce * p.B_p / p.A_p**2, rel=1e-6)
    # with a load spring the exact plant loses its integrator
    sprung = full_order_plant(p.with_(K_l=1e6), exact=True)
    assert math.isfinite(sprung.dc_gain())


def test_bad_inputs_raise() -> None:
    with pytest.raises(ModelError, match=r"K must be finite and > 0"):
        ReducedEhsa(K=-1.0, omega_hp=100.0, delta_hp=0.3)
    with pytest.raises(ModelError, match=r"omega_hp"):
        ReducedEhsa(K=1.0, omega_hp=math.inf, delta_hp=0.3)
    with pytest.raises(TypeError, match=r"delta_hp must be a real number"):
        ReducedEhsa(K=1.0, omega_hp=100.0, delta_hp="0.3")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="EhsaParameters"):
        ReducedEhsa.from_parameters({"K": 1.0})  # type: ignore[arg-type]
    with pytest.raises(OptionError, match=r"order must be one of 'reduced', 'full'"):
        loop_margins(SET_B, "eighth")  # type: ignore[arg-type]
    with pytest.raises(OptionError, match="order"):
        closed_loop_bandwidth(SET_B, "8")  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="F must be finite"):
        ReducedEhsa.from_parameters(SET_B).closed_loop(1.0, math.nan)
    with pytest.raises(ModelError, match="must be > 0"):
        ReducedEhsa.from_real_poles(1.0, -1.0, 2.0)
