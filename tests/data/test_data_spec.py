"""The TOML experiment file: schema, round trip, loading and splitting."""

from __future__ import annotations

import copy
import datetime
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from servoid import ChannelError, Experiment, FileFormatError, OptionError, OutputExistsError
from servoid.data import (
    ExperimentSpec,
    load_experiment_spec,
    write_csv,
    write_experiment_spec,
    write_tdms,
)

DT = 2e-4
N = 4000


def _raw(n: int = N) -> Experiment:
    """Rig channels in volts, as a DAQ records them."""
    k = np.arange(n)
    return Experiment.from_arrays(
        DT,
        side={
            "AI0": 1.0 + np.sin(2 * np.pi * k / 200),
            "AI1": 2.0 + np.cos(2 * np.pi * k / 200),
            "AI2": 0.5 * np.ones(n),
            "AI3": np.linspace(0, 1, n),
        },
        units={"AI0": "V", "AI1": "V", "AI2": "V", "AI3": "V"},
    )


def _doc(file: str = "bench.tdms") -> dict[str, Any]:
    return {
        "data": {"file": file, "group": "Measurements"},
        "channels": {
            "y_r": {"source": "AI0", "role": "r", "gain": 0.0023, "offset": 0.001, "unit": "m"},
            "i_v": {"source": "AI1", "role": "u", "gain": 0.01, "unit": "A"},
            "AI2": {"role": "side"},
        },
        "preprocess": {"detrend": "mean", "decimate": 2},
        "split": {"fraction": 0.5, "period": 100, "skip_periods": 1},
        "loop": {"controller": "P", "kp": 12.5, "feedback": True,
                 "sensor": {"gain": 1.0, "names": ["lvdt", "encoder"]}},
        "identify": {"method": "arx", "na": 3, "nb": 4, "nk": 0, "orders": [1, 2, 3]},
        "report": {"folder": "out dir/with \"quotes\" and \\ back"},
    }


@pytest.fixture
def rig(tmp_path: Path) -> Path:
    write_tdms(_raw(), tmp_path / "bench.tdms", group="Measurements")
    return tmp_path


def test_round_trip_dict_write_load(rig: Path) -> None:
    path = write_experiment_spec(_doc(), rig / "run.toml")
    spec = load_experiment_spec(path)
    assert spec == ExperimentSpec.from_dict(_doc(), base_dir=rig)
    assert spec.format == "tdms" and spec.data_path == rig / "bench.tdms"
    assert [c.name for c in spec.channels] == ["y_r", "i_v", "AI2"]
    assert spec.channels[2].source == "AI2" and spec.channels[1].offset == 0.0
    assert spec.identify["na"] == 3 and spec.loop["sensor"]["names"] == ("lvdt", "encoder")
    assert spec.report["folder"] == _doc()["report"]["folder"]
    with pytest.raises(TypeError):
        spec.identify["na"] = 4  # type: ignore[index]
    # Writing the loaded spec again gives the same spec and the same text.
    again = write_experiment_spec(spec, rig / "again.toml")
    assert load_experiment_spec(again) == spec
    assert again.read_text() == path.read_text()
    assert tomllib.loads(path.read_text())["data"]["file"] == "bench.tdms"


def test_write_elsewhere_keeps_pointing_at_the_rig_file(rig: Path) -> None:
    spec = ExperimentSpec.from_dict(_doc(), base_dir=rig)
    (rig / "sub").mkdir()
    moved = write_experiment_spec(spec, rig / "sub" / "run.toml")
    loaded = load_experiment_spec(moved)
    assert loaded.file == "../bench.tdms"
    assert loaded.data_path.resolve() == (rig / "bench.tdms").resolve()
    assert loaded.load().names == ("y_r", "i_v", "AI2")


def test_quoted_keys_and_minimal_spec(tmp_path: Path) -> None:
    doc = {"data": {"file": "a.csv", "dt": 0.001}, "channels": {"pos x.1": {"source": "a b"}}}
    path = write_experiment_spec(doc, tmp_path / "m.toml")
    assert '[channels."pos x.1"]' in path.read_text()
    spec = load_experiment_spec(path)
    assert spec.channels[0].name == "pos x.1" and spec.channels[0].role == "side"
    assert spec.dt == 0.001 and spec.format == "csv" and dict(spec.loop) == {}
    assert "[preprocess]" not in path.read_text()  # defaults are not written


def test_load_calibrates_selects_and_preprocesses(rig: Path) -> None:
    spec = load_experiment_spec(write_experiment_spec(_doc(), rig / "run.toml"))
    exp = spec.load()
    raw = _raw()
    assert exp.names == ("y_r", "i_v", "AI2")  # AI3 is not listed, so not loaded
    assert [c.role for c in exp.channels] == ["r", "u", "side"]
    assert [c.unit for c in exp.channels] == ["m", "A", "V"]  # AI2 uncalibrated: file unit
    assert exp.dt == 2 * DT and exp.n_samples == N // 2 and exp.name == "run"
    # Detrended r, u: the mean of 2000 samples of order 1e-3 rounds to ~1e-19.
    assert abs(exp["y_r"].mean()) < 1e-15
    # AI2 is constant and a side channel: decimation's unit DC gain keeps 0.5 to rounding.
    np.testing.assert_allclose(exp["AI2"], 0.5, rtol=1e-12)
    # A sine of period 200 raw samples is far below the new Nyquist: decimation keeps it
    # to the FIR's passband ripple (< 0.4 %) away from the edges.
    expected = 0.0023 * np.sin(2 * np.pi * np.arange(0, N, 2) / 200)
    np.testing.assert_allclose(exp["y_r"][50:-50], expected[50:-50], atol=0.004 * 0.0023)
    assert raw.names == ("AI0", "AI1", "AI2", "AI3")


def test_calibration_without_unit_drops_file_unit(rig: Path) -> None:
    doc = {"data": {"file": "bench.tdms"}, "channels": {"y": {"source": "AI0", "gain": 2.0}}}
    exp = ExperimentSpec.from_dict(doc, base_dir=rig).load()
    assert exp.unit("y") == ""  # 2·volts is no longer volts
    np.testing.assert_array_equal(exp["y"], 2.0 * _raw()["AI0"])


def test_split_data(rig: Path) -> None:
    spec = ExperimentSpec.from_dict(_doc(), base_dir=rig)
    est, val = spec.split_data()
    # 2000 samples after decimation, minus 1 skipped period of 100: 1900 -> 900 + 1000.
    assert (est.n_samples, val.n_samples) == (900, 1000)
    assert est.t0 == pytest.approx(100 * 2 * DT, rel=1e-12)  # one period of rounding
    doc = _doc()
    doc["split"] = {"index": 1500}
    est, val = ExperimentSpec.from_dict(doc, base_dir=rig).split_data()
    assert (est.n_samples, val.n_samples) == (1500, 500)
    del doc["split"]
    est, val = ExperimentSpec.from_dict(doc, base_dir=rig).split_data(spec.load())
    assert (est.n_samples, val.n_samples) == (1000, 1000)  # default: halves


def test_csv_and_mat_sources(tmp_path: Path) -> None:
    import scipy.io

    raw = _raw(500)
    write_csv(raw, tmp_path / "bench.csv")
    scipy.io.savemat(tmp_path / "bench.mat", {"t": raw.time, **{n: raw[n] for n in raw.names},
                                              "other": np.ones(3), "kp": 2.0})
    for file, extra in (("bench.csv", {}), ("bench.mat", {"time": "t"})):
        doc = {"data": {"file": file, **extra},
               "channels": {"y": {"source": "AI1", "role": "y"}, "u": {"source": "AI0"}}}
        exp = ExperimentSpec.from_dict(doc, base_dir=tmp_path).load()
        assert exp.names == ("y", "u")
        np.testing.assert_array_equal(exp["y"], raw["AI1"])
        assert exp.dt == pytest.approx(DT, rel=1e-12)  # dt from rounded time stamps


def test_channel_missing_from_file(rig: Path) -> None:
    doc = _doc()
    doc["channels"]["y_p"] = {"source": "AI9", "role": "y"}
    spec = ExperimentSpec.from_dict(doc, base_dir=rig)
    with pytest.raises(
        ChannelError,
        match=r"channel 'AI9' \(servoid channel 'y_p'\) is not in .*bench.tdms group "
        r"'Measurements'; the file has: AI0, AI1, AI2, AI3",
    ):
        spec.load()


def _without(doc: dict, *keys: str) -> dict:
    doc = copy.deepcopy(doc)
    *parents, last = keys
    table = doc
    for k in parents:
        table = table[k]
    del table[last]
    return doc


def _with(doc: dict, value: Any, *keys: str) -> dict:
    doc = copy.deepcopy(doc)
    *parents, last = keys
    table = doc
    for k in parents:
        table = table.setdefault(k, {})
    table[last] = value
    return doc


BASE = _doc()
SCHEMA_ERRORS = [
    (_with(BASE, 1, "extra"), OptionError,
     (r"unknown key\(s\) in the top level: 'extra'; valid keys: data, channels, preprocess, "
     r"split, validation, rig, loop, acceptance, identify, report")),
    (_without(BASE, "data"), FileFormatError,
     r"the top level is missing the required key\(s\) data"),
    (_without(BASE, "channels"), FileFormatError, r"missing the required key\(s\) channels"),
    (_without(BASE, "data", "file"), FileFormatError,
     r"\[data\] is missing the required key\(s\) file"),
    (_with(BASE, 1, "data", "path"), OptionError,
     r"unknown key\(s\) in \[data\]: 'path'; valid keys: file, format, group, time, dt"),
    (_with(BASE, "", "data", "file"), FileFormatError,
     r"\[data\] file must be a non-empty string"),
    (_with(BASE, "xls", "data", "format"), OptionError,
     r"\[data\] format must be one of 'csv', 'tdms', 'mat'; got 'xls'"),
    (_with(_without(BASE, "data", "group"), "bench.dat", "data", "file"), OptionError,
     r"cannot tell the format of 'bench.dat'"),
    (_with(_with(BASE, "a.csv", "data", "file"), "g", "data", "group"), FileFormatError,
     r"group applies to TDMS files only"),
    (_with(BASE, 0.0, "data", "dt"), FileFormatError, r"\[data\] dt must be > 0, got 0.0"),
    (_with(BASE, "1e-3", "data", "dt"), FileFormatError, r"dt must be a finite number, got str"),
    (_with(BASE, 5, "data", "time"), FileFormatError,
     r"time must be a non-empty string, got int"),
    (_with(BASE, {}, "channels"), FileFormatError, r"\[channels\] must hold at least one table"),
    (_with(BASE, 3, "channels", "y"), FileFormatError,
     r"\[channels.y\] must be a table, got int"),
    (_with(BASE, 1.0, "channels", "y_r", "scale"), OptionError,
     (r"unknown key\(s\) in \[channels.y_r\]: 'scale'; "
     r"valid keys: source, role, gain, offset, unit")),
    (_with(BASE, "x", "channels", "y_r", "role"), OptionError,
     r"\[channels.y_r\] role must be one of 'r', 'u', 'y', 'side'; got 'x'"),
    (_with(BASE, 0, "channels", "y_r", "gain"), FileFormatError, r"gain must be non-zero"),
    (_with(BASE, True, "channels", "y_r", "gain"), FileFormatError,
     r"gain must be a finite number, got bool"),
    (_with(BASE, float("nan"), "channels", "y_r", "offset"), FileFormatError,
     r"offset must be a finite number"),
    (_with(BASE, 1, "channels", "y_r", "unit"), FileFormatError, r"unit must be a string"),
    (_with(BASE, 1, "preprocess", "filter"), OptionError,
     r"unknown key\(s\) in \[preprocess\]: 'filter'; valid keys: lowpass, decimate, detrend"),
    (_with(BASE, "cubic", "preprocess", "detrend"), OptionError,
     r"detrend must be one of 'none', 'mean', 'linear'; got 'cubic'"),
    (_with(BASE, -5.0, "preprocess", "lowpass"), FileFormatError, r"lowpass must be > 0"),
    (_with(BASE, 2.5, "preprocess", "decimate"), FileFormatError,
     r"decimate must be an integer >= 1, got float"),
    (_with(BASE, 100, "split", "index"), FileFormatError, r"give fraction or index, not both"),
    (_with(BASE, 1.5, "split", "fraction"), FileFormatError, r"fraction must lie in \(0, 1\)"),
    (_with(BASE, 1, "split", "period"), FileFormatError, r"period must be an integer >= 2"),
    (_with(_without(BASE, "split", "period"), 2, "split", "skip_periods"), FileFormatError,
     r"skip_periods needs period"),
    (_with(BASE, 1, "split", "at"), OptionError, r"unknown key\(s\) in \[split\]: 'at'"),
    (_with(BASE, 3, "loop"), FileFormatError, r"\[loop\] must be a table, got int"),
    (_with(BASE, {"b": {"c": 1}}, "loop", "a"), FileFormatError,
     r"\[loop.a\]: table 'b' is nested more than one level deep"),
    (_with(BASE, datetime.date(2024, 1, 1), "report", "date"), FileFormatError,
     r"\[report\] date: unsupported value date"),
    (_with(BASE, [[1, 2]], "identify", "grid"), FileFormatError,
     r"arrays may hold only strings, numbers and booleans"),
]


@pytest.mark.parametrize(("doc", "error", "message"), SCHEMA_ERRORS)
def test_schema_errors(tmp_path: Path, doc: dict, error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        ExperimentSpec.from_dict(doc, base_dir=tmp_path)
    with pytest.raises(error, match=message):  # the writer validates before writing
        write_experiment_spec(doc, tmp_path / "x.toml")
    assert not (tmp_path / "x.toml").exists()


def test_schema_error_names_the_toml_file(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text('[data]\nfile = "b.tdms"\nfiel = 1\n[channels.y]\n')
    with pytest.raises(OptionError, match=r"run.toml: unknown key\(s\) in \[data\]: 'fiel'"):
        load_experiment_spec(path)


@pytest.mark.parametrize("text", ['[data\nfile = "x"', "[data]\nfile = \n", "\x00\x01"])
def test_not_toml(tmp_path: Path, text: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=r"bad.toml: not a valid TOML file \(.*line"):
        load_experiment_spec(path)


def test_existing_toml_is_refused_and_kept(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text("keep me")
    with pytest.raises(OutputExistsError):
        write_experiment_spec(_doc(), path)
    assert path.read_text() == "keep me"
    write_experiment_spec(_doc(), path, overwrite=True)
    assert load_experiment_spec(path) == ExperimentSpec.from_dict(_doc(), base_dir=tmp_path)
