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


def _killed_run(out, files, token="0123456789abcdef"):
    """What a run killed half way leaves: its lock (no process holds it) and a temporary file."""
    lock = {"servoid_lock": 1, "pid": 999999, "token": token, "folders": ["."],
            "files": files}
    (out / ".servoid.lock").write_text(json.dumps(lock))
    (out / f".report.html.{token}.0.tmp").write_text("half")


def test_an_interrupted_run_is_replaced_and_only_its_temporary_files_swept(rig):
    path = _toml(rig)
    out = rig / "res"
    first = identify(path, out)
    manifest = json.loads((out / "manifest.json").read_text())
    assert {f["name"] for f in manifest["files"]} == {p.name for p in first.files} - {
        "manifest.json"}
    assert not (out / ".servoid.lock").exists()  # removed at the end of the run
    # a run killed before its manifest: results without manifest, its lock, its temporary file
    (out / "manifest.json").unlink()
    _killed_run(out, sorted(p.name for p in first.files))
    (out / ".notes.0123456789ab.tmp").write_text("the user's")  # only named like servoid's
    with pytest.warns(ServoidWarning, match="interrupted earlier run"):
        identify(path, out)
    assert not (out / ".report.html.0123456789abcdef.0.tmp").exists()
    assert (out / ".notes.0123456789ab.tmp").read_text() == "the user's"
    assert (out / "manifest.json").exists() and not (out / ".servoid.lock").exists()
    # a complete run is protected as before
    with pytest.raises(OutputExistsError, match="earlier run; pass overwrite=True or"):
        identify(path, out)


def test_results_without_a_lock_or_manifest_are_not_servoids_to_replace(rig):
    path = _toml(rig)
    out = rig / "res"
    out.mkdir()
    (out / "report.html").write_text("the user's own report")
    with pytest.raises(OutputExistsError, match="only with overwrite=True"):
        identify(path, out)
    assert (out / "report.html").read_text() == "the user's own report"
    assert sorted(p.name for p in out.iterdir()) == ["report.html"]
    identify(path, out, overwrite=True)
    assert (out / "manifest.json").exists()


def test_a_changed_file_makes_the_manifest_incomplete(rig):
    path = _toml(rig)
    out = rig / "res"
    identify(path, out)
    (out / "report.html").write_text("edited by hand")
    with pytest.raises(OutputExistsError, match="only with overwrite=True"):
        identify(path, out)
    assert (out / "report.html").read_text() == "edited by hand"


def test_a_folder_a_live_run_holds_is_refused(rig):
    from servoid._lock import hold_folder

    path = _toml(rig)
    out = rig / "res"
    with hold_folder(out):  # a live run here (this process)
        before = _snapshot(rig)
        # another thread, as another run would: refused at once, nothing written
        import threading

        errors = []
        worker = threading.Thread(target=lambda: _catch(errors, identify, path, out))
        worker.start()
        worker.join()
        assert len(errors) == 1 and isinstance(errors[0], OutputExistsError)
        assert "in use by another servoid run" in str(errors[0])
        assert _snapshot(rig) == before
    identify(path, out)  # released: the folder is free again


def _catch(errors, fn, *args):
    try:
        fn(*args)
    except Exception as exc:  # noqa: BLE001 — the test inspects it
        errors.append(exc)


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
