"""Pole flags under output noise, prefiltering, direct OE and multi-segment data."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from loop_records import LOOP, TRUTH, halves, output_noise, record

from servoid import OptionError, ServoidWarning
from servoid.data import ExperimentSet
from servoid.plants.ehsa import fit_direct, fit_indirect
from servoid.plants.ehsa import fit_one_step as _fit_one_step

# The records here are the Tustin-discretised model's own output (spec E4): fit with that map.
fit_one_step = partial(_fit_one_step, discretization="tustin")


@pytest.fixture(scope="module")
def noisy30(r, y_clean):
    return halves(record(output_noise(y_clean, 30.0, seed=21), r))[0]


def test_output_noise_biases_arx_and_the_poles_say_so(noisy30):
    # spec §3.4 warning: ARX under white output noise at fs ≫ bandwidth is strongly biased
    with pytest.warns(ServoidWarning) as caught:
        res = fit_indirect(noisy30, LOOP)
    text = " ".join(str(w.message) for w in caught)
    assert "negative real" in text and "ARX artefact" in text
    assert "beyond the Nyquist frequency" in text
    assert not res.is_physical
    assert res.notes() and all(n in str(res) for n in res.notes())
    flagged = {(p.model, p.domain) for p in res.poles if not p.is_physical}
    assert ("closed loop", "discrete") in flagged and ("plant", "continuous") in flagged


def test_prefilter_removes_most_of_the_bias(noisy30):
    res = fit_indirect(noisy30, LOOP, prefilter=50.0)  # PRBS band edge 0.44/T_b = 44 Hz
    # observed ≈ 0.1–1 %; 5 % separates it clearly from the unfiltered 25× error
    np.testing.assert_allclose(res.estimate.parameters, TRUTH, rtol=0.05)
    assert res.source.options["prefilter_hz"] == 50.0
    with pytest.raises(OptionError, match="prefilter must lie in"):
        fit_indirect(noisy30, LOOP, prefilter=600.0)


def test_direct_oe_noise_free(r, y_clean):
    est = halves(record(y_clean, r))[0]
    res = fit_direct(est, LOOP, estimator="oe")
    # model inside the structure, no noise: the LM tolerance limits the agreement
    np.testing.assert_allclose(res.estimate.parameters, TRUTH, rtol=1e-7)
    assert res.estimate.method == "direct" and res.closed_loop is not None


def test_one_step_on_two_segments(r, y_clean):
    y = output_noise(y_clean, 40.0, seed=5)
    first, second = halves(record(y, r))
    # the second segment does not start from rest; start=300 skips that transient
    # (slowest closed-loop pole ≈ −35 rad/s: 300 samples = 10 time constants)
    res = fit_one_step(ExperimentSet((first, second)), LOOP, theta0=(2000.0, 100.0, 0.5),
                       start=300)
    assert res.source.n_samples == first.n_samples + second.n_samples - 600
    np.testing.assert_allclose(res.estimate.parameters, TRUTH, rtol=0.005)  # spec E4 on ω
    err = np.abs(res.estimate.parameters - TRUTH)
    assert np.all(err < 4 * res.estimate.std)  # 4σ of σ̂²(JᵀJ)⁻¹
