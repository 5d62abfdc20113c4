"""servoid.validate.data_limits: a step, one sine, drift and clipping are named; rich data is not."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from servoid import ServoidWarning
from servoid.data import Experiment, load_experiment_spec, write_csv, write_experiment_spec
from servoid.validate import DataLimit, data_limits
from servoid.workflows import identify

DT = 0.01
N = 4000
T = np.arange(N) * DT


def _response(u, seed=0):
    g = np.exp(-np.arange(60) / 12.0) / 12.0
    rng = np.random.default_rng(seed)
    return np.convolve(u, g)[:N] + 0.01 * rng.standard_normal(N)


def _rich():
    rng = np.random.default_rng(1)
    return {
        "prbs": np.repeat(np.sign(rng.standard_normal(N // 5)), 5),
        "multisine": sum(np.sin(2 * np.pi * f * T + f) for f in (0.5, 1.0, 2.0, 3.0, 5.0)),
        "noise": rng.standard_normal(N),
        "chirp": np.sin(2 * np.pi * (0.1 + 2 * T / 40) * T),
    }


@pytest.mark.parametrize("kind", list(_rich()))
def test_rich_excitation_is_not_flagged(kind):
    u = _rich()[kind]
    found = data_limits(Experiment.from_arrays(DT, u=u, y=_response(u)))
    assert found == (), [d.text() for d in found]


@pytest.mark.parametrize("noise", [0.0, 0.03])
def test_a_step_is_named(noise):
    u = np.where(T > 5, 1.0, 0.0) + noise * np.random.default_rng(3).standard_normal(N)
    (found,) = data_limits(Experiment.from_arrays(DT, u=u, y=_response(u)))
    assert (found.name, found.channel, found.value) == ("step", "u", "1 edge, level between")
    assert "static gain and the slowest time constant" in found.meaning


def test_one_sine_is_named_with_its_frequency():
    u = np.sin(2 * np.pi * 1.3 * T)
    (found,) = data_limits(Experiment.from_arrays(DT, u=u, y=_response(u)))
    assert found.name == "one sine" and "at 1.3 Hz" in found.value
    assert "the gain and the phase there" in found.meaning


def test_drift_in_the_output_is_named():
    u = _rich()["prbs"]
    y = _response(u) + 0.05 * T  # a trend the input does not have
    (found,) = data_limits(Experiment.from_arrays(DT, u=u, y=y))
    assert (found.name, found.channel) == ("drift", "y")
    assert found.value.startswith("a straight line explains")


def test_a_clipped_input_is_named():
    rng = np.random.default_rng(2)
    u = np.clip(2 * np.sin(2 * np.pi * 0.7 * T) + 0.3 * rng.standard_normal(N), -1, 1)
    found = data_limits(Experiment.from_arrays(DT, u=u, y=_response(u)))
    assert [d.name for d in found] == ["clipped"]
    assert found[0].channel == "u" and "% of the samples at 1" in found[0].value


def test_a_sine_with_a_whole_period_is_not_clipped():
    # every period hits the same peak sample: a repeated extreme, but in runs of one
    u = np.sin(2 * np.pi * np.arange(N) / 20) + 0.5 * np.sin(2 * np.pi * np.arange(N) / 7)
    assert [d.name for d in data_limits(Experiment.from_arrays(DT, u=u, y=_response(u)))] == []


def test_data_limit_as_text_and_plain_data():
    d = DataLimit("step", "u", "1 edge", "meaning")
    assert d.text() == "'u': step (1 edge): meaning"
    assert d.to_dict() == {"name": "step", "channel": "u", "value": "1 edge",
                           "meaning": "meaning"}


def test_a_step_record_gets_a_verdict_before_its_intervals(tmp_path):
    u = np.where(T > 5, 1.0, 0.0)
    write_csv(Experiment.from_arrays(DT, u=u, y=_response(u)), tmp_path / "step.csv")
    write_experiment_spec({"data": {"file": "step.csv"},
                           "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
                           "split": {"fraction": 0.5}, "identify": {"method": "oe"}},
                          tmp_path / "e.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        result = identify(load_experiment_spec(tmp_path / "e.toml"), write=False)
    verdict = result.verdict()
    first = verdict.checks[0]
    assert (first.name, first.outcome) == ("data: step", "caution")
    assert verdict.decision != "accept"
    text = str(result).splitlines()
    assert text[1].startswith("  data cannot fix: 'u' step (1 edge, level between)")
    assert any(n.startswith("the data cannot fix every parameter: 'u': step") for n in result.notes)
