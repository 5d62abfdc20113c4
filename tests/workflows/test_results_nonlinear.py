"""A nonlinear run read back: load_results and servoid export for narx and block models."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as sps

import servoid
from servoid import FileFormatError
from servoid.cli import main
from servoid.data import Experiment
from servoid.nonlinear import BlockModel, NarxModel
from servoid.validate import validate
from servoid.workflows import identify

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _narx_record(n: int, seed: int) -> Experiment:
    """The example's system from a plain loop, on a seed the run never saw."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, n)
    e = 0.02 * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = (0.6 * y[t - 1] - 0.15 * y[t - 2] + 0.8 * u[t - 1] + 0.3 * u[t - 2]
                - 0.25 * y[t - 1] * u[t - 1] + 0.2 * u[t - 1] ** 2 + e[t])
    return Experiment.from_arrays(0.01, u=u, y=y, names={"u": "valve", "y": "position"},
                                  units={"valve": "V", "position": "mm"})


def _block_record(n: int, seed: int) -> Experiment:
    """The block example's valve (dead band −0.4 … 0.6 V) and axis, through lfilter."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, n)
    v = np.where(u > 0.6, u - 0.6, np.where(u < -0.4, u + 0.4, 0.0))
    x = sps.lfilter([0.0, 0.5, 0.3], [1.0, -1.2, 0.5], v)
    return Experiment.from_arrays(0.01, u=u, y=x + 0.02 * rng.standard_normal(n),
                                  names={"u": "valve", "y": "position"})


@pytest.fixture(scope="module")
def narx_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("narx")
    for name in ("narx.toml", "narx_run1.csv", "narx_run2.csv", "truth.json"):
        shutil.copy(EXAMPLES / "narx" / name, folder / name)
    result = identify(folder / "narx.toml", folder / "run")
    return result, folder / "run" / "results.json"


@pytest.fixture(scope="module")
def block_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blocks")
    for name in ("blocks.toml", "make_data.py"):
        shutil.copy(EXAMPLES / "blocks" / name, folder / name)
    done = subprocess.run([sys.executable, "make_data.py"], cwd=folder, capture_output=True,
                          text=True, check=False, timeout=120)
    assert done.returncode == 0, done.stderr
    result = identify(folder / "blocks.toml", folder / "run")
    return result, folder / "run" / "results.json"


def test_load_results_gives_the_narx_model_that_validates_on_a_new_record(narx_run):
    result, path = narx_run
    loaded = servoid.load_results(path)
    model, fitted = loaded.models["G"], result.estimate.model
    assert isinstance(model, NarxModel) and set(loaded.models) == {"G"}
    assert model.terms == fitted.terms
    assert np.array_equal(model.coefficients, fitted.coefficients)  # repr floats in JSON
    assert np.array_equal(model.covariance, fitted.covariance)
    assert (model.input_names, model.output_name) == (("valve",), "position")
    assert (model.input_units, model.output_unit) == (("V",), "mm")
    new = _narx_record(2000, 7)
    report = validate(model, new)
    assert report.fit_percent == validate(result.estimate, new).fit_percent
    assert report.fit_percent > 90.0  # the true structure on a fresh record (noise σ 0.02)


def test_load_results_gives_the_block_model_that_validates_on_a_new_record(block_run):
    result, path = block_run
    model, fitted = servoid.load_results(path).models["G"], result.estimate.model
    assert isinstance(model, BlockModel) and model.structure == "hammerstein"
    assert np.array_equal(model.input_nonlinearity.parameters,
                          fitted.input_nonlinearity.parameters)
    assert np.array_equal(model.linear.b[0], fitted.linear.b[0])
    assert np.array_equal(model.linear.f[0], fitted.linear.f[0])
    new = _block_record(2000, 11)
    report = validate(model, new)
    assert report.fit_percent == validate(result.estimate, new).fit_percent
    assert report.fit_percent > 90.0  # the true structure on a fresh record (noise σ 0.02)


@pytest.mark.parametrize("which", ["narx_run", "block_run"])
def test_export_to_json_writes_a_model_file_with_its_covariance(which, request, tmp_path,
                                                                capsys):
    result, path = request.getfixturevalue(which)
    out = tmp_path / "model.json"
    assert main(["export", str(path), "--to", "json", "--out", str(out)]) == 0
    capsys.readouterr()
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["type"] == type(result.estimate.model).__name__
    assert np.array_equal(np.array(data["covariance"]), result.estimate.covariance)
    back = servoid.load_model(out)
    original = result.estimate.model
    new = _narx_record(800, 3) if which == "narx_run" else _block_record(800, 3)
    u, y = new.u, new.y[:, 0]
    assert np.array_equal(back.replay(y, u)[0], original.replay(y, u)[0])


@pytest.mark.parametrize("to", ["mat", "python"])
def test_export_to_mat_or_python_names_json(narx_run, to, tmp_path, capsys):
    _, path = narx_run
    out = tmp_path / ("m.mat" if to == "mat" else "m.py")
    assert main(["export", str(path), "--to", to, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "nonlinear model (NarxModel)" in err and "use --to json" in err
    assert not out.exists()


def test_an_older_results_file_without_units_or_covariance_still_loads(narx_run, tmp_path):
    _, path = narx_run
    data = json.loads(path.read_text(encoding="utf-8"))
    for key in ("covariance", "output_unit", "input_units"):
        del data["model"][key]
    old = tmp_path / "results.json"
    old.write_text(json.dumps(data), encoding="utf-8")
    model = servoid.load_results(old).models["G"]
    assert model.covariance is None and model.output_unit == ""
    assert np.isfinite(validate(model, _narx_record(600, 5)).fit_percent)


@pytest.mark.parametrize(
    ("which", "change", "match"),
    [
        ("narx_run", {"coefficients": [1.0]}, "model is not a valid NarxModel"),
        ("block_run", {"input_nonlinearity": {"kind": "deadzone", "parameters": {"x": 1}}},
         "model.input_nonlinearity is not a valid static block"),
        ("block_run", {"linear": None}, "model is not a valid BlockModel"),
    ],
)
def test_a_damaged_model_entry_is_refused(which, change, match, request, tmp_path):
    _, path = request.getfixturevalue(which)
    data = json.loads(path.read_text(encoding="utf-8"))
    data["model"].update(change)
    bad = tmp_path / "results.json"
    bad.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(FileFormatError, match=match):
        servoid.load_results(bad)
