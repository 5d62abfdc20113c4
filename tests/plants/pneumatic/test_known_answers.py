"""Known answers P2 and P4 (models-spec §4) and the S6 validation fit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pneumatic_records import TRUTH, to_record

from servoid.plants.pneumatic import (
    REFINABLE,
    identify_critical_pressure,
    identify_flow,
    identify_multistep,
    identify_thermodynamics,
    identify_valve,
)


def rel(value, name):
    return abs(value / getattr(TRUTH, name) - 1.0)


def test_p2_servovalve_at_40_db(responses):
    res = responses["valve"]
    rng = np.random.default_rng(7)
    x_v = np.asarray(res.x_v)
    noisy = x_v + np.std(x_v) / 10 ** (40 / 20) * rng.standard_normal(x_v.size)  # 40 dB
    rec = to_record(res, "valve").replace_channels(
        [c.with_values(noisy) if c.name == "x_v" else c for c in to_record(res, "v").channels])
    step = identify_valve(rec)
    # spec P2 tolerances; observed errors are below 0.05 %
    assert rel(step["xi_v"], "xi_v") < 0.03
    assert rel(step["omega_v"], "omega_v") < 0.02
    assert rel(step["k_v"], "k_v") < 0.005
    assert step.n_used == rec.n_samples - step.segment[0]
    assert "ẍ_v" in step.equation


def test_p4a_noise_free_measured_derivatives(clean_records, responses, known):
    sine = responses["sine"]
    # spec §2: the 1 Hz, 20 mm closed loop stays inside the 4 g/s sensor range
    assert max(np.abs(sine.m_dot_I).max(), np.abs(sine.m_dot_II).max()) <= 4e-3
    result = identify_multistep(clean_records, known, derivatives="measured")
    p = result.parameters
    for name in ("kappa", "R"):
        assert rel(getattr(p, name), name) < 1e-3  # P4: ± 0.1 % (observed 1e-8)
    assert abs(p.p_krit - 0.25) < 0.01  # P4: separable search over [0.1, 0.6] step 0.01
    for name in ("d_k", "c_k", "F_haft"):
        assert rel(getattr(p, name), name) < 0.01  # P4: ± 1 % (observed 1e-13)
    for name in ("ad_1", "ad_2", "ad_3", "ad_4"):
        assert rel(getattr(p, name), name) < 0.005  # P4 ± 0.5 % (κ, R estimated here)
    # S6 on the held-back 2 Hz, 50 mm record: exact parameters give an exact simulation
    assert result.validation.fit["p_I"] > 99.9 and result.validation.fit["p_II"] > 99.9
    assert list(result.steps) == ["S0 p_krit", "S0 ẋ_krit", "S1", "S2", "S3", "S4", "S5"]


def test_p4a_flow_edges_with_b_known(clean_records, known):
    step = identify_flow(clean_records["flow"], known, kappa=1.4, R=290.0, p_krit=0.25)
    for k in range(1, 5):
        assert rel(step[f"ad_{k}"], f"ad_{k}") < 1e-9  # noise-free, inside the structure
    s0 = identify_critical_pressure(clean_records["flow"], known)
    assert abs(s0["p_krit"] - 0.25) < 1e-6  # the profile's exact minimum


def test_p4a_thermodynamics_svf_noise_free(clean_records, known):
    step = identify_thermodynamics(clean_records["thermo"], known, derivatives="measured")
    assert rel(step["kappa"], "kappa") < 1e-6 and rel(step["R"], "R") < 1e-6
    assert abs(step.extra["rls_kappa"] - step["kappa"]) < 1e-6  # RLS (λ = 1) = batch LS
    svf = identify_thermodynamics(clean_records["thermo"], known, derivatives="svf")
    # the velocity from the zero-phase SVF of x_k loses |F|² at the stick–slip bursts: 0.1 %
    assert rel(svf["kappa"], "kappa") < 1e-3 and rel(svf["R"], "R") < 1e-3


def test_p4b_noisy_records_with_svf(noisy_records, known):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify_multistep(noisy_records, known, derivatives="svf")
    p = result.parameters
    # tolerances reached with the noise of conftest.NOISE (observed in brackets); the
    # friction steps classify regimes from a zero-phase filtered velocity (ω_f = 2π·400),
    # which blurs the 18 N friction drop at ẋ_krit: that, not the noise, sets their error
    tol = {"k_v": 1e-3, "xi_v": 1e-3, "omega_v": 1e-3,  # (2e-5)
           "kappa": 3e-3, "R": 1e-3,  # (9e-4, 2e-4)
           "ad_1": 5e-3, "ad_2": 5e-3, "ad_3": 5e-3, "ad_4": 5e-3,  # (≤ 2.2e-3)
           "v_krit": 0.08, "d_k": 0.02, "c_k": 0.02, "F_haft": 0.04}  # (4.6, 0.7, 1.0, 2.4 %)
    for name, t in tol.items():
        assert rel(getattr(p, name), name) < t, name
    assert abs(p.p_krit - 0.25) < 0.01
    # S6: both pressures ≥ 90 % on the held-back record (observed 98.5 %)
    assert result.validation.fit["p_I"] >= 90 and result.validation.fit["p_II"] >= 90
    assert {r["name"] for r in result.table()} == set(REFINABLE)


def test_p4b_measured_derivatives_with_noise(noisy_records, known):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify_multistep(noisy_records, known, derivatives="measured")
    p = result.parameters
    for name in ("d_k", "c_k", "F_haft", "kappa", "R"):
        assert rel(getattr(p, name), name) < 0.01, name  # (observed ≤ 0.5 %)
    assert result.validation.fit["p_I"] >= 90 and result.validation.fit["p_II"] >= 90


@pytest.mark.parametrize("derivatives", ["measured", "svf"])
def test_result_serialises(clean_records, known, derivatives):
    result = identify_multistep(clean_records, known, derivatives=derivatives)
    d = result.to_dict()
    assert d["derivatives"] == derivatives
    assert set(d["steps"]) == set(result.steps)
    assert "S6 validation fit" in str(result)
    s3 = result.steps["S3"]
    assert s3.n_used > 0 and s3.segment[0] >= 0 and s3.std("ad_1") >= 0
