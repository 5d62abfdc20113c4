"""The experiment file's ``[rig]`` table: declared anti-alias filter and logged command."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import FileFormatError, OptionError
from servoid.data import (
    Experiment,
    ExperimentSpec,
    RigSpec,
    load_experiment_spec,
    write_csv,
    write_experiment_spec,
)

Q = 5  # decimation


@pytest.fixture()
def folder(tmp_path):
    n = 400
    command = np.repeat(np.random.default_rng(0).choice([-1.0, 1.0], n // Q), Q)
    y = np.convolve(command, np.ones(7) / 7, mode="same")  # something smooth
    exp = Experiment.from_arrays(1e-4, r=command, y=y, names={"r": "cmd", "y": "pos"})
    write_csv(exp, tmp_path / "run.csv")
    return tmp_path


def _table(rig, **extra):
    table = {
        "data": {"file": "run.csv", "time": "time"},
        "channels": {"cmd": {"role": "r"}, "pos": {"role": "y"}},
        "preprocess": {"decimate": Q, **extra},
    }
    if rig is not None:
        table["rig"] = rig
    return table


def test_rig_round_trips(folder):
    table = _table({"anti_alias": {"order": 4, "cutoff": 1000.0}, "reference": "command"})
    path = write_experiment_spec(table, folder / "run.toml")
    text = path.read_text()
    assert "[rig]" in text and 'reference = "command"' in text
    spec = load_experiment_spec(path)
    assert spec.rig == RigSpec(4, 1000.0, "command") and spec.rig.is_declared
    assert spec.to_dict()["rig"] == {"anti_alias": {"order": 4, "cutoff": 1000.0},
                                      "reference": "command"}
    assert not ExperimentSpec.from_dict(_table(None), folder).rig.is_declared


def test_command_is_subsampled_not_filtered(folder):
    spec = ExperimentSpec.from_dict(_table({"reference": "command"}), folder)
    exp = spec.load()
    cmd = exp["cmd"]
    # the staircase stays a staircase: exactly the held values, one per decimated period
    assert set(np.unique(cmd)) <= {-1.0, 1.0} and cmd.size == 80
    filtered = ExperimentSpec.from_dict(_table({"reference": "readback"}), folder).load()
    assert np.unique(filtered["cmd"]).size > 10  # the FIR smooths a read-back reference
    # the output is decimated by the same FIR either way
    np.testing.assert_array_equal(exp["pos"], filtered["pos"])


def test_command_not_held_is_refused(folder):
    table = _table({"reference": "command"})
    table["preprocess"]["decimate"] = 3  # blocks of 3 cut across the held periods of 5
    spec = ExperimentSpec.from_dict(table, folder)
    with pytest.raises(FileFormatError, match=r"changes within samples \d+…\d+ \(decimate = 3\)"):
        spec.load()


@pytest.mark.parametrize(
    ("rig", "extra", "error", "match"),
    [
        ({"reference": "dac"}, {}, OptionError, "reference must be one of 'command', 'readback'"),
        ({"filter": 4}, {}, OptionError, r"unknown key\(s\) in \[rig\]: 'filter'"),
        ({"anti_alias": {"order": 4}}, {}, FileFormatError, "missing the required key.*cutoff"),
        ({"anti_alias": {"order": 0, "cutoff": 1.0}}, {}, FileFormatError,
         "order must be an integer >= 1"),
        ({"anti_alias": {"order": 12, "cutoff": 1.0}}, {}, FileFormatError, "order 1..10"),
        ({"anti_alias": {"order": 4, "cutoff": -1.0}}, {}, FileFormatError, "cutoff must be > 0"),
        ({"reference": "command"}, {"lowpass": 100.0}, FileFormatError,
         "lowpass would filter the logged command"),
    ],
)
def test_rig_errors(rig, extra, error, match, folder):
    with pytest.raises(error, match=match):
        ExperimentSpec.from_dict(_table(rig, **extra), folder)
