"""Friction models shared by the actuator simulators."""

import numpy as np
import pytest

from servoid._errors import ModelError
from servoid.plants._friction import (
    coulomb_friction,
    coulomb_nb,
    karnopp_friction,
    karnopp_nb,
    stribeck_friction,
    stribeck_nb,
    three_regime_friction,
    three_regime_nb,
    viscous_friction,
    viscous_nb,
)

V = np.concatenate([np.linspace(-0.3, 0.3, 601), [0.0, 1e-4, -1e-4, 0.1, -0.1, 5e-5]])
F = np.linspace(-150.0, 150.0, V.size)
KW = {"F_haft": 85.0, "d_k": 55.0, "c_k": 120.0, "v_krit": 0.1, "eps": 1e-4}


def test_scalar_kernels_match_vectorised() -> None:
    # the same arithmetic in both: equal to rounding
    assert [coulomb_nb(v, 55.0) for v in V] == pytest.approx(coulomb_friction(V, 55.0), abs=0)
    assert [viscous_nb(v, 120.0) for v in V] == pytest.approx(viscous_friction(V, 120.0), abs=0)
    want = stribeck_friction(V, 55.0, 85.0, 0.02, c=120.0, delta=2.0)
    got = [stribeck_nb(v, 55.0, 85.0, 0.02, 120.0, 2.0) for v in V]
    assert got == pytest.approx(want, rel=1e-14, abs=1e-12)
    want = karnopp_friction(V, F, 55.0, 85.0, 1e-4, c=120.0)
    assert [karnopp_nb(v, f, 55.0, 85.0, 1e-4, 120.0) for v, f in zip(V, F)] == pytest.approx(
        want, rel=1e-14, abs=1e-12)
    for blend in (False, True):
        want = three_regime_friction(V, F, blend=blend, **KW)
        got = [three_regime_nb(v, f, 85.0, 55.0, 120.0, 0.1, 1e-4, blend) for v, f in zip(V, F)]
        assert got == pytest.approx(want, rel=1e-14, abs=1e-12)
        got_py = [three_regime_nb.py_func(v, f, 85.0, 55.0, 120.0, 0.1, 1e-4, blend)
                  for v, f in zip(V, F)]
        assert got_py == pytest.approx(want, rel=1e-14, abs=1e-12)


def test_three_regime_values() -> None:
    out = three_regime_friction([0.2, -0.2, 0.05, -0.05, 0.0, 0.0, 5e-5], [0, 0, 0, 0, 40, -100, 0],
                                **KW)
    assert out.tolist() == [79.0, -79.0, 85.0, -85.0, 40.0, -85.0, 0.0]
    # sliding friction at ẋ_krit: d_k + c_k ẋ_krit = 67 N (spec §2)
    assert float(three_regime_friction(0.1, 0.0, **KW)) == pytest.approx(67.0, rel=1e-15)


def test_blend_is_continuous() -> None:
    # the blend meets F_haft at ε and d_k + c_k ẋ_krit at ẋ_krit (up to the 1e-12 offset)
    assert float(three_regime_friction(1e-4 + 1e-12, 0.0, blend=True, **KW)) == pytest.approx(
        85.0, abs=1e-6)
    assert float(three_regime_friction(0.1 - 1e-12, 0.0, blend=True, **KW)) == pytest.approx(
        67.0, abs=1e-6)


def test_stribeck_limits() -> None:
    assert float(stribeck_friction(1e-9, 55.0, 85.0, 0.02)) == pytest.approx(85.0, rel=1e-9)
    assert float(stribeck_friction(1.0, 55.0, 85.0, 0.02, c=10.0)) == pytest.approx(65.0, rel=1e-9)


def test_karnopp_band_balances_applied_force() -> None:
    out = karnopp_friction([0.0, 0.0, 0.0, 1e-3], [30.0, 100.0, -100.0, 0.0], 55.0, 85.0, 1e-4)
    assert out.tolist() == [30.0, 85.0, -85.0, 55.0]


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: coulomb_friction(0.1, -1.0), ModelError, "F_c must be >= 0"),
        (lambda: stribeck_friction(0.1, 90.0, 85.0, 0.01), ModelError, "F_s must be >= F_c"),
        (lambda: three_regime_friction(0.1, 0.0, **{**KW, "v_krit": 1e-5}), ModelError,
         "v_krit must be > eps"),
        (lambda: three_regime_friction(0.1, 0.0, blend=1, **KW), TypeError, "blend must be a bool"),
        (lambda: viscous_friction([np.inf], 1.0), ModelError, "v must be finite"),
        (lambda: karnopp_friction(0.0, 0.0, 1.0, 2.0, 0.0), ModelError, "eps must be > 0"),
    ],
)
def test_bad_input(call, error, match) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(error, match=match):
        call()
