"""Orifice flow functions and the chamber equation (spec §2, P5)."""

import math

import numpy as np
import pytest

from servoid._errors import ModelError, OptionError
from servoid.plants.pneumatic import (
    PNEUMATIC_NOMINAL,
    chamber_pressure_rate,
    critical_pressure_ratio,
    orifice_mass_flow,
    psi_ellipse,
    psi_max,
    psi_saint_venant,
)
from servoid.plants.pneumatic._flow import (
    chamber_pressure_rate_nb,
    orifice_mass_flow_nb,
    psi_ellipse_nb,
    psi_saint_venant_nb,
)

GRID = np.linspace(0.0, 1.2, 12001)  # includes π > 1 (reversed drop: ψ = 0)
P = PNEUMATIC_NOMINAL


def test_constants() -> None:
    assert psi_max(1.4) == pytest.approx(0.4842, abs=5e-5)  # spec prints 4 digits
    assert critical_pressure_ratio(1.4) == pytest.approx(0.5283, abs=5e-5)  # 4 digits


@pytest.mark.parametrize("b", [0.0, 0.25, 0.528, 0.9])
def test_ellipse_invariants(b: float) -> None:
    psi = psi_ellipse(GRID, b)
    pm = psi_max(1.4)
    assert np.all(psi <= pm)  # exact: the sqrt argument is <= 1
    assert np.all(psi >= 0.0)
    assert float(psi_ellipse(1.0, b)) == 0.0  # ψ(1) = 0 exactly
    assert np.all(np.diff(psi) <= 0.0)  # non-increasing in π
    # continuous at b: ψ(b + δ) = ψ_max(1 − δ²/(2(1−b)²) + …), δ = 1e-9
    assert abs(float(psi_ellipse(b + 1e-9, b)) - pm) < 1e-15
    assert float(psi_ellipse(b, b)) == pm


def test_saint_venant_invariants() -> None:
    psi = psi_saint_venant(GRID)
    pc, pm = critical_pressure_ratio(), psi_max()
    assert np.all(psi <= pm * (1 + 1e-15))  # its maximum is ψ_max at π_c (one ulp)
    assert float(psi_saint_venant(1.0)) == 0.0
    assert np.all(np.diff(psi) <= 1e-15)  # non-increasing up to one ulp
    # continuous at the clamp: the unclamped formula meets ψ_max at π_c
    assert abs(float(psi_saint_venant(pc * (1 + 1e-9))) - pm) < 1e-12


def test_ellipse_at_0528_matches_saint_venant() -> None:
    x = np.linspace(0.0, 1.0, 200001)
    sv = psi_saint_venant(x)
    # spec: "within 8e-4"; the supremum is 8.18e-4 at π ≈ 0.8675 (checked on 2e6 points)
    assert np.max(np.abs(psi_ellipse(x, 0.528) - sv)) < 8.2e-4
    # with b at the exact critical ratio 0.52828 it is 7.34e-4
    assert np.max(np.abs(psi_ellipse(x, critical_pressure_ratio()) - sv)) < 8e-4


def test_scalar_kernels_match_vectorised() -> None:
    pm, pc = psi_max(), critical_pressure_ratio()
    for b in (0.25, 0.528):
        ref = psi_ellipse(GRID, b)
        assert [psi_ellipse_nb(x, b, pm) for x in GRID] == pytest.approx(ref, abs=1e-15)
        assert [psi_ellipse_nb.py_func(x, b, pm) for x in GRID[::97]] == pytest.approx(
            ref[::97], abs=1e-15)
    ref = psi_saint_venant(GRID)
    got = np.array([psi_saint_venant_nb(x, 1.4, pc, pm) for x in GRID])
    np.testing.assert_array_equal(got[(GRID <= pc) | (GRID >= 1.0)],
                                  ref[(GRID <= pc) | (GRID >= 1.0)])  # clamped: exact constants
    assert np.all(np.abs(got - ref) <= _saint_venant_rounding(GRID))
    c = math.sqrt(2 / (P.R * P.T_S))
    for kind, flow in enumerate(("ellipse", "saint-venant")):
        for pu, pd in ((6e5, 2e5), (6e5, 5.5e5), (3e5, 4e5), (4e5, 4e5)):
            want = float(orifice_mass_flow(1e-5, pu, pd, R=P.R, T_up=P.T_S, flow=flow, b=0.25))
            got = orifice_mass_flow_nb(1e-5, pu, pd, c, kind, 0.25, 1.4, pc, pm)
            assert got == pytest.approx(want, rel=1e-14, abs=1e-20)
    assert chamber_pressure_rate_nb(4e5, 1e-3, 2e-4, 1e-5, 1.4 * P.R * P.T_S, 1.4) == (
        pytest.approx(float(chamber_pressure_rate(4e5, 1e-3, 2e-4, 1e-5, R=P.R, T=P.T_S))))


def _saint_venant_rounding(pi: np.ndarray, kappa: float = 1.4) -> np.ndarray:
    """Twice one ulp per operation of ψ = √(κ/(κ−1)·(a − b)), a = π^(2/κ), b = π^((κ+1)/κ).

    numpy's vectorised and numba's scalar powers may round a and b differently, each
    within an ulp. The difference a − b cancels as π → 1, so their rounding ε·(a + b)
    enters ψ multiplied by ψ/(2(a − b)); the subtraction, product and square root add about
    2ε·ψ. Two evaluations, each within this, differ by at most twice it (and are equal
    where ψ is clamped to ψ_max or 0).
    """
    pc = critical_pressure_ratio(kappa)
    x = np.clip(pi, pc, 1.0)
    a, b = x ** (2.0 / kappa), x ** ((kappa + 1.0) / kappa)
    psi = np.sqrt(kappa / (kappa - 1.0) * (a - b))
    with np.errstate(divide="ignore", invalid="ignore"):  # a = b at π = 1, masked below
        one = np.finfo(float).eps * psi * ((a + b) / (2.0 * (a - b)) + 2.0)
    return np.where((pi <= pc) | (pi >= 1.0), 0.0, 2.0 * one)


def test_choked_flow_at_1mm_is_26_6_g_per_s() -> None:
    area = math.pi * P.ad_2 * 1e-3
    m = float(orifice_mass_flow(area, P.p_S, P.p_R, R=P.R, T_up=P.T_S, b=P.p_krit))
    assert m * 1e3 == pytest.approx(26.6, abs=0.05)  # spec prints 3 digits
    assert P.choked_mass_flow(1e-3) == pytest.approx(m, rel=1e-14)
    # the 4 g/s sensor limit is reached at |x_v| ≈ 0.15 mm (spec §2)
    assert 4e-3 / P.choked_mass_flow(1e-3) * 1e-3 == pytest.approx(0.15e-3, abs=0.005e-3)


@pytest.mark.parametrize("flow", ["ellipse", "saint-venant"])
def test_orifice_sign_and_zero(flow: str) -> None:
    kw = {"flow": flow, "b": 0.25}
    fwd = orifice_mass_flow(2e-5, 5e5, 3e5, **kw)
    assert fwd > 0
    assert orifice_mass_flow(2e-5, 3e5, 5e5, **kw) == pytest.approx(-fwd, rel=1e-15)  # antisymmetric
    assert orifice_mass_flow(0.0, 5e5, 3e5, **kw) == 0.0
    assert orifice_mass_flow(2e-5, 4e5, 4e5, **kw) == 0.0


def test_chamber_rate_formula() -> None:
    got = chamber_pressure_rate(4e5, 2e-3, 2e-4, -1e-4, R=290.0, T=300.0, kappa=1.4)
    assert float(got) == pytest.approx(1.4 * (290 * 300 * 2e-3 + 4e5 * 1e-4) / 2e-4, rel=1e-15)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: psi_max(1.0), ModelError, "kappa must be > 1"),
        (lambda: psi_ellipse(0.5, 1.0), ModelError, r"b \(critical pressure ratio\)"),
        (lambda: psi_ellipse(-0.1, 0.25), ModelError, "pi must be finite and >= 0"),
        (lambda: psi_saint_venant(np.nan), ModelError, "finite"),
        (lambda: orifice_mass_flow(1e-5, -1.0, 1e5), ModelError, "p_up must be finite and > 0"),
        (lambda: orifice_mass_flow(-1e-5, 2e5, 1e5), ModelError, "area"),
        (lambda: orifice_mass_flow(1e-5, 2e5, 1e5, flow="sv"), OptionError, "'saint-venant'"),
        (lambda: chamber_pressure_rate(1e5, 0, 0.0, 0), ModelError, "V must be > 0"),
        (lambda: psi_max(True), TypeError, "real number"),
    ],
)
def test_bad_input(call, error, match) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(error, match=match):
        call()
