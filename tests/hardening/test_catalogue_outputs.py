"""The bad-input catalogue for outputs and re-rendering (issue 21, items 2, 3 and 5).

Each case puts a folder in a state a user, an unlucky moment or an edited
file can make, and checks that servoid replaces or deletes nothing it was
not given leave to, reads nothing it was not pointed at, and says so in one
message naming the fix:

- two runs into one folder, as two processes started together, over several
  tries: exactly one succeeds, the other is refused, nothing of the first is
  deleted;
- a run killed (SIGKILL) at varied moments: the next run, without
  ``--overwrite``, completes, and deletes only the dead run's temporary files
  (recognised by the token in its lock), never a user's file named like one;
- every writing command refuses to replace a user's file without
  ``--overwrite`` and refuses an empty ``--out``;
- ``servoid report`` reads only the run's folder or what its command line
  names (an edited results file cannot point it elsewhere), resolves a run
  made with a relative path the same way from any working directory, and
  never replaces another complete run;
- ``fleet --out`` into a folder of the user's files is refused without
  ``--overwrite``.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import servoid
from servoid.cli import main
from servoid.data import Experiment, write_csv
from servoid.models import PolynomialModel

TRUTH = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)
TOML = """\
[data]
file = "run.csv"
time = "time"

[channels.u]
role = "u"

[channels.y]
role = "y"

[identify]
method = "arx"
na = 2
nb = 2
nk = 1
"""
# the child processes import the servoid under test
ENV = {**os.environ, "PYTHONPATH": str(Path(servoid.__file__).parents[1]),
       "OPENBLAS_NUM_THREADS": "1"}


def _record(folder: Path, seed: int = 3, n: int = 1500) -> None:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = TRUTH.simulate(u) + 0.01 * rng.standard_normal(n)
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), folder / "run.csv")


@pytest.fixture
def rig(tmp_path):
    _record(tmp_path)
    (tmp_path / "e.toml").write_text(TOML, encoding="utf-8")
    return tmp_path


def _tree(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _complete(folder: Path) -> bool:
    manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    return all(hashlib.sha256((folder / f["name"]).read_bytes()).hexdigest() == f["sha256"]
               for f in manifest["files"])


def _servoid(*args: str, cwd: Path | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "servoid", *args], env=ENV, cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


# -- one run owns its folder ---------------------------------------------------------------


@pytest.mark.parametrize("attempt", range(3))
def test_two_runs_into_one_folder_exactly_one_succeeds(rig, attempt):
    # two experiments on different records, so a file of one run is told from the other's
    other = rig / "second"
    other.mkdir()
    _record(other, seed=5)
    (other / "e.toml").write_text(TOML, encoding="utf-8")
    tomls = [rig / "e.toml", other / "e.toml"]
    out = rig / "res"
    runs = [_servoid("identify", str(toml), "--out", str(out)) for toml in tomls]
    done = [(p.wait(timeout=300), *p.communicate()) for p in runs]
    codes = [code for code, _, _ in done]
    messages = " ".join(err for _, _, err in done)
    assert sorted(codes) == [0, 1], messages
    assert ("in use by another servoid run" in messages
            or "exists from an earlier run" in messages)  # the loser came after the winner
    assert "Traceback" not in messages
    assert _complete(out)  # nothing of the winner's was deleted or replaced by the loser
    winner = tomls[codes.index(0)]
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert results["experiment_file"] == str(winner)
    assert not (out / ".servoid.lock").exists()
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("delay", [1.0, 3.0])
def test_a_killed_run_is_taken_over_without_overwrite(rig, delay):
    out = rig / "res"
    out.mkdir()
    (out / ".notes.0123456789ab.tmp").write_text("the user's")  # named like a temporary file
    proc = _servoid("identify", str(rig / "e.toml"), "--out", str(out))
    time.sleep(delay)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    again = _servoid("identify", str(rig / "e.toml"), "--out", str(out))
    code = again.wait(timeout=300)
    _, err = again.communicate()
    if code != 0:  # the killed run finished before the signal: a complete run is kept
        assert "exists from an earlier run" in err, err
    assert _complete(out)
    assert (out / ".notes.0123456789ab.tmp").read_text() == "the user's"
    leftovers = [p.name for p in out.iterdir() if p.name.endswith(".tmp") and p.name !=
                 ".notes.0123456789ab.tmp"]
    assert leftovers == [] and not (out / ".servoid.lock").exists()


DIE_WRITING = """
import os, sys
import servoid.report
from servoid._atomic import atomic_path
from servoid.cli import main

def die(page, path, overwrite=False):  # killed half way through writing report.html
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text("half")
        os._exit(9)

servoid.report.write_html = die
sys.exit(main(sys.argv[1:]))
"""


def test_a_run_killed_while_writing_is_taken_over(rig):
    out = rig / "res"
    out.mkdir()
    (out / ".notes.0123456789ab.tmp").write_text("the user's")
    proc = subprocess.run([sys.executable, "-c", DIE_WRITING, "identify", str(rig / "e.toml"),
                           "--out", str(out)], env=ENV, capture_output=True, text=True)
    assert proc.returncode == 9
    left = sorted(p.name for p in out.iterdir())
    assert ".servoid.lock" in left and "results.json" in left and "manifest.json" not in left
    assert any(n.startswith(".report.html.") and n.endswith(".tmp") for n in left)
    again = _servoid("identify", str(rig / "e.toml"), "--out", str(out))
    assert again.wait(timeout=300) == 0, again.communicate()
    assert "interrupted earlier run" in again.communicate()[1]
    assert _complete(out) and not (out / ".servoid.lock").exists()
    assert sorted(p.name for p in out.iterdir() if p.name.endswith(".tmp")) == [
        ".notes.0123456789ab.tmp"]  # the dead run's temporary file went, the user's stayed


# -- nothing replaced without consent --------------------------------------------------------


@pytest.mark.parametrize("name", ["report.html", "results.json", "manifest.json"])
def test_identify_keeps_a_users_file(rig, capsys, name):
    out = rig / "res"
    out.mkdir()
    (out / name).write_text("mine")
    before = _tree(rig)
    assert main(["identify", str(rig / "e.toml"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "--overwrite" in err and name in err
    assert _tree(rig) == before
    assert main(["identify", str(rig / "e.toml"), "--out", str(out), "--overwrite"]) == 0


@pytest.mark.parametrize("argv", [
    ["identify", "{rig}/e.toml", "--out", ""],
    ["report", "{rig}/res/results.json", "--out", ""],
    ["report", "{rig}/res/results.json", "--experiment", ""],
    ["export", "{rig}/res/results.json", "--to", "json", "--out", ""],
    ["fleet", "{rig}/fleet.toml", "--out", ""],
    ["bench", "ehsa", "--out", ""],
    ["excite", "prbs", "--register", "5", "--dt", "0.01", "--out", ""],
    ["demo", "--out", ""],
])
def test_an_empty_out_is_a_usage_error(rig, capsys, monkeypatch, argv):
    monkeypatch.chdir(rig)
    before = _tree(rig)
    assert main([a.format(rig=rig) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "empty path" in err and "Traceback" not in err
    assert _tree(rig) == before


def test_excite_bench_and_demo_keep_a_users_file(rig, capsys):
    (rig / "signal.csv").write_text("mine")
    before = _tree(rig)
    assert main(["excite", "prbs", "--register", "5", "--dt", "0.01", "--out",
                 str(rig / "signal.csv")]) == 1
    (rig / "ehsa.toml").write_text("mine")
    (rig / "batch").mkdir()
    (rig / "batch" / "units.csv").write_text("mine")
    before = _tree(rig)
    assert main(["bench", "fleet", "--out", str(rig / "batch"), "--units", "3", "--corrupt",
                 "0", "--register", "5"]) == 1
    assert not (rig / "batch" / "units").exists()  # refused before any unit was written
    assert main(["bench", "ehsa", "--out", str(rig), "--format", "csv"]) == 1
    assert main(["demo", "--out", str(rig)]) == 1
    err = capsys.readouterr().err
    assert err.count("--overwrite") >= 4
    assert _tree(rig) == before


# -- report: only the run's folder or what the command line names ---------------------------


@pytest.fixture
def done(rig):
    """A complete run whose experiment file lies inside its folder (so report may read it)."""
    run = rig / "run"
    run.mkdir()
    for name in ("e.toml", "run.csv"):
        (run / name).write_bytes((rig / name).read_bytes())
    assert main(["identify", str(run / "e.toml"), "--out", str(run)]) == 0
    return run


def test_report_into_its_own_folder_needs_nothing_more(done, capsys):
    capsys.readouterr()
    before = json.loads((done / "results.json").read_text(encoding="utf-8"))
    assert main(["report", str(done / "results.json")]) == 0, capsys.readouterr().err
    after = json.loads((done / "results.json").read_text(encoding="utf-8"))
    assert after["model"] == before["model"] and _complete(done)


def test_an_edited_results_file_cannot_point_report_elsewhere(done, rig, tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _record(elsewhere, seed=9)
    (elsewhere / "e.toml").write_text(TOML, encoding="utf-8")
    # the edit an attacker makes: results.json and a manifest that agree with the other files
    data = json.loads((done / "results.json").read_text(encoding="utf-8"))
    data["experiment_file"] = str(elsewhere / "e.toml")
    (done / "results.json").write_text(json.dumps(data), encoding="utf-8")
    manifest = json.loads((done / "manifest.json").read_text(encoding="utf-8"))
    manifest["inputs"] = [{"path": str(p), "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
                          for p in (elsewhere / "e.toml", elsewhere / "run.csv")]
    (done / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    before = _tree(tmp_path)
    capsys.readouterr()
    assert main(["report", str(done / "results.json")]) == 1
    err = capsys.readouterr().err
    assert "outside the run's folder" in err and "--experiment" in err
    assert _tree(tmp_path) == before


def test_an_experiment_inside_that_reads_outside_is_refused(done, tmp_path, capsys):
    toml = done / "e.toml"
    outside = tmp_path / "outside.csv"
    outside.write_bytes((done / "run.csv").read_bytes())
    toml.write_text(TOML.replace('"run.csv"', f'"{outside}"'), encoding="utf-8")
    manifest = json.loads((done / "manifest.json").read_text(encoding="utf-8"))
    manifest["inputs"] = [{"path": str(p.resolve()),
                           "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
                          for p in (toml, outside)]
    (done / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    capsys.readouterr()
    assert main(["report", str(done / "results.json")]) == 1
    err = capsys.readouterr().err
    assert f"reads {outside}" in err and "--experiment" in err


def test_a_relative_run_is_rerendered_the_same_from_any_folder(rig, tmp_path, capsys):
    """A run made with relative paths; another folder holds a same-named experiment."""
    proc = _servoid("identify", "e.toml", "--out", "res", cwd=rig)
    assert proc.wait(timeout=300) == 0, proc.communicate()
    other = tmp_path / "other"
    other.mkdir()
    _record(other, seed=11)  # other data under the same names
    (other / "e.toml").write_text(TOML, encoding="utf-8")
    before = json.loads((rig / "res" / "results.json").read_text(encoding="utf-8"))
    assert before["experiment_file"] == "e.toml"  # as given, relative
    proc = _servoid("report", str(rig / "res" / "results.json"), "--out", str(tmp_path / "x"),
                    cwd=other)
    _, err = proc.communicate()
    assert proc.returncode == 1 and f"--experiment {rig / 'e.toml'}" in err
    proc = _servoid("report", str(rig / "res" / "results.json"), "--out", str(tmp_path / "x"),
                    "--experiment", str(rig / "e.toml"), cwd=other)
    assert proc.wait(timeout=300) == 0, proc.communicate()
    after = json.loads((tmp_path / "x" / "results.json").read_text(encoding="utf-8"))
    assert after["model"] == before["model"]  # the run's record, not the other one
    # naming the same-named file of the other folder is refused: not the file the run read
    proc = _servoid("report", str(rig / "res" / "results.json"), "--out", str(tmp_path / "y"),
                    "--experiment", "e.toml", cwd=other)
    _, err = proc.communicate()
    assert proc.returncode == 1 and "not the experiment file this run read" in err
    assert not (tmp_path / "y").exists()


def test_report_out_never_replaces_another_complete_run(done, rig, capsys):
    other = rig / "other"
    assert main(["identify", str(rig / "e.toml"), "--out", str(other)]) == 0
    before = _tree(other)
    capsys.readouterr()
    assert main(["report", str(done / "results.json"), "--out", str(other)]) == 1
    assert "--overwrite" in capsys.readouterr().err
    assert _tree(other) == before
    assert main(["report", str(done / "results.json"), "--out", str(other),
                 "--overwrite"]) == 0


# -- fleet --out ----------------------------------------------------------------------------


def test_fleet_out_keeps_a_users_files(rig, capsys):
    (rig / "fleet.toml").write_text(
        '[records]\nglob = "e.toml"\n\n[identify]\nmethod = "arx"\nna = 2\nnb = 2\nnk = 1\n',
        encoding="utf-8")
    out = rig / "fleet-out"
    out.mkdir()
    (out / "fleet.csv").write_text("mine")
    before = _tree(rig)
    code = main(["fleet", str(rig / "fleet.toml"), "--out", str(out), "--workers", "1",
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and "--overwrite" in err and "fleet.csv" in err
    assert _tree(rig) == before
    assert main(["fleet", str(rig / "fleet.toml"), "--out", str(out), "--workers", "1",
                 "--quiet", "--overwrite"]) == 0
    capsys.readouterr()
    # a re-run replaces the files the earlier fleet wrote, without --overwrite
    assert main(["fleet", str(rig / "fleet.toml"), "--out", str(out), "--workers", "1",
                 "--quiet"]) == 0
