"""Outputs stay where the user said, inputs are never written, interrupted runs are recognised."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import DataError, OptionError, OutputExistsError, ServoidWarning
from servoid.cli import main
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import PolynomialModel
from servoid.workflows import identify

TRUTH = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)


@pytest.fixture
def rig(tmp_path):
    rng = np.random.default_rng(3)
    u = rng.standard_normal(1500)
    y = TRUTH.simulate(u) + lfilter([1.0], TRUTH.a, 0.01 * rng.standard_normal(1500))
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), tmp_path / "run.csv")
    return tmp_path


def _toml(folder, report=None, identify_table=None):
    table = {"data": {"file": "run.csv"},
             "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
             "identify": {"method": "arx", **(identify_table or {})}}
    if report:
        table["report"] = report
    path = folder / "e.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_a_toml_folder_outside_is_the_command_lines_choice(rig):
    inner = rig / "experiment"  # the TOML one level down, so "../x" stays in this test's folder
    inner.mkdir()
    (inner / "run.csv").write_bytes((rig / "run.csv").read_bytes())
    path = _toml(inner, {"folder": "../escape"})
    with pytest.raises(OptionError, match=r"points outside .* pass --out"):
        identify(path)
    assert not (rig / "escape").exists()
    result = identify(path, allow_outside=True)
    assert result.folder.resolve() == (rig / "escape").resolve()


def test_a_truth_file_in_the_results_folder_is_never_replaced(rig):
    out = rig / "res"
    out.mkdir()
    (out / "results.json").write_text('{"a1": -1.2}')
    before = _snapshot(rig)
    path = _toml(rig, {"truth": "res/results.json"})
    before = _snapshot(rig)
    with pytest.raises(OutputExistsError, match="it is an input of this run"):
        identify(path, out, overwrite=True)
    assert _snapshot(rig) == before  # nothing written, nothing replaced


def test_a_missing_truth_file_is_an_error(rig):
    with pytest.raises(FileNotFoundError, match="nope.json"):
        identify(_toml(rig, {"truth": "nope.json"}), write=False)


def test_an_interrupted_run_is_replaced_and_its_temporary_files_swept(rig):
    path = _toml(rig)
    out = rig / "res"
    first = identify(path, out)
    manifest = json.loads((out / "manifest.json").read_text())
    assert {f["name"] for f in manifest["files"]} == {p.name for p in first.files} - {
        "manifest.json"}
    # a run killed before its manifest: results without manifest, a temporary file left over
    (out / "manifest.json").unlink()
    (out / ".report.html.0123456789ab.tmp").write_text("half")
    with pytest.warns(ServoidWarning, match="interrupted earlier run"):
        identify(path, out)
    assert not (out / ".report.html.0123456789ab.tmp").exists()
    assert (out / "manifest.json").exists()
    # a complete run is protected as before
    with pytest.raises(OutputExistsError, match="earlier run; pass overwrite=True or"):
        identify(path, out)


def test_a_changed_file_makes_the_manifest_incomplete(rig):
    path = _toml(rig)
    out = rig / "res"
    identify(path, out)
    (out / "report.html").write_text("edited by hand")
    with pytest.warns(ServoidWarning, match="interrupted"):
        identify(path, out)


def test_a_prediction_horizon_beyond_the_record_is_refused(rig):
    with pytest.raises(DataError, match="horizon = 100000000 samples is not shorter"):
        identify(_toml(rig, identify_table={"horizon": 100_000_000}), write=False)


def test_cli_allow_outside_flag(rig, capsys):
    inner = rig / "experiment"
    inner.mkdir()
    (inner / "run.csv").write_bytes((rig / "run.csv").read_bytes())
    path = _toml(inner, {"folder": "../outside"})
    assert main(["identify", str(path)]) == 1
    assert "--allow-outside" in capsys.readouterr().err
    assert main(["identify", str(path), "--allow-outside"]) == 0
