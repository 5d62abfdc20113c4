"""Nonlinear models in model files: NARX and block models saved today, replayed tomorrow."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as sps

from servoid import DataError, FileFormatError, ModelError
from servoid.data import Experiment
from servoid.models import PolynomialModel, TransferFunction, export_mat, load_model, save_model
from servoid.nonlinear import (
    AbsoluteValue,
    BlockModel,
    DeadZone,
    NarxModel,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    SignedPower,
    StaticFunction,
    fit_hammerstein,
    fit_narx,
    fit_wiener,
)
from servoid.validate import validate

DOCS = Path(__file__).resolve().parents[2] / "docs"


# -- records from generators the estimators do not share (plain loops, scipy's lfilter) -------


def _narx_record(n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, n)
    e = 0.02 * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = (0.6 * y[t - 1] - 0.15 * y[t - 2] + 0.8 * u[t - 1] + 0.3 * u[t - 2]
                - 0.25 * y[t - 1] * u[t - 1] + 0.2 * u[t - 1] ** 2 + e[t])
    return Experiment.from_arrays(0.01, u=u, y=y, names={"u": "valve", "y": "position"},
                                  units={"valve": "V", "position": "mm"})


def _hammerstein_record(n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, n)
    v = np.where(u > 0.6, u - 0.6, np.where(u < -0.4, u + 0.4, 0.0))  # dead band
    x = sps.lfilter([0.0, 0.5, 0.3], [1.0, -1.2, 0.5], v)
    return Experiment.from_arrays(0.01, u=u, y=x + 0.02 * rng.standard_normal(n))


def _wiener_record(n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, n)
    x = sps.lfilter([0.0, 0.4, 0.2], [1.0, -1.1, 0.4], u)
    speed = np.abs(x - 0.3)  # a sensor that reads magnitude only
    return Experiment.from_arrays(0.01, u=u, y=speed + 0.02 * rng.standard_normal(n))


@pytest.fixture(scope="module")
def fitted():
    """Each model fitted on one record, with a second record it never saw."""
    return {
        "narx": (fit_narx(_narx_record(2000, 1), na=2, nb=2, degree=2),
                 _narx_record(1500, 2)),
        "hammerstein": (fit_hammerstein(_hammerstein_record(2000, 3), "deadzone"),
                        _hammerstein_record(1500, 4)),
        "wiener": (fit_wiener(_wiener_record(2000, 5), "abs"), _wiener_record(1500, 6)),
    }


def _same_shape(a, b):
    if a is None or b is None:
        assert a is b
        return
    assert type(a) is type(b)
    assert np.array_equal(a.parameters, b.parameters)  # bit for bit: repr floats in JSON
    assert getattr(a, "breakpoints", None) == getattr(b, "breakpoints", None)


def _same_linear(a, b):
    assert type(a) is type(b) and a.dt == b.dt
    if isinstance(a, TransferFunction):
        assert np.array_equal(a.num, b.num) and np.array_equal(a.den, b.den)
    else:
        assert a.nk == b.nk
        assert all(np.array_equal(p, q) for p, q in zip(a.b, b.b, strict=True))
        assert all(np.array_equal(p, q) for p, q in zip(a.f, b.f, strict=True))


def _same(a, b):
    assert type(a) is type(b) and a.dt == b.dt
    if isinstance(a, NarxModel):
        assert a.terms == b.terms
        assert np.array_equal(a.coefficients, b.coefficients)
        assert (a.covariance is None and b.covariance is None) or np.array_equal(
            a.covariance, b.covariance)
        for name in ("noise_variance", "input_names", "output_name", "output_unit",
                     "input_units"):
            assert getattr(a, name) == getattr(b, name), name
    else:
        assert a.structure == b.structure and a.offset == b.offset
        _same_shape(a.input_nonlinearity, b.input_nonlinearity)
        _same_shape(a.output_nonlinearity, b.output_nonlinearity)
        _same_linear(a.linear, b.linear)


# -- fitted models: save, load, replay ------------------------------------------------------


@pytest.mark.parametrize("name", ["narx", "hammerstein", "wiener"])
def test_fitted_model_round_trip_replays_identically(fitted, tmp_path, name):
    est, other = fitted[name]
    path = save_model(est.model, tmp_path / f"{name}.json")
    back = load_model(path)
    _same(est.model, back)
    u, y = other.u, other.y[:, 0]
    # the same floats through the same code: the replays agree to the last bit, initial
    # state fit included (a deterministic least squares on identical inputs)
    first, again = est.model.replay(y, u), back.replay(y, u)
    assert np.array_equal(first[0], again[0]) and first[1:] == again[1:]
    before, after = validate(est, other), validate(back, other)
    assert after.fit_percent == before.fit_percent
    # and the model is the system's, not a trivial one that replays the same: the free run
    # of the true structure on a fresh record explains most of it (noise is 1–2 % of range)
    assert after.fit_percent > 90.0


def test_narx_file_keeps_names_units_and_covariance(fitted, tmp_path):
    est, _ = fitted["narx"]
    path = save_model(est, tmp_path / "narx.json")  # from the Estimate: names of parameters
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["type"] == "NarxModel" and data["servoid_model"] == 1
    assert data["input_names"] == ["valve"] and data["output_name"] == "position"
    assert data["input_units"] == ["V"] and data["output_unit"] == "mm"
    assert data["term_names"] == list(est.names) == data["parameter_names"]
    back = load_model(path)
    assert np.array_equal(back.covariance, est.covariance)
    assert back.names == est.model.names


def test_block_file_keeps_the_estimates_covariance(fitted, tmp_path):
    est, _ = fitted["hammerstein"]
    path = save_model(est, tmp_path / "h.json", units={"u": "V", "y": "mm"})
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["type"] == "BlockModel" and data["structure"] == "hammerstein"
    assert data["input_nonlinearity"]["kind"] == "deadzone"
    assert data["linear"]["type"] == "PolynomialModel"
    assert data["parameter_names"] == list(est.names)
    assert np.array_equal(np.array(data["covariance"]), est.covariance)
    assert data["units"] == {"u": "V", "y": "mm"}
    # a model alone has no covariance of its own: the file then holds none
    data = json.loads(save_model(est.model, tmp_path / "bare.json").read_text(encoding="utf-8"))
    assert data["covariance"] is None and "parameter_names" not in data


# -- every shape and both linear blocks, built by hand --------------------------------------

OE = PolynomialModel([1.0], ([0.5, 0.3],), (1,), 0.01, f=([1.0, -1.2, 0.5],))
CONTINUOUS = TransferFunction([2.0], [0.05, 1.0])
BLOCKS = {
    "hammerstein saturation": BlockModel("hammerstein", OE, 0.01,
                                         input_nonlinearity=Saturation(-1.0, 0.75)),
    "hammerstein power": BlockModel("hammerstein", OE, 0.01,
                                    input_nonlinearity=SignedPower(0.5)),
    "wiener polynomial, continuous": BlockModel(
        "wiener", CONTINUOUS, 0.01, output_nonlinearity=Polynomial([1.0, 0.1, -1 / 3]),
        offset=0.125),
    "hammerstein-wiener pwl/abs": BlockModel(
        "hammerstein-wiener", OE, 0.01,
        input_nonlinearity=PiecewiseLinear([-0.5, 0.1, 0.7], [0.3, 1.0, 1.7, 0.2]),
        output_nonlinearity=AbsoluteValue(0.1)),
    "hammerstein-wiener deadzone/pwl": BlockModel(
        "hammerstein-wiener", CONTINUOUS, 0.01, input_nonlinearity=DeadZone(-0.1, 0.2),
        output_nonlinearity=PiecewiseLinear([0.0], [0.5, 2.0])),
}


@pytest.mark.parametrize("model", BLOCKS.values(), ids=BLOCKS.keys())
def test_every_shape_round_trips(tmp_path, model):
    back = load_model(save_model(model, tmp_path / "b.json"))
    _same(model, back)
    u = np.sin(np.linspace(0.0, 20.0, 300)) * 1.5
    assert np.array_equal(model.simulate(u), back.simulate(u))


def test_a_user_function_cannot_be_saved(tmp_path):
    shape = StaticFunction(lambda x, th: th[0] * np.tanh(x), [2.0])
    model = BlockModel("hammerstein", OE, 0.01, input_nonlinearity=shape)
    with pytest.raises(ModelError, match=r"user StaticFunction cannot be written.*numbers, not "
                                         r"Python code.*save_model\(model\.linear"):
        save_model(model, tmp_path / "f.json")
    assert not list(tmp_path.iterdir())  # nothing half written


def test_export_mat_refuses_a_nonlinear_model(fitted, tmp_path):
    with pytest.raises(ModelError, match=r"NarxModel has no MATLAB form.*save_model.*--to json"):
        export_mat(fitted["narx"][0].model, tmp_path / "n.mat")
    assert not list(tmp_path.iterdir())


def test_a_covariance_that_does_not_fit_the_model_is_refused(fitted, tmp_path):
    with pytest.raises(DataError, match=r"covariance must have shape \(6, 6\)"):
        save_model(fitted["narx"][0].model, tmp_path / "n.json", covariance=np.eye(2))
    assert not list(tmp_path.iterdir())


# -- files servoid cannot read ---------------------------------------------------------------


@pytest.mark.parametrize("model", [BLOCKS["hammerstein-wiener pwl/abs"],
                                   NarxModel([((0, 1),), ((1, 1),)], [0.5, 1.0], 0.1)],
                         ids=["block", "narx"])
def test_a_newer_version_or_an_unknown_type_is_refused(tmp_path, model):
    path = save_model(model, tmp_path / "m.json")
    data = json.loads(path.read_text(encoding="utf-8"))
    path.write_text(json.dumps({**data, "servoid_model": 2}), encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"m\.json has format version 2.*reads version 1"):
        load_model(path)
    path.write_text(json.dumps({**data, "type": "VolterraModel"}), encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"must be one of .*'NarxModel', 'BlockModel', "
                                              r"'PnlssModel', 'OdeModel', got 'VolterraModel'"
                                              r".*does not know"):
        load_model(path)


NARX = NarxModel([((0, 1),), ((1, 1),)], [0.5, 1.0], 0.1)


@pytest.mark.parametrize(
    ("model", "change", "match"),
    [
        (NARX, {"terms": None}, "NarxModel is damaged.*terms"),
        (NARX, {"coefficients": [0.5]}, "damaged.*one value per term"),
        (NARX, {"terms": [[[0, 0]]], "coefficients": [1.0]}, "damaged.*lag"),
        (NARX, {"covariance": [[1.0]]}, r"damaged.*covariance must have shape \(2, 2\)"),
        (NARX, {"dt": 0.0}, "damaged.*dt"),
        (BLOCKS["hammerstein saturation"], {"structure": "hammer"}, "damaged.*structure"),
        (BLOCKS["hammerstein saturation"],
         {"input_nonlinearity": {"kind": "saturation", "parameters": {"a": 0.0, "b": 1.0}}},
         r"damaged.*named \['saturation.lower', 'saturation.upper'\]"),
        (BLOCKS["hammerstein saturation"],
         {"input_nonlinearity": {"kind": "saturation",
                                 "parameters": {"saturation.lower": 1.0,
                                                "saturation.upper": 0.0}}},
         "damaged.*wrong order"),
        (BLOCKS["hammerstein saturation"],
         {"input_nonlinearity": {"kind": "function", "parameters": {"f.theta0": 1.0}}},
         "damaged.*user StaticFunction"),
        (BLOCKS["hammerstein saturation"], {"linear": {"a": 1}},
         "damaged.*the linear block is not a servoid model file"),
        (BLOCKS["hammerstein saturation"], {"output_nonlinearity": {"kind": "abs",
                                                                    "parameters": {}}},
         "damaged.*abs has 1 parameter"),
    ],
)
def test_damaged_nonlinear_files_are_refused(tmp_path, model, change, match):
    path = save_model(model, tmp_path / "m.json")
    path.write_text(json.dumps({**json.loads(path.read_text(encoding="utf-8")), **change}),
                    encoding="utf-8")
    with pytest.raises(FileFormatError, match=match):
        load_model(path)


def test_a_missing_key_is_named(tmp_path):
    path = save_model(BLOCKS["hammerstein power"], tmp_path / "m.json")
    data = json.loads(path.read_text(encoding="utf-8"))
    del data["linear"]
    path.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(FileFormatError, match="BlockModel has no 'linear'"):
        load_model(path)


# -- packaging: models stays free of nonlinear until a nonlinear file is read ---------------


def test_models_does_not_import_nonlinear():
    code = ("import sys, servoid.models; print('servoid.nonlinear' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=120)
    assert done.stdout.strip() == "False"


# -- the documented examples run -------------------------------------------------------------


@pytest.mark.parametrize("doc", ["narx.md", "block-oriented.md"])
def test_the_documented_save_and_replay_runs(doc, tmp_path, monkeypatch, capsys):
    text = (DOCS / doc).read_text(encoding="utf-8")
    section = text.split("## Save the model and replay it on a new record", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)  # the example writes its model file here
    exec(compile(code, f"docs/{doc}", "exec"), {})  # noqa: S102 - our own docs
    out = capsys.readouterr().out
    assert "same fit: True" in out


def test_an_estimate_with_an_undetermined_parameter_is_saved_without_covariance(tmp_path):
    from servoid import ServoidWarning
    from servoid.estimate import Estimate

    est = Estimate(model=CONTINUOUS, parameters=np.array([2.0, 0.05]), names=("K", "T"),
                   covariance=np.array([[np.nan, 0.0], [0.0, 1e-4]]), noise_variance=0.1,
                   n_samples=100, method="tf")
    with pytest.warns(ServoidWarning, match="non-finite.*written without it"):
        path = save_model(est, tmp_path / "g.json")
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["covariance"] is None and data["parameter_names"] == ["K", "T"]
    finite = Estimate(model=CONTINUOUS, parameters=np.array([2.0, 0.05]), names=("K", "T"),
                      covariance=np.diag([0.01, 1e-4]), noise_variance=0.1, n_samples=100,
                      method="tf")
    data = json.loads(save_model(finite, tmp_path / "h.json").read_text(encoding="utf-8"))
    assert data["covariance"] == [[0.01, 0.0], [0.0, 1e-4]]
