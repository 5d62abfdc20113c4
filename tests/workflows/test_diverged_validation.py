"""A free run that diverges on a validation record fails the model, not the run.

The reviewer's reproduction: a cubic NARX fitted on a small-amplitude
record of the plant y(t) = tanh(0.8·y(t−1) + u(t−1)) (plain loop, white
measurement noise) is fine on a second small record and diverges on a
large-amplitude one, where its y³ terms take over.  ``servoid identify``
must still write results.json, the report and the console text, mark the
record with ``diverged_at`` and say in the verdict box that the model
failed validation.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import ServoidWarning
from servoid.cli import main
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.workflows import identify
from servoid.workflows._summary import summarise


def _tanh_record(amplitude: float, n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    u = amplitude * rng.uniform(-1.0, 1.0, n)
    y = np.zeros(n)
    for t in range(1, n):
        y[t] = np.tanh(0.8 * y[t - 1] + u[t - 1])
    return Experiment.from_arrays(0.01, u=u, y=y + 0.01 * rng.standard_normal(n),
                                  names={"u": "valve", "y": "position"},
                                  units={"valve": "V", "position": "mm"})


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    here = tmp_path_factory.mktemp("diverge")
    write_csv(_tanh_record(0.3, 2000, 1), here / "small.csv")
    write_csv(_tanh_record(0.3, 2000, 2), here / "small2.csv")
    write_csv(_tanh_record(3.0, 2000, 3), here / "large.csv")
    return here


def _toml(folder, name, validation):
    table = {"data": {"file": "small.csv"},
             "channels": {"valve": {"source": "valve", "role": "u", "unit": "V"},
                          "position": {"source": "position", "role": "y", "unit": "mm"}},
             "validation": {"file": validation},
             "identify": {"method": "narx", "na": 1, "nb": 1, "degree": 3}}
    path = folder / f"{name}.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_cli_writes_the_run_and_names_the_diverging_record(folder, tmp_path, capsys):
    path = _toml(folder, "one", "large.csv")
    out = tmp_path / "run"
    assert main(["identify", str(path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "FAILED — the free run diverges at sample" in text
    data = json.loads((out / "results.json").read_text(encoding="utf-8"))
    entry = data["validations"][0]
    assert entry["experiment"] == "large" and "fit_percent" not in entry
    k = entry["diverged_at"]["sample"]
    assert 0 < k < 2000 and entry["diverged_at"]["time"] == pytest.approx(k * 0.01)  # dt
    assert any(n.startswith(f"the free run diverges at sample {k} (t = ") and "'large'" in n
               for n in data["notes"])
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "Validation: FAILED" in html and "Term selection" in html
    assert not (out / "validation.png").exists()  # nothing finite to draw
    assert (out / "manifest.json").is_file()  # a complete run


def test_json_output_carries_the_diverged_record(folder, tmp_path, capsys):
    path = _toml(folder, "json", "large.csv")
    assert main(["identify", str(path), "--out", str(tmp_path / "j"), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["ok"] is True
    assert "diverged_at" in payload["validation"]
    assert any("diverges at sample" in w for w in payload["warnings"])


def test_a_good_record_keeps_its_metrics_beside_a_diverging_one(folder):
    path = _toml(folder, "two", ["small2.csv", "large.csv"])
    with pytest.warns(ServoidWarning, match="diverges at sample"):
        result = identify(path, write=False)
    good, bad = result.validations
    # the cubic is a good model where it was fitted: σ = 0.01 on an output of std ≈ 0.2
    assert good.fit_percent > 90
    assert bad.experiment == "large" and result.diverged == (bad,)
    summary = summarise(result.to_dict())
    assert summary.fit_percent == pytest.approx(good.fit_percent)
    assert summary.diverged and summary.diverged[0].startswith("large (sample ")
    verdict = result.verdict()
    assert verdict.decision == "reject" and summary.decision == "reject"
    failed = [c for c in verdict.checks if c.outcome == "fail"]
    assert [c.name for c in failed] == ["free run (large)"]
    assert failed[0].value == f"diverges at t = {bad.time:.6g} s"
    # the good record keeps its own checks, named after it
    assert any(c.name == "simulation fit (small2)" and c.outcome == "pass"
               for c in verdict.checks)


def test_a_run_that_does_not_diverge_has_no_failed_verdict(folder):
    result = identify(_toml(folder, "fine", "small2.csv"), write=False)
    assert result.diverged == ()
    assert not any(c.name.startswith("free run") for c in result.verdict().checks)
