"""What an EHSA record cannot fix: one sine's free combination, a saturated command."""

from __future__ import annotations

import math
import re
import warnings
from types import SimpleNamespace

import numpy as np
from scipy import signal

from servoid.data import Experiment
from servoid.plants.ehsa import FeedbackLoop, fit_one_step
from servoid.plants.ehsa._data_check import one_sine_combination, record_notes, saturation_note
from servoid.plants.ehsa._loop import plant_of_theta

LOOP = FeedbackLoop(0.01, 0.01)
THETA = (3451.7, 163.3, 0.249)  # Set B


def _loop_response(theta, f0):
    return complex(LOOP.close(plant_of_theta(theta)).freqresp(np.array([2 * math.pi * f0]))[0])


def _record(r):
    h = LOOP.close(plant_of_theta(THETA))
    t = np.arange(r.size) * 1e-3
    _, y, _ = signal.lsim((h.num, h.den), r, t)
    y = y + np.random.default_rng(0).standard_normal(r.size) * y.std() * 0.03
    return Experiment.from_arrays(1e-3, r=r, y=y)


def test_one_sine_names_the_combination_it_leaves_free():
    text = one_sine_combination(THETA, LOOP, 2.0)
    a, b, c = (float(x) for x in re.search(
        r"= ([-+.\d e]+) : ([-+.\d e]+) : ([-+.\d e]+) without", text).groups())
    assert "fixes two numbers, the loop's gain and phase there (|H| = 0.952" in text
    # a 1 % move along the named direction changes |H| and ∠H only to second order (the text's
    # three digits leave ~1e-3 of the step); a move along ln K alone changes |H| at first order
    step = 0.01
    moved = (THETA[0] * math.exp(a * step), THETA[1] * math.exp(b * step), THETA[2] + c * step)
    h0, h1 = _loop_response(THETA, 2.0), _loop_response(moved, 2.0)
    h2 = _loop_response((THETA[0] * math.exp(step), *THETA[1:]), 2.0)
    assert abs(h1 / h0 - 1) < 2e-4 < abs(h2 / h0 - 1) / 10


def test_the_workflow_notes_a_sine_record_and_not_a_prbs():
    t = np.arange(4000) * 1e-3
    sine = _record(0.2e-3 * np.sin(2 * math.pi * 2.0 * t))
    prbs = _record(0.2e-3 * np.sign(np.sin(2 * math.pi * 7.3 * t) + np.sin(2 * math.pi * 31 * t)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = fit_one_step(sine, LOOP)
    (note,) = record_notes(sine, fit, LOOP)
    assert note.startswith("data cannot fix: 'r': one sine") and "one sine at 2 Hz" in note
    # the workflow prints these before the intervals and makes each a caution of the verdict
    from servoid.plants.ehsa._workflow import _LIMIT

    assert note.startswith(_LIMIT) and note.split(": ")[2].split(" (")[0] == "one sine"
    assert record_notes(prbs, None, LOOP) == []


def test_a_saturated_command_is_named_when_flow_law_and_dc_gain_both_fire():
    fires, calm = SimpleNamespace(biased=True), SimpleNamespace(biased=False)
    off, on = SimpleNamespace(mismatch=True), SimpleNamespace(mismatch=False)
    assert "likely saturated" in saturation_note(fires, off)
    assert saturation_note(fires, on) == saturation_note(calm, off) == ""
    assert saturation_note(None, off) == ""


def test_structure_auto_runs_the_nonlinear_refinement_only_on_a_verdict():
    from servoid.plants.ehsa._data_check import nonlinear_wanted

    flow = SimpleNamespace(biased=True, z=12.3)
    quiet = SimpleNamespace(biased=False, z=0.4)
    dc_ok = SimpleNamespace(mismatch=False)
    linear_val = SimpleNamespace(nonlinearity=SimpleNamespace(detected=False, pvalue=0.4))
    bent_val = SimpleNamespace(nonlinearity=SimpleNamespace(detected=True, pvalue=1e-6))
    run, why = nonlinear_wanted(flow, dc_ok, linear_val)
    assert run and "the flow-law check fired (z = +12.3)" in why and "refinement ran" in why
    run, why = nonlinear_wanted(quiet, dc_ok, bent_val)
    assert run and "higher-order correlation tests" in why
    run, why = nonlinear_wanted(quiet, dc_ok, linear_val)
    assert not run and "the linear model stands" in why


def test_structure_is_an_identify_key():
    import pytest

    from servoid._errors import OptionError
    from servoid.plants.ehsa._workflow import METHOD

    option = next(o for o in METHOD.options if o.name == "structure")
    assert option.default == "linear" and option.check("auto", "[identify]", "structure") == "auto"
    with pytest.raises(OptionError, match="structure"):
        option.check("nonlinear-ish", "[identify]", "structure")
