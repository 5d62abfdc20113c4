"""Block-oriented models from the experiment file: rig files in, validated models out.

The rig records are made here with plain numpy (a dead zone written with
numpy.where, the linear block an explicit difference-equation loop, white
noise) and written as CSV; ``servoid identify`` reads them through the
TOML like any rig file.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import DataError, OptionError
from servoid.cli import main
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.workflows import identify

DT = 0.01
LOWER, UPPER = -0.4, 0.6


def _loop(v, b=(0.5, 0.3), f=(-1.2, 0.5)):
    x = np.zeros(v.size)
    for t in range(v.size):
        acc = sum(bj * v[t - 1 - j] for j, bj in enumerate(b) if t - 1 - j >= 0)
        acc -= sum(fi * x[t - i] for i, fi in enumerate(f, start=1) if t - i >= 0)
        x[t] = acc
    return x


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blocks")
    for k, seed in enumerate((21, 22)):
        rng = np.random.default_rng(seed)
        u = rng.uniform(-2.0, 2.0, 2500)
        v = np.where(u > UPPER, u - UPPER, np.where(u < LOWER, u - LOWER, 0.0))
        y = _loop(v) + 0.02 * rng.standard_normal(u.size)
        x = _loop(u, (0.4, 0.2), (-1.1, 0.4))
        w = np.abs(x - 0.3) + 0.02 * rng.standard_normal(u.size)
        exp = Experiment.from_arrays(DT, u=u, y=np.column_stack([y, w]),
                                     names={"y": ["position", "speed"]})
        write_csv(exp, folder / f"run{k}.csv")
    return folder


def _toml(folder, name, identify_table, output="position"):
    table = {"data": {"file": "run0.csv"},
             "channels": {"valve": {"source": "u", "role": "u", "unit": "V"},
                          output: {"source": output, "role": "y", "unit": "mm"}},
             "validation": {"file": "run1.csv"},
             "identify": identify_table}
    path = folder / f"{name}.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_hammerstein_from_the_experiment_file_writes_its_report(rig, tmp_path):
    path = _toml(rig, "ham", {"method": "hammerstein", "input_nonlinearity": "deadzone",
                              "nb": 2, "nf": 2, "nk": 1})
    result = identify(path, tmp_path / "out")
    est = result.estimate
    std = dict(zip(est.names, est.std, strict=True))
    assert abs(est["deadzone.lower"] - LOWER) < 4 * std["deadzone.lower"]  # 4σ
    assert abs(est["deadzone.upper"] - UPPER) < 4 * std["deadzone.upper"]  # 4σ
    # validated on the second file (its own noise, σ = 0.02 on an output of std ≈ 1)
    assert result.validation.experiment and result.validation.fit_percent > 95
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["method"] == "hammerstein"
    assert data["model"]["input_nonlinearity"]["kind"] == "deadzone"
    assert [p["name"] for p in data["estimate"]["parameters"]][:2] == [
        "deadzone.lower", "deadzone.upper"]
    html = (tmp_path / "out" / "report.html").read_text()
    assert "static curve" in html and (tmp_path / "out" / "static.png").exists()
    assert "Hammerstein (deadzone; nb = 2, nf = 2, nk = 1)" in str(result)


def test_wiener_through_the_command_line(rig, tmp_path, capsys):
    path = _toml(rig, "wie", {"method": "wiener", "output_nonlinearity": "abs",
                              "output_parameters": [0.1]}, output="speed")
    code = main(["identify", str(path), "--out", str(tmp_path / "w"), "--json"])
    assert code == 0
    data = json.loads((tmp_path / "w" / "results.json").read_text())
    center = next(p for p in data["estimate"]["parameters"] if p["name"] == "abs.center")
    assert abs(center["value"] - 0.3) < 4 * center["std"]  # 4σ
    assert data["validation"]["fit_percent"] > 90
    capsys.readouterr()


def test_hammerstein_wiener_runs_end_to_end(rig):
    path = _toml(rig, "hw", {"method": "hammerstein-wiener", "input_nonlinearity": "deadzone",
                             "output_nonlinearity": "power"})
    result = identify(path, write=False)
    # g = identity is a power of 1: the fit must find it
    std = dict(zip(result.estimate.names, result.estimate.std, strict=True))
    assert abs(result.estimate["output.power.exponent"] - 1.0) < 4 * std["output.power.exponent"]


@pytest.mark.parametrize(("table", "error", "match"), [
    ({"method": "hammerstein", "input_nonlinearity": "deadband"}, OptionError,
     r"\[identify\] input_nonlinearity"),
    ({"method": "hammerstein", "output_nonlinearity": "abs"}, OptionError, "output_nonlinearity"),
    ({"method": "hammerstein", "input_nonlinearity": "deadzone", "input_parameters": [1.0, -1.0]},
     DataError, r"\[identify\] input_parameters.*wrong order"),
    ({"method": "hammerstein", "input_nonlinearity": "deadzone", "input_parameters": [1.0]},
     DataError, r"\[identify\] input_parameters .* 2 value"),
])
def test_bad_keys_name_the_experiment_file_key(rig, table, error, match):
    with pytest.raises(error, match=match):
        identify(_toml(rig, "bad", table), write=False)


def test_the_documented_example_runs(capsys):
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "block-oriented.md").read_text(encoding="utf-8")
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(code, "docs/block-oriented.md", "exec"), {})  # noqa: S102 - our own docs
    assert "deadzone.lower" in capsys.readouterr().out


def test_measured_initial_conditions_are_refused_in_the_file_words(rig):
    from servoid import ModelError

    path = _toml(rig, "meas", {"method": "hammerstein", "input_nonlinearity": "deadzone"})
    text = path.read_text().replace('file = "run1.csv"', 'file = "run1.csv"\ninitial = "measured"')
    path.write_text(text)
    with pytest.raises(ModelError, match=r"\[validation\] initial"):
        identify(path, write=False)


def test_the_example_folder_runs(tmp_path):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    source = Path(__file__).parents[2] / "examples" / "blocks"
    for name in ("make_data.py", "blocks.toml"):
        shutil.copy(source / name, tmp_path / name)
    done = subprocess.run([sys.executable, "make_data.py"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    result = identify(tmp_path / "blocks.toml", write=False)
    truth = json.loads((tmp_path / "truth.json").read_text())
    est = result.estimate
    std = dict(zip(est.names, est.std, strict=True))
    for name, value in truth.items():
        assert abs(est[name] - value) < 4 * std[name], name  # 4σ
    assert result.truth == truth and "truth -0.4" in str(result)
