"""CSV files as rigs write them: semicolons, decimal commas, time in milliseconds."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import FileFormatError
from servoid.data import load_experiment_spec, read_csv

N = 400


def _write(path, sep=",", comma=False, header="time"):
    t = np.arange(N) * 1.0  # 1 ms steps written as plain numbers
    rows = [f"{a}{sep}{np.sin(a / 9)}{sep}{np.cos(a / 7)}" for a in t]
    if comma:
        rows = [r.replace(".", ",") for r in rows]
    path.write_text(f"{header}{sep}u{sep}y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_semicolon_file_names_the_delimiter(tmp_path):
    path = _write(tmp_path / "a.csv", sep=";")
    with pytest.raises(FileFormatError, match="separated by ';': pass delimiter=';'"):
        read_csv(path)
    assert read_csv(path, delimiter=";", time_unit="ms").n_samples == N


def test_decimal_comma_is_detected_and_read(tmp_path):
    path = _write(tmp_path / "a.csv", sep=";", comma=True)
    with pytest.raises(FileFormatError, match="decimal comma: pass decimal=','"):
        read_csv(path, delimiter=";")
    exp = read_csv(path, delimiter=";", decimal=",", time_unit="ms")
    np.testing.assert_allclose(exp.channel("u").values, np.sin(np.arange(N) / 9), rtol=1e-12)
    with pytest.raises(Exception, match="decimal comma needs another field separator"):
        read_csv(path, decimal=",")


def test_millisecond_time_column_stops_and_time_unit_fixes_it(tmp_path):
    """Whole-number stamps without a unit stop the read (issue 20): 1000× off otherwise."""
    path = _write(tmp_path / "a.csv")
    with pytest.raises(FileFormatError, match=r"has no unit and holds whole numbers stepping by "
                       r"1: likely milliseconds .*give the unit: time_unit='ms'"):
        read_csv(path)
    assert read_csv(path, time_unit="ms").dt == pytest.approx(1e-3)
    assert read_csv(path, time_unit="s").dt == 1.0  # said to be seconds: taken as said
    labelled = _write(tmp_path / "b.csv", header="time [ms]")
    assert read_csv(labelled).dt == pytest.approx(1e-3)  # the header says it; no warning


def test_experiment_file_keys(tmp_path):
    _write(tmp_path / "a.csv", sep=";", comma=True)
    toml = tmp_path / "e.toml"
    base = '[data]\nfile = "a.csv"\n{extra}\n[channels.u]\nrole = "u"\n[channels.y]\nrole = "y"\n'
    toml.write_text(base.format(extra='delimiter = ";"\ndecimal = ","\ntime_unit = "ms"'),
                    encoding="utf-8")
    spec = load_experiment_spec(toml)
    exp = spec.load()
    assert exp.dt == pytest.approx(1e-3) and exp.n_samples == N
    assert spec.to_dict()["data"]["decimal"] == ","
    toml.write_text(base.format(extra=""), encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"set \[data\] delimiter = ';'"):
        load_experiment_spec(toml).load()


def test_csv_keys_are_refused_for_other_formats(tmp_path):
    toml = tmp_path / "e.toml"
    toml.write_text('[data]\nfile = "a.tdms"\ndelimiter = ";"\n[channels.y]\nrole = "y"\n',
                    encoding="utf-8")
    with pytest.raises(FileFormatError, match="delimiter apply to CSV files only"):
        load_experiment_spec(toml)


def test_time_stamp_jitter_tolerance(tmp_path):
    """A logger whose stamps jitter by 0.5 % of the step: refused by default, read with jitter."""
    gen = np.random.default_rng(3)
    t = (np.arange(N) + gen.uniform(-0.005, 0.005, N)) * 1e-3
    rows = [f"{float(a)!r},{np.sin(k / 9)},{np.cos(k / 7)}" for k, a in enumerate(t)]
    (tmp_path / "a.csv").write_text("time,u,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    with pytest.raises(Exception, match=r"pass jitter="):
        read_csv(tmp_path / "a.csv")
    assert read_csv(tmp_path / "a.csv", jitter=0.02).dt == pytest.approx(1e-3, rel=1e-4)
    toml = tmp_path / "e.toml"
    base = '[data]\nfile = "a.csv"\n{extra}\n[channels.u]\nrole = "u"\n[channels.y]\nrole = "y"\n'
    toml.write_text(base.format(extra=""), encoding="utf-8")
    with pytest.raises(Exception, match=r"\[data\] jitter = <fraction of the step>"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra="jitter = 0.02"), encoding="utf-8")
    assert load_experiment_spec(toml).load().n_samples == N
