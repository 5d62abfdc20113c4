"""Studies (benchmarks/study_*.py) write their recorded results only when asked to."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

from servoid.estimate import fit_arx

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_nonlinear_study_rewrites_its_recorded_results_only_when_asked(
        tmp_path, monkeypatch, capsys):
    study = _load("study_nonlinear_real")
    recorded = tmp_path / "results-nonlinear-real.json"
    recorded.write_text("the recorded results\n")
    # the recorded file and its folder are the study's, moved here; a one-candidate grid
    monkeypatch.setattr(study, "HERE", tmp_path)
    monkeypatch.setattr(study, "RECORDED", recorded)
    monkeypatch.setattr(study, "grids", lambda quick: {
        "ARX": [("ARX na=2 nb=2 nk=1", lambda e: fit_arx(e, 2, 2, 1))]})
    monkeypatch.chdir(tmp_path)
    assert study.main([]) == 0
    assert "| arm | ARX | ARX na=2 nb=2 nk=1 |" in capsys.readouterr().out
    assert recorded.read_text() == "the recorded results\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [recorded.name]
    assert study.main(["--out", "elsewhere.json"]) == 0
    assert recorded.read_text() == "the recorded results\n"
    assert json.loads((tmp_path / "elsewhere.json").read_text())["quick"] is False
    assert study.main(["--write"]) == 0
    assert "ARX na=2 nb=2 nk=1" in json.loads(recorded.read_text())["records"]["arm"]["ARX"][
        "chosen"]["model"]
    assert study.main(["--table"]) == 0
    assert "recorded in results-nonlinear-real.json" in capsys.readouterr().out
