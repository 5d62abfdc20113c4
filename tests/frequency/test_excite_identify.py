"""From ``servoid excite random-multisine`` to ``servoid identify`` (method = "frequency").

The test plays the written file through the virtual rig (a continuous plant behind a static
cubic, 20× oversampled) and identifies the record beside its plan file from the command line:
the acceptance numbers' intervals hold the BLA's truth, the limits are judged, and the
report holds the Bode figure.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from dataclasses import replace

import numpy as np
import pytest

from servoid import ServoidError
from servoid.bench import simulate_lti
from servoid.cli import main
from servoid.data import (
    Experiment,
    load_experiment_spec,
    read_csv,
    write_csv,
    write_experiment_spec,
)
from servoid.models import TransferFunction, c2d, resonance_peak
from servoid.signals import read_plan
from servoid.workflows import get_method, identify

WN = 2 * np.pi * 8.0
PLANT = TransferFunction([WN**2], [1.0, 0.8 * WN, WN**2])  # ζ = 0.4: 2.70 dB at 6.60 Hz


def _cli(words):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(words)
    return code, json.loads(out.getvalue())


def test_excite_writes_the_test_and_its_plan_and_identify_reads_them(tmp_path):
    code, info = _cli(["excite", "random-multisine", "--dt", "0.01", "--f-min", "0.2",
                       "--f-max", "25", "--period", "512", "--realisations", "6",
                       "--periods", "2", "--settling-time", "1.0", "--amplitude", "2.0",
                       "--seed", "3", "--out", str(tmp_path / "test.csv"), "--json"])
    assert code == 0
    plan = read_plan(tmp_path / "test.plan.json")
    assert info["plan_file"] == str(tmp_path / "test.plan.json")
    assert plan.realisations == 6 and plan.transient_periods == 1 and plan.lines == "random-odd"
    played = read_csv(tmp_path / "test.csv")
    u = played["r"]
    assert u.size == plan.n_samples and np.max(np.abs(u)) == pytest.approx(2.0)
    # the rig: a cubic before the plant (its BLA: the plant times a Bussgang gain)
    y = simulate_lti(PLANT, u + 0.02 * u**3, 0.01, noise_std=0.02, rng=5)["y"]
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), tmp_path / "test-record.csv")
    plan.write(tmp_path / "test-record.plan.json")
    exp_file = tmp_path / "experiment.toml"
    write_experiment_spec({
        "data": {"file": "test-record.csv"},
        "channels": {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "mm"}},
        "acceptance": {"bandwidth_min": 5.0, "resonance_peak_max": 2.0},
        "identify": {"method": "frequency", "n_poles": 2, "n_zeros": 0, "phase_frequency": 5.0},
    }, exp_file)
    code, payload = _cli(["identify", str(exp_file), "--out", str(tmp_path / "out"), "--json"])
    assert code == 0 and payload["method"] == "frequency"
    results = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    numbers = {n["name"]: n for n in results["acceptance_numbers"]}
    # the BLA gain of u + 0.02u³ for this u: E[f(u)·u]/E[u²] = 1 + 0.02·E[u⁴]/E[u²] (the
    # clipped, low-crest multisine is not Gaussian: 3·E[u²] would overstate it)
    gain = 1 + 0.02 * float(np.mean(u**4) / np.mean(u**2))
    truth = {"dc_gain": gain, "resonance_frequency": resonance_peak(PLANT).frequency,
             "resonance_peak": resonance_peak(PLANT).peak_db}
    for name, value in truth.items():  # 95 % intervals: each holds its truth (4σ)
        n = numbers[name]
        assert abs(n["value"] - value) < 4 * n["std"], (name, n, value)
    assert results["measurement"]["method"] == "bla"
    assert results["measurement"]["distortion"]["odd_db"] > -60  # the cubic shows
    verdicts = {c["name"]: c["passed"] for c in results["acceptance"]}
    # 11 Hz ≥ 5 Hz passes; a 2.7 dB peak is above 2 dB: fails, and the run says reject
    assert verdicts == {"bandwidth": True, "resonance_peak": False}
    assert payload["summary"]["decision"] == "reject"
    assert (tmp_path / "out" / "frequency.png").is_file()
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "Acceptance numbers" in html and "acceptance: resonance_peak" in html
    # the fleet's columns: the numbers with their intervals
    row = {p["name"]: p for p in payload["summary"]["parameters"]}
    assert row["bandwidth"]["ci_low"] <= row["bandwidth"]["value"] <= row["bandwidth"]["ci_high"]
    assert math.isfinite(row["resonance_peak"]["std"])


def test_identify_without_a_plan_uses_the_lpm(tmp_path):
    u = np.random.default_rng(0).standard_normal(4096)
    y = simulate_lti(PLANT, u, 0.01, noise_std=0.02, rng=1)["y"]
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), tmp_path / "noise.csv")
    exp_file = tmp_path / "experiment.toml"
    write_experiment_spec({
        "data": {"file": "noise.csv"},
        "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
        "identify": {"method": "frequency", "domain": "z", "n_poles": 2, "n_zeros": 1,
                     "delay_samples": 1, "f_max": 30.0},
    }, exp_file)
    code, _ = _cli(["identify", str(exp_file), "--out", str(tmp_path / "out"), "--json"])
    assert code == 0
    results = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert results["measurement"]["method"] == "lpm"
    numbers = {n["name"]: n for n in results["acceptance_numbers"]}
    truth = resonance_peak(c2d(PLANT, 0.01, "zoh"))
    n = numbers["resonance_frequency"]
    assert abs(n["value"] - truth.frequency) < 4 * n["std"]


def test_bla_without_a_plan_is_refused_with_the_fix(tmp_path):
    u = np.random.default_rng(0).standard_normal(1024)
    write_csv(Experiment.from_arrays(0.01, u=u, y=u), tmp_path / "r.csv")
    exp_file = tmp_path / "experiment.toml"
    write_experiment_spec({"data": {"file": "r.csv"},
                           "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
                           "identify": {"method": "frequency", "estimator": "bla"}}, exp_file)
    out = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(out):
        code = main(["identify", str(exp_file), "--out", str(tmp_path / "o")])
    assert code != 0 and "servoid excite random-multisine" in out.getvalue()


@pytest.mark.parametrize("acceptance, match", [
    ({"bandwith_min": 5.0},
     r"unknown key\(s\) in \[acceptance\]: bandwith_min; valid keys are bandwidth_min"),
    ({"bandwidth_min": "fast"}, r"bandwidth_min"),
    (5.0, r"acceptance must be a mapping"),
])
def test_bad_acceptance_tables_are_refused_naming_the_key(tmp_path, acceptance, match):
    experiment = get_method("frequency").example(tmp_path, 0)
    spec = load_experiment_spec(experiment)
    with pytest.raises(ServoidError, match=match):
        identify(replace(spec, acceptance=acceptance), write=False)
