"""A fitted grey-box ODE travels: model file, results.json, export and report, with consent.

The model file holds a reference to the user's Python file (path, SHA-256,
function names) and the numbers; the file runs again only with
``allow_code=True`` / ``--allow-code`` and only while its bytes are those the
fit executed.  The records come from the example's independent generator
(``examples/greybox/make_data.py``: numpy RK4 at 20 steps per sample,
overflow by projection, white sensor noise), on seeds the fit never saw.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import servoid
from servoid import MissingFileError, ModelError, OptionError, OptionTypeError, OutputExistsError
from servoid.cli import main
from servoid.models import save_model
from servoid.workflows import identify, rerender

EXAMPLE = Path(__file__).parents[2] / "examples" / "greybox"
_spec = importlib.util.spec_from_file_location("greybox_example_data_files",
                                               EXAMPLE / "make_data.py")
GEN = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(GEN)

# the example's model, leaving a trace each time it is executed
MODEL = (EXAMPLE / "tanks.py").read_text(encoding="utf-8") + '''

from pathlib import Path as _Path

_Path(__file__).with_name("executed.txt").write_text("the model file ran")
'''

TOML = """
[data]
file = "est.csv"
time = "t"
time_unit = "s"

[channels]
pump = { role = "u", unit = "V" }
level = { role = "y", unit = "m" }

[validation]
file = "val.csv"

[identify]
method = "greybox"
model = "tanks.py:rhs"
output_function = "tanks.py:level"
states = ["h1", "h2"]
initial_state = [0.1, 0.1]
estimate_initial = ["h1", "h2"]
fixed = ["A"]

[identify.parameters]
k = [2.0e-5, 1.0e-7, 1.0e-3]
a1 = [2.0e-5, 1.0e-7, 1.0e-3]
a2 = [2.0e-5, 1.0e-7, 1.0e-3]
A = 0.0154

[identify.units]
k = "m³/(s·V)"

[identify.saturation]
h1 = [0.0, 0.30]
pump = [0.0, 8.0]
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One grey-box run written to disk, its model saved from the estimate."""
    base = tmp_path_factory.mktemp("greybox-files")
    (base / "tanks.py").write_text(MODEL, encoding="utf-8")
    (base / "tanks.toml").write_text(TOML, encoding="utf-8")
    for name, seed, h0 in (("est.csv", 51, (0.12, 0.06)), ("val.csv", 52, (0.05, 0.15))):
        t, u, y, _ = GEN.record(500, seed, h0)  # short records: the whole module runs in ~10 s
        GEN.write(base / name, t, u, y)
    result = identify(base / "tanks.toml", base / "out", allow_code=True)
    model_file = save_model(result.estimate, base / "model.json")
    return base, result, model_file


@pytest.fixture(scope="module")
def new_record():
    """A record the fit never saw: another seed, another initial state."""
    _, u, y, levels = GEN.record(600, 97, (0.20, 0.02))
    return u, y, levels[:, 1]


def _fresh(base: Path) -> Path:
    trace = base / "executed.txt"
    trace.unlink(missing_ok=True)
    return trace


def test_the_model_file_references_the_code_and_holds_no_code(run):
    base, result, model_file = run
    text = model_file.read_text(encoding="utf-8")
    record = json.loads(text)
    assert record["type"] == "OdeModel"
    assert record["model_file"] == str((base / "tanks.py").resolve())
    digest = hashlib.sha256((base / "tanks.py").read_bytes()).hexdigest()
    assert record["model_sha256"] == record["output_sha256"] == digest
    assert (record["rhs"], record["output_function"]) == ("rhs", "level")
    assert record["signature"] == "rhs(x, u, p)"
    assert record["state_saturation"] == [[0.0, 0.3], [None, None]]  # null: no limit
    assert record["input_saturation"] == [[0.0, 8.0]]
    assert record["parameters"][0] == {"name": "k", "value": result.estimate.model["k"],
                                       "unit": "m³/(s·V)", "fixed": False}
    assert record["parameters"][3]["fixed"] is True
    assert record["parameter_names"] == ["k", "a1", "a2", "h1(0)", "h2(0)"]
    for code in ("def rhs", "sqrt", "executed.txt"):  # a reference, never the code
        assert code not in text


def test_load_with_consent_gives_the_same_model_and_replay(run, new_record):
    _, result, model_file = run
    fitted = result.estimate.model
    loaded = servoid.load_model(model_file, allow_code=True)
    assert type(loaded).__name__ == "OdeModel"
    assert loaded.names == fitted.names and loaded.states == fitted.states
    assert np.array_equal(loaded.theta, fitted.theta)  # the floats of the fit, bit for bit
    assert np.array_equal(loaded.x0, fitted.x0) and loaded.estimated == fitted.estimated
    assert np.array_equal(loaded.covariance, result.estimate.covariance)
    assert loaded.system.compiled == fitted.system.compiled
    assert loaded.units[0] == "m³/(s·V)" and loaded.fixed == (False, False, False, True)
    u, y, level = new_record
    got, first, rule = loaded.replay(y, u)
    want = fitted.replay(y, u)
    assert np.array_equal(got, want[0]) and (first, rule) == want[1:]  # bit for bit
    # and it is the plant: within 3 mm of the noise-free level after the initial-state
    # refit (sensor σ = 1 mm; the parameters carry a few % uncertainty from 500 samples)
    assert np.max(np.abs(got - level)) < 3e-3


@pytest.mark.slow  # ~4-9 s: a new interpreter imports numba and compiles the model again
def test_a_fresh_process_replays_bit_for_bit(run, new_record, tmp_path):
    """Later, elsewhere: a new Python process loads the file and compiles the model anew.

    The default suite checks the same file read back in this process
    (``test_load_with_consent_gives_the_same_model_and_replay``).
    """
    _, result, model_file = run
    u, y, _ = new_record
    np.save(tmp_path / "u.npy", u)
    np.save(tmp_path / "y.npy", y)
    script = (f"import numpy as np, servoid\n"
              f"m = servoid.load_model({str(model_file)!r}, allow_code=True)\n"
              f"u, y = np.load({str(tmp_path / 'u.npy')!r}), np.load({str(tmp_path / 'y.npy')!r})\n"
              f"np.save({str(tmp_path / 'replay.npy')!r}, m.replay(y, u)[0])\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert np.array_equal(np.load(tmp_path / "replay.npy"), result.estimate.model.replay(y, u)[0])


def test_load_without_consent_is_refused_and_nothing_runs(run):
    base, _, model_file = run
    trace = _fresh(base)
    with pytest.raises(OptionError) as info:
        servoid.load_model(model_file)
    message = str(info.value)
    assert str((base / "tanks.py").resolve()) in message
    assert "allow_code=True" in message and "--allow-code" in message
    assert str(model_file) in message
    assert not trace.exists()  # the model file never ran
    with pytest.raises(OptionTypeError, match="allow_code must be true or false"):
        servoid.load_model(model_file, allow_code="yes")
    assert not trace.exists()


def test_a_changed_or_missing_python_file_is_refused(run, tmp_path):
    base, _, model_file = run
    record = json.loads(model_file.read_text(encoding="utf-8"))
    copy = tmp_path / "tanks.py"
    shutil.copy(base / "tanks.py", copy)
    before = hashlib.sha256(copy.read_bytes()).hexdigest()
    for key in ("model_file", "output_file"):
        record[key] = str(copy)
    moved = tmp_path / "model.json"
    moved.write_text(json.dumps(record), encoding="utf-8")
    with copy.open("a", encoding="utf-8") as fh:
        fh.write("\nG = 9.80665  # a changed constant\n")
    after = hashlib.sha256(copy.read_bytes()).hexdigest()
    with pytest.raises(ModelError) as info:
        servoid.load_model(moved, allow_code=True)
    message = str(info.value)
    assert before in message and after in message and str(copy) in message
    assert "restore the file" in message and "fit the model again" in message
    assert not (tmp_path / "executed.txt").exists()  # refused before it ran
    copy.unlink()
    with pytest.raises(MissingFileError, match=r"put the file it was fitted with back"):
        servoid.load_model(moved, allow_code=True)


def test_a_damaged_record_is_named(run, tmp_path):
    _, _, model_file = run
    record = json.loads(model_file.read_text(encoding="utf-8"))
    for key, value, match in (("model_sha256", "abc", "SHA-256 in hex"),
                              ("state_saturation", [[0.3, 0.0], [None, None]],
                               "lower 0.3 must be below upper 0"),
                              ("model_file", "tanks.py", "absolute path of a .py file"),
                              ("model_file", "/etc/passwd", "absolute path of a .py file")):
        path = tmp_path / f"{key}.json"
        path.write_text(json.dumps({**record, key: value}), encoding="utf-8")
        with pytest.raises(servoid.FileFormatError, match=match):
            servoid.load_model(path, allow_code=True)
    del record["rhs"]
    path = tmp_path / "no-rhs.json"
    path.write_text(json.dumps(record), encoding="utf-8")
    with pytest.raises(servoid.FileFormatError, match=r"the OdeModel has no 'rhs'"):
        servoid.load_model(path)  # damage is reported before consent is asked


def test_load_results_with_and_without_consent(run, new_record):
    base, result, _ = run
    results = base / "out" / "results.json"
    trace = _fresh(base)
    with pytest.raises(OptionError, match=r"allow_code=True") as info:
        servoid.load_results(results)
    assert str((base / "tanks.py").resolve()) in str(info.value)
    assert not trace.exists()
    loaded = servoid.load_results(results, allow_code=True)
    model = loaded.models["G"]
    assert np.array_equal(model.theta, result.estimate.model.theta)
    u, y, _ = new_record
    assert np.array_equal(model.replay(y, u)[0], result.estimate.model.replay(y, u)[0])
    assert {p.name for p in loaded.summary.parameters} >= {"k", "a1", "a2"}


def test_export_json_writes_the_model_file_without_running_code(run, tmp_path, capsys):
    base, _, model_file = run
    results = base / "out" / "results.json"
    trace = _fresh(base)
    out = tmp_path / "exported.json"
    code = main(["export", str(results), "--to", "json", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert not trace.exists()  # writing the file needs no code
    # the same file as save_model(estimate): the run's record is the whole model
    assert out.read_text(encoding="utf-8") == model_file.read_text(encoding="utf-8")
    for to in ("mat", "python"):
        code = main(["export", str(results), "--to", to, "--out", str(tmp_path / f"m.{to}")])
        err = capsys.readouterr().err
        assert code != 0
        assert "OdeModel" in err and "use --to json" in err and "allow_code=True" in err
    assert not trace.exists()


def test_report_needs_allow_code_and_an_unchanged_model_file(run, tmp_path, capsys):
    base, _, _ = run
    results = base / "out" / "results.json"
    trace = _fresh(base)
    code = main(["report", str(results), "--out", str(tmp_path / "again")])
    err = capsys.readouterr().err
    assert code != 0 and "--allow-code" in err and str((base / "tanks.py").resolve()) in err
    assert not trace.exists()
    before = json.loads(results.read_text(encoding="utf-8"))
    (base / "out" / "report.html").unlink()
    code = main(["report", str(results), "--allow-code",  # into the run's own folder
                 "--experiment", str(base / "tanks.toml")])
    assert code == 0, capsys.readouterr().err
    assert trace.exists()  # this time the model file ran
    again = json.loads(results.read_text(encoding="utf-8"))
    assert again["model"]["parameters"] == before["model"]["parameters"]  # the same fit
    assert (base / "out" / "report.html").is_file()
    # a results.json whose model record names other code than the file now holds
    data = json.loads(results.read_text(encoding="utf-8"))
    data["model"]["model_file"]["model_sha256"] = "0" * 64
    folder = tmp_path / "copy"
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps(data), encoding="utf-8")
    shutil.copy(base / "out" / "manifest.json", folder / "manifest.json")
    with pytest.raises(OutputExistsError, match=r"not the model file this run fitted"):
        rerender(folder / "results.json", tmp_path / "third", allow_code=True,
                 experiment=base / "tanks.toml")


def test_the_python_integrator_travels_too(run, new_record, tmp_path):
    base, _, _ = run
    toml = base / "plain.toml"  # one free parameter: the Python integrator is slow
    toml.write_text(TOML.replace('fixed = ["A"]', 'fixed = ["A", "k", "a1"]\ncompile = false')
                    .replace('estimate_initial = ["h1", "h2"]', "estimate_initial = []"),
                    encoding="utf-8")
    result = identify(toml, write=False, allow_code=True)
    assert not result.estimate.model.system.compiled
    path = save_model(result.estimate, tmp_path / "plain.json")
    assert json.loads(path.read_text(encoding="utf-8"))["compiled"] is False
    loaded = servoid.load_model(path, allow_code=True)
    assert not loaded.system.compiled  # the integrator the fit used, so the same numbers
    u, y, _ = new_record
    assert np.array_equal(loaded.replay(y, u)[0], result.estimate.model.replay(y, u)[0])
    assert np.array_equal(loaded.simulate(u), result.estimate.model.simulate(u))


def test_a_model_whose_function_is_in_no_file_is_not_saved(tmp_path):
    from servoid.estimate._ode import make_system
    from servoid.estimate._ode_model import OdeModel

    free = (np.full(1, -np.inf), np.full(1, np.inf))
    system = make_system(lambda x, u, p: (u[0] - p[0] * x[0],), 0, x0=np.zeros(1),
                         u=np.zeros((4, 1)), p=np.ones(1), state_lower=free[0],
                         state_upper=free[1], input_lower=free[0], input_upper=free[1],
                         source="<lambda>", compile=False)
    model = OdeModel(system, ("a",), np.ones(1), ("x",), np.zeros(1), (), 0.1)
    with pytest.raises(ModelError, match=r"not a function defined at the top level of a "
                                         r"Python file.*define it with def in a \.py file"):
        save_model(model, tmp_path / "m.json")
    assert not list(tmp_path.iterdir())
    assert model.to_dict()["model_file"] is None  # results.json then has nothing to load


def test_report_runs_the_bytes_it_hashed_not_a_file_swapped_after(run, tmp_path, monkeypatch):
    """A model file swapped between the hash check and the run: the swapped code never runs."""
    import servoid.workflows._results as results_module

    base, _, _ = run
    results = base / "out" / "results.json"
    model = base / "tanks.py"
    original = model.read_bytes()
    evil = b'from pathlib import Path\nPath(__file__).with_name("evil.txt").write_text("ran")\n'
    checked = results_module.sha256
    seen = hashlib.sha256(original).hexdigest()

    def check_then_swap(path):
        if Path(path).resolve() != model.resolve():
            return checked(path)
        model.write_bytes(evil)  # the swap lands just after each check saw the original
        return seen

    monkeypatch.setattr(results_module, "sha256", check_then_swap)
    try:
        with pytest.raises(servoid.ModelError, match="not the model file this run fitted"):
            rerender(results, tmp_path / "swapped", allow_code=True,
                     experiment=base / "tanks.toml")
    finally:
        model.write_bytes(original)
    assert not (base / "evil.txt").exists()
    assert not (tmp_path / "swapped").exists()


@pytest.mark.parametrize("where", ["top", "rhs"])
def test_a_model_file_calling_sys_exit_is_an_error_naming_it(run, tmp_path, capsys, where):
    base, _, _ = run
    folder = tmp_path / "exits"
    folder.mkdir()
    for name in ("est.csv", "val.csv"):
        shutil.copy(base / name, folder / name)
    code = (base / "tanks.py").read_text(encoding="utf-8")
    if where == "top":
        code = "import sys\nsys.exit(0)\n" + code
    else:
        code = code.replace("def rhs(", "def _rhs(") + (
            "\n\ndef rhs(x, u, p):\n    import sys\n    sys.exit(0)\n")
    (folder / "tanks.py").write_text(code, encoding="utf-8")
    (folder / "tanks.toml").write_text(TOML.replace("[identify]\n",
                                                    "[identify]\ncompile = false\n"),
                                       encoding="utf-8")
    with pytest.raises(servoid.ModelError, match=r"sys\.exit\(0\).*tanks\.py"):
        identify(folder / "tanks.toml", allow_code=True, write=False)
    assert main(["identify", str(folder / "tanks.toml"), "--allow-code"]) == 1
    err = capsys.readouterr().err
    assert "sys.exit(0)" in err and "tanks.py" in err
    assert not (folder / "tanks-results").exists()
