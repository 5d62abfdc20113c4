"""The loop's constants against the DC gain the data carry (independent Merritt rig)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from merritt_rig import Rig, record

from servoid._errors import DataError
from servoid.data import Experiment
from servoid.plants.ehsa import FeedbackLoop, fit_one_step, loop_from_table
from servoid.plants.ehsa._dc_gain import Tolerances, check_dc_gain, with_tolerances
from servoid.plants.ehsa._first_order import first_order_fit
from servoid.plants.ehsa._workflow import LOOP

LOOP_B = FeedbackLoop(0.01, 0.01)


def _fit(rig: Rig, seed: int):
    r, y = record(rig, 30.0, seed)
    half = Experiment.from_arrays(1e-3, r=r[: r.size // 2], y=y[: r.size // 2])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = fit_one_step(half, LOOP_B)
    return fit, first_order_fit(fit, half)


def test_a_reference_gain_error_is_named_and_can_be_tolerated():
    # the rig's true c is 0.5 % above the c the identification is told
    rig = Rig(amplitude=0.2e-3, register=9, flow_law=False, c_true=0.01005)
    truth = rig.truth()
    for seed in range(2):
        fit, first = _fit(rig, seed)
        z = (fit.estimate.parameters - truth) / fit.estimate.std
        assert z[0] > 3  # K absorbs the gain error, silently (z ≈ +6 seen)
        exact = check_dc_gain(first, 1.0)
        # the error the data carry (0.5 %; −0.1 % noise bias seen at 30 dB over 3 seeds)
        assert exact.error == pytest.approx(0.005, abs=0.0025)
        assert exact.mismatch and "beyond the tolerance" in exact.verdict
        assert "c_tolerance" in exact.verdict
        # taken from the data, K is back within 3σ
        corrected = (np.array(exact.parameters) - truth) / np.array(first.corrected_std())
        assert abs(corrected[0]) < 3
        # stated, a 1 % tolerance of c covers it, and K's interval grows to carry it
        loose = check_dc_gain(first, 1.0, Tolerances(c=0.01))
        assert not loose.mismatch
        assert loose.propagated_std[0] > 3 * fit.estimate.std[0]
        widened = with_tolerances(fit, loose)
        assert widened.estimate.std[0] == pytest.approx(loose.propagated_std[0])
        assert abs(widened.estimate.parameters[0] - truth[0]) < 1.96 * widened.estimate.std[0]


def test_right_constants_pass():
    rig = Rig(amplitude=0.2e-3, register=9, flow_law=False)
    checks = [check_dc_gain(_fit(rig, seed)[1], 1.0) for seed in range(3)]
    assert not any(c.mismatch for c in checks)
    assert all("consistent with the loop's constants" in c.verdict for c in checks)


def test_loop_table_takes_tolerances():
    opts = LOOP.parse({"c": 0.01, "F": 0.01, "c_tolerance": 0.003, "gain_tolerance": 0.001},
                      "closedloop")
    assert opts["c_tolerance"] == 0.003 and opts["F_tolerance"] == 0.0
    assert loop_from_table({"c": 0.01, "F": 0.01, "F_tolerance": 0.002}).c == 0.01
    with pytest.raises(DataError, match="c_tolerance"):
        LOOP.parse({"c": 0.01, "F": 0.01, "c_tolerance": -0.1}, "closedloop")
    assert Tolerances(0.003, 0.004, 0.0).dc == pytest.approx(0.005)
