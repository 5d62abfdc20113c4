"""servoid export: the model(s) of a results.json as .mat, a model file or python-control code."""

from __future__ import annotations

import json
import runpy

import numpy as np
import pytest
from scipy import io as sio

from servoid.cli import main
from servoid.models import (
    PolynomialModel,
    StateSpace,
    TransferFunction,
    load_model,
    to_control,
)
from servoid.report import write_json

# the writer servoid identify uses for "model", so these files have the real shape
from servoid.workflows._lti import model_dict


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A closed-loop run (the demo) and an ARX run on the demo's records."""
    folder = tmp_path_factory.mktemp("export") / "demo"
    assert main(["demo", "--out", str(folder)]) == 0
    toml = (folder / "ehsa.toml").read_text().replace('role = "r"', 'role = "u"')
    start, end = toml.index("[loop]"), toml.index("[report]")
    toml = toml[:start] + '[identify]\nmethod = "arx"\nna = 2\nnb = 2\nnk = 1\n\n' + toml[end:]
    (folder / "arx.toml").write_text(toml)
    assert main(["identify", str(folder / "arx.toml"), "--out", str(folder / "arx")]) == 0
    return {"closedloop": folder / "report" / "results.json",
            "arx": folder / "arx" / "results.json"}


def _results(tmp_path, model, name="results.json"):
    path = tmp_path / name
    write_json({"servoid_version": "test", "method": "tf", "model": model_dict(model)}, path)
    return path


def test_arx_to_model_file(capsys, runs, tmp_path):
    out = tmp_path / "arx.json"
    code, text, _ = run(capsys, "export", str(runs["arx"]), "--to", "json", "--out", str(out))
    assert code == 0 and "G (PolynomialModel)" in text
    model = load_model(out)
    saved = json.loads(runs["arx"].read_text())
    assert isinstance(model, PolynomialModel) and model.dt == saved["model"]["dt"]
    assert np.array_equal(model.a, saved["model"]["a"])  # the same floats, read and written
    assert np.array_equal(model.b[0], saved["model"]["b"][0]) and model.nk == (1,)
    assert model.noise_variance == saved["estimate"]["noise_variance"]


def test_arx_to_mat_and_python(capsys, runs, tmp_path):
    control = pytest.importorskip("control")
    saved = json.loads(runs["arx"].read_text())["model"]
    assert run(capsys, "export", str(runs["arx"]), "--to", "mat", "--out",
               str(tmp_path / "arx.mat"))[0] == 0
    s = sio.loadmat(tmp_path / "arx.mat", squeeze_me=True, struct_as_record=False)["G"]
    assert s.type == "idpoly" and s.Ts == saved["dt"] and s.nk == 1
    assert np.array_equal(s.A, saved["a"]) and np.array_equal(s.B, [0.0, *saved["b"][0]])

    assert run(capsys, "export", str(runs["arx"]), "--to", "python", "--out",
               str(tmp_path / "arx.py"))[0] == 0
    g = runpy.run_path(str(tmp_path / "arx.py"))["G"]
    want = to_control(_arx(saved))
    assert isinstance(g, control.TransferFunction) and g.dt == saved["dt"]
    assert np.array_equal(g.num[0][0], want.num[0][0])  # repr floats: exact
    assert np.array_equal(g.den[0][0], want.den[0][0])


def test_closed_loop_results_hold_a_model_per_approach(capsys, runs, tmp_path):
    saved = json.loads(runs["closedloop"].read_text())["approaches"]
    code, out, _ = run(capsys, "export", str(runs["closedloop"]), "--to", "mat", "--out",
                       str(tmp_path / "cl.mat"), "--json")
    assert code == 0
    names = json.loads(out)["models"]
    assert set(names) == {f"{a.replace('-', '_')}_{k}" for a in saved
                          for k in ("plant", "closed_loop")}
    mat = sio.loadmat(tmp_path / "cl.mat", squeeze_me=True, struct_as_record=False)
    for approach, result in saved.items():
        plant = mat[f"{approach.replace('-', '_')}_plant"]
        assert plant.Ts == 0.0  # continuous
        assert np.array_equal(np.atleast_1d(plant.num), result["plant_continuous"]["num"])
        assert np.array_equal(plant.den, result["plant_continuous"]["den"])

    code, _, err = run(capsys, "export", str(runs["closedloop"]), "--to", "json")
    assert code == 1 and "--model NAME" in err and "one_step_plant" in err
    code, _, err = run(capsys, "export", str(runs["closedloop"]), "--to", "json",
                       "--model", "plant")
    assert code == 1 and "--model must be one of" in err
    code, out, _ = run(capsys, "export", str(runs["closedloop"]), "--to", "json",
                       "--model", "one_step_plant")
    written = runs["closedloop"].parent / "model_one_step_plant.json"  # the default --out
    assert code == 0 and str(written) in out
    plant = load_model(written)
    assert isinstance(plant, TransferFunction) and plant.dt is None
    assert np.array_equal(plant.den, saved["one-step"]["plant_continuous"]["den"])


def test_state_space_and_delay(capsys, tmp_path):
    control = pytest.importorskip("control")
    ss = StateSpace([[0.9, 0.1], [0.0, 0.5]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], 0.01)
    path = _results(tmp_path, ss)
    assert run(capsys, "export", str(path), "--to", "python")[0] == 0
    g = runpy.run_path(str(tmp_path / "model.py"))["G"]
    assert isinstance(g, control.StateSpace) and np.array_equal(g.A, ss.A) and g.dt == 0.01

    late = TransferFunction([2.0], [0.1, 1.0], delay=0.02)
    path = _results(tmp_path, late, "late.json")
    code, _, err = run(capsys, "export", str(path), "--to", "python", "--out",
                       str(tmp_path / "late.py"))
    assert code == 1 and "delay" in err and "--to mat or --to json" in err
    assert not (tmp_path / "late.py").exists()
    assert run(capsys, "export", str(path), "--to", "json", "--out",
               str(tmp_path / "late_model.json"))[0] == 0
    assert load_model(tmp_path / "late_model.json").delay == 0.02


def test_out_names_the_fix(capsys, tmp_path):
    path = _results(tmp_path, TransferFunction([1.0], [1.0, 1.0]))
    code, _, err = run(capsys, "export", str(path), "--to", "mat", "--out",
                       str(tmp_path / "g.json"))
    assert code == 1 and "--to mat" in err and "g.mat" in err
    assert run(capsys, "export", str(path), "--to", "mat")[0] == 0
    code, _, err = run(capsys, "export", str(path), "--to", "mat")
    assert code == 1 and "--overwrite" in err
    assert run(capsys, "export", str(path), "--to", "mat", "--overwrite")[0] == 0


def test_results_without_a_model(capsys, tmp_path):
    path = tmp_path / "results.json"
    write_json({"servoid_version": "test", "method": "frf", "measured_frf": {}}, path)
    code, out, err = run(capsys, "export", str(path), "--to", "mat", "--json")
    assert code == 1 and "no model to export" in err and "frf" in err
    assert json.loads(out)["type"] == "ModelError"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ('{"model": {}}', "not a results.json"),
        (('{"servoid_version": "x", "model": {"type": "transfer_function", "num": [1], '
          '"den": [0], "dt": null}}'), "damaged"),
        ('{"servoid_version": "x", "model"', "not valid JSON"),
    ],
)
def test_bad_results_files(capsys, tmp_path, text, match):
    path = tmp_path / "results.json"
    path.write_text(text)
    code, _, err = run(capsys, "export", str(path), "--to", "json")
    assert code == 1 and match in err


def test_missing_results_and_bad_usage(capsys, tmp_path):
    code, _, err = run(capsys, "export", str(tmp_path / "nope.json"), "--to", "json")
    assert code == 1 and "no such file" in err
    code, _, err = run(capsys, "export", str(tmp_path / "nope.json"), "--to", "csv")
    assert code == 2 and "mat" in err and "python" in err
    code, out, _ = run(capsys, "export", "--help")
    assert code == 0 and "--to" in out


def _arx(saved):
    return PolynomialModel(saved["a"], tuple(saved["b"]), tuple(saved["nk"]), saved["dt"])


HOSTILE = [
    'x"""; __import__("pathlib").Path("PWNED").write_text("1"); """',
    "x'''; __import__('pathlib').Path('PWNED').write_text('1'); '''",
    'x\\"\\\\"; __import__("pathlib").Path("PWNED").write_text("1") #',
    'x\n__import__("pathlib").Path("PWNED").write_text("1")\n',
    "x\\\n__import__('pathlib').Path('PWNED').write_text('1')",
]


@pytest.mark.parametrize("name", HOSTILE)
def test_python_export_escapes_every_name(capsys, tmp_path, name, monkeypatch):
    """A results file named like code: the script compiles, runs, and runs nothing else."""
    tf = TransferFunction([0.5], [1.0, -0.5], 0.01)
    results = _results(tmp_path, tf, name=f"{name}.json")
    (tmp_path / "results.json").write_bytes(results.read_bytes())
    models = {"G": tf, 'odd"""name\n__import__': tf}  # a model name is escaped the same way
    from servoid.cli._export import _python

    for text in (_python({"G": tf}, results), _python(models, results)):
        compile(text, "exported.py", "exec")
        script = tmp_path / "exported.py"
        script.write_text(text, encoding="utf-8")
        monkeypatch.chdir(tmp_path)
        namespace = runpy.run_path(str(script))
        assert not (tmp_path / "PWNED").exists()
        assert set(namespace["models"]) <= set(models) and namespace["G"].dt == 0.01
        assert namespace["__doc__"].endswith(f"{results.name}; needs python-control.")
    code, _, err = run(capsys, "export", str(results), "--to", "python", "--out",
                       str(tmp_path / "cli.py"))
    assert code == 0, err
    namespace = runpy.run_path(str(tmp_path / "cli.py"))
    assert not (tmp_path / "PWNED").exists() and "G" in namespace


def test_export_never_replaces_its_input(capsys, tmp_path):
    results = _results(tmp_path, TransferFunction([0.5], [1.0, -0.5], 0.01))
    before = results.read_bytes()
    code, _, err = run(capsys, "export", str(results), "--to", "json", "--out", str(results),
                       "--overwrite")
    assert code == 1 and "an input of this export" in err
    assert results.read_bytes() == before


def test_an_empty_out_is_a_usage_error(capsys, tmp_path, monkeypatch):
    results = _results(tmp_path, TransferFunction([0.5], [1.0, -0.5], 0.01))
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    code, _, err = run(capsys, "export", str(results), "--to", "json", "--out", "")
    assert code == 2 and "empty path" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
