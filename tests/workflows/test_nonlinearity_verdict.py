"""A linear model that misses a nonlinearity is flagged in the verdict, beside the linear tests."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid.bench import simulate_lti
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import TransferFunction
from servoid.workflows import identify

DT = 0.01
PLANT = TransferFunction([(2 * np.pi * 2.0) ** 2],
                         [1.0, 2 * 0.5 * 2 * np.pi * 2.0, (2 * np.pi * 2.0) ** 2])


def _records(folder, wiener):
    for k, seed in enumerate((21, 22)):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.standard_normal(1500), 2)
        x = simulate_lti(PLANT, u, DT, rng=seed)["y"]  # continuous plant, far above the rate
        y = np.tanh(1.2 * x) if wiener else x
        y = y + lfilter([1.0], [1.0, -0.9], 0.01 * rng.standard_normal(u.size))  # coloured
        write_csv(Experiment.from_arrays(DT, u=u, y=y), folder / f"run{k}.csv")
    path = folder / "oe.toml"
    write_experiment_spec({"data": {"file": "run0.csv"},
                           "channels": {"u": {"source": "u", "role": "u"},
                                        "y": {"source": "y", "role": "y"}},
                           "validation": {"file": "run1.csv"},
                           "identify": {"method": "oe", "nb": 2, "nf": 2, "nk": 1}}, path)
    return path


def _check(result):
    return next(c for c in result.verdict().checks if c.name.startswith("higher-order"))


def test_oe_on_a_wiener_plant_is_flagged(tmp_path):
    with pytest.warns(Warning, match="nonlinearity unexplained"):
        result = identify(_records(tmp_path, wiener=True), tmp_path / "out")
    assert _check(result).outcome == "caution"
    assert result.verdict().decision != "accept"
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["validation"]["nonlinearity"]["detected"] is True
    assert "higher-order test" in (tmp_path / "out" / "report.html").read_text()


def test_oe_on_the_linear_plant_passes_them(tmp_path):
    result = identify(_records(tmp_path, wiener=False), write=False)
    assert _check(result).outcome == "pass"
