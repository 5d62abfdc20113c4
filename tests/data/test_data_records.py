"""Separate validation records, estimation sets, sensor limits and reused detrending."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from servoid import ChannelError, Experiment, ExperimentSet, FileFormatError, OptionError
from servoid.data import ExperimentSpec, load_experiment_spec, write_csv, write_experiment_spec

DT = 0.01


def _record(folder: Path, name: str, level: float, n: int = 200, dt: float = DT) -> str:
    rng = np.random.default_rng(len(name))
    exp = Experiment.from_arrays(dt, u=rng.normal(size=n) + level, y=rng.normal(size=n) + 2 * level)
    write_csv(exp, folder / name)
    return name


def _doc(data, validation=None, **extra):
    doc = {"data": {"file": data},
           "channels": {"u": {"role": "u"}, "y": {"role": "y", "unit": "m", "limits": [-5, 5]}},
           "preprocess": {"detrend": "mean"}}
    if validation is not None:
        doc["validation"] = validation
    doc.update(extra)
    return doc


def test_separate_validation_record_reuses_the_estimation_means(tmp_path):
    _record(tmp_path, "est.csv", 1.0)
    _record(tmp_path, "val.csv", 3.0)
    spec = ExperimentSpec.from_dict(_doc("est.csv", {"file": "val.csv", "transient": 5}),
                                    base_dir=tmp_path)
    est, (val,) = spec.records()
    assert isinstance(est, Experiment) and est.n_samples == 200 and val.name == "val"
    raw_est = spec.load(detrend=False)
    raw_val = spec.load(tmp_path / "val.csv", detrend=False)
    # the validation record loses the estimation mean, not its own: its offset survives
    np.testing.assert_allclose(val["y"], raw_val["y"] - raw_est["y"].mean(), atol=1e-12)
    assert abs(val["y"].mean() - 4.0) < 0.3  # 2·(3 − 1) = 4, up to the noise means
    assert spec.validation.transient == 5 and spec.limits("y") == (-5.0, 5.0)


def test_several_estimation_files_make_a_set(tmp_path):
    names = [_record(tmp_path, f"run{k}.csv", float(k)) for k in range(3)]
    spec = ExperimentSpec.from_dict(_doc(names[:2], {"file": [names[2]]}), base_dir=tmp_path)
    est, vals = spec.records()
    assert isinstance(est, ExperimentSet) and len(est) == 2 and len(vals) == 1
    # one mean over both estimation segments, removed from both
    total = np.concatenate([s["u"] for s in est])
    assert abs(total.mean()) < 1e-12  # rounding of the subtraction


def test_split_reuses_the_estimation_half_means(tmp_path):
    rng = np.random.default_rng(0)
    y = np.concatenate([rng.normal(size=100), rng.normal(size=100) + 10.0])
    write_csv(Experiment.from_arrays(DT, u=rng.normal(size=200), y=y), tmp_path / "r.csv")
    spec = ExperimentSpec.from_dict(_doc("r.csv"), base_dir=tmp_path)
    est, val = spec.split_data()
    assert abs(est["y"].mean()) < 1e-12  # the estimation half is centred exactly
    assert abs(val["y"].mean() - 10.0) < 0.5  # the step is kept, not hidden by its own mean


def test_round_trip_through_toml(tmp_path):
    for k in range(3):
        _record(tmp_path, f"run{k}.csv", float(k))
    spec = ExperimentSpec.from_dict(
        _doc(["run0.csv", "run1.csv"], {"file": "run2.csv", "initial": "zero"}),
        base_dir=tmp_path)
    sub = tmp_path / "sub"
    sub.mkdir()
    written = load_experiment_spec(write_experiment_spec(spec, sub / "e.toml"))
    assert written.data_paths[1].resolve() == (tmp_path / "run1.csv").resolve()
    assert written.validation_paths[0].resolve() == (tmp_path / "run2.csv").resolve()
    assert written.validation.initial == "zero" and written.limits("y") == (-5.0, 5.0)


@pytest.mark.parametrize(
    ("doc", "error", "match"),
    [
        (_doc("a.csv", {"file": "b.csv"}, split={"fraction": 0.3}), FileFormatError,
         r"remove \[split\]"),
        (_doc(["a.csv", "b.csv"]), FileFormatError, r"add \[validation\] file"),
        (_doc("a.csv", {"initial": "zero"}), FileFormatError, r"needs file"),
        (_doc("a.csv", {"file": "b.tdms"}), FileFormatError, "written like the estimation"),
        (_doc("a.csv", {"file": "b.csv", "initial": "guess"}), OptionError, "initial"),
        (_doc("a.csv", {"file": "b.csv", "where": 1}), OptionError, "valid keys: file"),
        (_doc([]), FileFormatError, "at least one file"),
    ],
)
def test_schema_errors(doc, error, match):
    with pytest.raises(error, match=match):
        ExperimentSpec.from_dict(doc)


def test_validation_record_at_another_rate_is_refused(tmp_path):
    _record(tmp_path, "est.csv", 0.0)
    _record(tmp_path, "val.csv", 0.0, dt=0.02)
    spec = ExperimentSpec.from_dict(_doc("est.csv", {"file": "val.csv"}), base_dir=tmp_path)
    with pytest.raises(FileFormatError, match="record both at one rate"):
        spec.records()


def test_bad_limits():
    doc = _doc("a.csv")
    doc["channels"]["y"]["limits"] = [1, -1]
    with pytest.raises(FileFormatError, match="low < high"):
        ExperimentSpec.from_dict(doc)


def test_validation_record_without_a_channel_names_it(tmp_path):
    _record(tmp_path, "est.csv", 0.0)
    rng = np.random.default_rng(1)
    write_csv(Experiment.from_arrays(DT, u=rng.normal(size=50), y=rng.normal(size=50),
                                     names={"y": "pos"}), tmp_path / "val.csv")
    spec = ExperimentSpec.from_dict(_doc("est.csv", {"file": "val.csv"}), base_dir=tmp_path)
    with pytest.raises(ChannelError, match=r"channel 'y' .* is not in .*val.csv"):
        spec.records()
