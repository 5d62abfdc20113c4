"""Servopneumatic parameters: Table 2, assumptions, derived values (spec §2)."""

import dataclasses
import math
import re

import pytest

from servoid._errors import ModelError
from servoid.plants.pneumatic import PNEUMATIC_NOMINAL, PneumaticParameters

P = PNEUMATIC_NOMINAL


def test_table_2_values() -> None:
    table = {"k_v": 1e-4, "xi_v": 0.35, "omega_v": 1000.0, "ad_1": 6e-3, "ad_2": 6e-3,
             "ad_3": 6e-3, "ad_4": 6e-3, "R": 290.0, "kappa": 1.4, "F_haft": 85.0,
             "v_krit": 0.1, "c_k": 120.0, "d_k": 55.0, "p_krit": 0.25}
    for name, value in table.items():
        assert getattr(P, name) == value, name


def test_derived_geometry_matches_spec() -> None:
    # the spec prints four digits
    assert P.A_I == pytest.approx(1.963e-3, abs=5e-7)
    assert P.A_II == pytest.approx(1.649e-3, abs=5e-7)
    assert P.V_0I == pytest.approx(2.163e-4, abs=5e-8)
    assert P.V_0II == pytest.approx(1.849e-4, abs=5e-8)
    assert P.psi_max == pytest.approx(0.4842, abs=5e-5)
    assert P.static_force == pytest.approx(1.013e5 * math.pi * 0.01**2 + 3 * 9.81, rel=1e-14)


def test_checked_stiffness_and_frequency() -> None:
    k = P.stiffness(3.5e5)
    assert k == pytest.approx(1.6e4, rel=0.01)  # spec "≈ 1.6e4" (2 digits); computed 15 939
    assert P.natural_frequency(3.5e5) / (2 * math.pi) == pytest.approx(11.6, abs=0.05)  # 3 digits
    assert P.choked_mass_flow(1e-3) * 1e3 == pytest.approx(26.6, abs=0.05)  # 3 digits
    # moving towards chamber I's end stiffens it
    assert P.stiffness(3.5e5, x_k=-0.09) > k


def test_every_field_is_documented_with_unit_and_source() -> None:
    doc = PneumaticParameters.__doc__ or ""
    for f in dataclasses.fields(PneumaticParameters):
        block = re.search(rf"^    {f.name} : float\n((?:        .*\n)+)", doc, re.MULTILINE)
        assert block, f.name
        text = block.group(1)
        brackets = re.findall(r"\[([^\]]+)\]", text)
        assert {"P", "P*", "A", "D"} & set(brackets), (f.name, "source tag")
        assert set(brackets) - {"P", "P*", "A", "D"}, (f.name, "unit")


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"m_k": 0.0}, "m_k must be > 0"),
        ({"kappa": 1.0}, "kappa must be > 1"),
        ({"p_krit": 1.0}, "p_krit must be < 1"),
        ({"p_R": 7e5}, "p_R must be < p_S"),
        ({"rod": 0.05}, "rod must be < bore"),
        ({"v_krit": 1e-5}, "v_krit must be > eps_v"),
        ({"c_k": -1.0}, "c_k must be >= 0"),
        ({"T_S": math.nan}, "T_S must be finite"),
    ],
)
def test_bad_values(changes: dict[str, float], match: str) -> None:
    with pytest.raises(ModelError, match=match):
        P.with_(**changes)


def test_bad_types_and_names() -> None:
    with pytest.raises(TypeError, match="m_k must be a real number"):
        P.with_(m_k=True)
    with pytest.raises(TypeError, match="no parameter"):
        P.with_(mass=3.0)
    with pytest.raises(ModelError, match="edge must be"):
        P.orifice_area(5, 1e-3)
    with pytest.raises(ModelError, match="pressures must be > 0"):
        P.stiffness(-1.0)
    assert P.with_(p_krit=0.528).p_krit == 0.528
