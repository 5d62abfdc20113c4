"""identify(): experiment file → estimate, validation, results folder."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import ChannelError, OptionError, OutputExistsError
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import PolynomialModel
from servoid.workflows import identify

TRUTH = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)


@pytest.fixture
def rig(tmp_path):
    rng = np.random.default_rng(7)
    u = rng.standard_normal(4000)
    # equation-error noise e/A keeps the truth inside the ARX structure
    y = TRUTH.simulate(u) + lfilter([1.0], TRUTH.a, 0.01 * rng.standard_normal(4000))
    # volts on the rig: position sensor 2 V/mm around 1 V
    exp = Experiment.from_arrays(0.01, u=u, y=1.0 + 2.0 * y, names={"u": "AI0", "y": "AI1"},
                                 units={"AI0": "V", "AI1": "V"})
    write_csv(exp, tmp_path / "run.csv")
    return tmp_path


def spec(folder, **identify_table):
    table = {
        "data": {"file": "run.csv", "time": "time"},
        "channels": {"cmd": {"source": "AI0", "role": "u", "unit": "V"},
                     "pos": {"source": "AI1", "role": "y", "gain": 0.5, "offset": -0.5,
                             "unit": "mm"}},
        "preprocess": {"detrend": "mean"},
        "identify": {"method": "arx", "na": 2, "nb": 2, "nk": 1, **identify_table},
    }
    path = folder / "run.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_identify_recovers_truth_and_writes_folder(rig):
    result = identify(spec(rig))
    est = result.estimate
    truth = np.array([-1.2, 0.5, 0.8, 0.3])
    assert np.all(np.abs(est.parameters - truth) < 4 * est.std)  # 4σ of the reported covariance
    assert result.validation.fit_percent > 95  # noise ~1 % of the signal
    data = json.loads((rig / "run-results" / "results.json").read_text())
    assert data["model"]["nk"] == [1]
    assert len(data["data_sha256"]) == 64
    assert {p.name for p in result.files} == {"results.json", "validation.png", "residuals.png",
                                              "bode.png", "poles.png", "report.html",
                                              "manifest.json"}


def test_identify_grid_search(rig):
    result = identify(spec(rig, na=[1, 2, 3], nb=[1, 2, 3], criterion="mdl"), write=False)
    assert result.estimate.options["na"] == 2
    assert result.estimate.options["nb"] == [2]


def test_identify_unknown_method_lists_valid(rig):
    with pytest.raises(OptionError, match=r"method must be one of 'arx'"):
        identify(spec(rig, method="magic"), write=False)


def test_identify_unknown_key(rig):
    with pytest.raises(OptionError, match="unknown key.*orders"):
        identify(spec(rig, orders=3), write=False)


def test_identify_missing_channel(rig):
    path = spec(rig)
    text = path.read_text().replace('source = "AI1"', 'source = "AI7"')
    path.write_text(text)
    with pytest.raises(ChannelError, match="AI7"):
        identify(path, write=False)


def test_identify_never_overwrites_inputs(rig):
    path = spec(rig)
    before = (rig / "run.csv").read_bytes()
    identify(path, out=rig / "res")
    with pytest.raises(OutputExistsError, match="earlier run"):
        identify(path, out=rig / "res")
    assert (rig / "run.csv").read_bytes() == before
