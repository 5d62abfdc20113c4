"""results.json read back into objects, and a run's report written again."""

from __future__ import annotations

import json

import numpy as np
import pytest

import servoid
from servoid import OutputExistsError
from servoid.cli import main
from servoid.workflows import load_results


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("run")
    assert main(["bench", "ehsa", "--out", str(root / "b"), "--register", "9"]) == 0
    assert main(["identify", str(root / "b" / "ehsa.toml"), "--out", str(root / "r")]) == 0
    return root


def test_load_results_gives_models_and_parameters(run):
    loaded = servoid.load_results(run / "r" / "results.json")
    data = json.loads((run / "r" / "results.json").read_text(encoding="utf-8"))
    assert set(loaded.models) == {"indirect_plant", "indirect_closed_loop", "one_step_plant",
                                  "one_step_closed_loop"}
    tf = data["approaches"]["one-step"]["plant_continuous"]
    np.testing.assert_allclose(loaded.models["one_step_plant"].den, np.array(tf["den"]) / tf["den"][0],
                               rtol=1e-12)
    names = [p.name for p in loaded.summary.parameters]
    assert names == ["K", "omega_hp", "delta_hp"]
    assert loaded.summary.parameters[0].value == pytest.approx(
        data["parameters"][0]["one-step"]["value"], rel=1e-15)


def test_report_is_rewritten_from_unchanged_inputs_only(run, capsys, tmp_path):
    out = tmp_path / "again"
    results = run / "r" / "results.json"
    toml = run / "b" / "ehsa.toml"
    # the experiment file is outside the run's folder: read only when the command line names it
    assert main(["report", str(results), "--out", str(out)]) == 1
    assert f"--experiment {toml}" in capsys.readouterr().err
    assert not out.exists()
    assert main(["report", str(results), "--out", str(out), "--experiment", str(toml)]) == 0
    capsys.readouterr()
    assert (out / "report.html").is_file()
    before = json.loads(results.read_text(encoding="utf-8"))
    after = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert after["parameters"] == before["parameters"]
    # another complete run in --out is not the run's own: --overwrite, or refused
    assert main(["report", str(results), "--out", str(out), "--experiment", str(toml)]) == 1
    assert "--overwrite" in capsys.readouterr().err
    original = toml.read_text(encoding="utf-8")
    try:
        toml.write_text(original + "\n# edited\n", encoding="utf-8")
        with pytest.raises(OutputExistsError, match="is not the experiment file this run read"):
            servoid.workflows.rerender(results, tmp_path / "x", experiment=toml)
        assert main(["report", str(results), "--experiment", str(toml)]) == 1
    finally:
        toml.write_text(original, encoding="utf-8")
    data = next(p for p in toml.parent.iterdir() if p.suffix in (".csv", ".tdms"))
    saved = data.read_bytes()
    try:
        data.write_bytes(saved[:-1] + bytes([saved[-1] ^ 1]))
        with pytest.raises(OutputExistsError, match="is not the file this run read"):
            servoid.workflows.rerender(results, tmp_path / "y", experiment=toml)
    finally:
        data.write_bytes(saved)
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_load_results_refuses_other_files(tmp_path):
    (tmp_path / "x.json").write_text('{"a": 1}', encoding="utf-8")
    with pytest.raises(servoid.FileFormatError, match="not a results.json"):
        load_results(tmp_path / "x.json")
    with pytest.raises(servoid.MissingFileError):
        load_results(tmp_path / "none.json")


def test_report_of_the_default_layout_needs_no_experiment_flag(tmp_path, capsys):
    # <dir>/ehsa.toml wrote <dir>/ehsa-results: the folder holding both is the run's, known from
    # the results folder's own path, so the report is remade from any working directory
    assert main(["bench", "ehsa", "--out", str(tmp_path / "b"), "--register", "9"]) == 0
    assert main(["identify", str(tmp_path / "b" / "ehsa.toml")]) == 0
    results = tmp_path / "b" / "ehsa-results" / "results.json"
    capsys.readouterr()
    assert main(["report", str(results), "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "report.html").is_file()
    # a results folder renamed away from the default layout is no longer the experiment's
    moved = tmp_path / "b" / "elsewhere"
    results.parent.rename(moved)
    assert main(["report", str(moved / "results.json"), "--out", str(tmp_path / "x")]) == 1
    assert "--experiment" in capsys.readouterr().err
