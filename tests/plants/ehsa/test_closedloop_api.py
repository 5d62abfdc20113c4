"""identify_closed_loop, the result type and simulate_closed_loop."""

from __future__ import annotations

import json

import numpy as np
import pytest
from loop_records import DT, LOOP, TRUTH, halves, output_noise, record

from servoid import ModelError, OptionError
from servoid.plants.ehsa import (
    APPROACHES,
    ClosedLoopResult,
    identify_closed_loop,
    simulate_closed_loop,
)


@pytest.fixture(scope="module")
def noisy(r, y_clean):
    return halves(record(output_noise(y_clean, 40.0, seed=11), r))[0]


@pytest.mark.parametrize("approach", APPROACHES)
def test_every_approach_returns_a_result(noisy, approach):
    with pytest.warns() if approach != "one-step" else _nothing():
        res = identify_closed_loop(noisy, LOOP, approach=approach)
    assert isinstance(res, ClosedLoopResult)
    assert res.approach == approach
    assert set(res.parameters()) == {"K", "omega_hp", "delta_hp"}
    payload = json.loads(json.dumps(res.to_dict()))
    assert payload["approach"] == approach
    assert [p["name"] for p in payload["estimate"]["parameters"]] == ["K", "omega_hp", "delta_hp"]
    assert {"closed_loop", "plant", "plant_continuous", "poles", "loop"} <= set(payload)
    assert all({"real", "imag", "is_physical", "note"} <= set(p) for p in payload["poles"])
    assert res.plant.dt == DT and res.plant_continuous.dt is None


def test_unknown_approach_lists_the_valid_ones(noisy):
    with pytest.raises(OptionError, match="approach must be one of 'indirect', 'one-step', "
                                          "'direct'; got 'joint'"):
        identify_closed_loop(noisy, LOOP, approach="joint")  # type: ignore[arg-type]


def test_unknown_option_is_an_option_error(noisy):
    with pytest.raises(OptionError, match="approach 'indirect'.*theta0"):
        identify_closed_loop(noisy, LOOP, approach="indirect", theta0=(1.0, 2.0, 3.0))


def test_loop_required_except_direct(noisy):
    with pytest.raises(ModelError, match="needs the known loop"):
        identify_closed_loop(noisy, None, approach="one-step")


def test_simulate_from_theta_and_result(r, y_clean):
    y = simulate_closed_loop(TRUTH, r, DT, LOOP)
    np.testing.assert_array_equal(y, y_clean)
    res = identify_closed_loop(halves(record(y_clean, r))[0], LOOP, approach="one-step",
                               theta0=TRUTH, discretization="tustin")
    # same model to the LM tolerance: outputs agree far below the 1 mm amplitude
    np.testing.assert_allclose(simulate_closed_loop(res, r), y_clean, atol=1e-12)
    # step response settles at c/F = 1 (spec §1.1)
    assert simulate_closed_loop(TRUTH, np.ones(3000), DT, LOOP)[-1] == pytest.approx(1.0, 1e-6)
    with pytest.raises(ModelError, match="needs dt and loop"):
        simulate_closed_loop(TRUTH, r)


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
