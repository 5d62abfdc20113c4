"""Set A and the Eq. 13 / Eq. 14 consistency check (spec §1.2, E5)."""

import numpy as np
import pytest

from servoid.plants.ehsa import SET_A, PaperSetA, ReducedEhsa, paper_consistency


def test_e5_decoded_reading_reproduces_eq14() -> None:
    rep = paper_consistency()
    expected = np.array([-7104.0, -30.0 - 18.0j, -30.0 + 18.0j])
    assert rep.decoded_consistent
    # E5: within 0.5 rad/s (Eq. 14's 60 and 1224 carry ±0.5 in the last digit)
    for root in expected:
        assert np.min(np.abs(rep.decoded_roots - root)) < 0.5
    assert rep.decoded_error < 0.5
    # spec §1.2, "checked": −7104.17, −30.01 ± 17.99j (printed to 0.01)
    assert np.sort_complex(rep.decoded_roots)[0].real == pytest.approx(-7104.17, abs=0.005)
    assert rep.decoded_roots[1].real == pytest.approx(-30.01, abs=0.005)
    assert abs(rep.decoded_roots[1].imag) == pytest.approx(17.99, abs=0.005)


def test_e5_literal_reading_is_flagged() -> None:
    rep = paper_consistency()
    assert not rep.literal_consistent
    assert -1.0 < rep.literal_slow_pole < 0.0  # E5: slow pole < 1 rad/s
    assert rep.literal_slow_pole == pytest.approx(-0.203, abs=5e-4)  # with F = 0.8783
    assert "6019" in rep.explanation and "60.19" in rep.explanation
    assert "13123" in rep.explanation and "7164" in rep.explanation


def test_literal_with_unit_feedback_matches_spec() -> None:
    # spec §1.2: closing with F = 1 gives poles −7105, −6017 and −0.23 rad/s
    den = np.polymul([1.0, 0.0], np.polymul([1.0, 7104.0], [1.0, 6019.0]))
    den[-1] += SET_A.gain
    roots = np.sort(np.roots(den).real)
    assert roots == pytest.approx([-7105, -6017, -0.23], abs=0.5)
    assert roots[2] == pytest.approx(-0.23, abs=0.005)


def test_set_a_numbers() -> None:
    rep = paper_consistency()
    # F is derived, 7104·1224/9 900 135
    assert SET_A.F == 7104.0 * 1224.0 / 9_900_135.0
    assert rep.F == pytest.approx(0.8783, abs=5e-5)
    assert rep.dc_gain == pytest.approx(1.139, abs=5e-4)
    assert rep.dc_gain == pytest.approx(1.0 / SET_A.F, rel=1e-15)
    assert rep.K_v == pytest.approx(23.15, abs=0.005)
    assert rep.omega_hp == pytest.approx(653.9, abs=0.05)
    assert rep.delta_hp == pytest.approx(5.48, abs=0.005)
    # loop gain F·K_v = 20.3 1/s (spec §1.2)
    assert rep.F * rep.K_v == pytest.approx(20.3, abs=0.05)


def test_set_a_model_is_eq13_decoded() -> None:
    g = SET_A.model.plant()
    expected = np.array([1.0, 7164.19, 7104.0 * 60.19, 0.0])
    assert g.den == pytest.approx(expected, rel=1e-12)  # rounding of K·ω², 2δω
    assert g.num == pytest.approx([9_900_135.0], rel=1e-12)
    cl = SET_A.model.closed_loop(SET_A.c, SET_A.F)
    assert np.sort_complex(cl.poles()) == pytest.approx(
        np.sort_complex(paper_consistency().decoded_roots), rel=1e-9)
    assert cl.dc_gain() == pytest.approx(1.0 / SET_A.F, rel=1e-12)
    assert isinstance(SET_A.model, ReducedEhsa)


def test_paper_consistency_rejects_wrong_type() -> None:
    with pytest.raises(TypeError, match="PaperSetA"):
        paper_consistency("eq13")  # type: ignore[arg-type]
    assert paper_consistency(PaperSetA(pole_slow=60.19)).decoded_consistent
