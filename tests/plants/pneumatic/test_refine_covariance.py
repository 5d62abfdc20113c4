"""The servopneumatic refinement: covariance choice and identifiability checks.

The compiled simulator switches (stick–slip, events on the sample grid), so
its outputs jump when a parameter moves by 1e-5…1e-4 relative.  A √ε
finite-difference Jacobian then misdescribes the cost: on the noisy P4
record the (c_k, κ) refinement stopped 4 % off with a std 100× too small —
the issue's "std 1e-8, silently".  The refinement now differences over
1e-4 and the diagnostics flag the √ε case.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from pneumatic_records import NOISE, TRUTH, sine_response, to_record

from servoid import OptionError, ServoidWarning
from servoid.plants.pneumatic import PositionController, identify_multistep, refine_parameters


@pytest.fixture(scope="module")
def noisy_thermo():
    rng = np.random.default_rng(2024)
    return to_record(sine_response(force=60.0), "thermo", NOISE, rng).slice(0, 5000)


def refine(record, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = refine_parameters(record, TRUTH.with_(c_k=126.0, kappa=1.39),
                                free=["c_k", "kappa"], controller=PositionController(), **kw)
    return out, [str(w.message) for w in caught if w.category is ServoidWarning]


def test_robust_by_default_with_one_ar_model_per_channel(noisy_thermo):
    out, caught = refine(noisy_thermo)
    est = out.estimate
    assert not caught
    assert est.options["covariance"] == "robust"
    # the residual is not white: the noisy first sample starts the simulation off the record,
    # and its transient is coloured in every channel
    assert set(est.options["covariance_ar_orders"]) == {"p_I", "p_II", "x_k"}
    assert min(est.options["covariance_ar_orders"].values()) > 0
    ident = est.options["identifiability"]
    assert ident["identifiable"]
    # differenced over 1e-4 the cost is quadratic over ±1σ: measured 0.95 and 0.78
    assert all(0.5 <= v <= 2.0 for v in ident["curvature_ratio"].values())
    # c_k within 4σ of the truth (measured −1.4σ)
    assert abs(out.parameters.c_k - 120.0) < 4 * est.std[0]
    json.dumps(out.to_dict())


def test_white_is_several_times_narrower_on_the_same_fit(noisy_thermo):
    robust, _ = refine(noisy_thermo)
    white, _ = refine(noisy_thermo, covariance="white")
    assert white.estimate.options["covariance"] == "white"
    np.testing.assert_array_equal(white.estimate.parameters, robust.estimate.parameters)
    # measured ×19: the colour of the transient, which σ̂²(JᵀJ)⁻¹ ignores
    assert np.all(robust.estimate.std > 5 * white.estimate.std)


def test_a_sqrt_eps_jacobian_is_flagged(noisy_thermo):
    out, caught = refine(noisy_thermo, diff_step=None)
    text = " | ".join(caught)
    assert "not quadratic over ±1σ" in text and "c_k–kappa" in text
    ratios = out.estimate.options["identifiability"]["curvature_ratio"]
    assert max(ratios.values()) < 1e-3  # measured 5e-7: the columns are 1e3× too steep


def test_pipeline_validates_and_passes_the_choice(clean_records, known):
    with pytest.raises(OptionError, match="refine_covariance must be one of 'auto', 'white', "
                                          "'robust', 'bootstrap'"):
        identify_multistep(clean_records, known, refine=["c_k"], refine_covariance="hac")
