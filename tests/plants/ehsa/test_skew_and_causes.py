"""A channel skew in the structure catalogue, and the cause a rejection names."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from merritt_rig import Rig, record

from servoid._errors import ModelError, ServoidWarning
from servoid.data import Experiment
from servoid.plants.ehsa import FeedbackLoop, compare_structures, fit_one_step
from servoid.plants.ehsa._causes import rejection_note
from servoid.plants.ehsa._structures import skew_structure

LOOP = FeedbackLoop(0.01, 0.01)
SKEW = skew_structure(0.01)


def test_skew_plant_is_the_reduced_loop_times_a_delay():
    theta = np.array([3451.7, 163.3, 0.249])
    assert SKEW.plant(np.array([*theta, 0.0])).den.size == 4  # τ_d = 0: the reduced plant
    tau = 2e-4
    closed = LOOP.close(SKEW.plant(np.array([*theta, tau])))
    reduced = LOOP.close(SKEW.plant(np.array([*theta, 0.0])))
    w = np.array([1.0, 30.0, 300.0, 3000.0])
    ratio = closed.freqresp(w) / reduced.freqresp(w)
    # the (1, 1) Padé all-pass of the delay: |D| = 1, phase −2·atan(ωτ/2) ≈ −ωτ
    np.testing.assert_allclose(np.abs(ratio), 1.0, rtol=1e-9)
    np.testing.assert_allclose(np.angle(ratio), -2 * np.arctan(w * tau / 2), atol=1e-9)
    with pytest.raises(ModelError, match="static feedback"):
        skew_structure(0.0)


def test_skew_is_found_with_its_sigma_and_named():
    # the independent rig reads the position 50 µs late: y(t + 50 µs) against r(t), a delay of
    # −50 µs (the position leads)
    rig = Rig(amplitude=0.2e-3, register=9, flow_law=False, skew=50e-6)
    r, y = record(rig, 30.0, 0)
    data = Experiment.from_arrays(1e-3, r=r[: r.size // 2], y=y[: r.size // 2])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        reduced = fit_one_step(data, LOOP)
        skew = fit_one_step(data, LOOP, (*reduced.estimate.parameters, 0.0), structure=SKEW)
        test = compare_structures({"reduced": reduced, "reduced+skew": skew}, data,
                                  structures={"reduced+skew": SKEW})
    tau, std = skew.source["tau_d"], skew.source.std[3]
    assert abs(tau + 50e-6) < 4 * std and std < 15e-6  # found, not absorbed (σ ≈ 10 µs seen)
    assert test.rejected and test.preferred == "reduced+skew"
    truth = rig.truth()
    z = (skew.estimate.parameters - truth) / skew.estimate.std
    assert np.all(np.abs(z) < 3)
    note = rejection_note(test, None, reduced)
    assert "a delay between the reference and the position channels (tau_d = -" in note
    assert "Read the reduced+skew estimates: K = " in note and " ± " in note
    assert "multiplexed converter" in note
    # the preferred structure's estimates carry intervals in the verdict too
    assert "under reduced+skew (lowest BIC): K " in test.verdict
    assert test.fit("reduced+skew").reduced_std["omega_hp"] > 0


def _test(preferred, lr=True, extra=None):
    nested = SimpleNamespace(larger=preferred, rejected=lr, extra=extra or {"tau_v": 1e-3},
                             extra_std={"tau_v": 1e-4})
    fit = SimpleNamespace(reduced={"K": 1.0}, reduced_std={"K": 0.1})
    return SimpleNamespace(tests=(nested,), preferred=preferred, fit=lambda name: fit)


def test_the_note_names_the_cause():
    plain = SimpleNamespace(flags=())
    lag = rejection_note(_test("reduced+lag"), None, plain)
    assert "a missing dynamic" in lag and "(tau_v = 1 ms ± 100 µs)" in lag and "Read the reduced+lag estimates: K = 1 ± 0.1" in lag
    flow = SimpleNamespace(biased=True, z=40.0, pressure_ratio=0.28, gamma=0.04)
    both = rejection_note(_test("reduced+lag"), flow, plain)
    assert both.index("the valve's flow law (z = +40.0; the load pressure reaches about 28 %") \
        < both.index("a missing dynamic")
    assert "its numbers are not the physical ones" in both and "refine = true" in both
    other = SimpleNamespace(biased=True, z=-6.0, pressure_ratio=-0.3, gamma=-0.08)
    assert "a nonlinearity other than the valve's flow law" in rejection_note(
        _test("reduced+skew"), other, plain)
    residual_only = rejection_note(_test("reduced", lr=False), None, plain)
    assert "no richer linear structure explains it" in residual_only
    poor = rejection_note(_test("full-order"), None,
                          SimpleNamespace(flags=("the data do not determine the resonance",)))
    assert "poor excitation: the data do not determine the resonance" in poor
