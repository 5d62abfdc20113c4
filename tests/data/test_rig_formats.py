"""RIG_FORMATS: one record per rig-file format, read by the spec, the benches and the CLI."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from servoid import FileFormatError, OptionError
from servoid.data import (
    FORMATS,
    RIG_FORMATS,
    Experiment,
    RigFormat,
    read_csv,
    read_experiment,
)


def test_the_registry_names_every_format_once_with_its_extensions():
    assert FORMATS == ("csv", "tdms", "mat") == tuple(RIG_FORMATS)
    for name, fmt in RIG_FORMATS.items():
        assert fmt.name == name and RigFormat.named(name) is fmt
        for suffix in fmt.suffixes:
            assert RigFormat.of(f"run{suffix.upper()}") is fmt is RigFormat.find(f"a/b{suffix}")
    assert RigFormat.find("run.xlsx") is None
    assert RigFormat.of("run.dat", "mat").name == "mat"  # an explicit format wins


def test_only_formats_with_a_writer_are_offered_for_writing():
    assert RigFormat.writable() == ("csv", "tdms")
    assert RigFormat.writable(first="tdms") == ("tdms", "csv")  # a bench's default first
    with pytest.raises(OptionError, match=r"first must be one of 'csv', 'tdms'; got 'mat'"):
        RigFormat.writable(first="mat")


@pytest.mark.parametrize("name", RigFormat.writable())
def test_each_writable_format_reads_back_what_it_wrote(tmp_path, name):
    fmt = RigFormat.named(name)
    exp = Experiment.from_arrays(0.001, u=np.sin(np.arange(50.0)), y=np.cos(np.arange(50.0)))
    path = fmt.write(exp, tmp_path / f"run{fmt.suffixes[0]}")
    back = read_experiment(path, time=fmt.time)
    np.testing.assert_array_equal(back["u"], exp["u"])  # exact: CSV writes repr() digits
    assert back.dt == pytest.approx(exp.dt, rel=1e-12)  # one mean step of the time column


def test_the_registry_reads_with_the_formats_reader(tmp_path):
    exp = Experiment.from_arrays(0.01, u=np.arange(8.0), y=np.ones(8))
    path = RIG_FORMATS["csv"].write(exp, tmp_path / "r.csv")
    np.testing.assert_array_equal(RIG_FORMATS["csv"].read(path)["u"], read_csv(path)["u"])


def test_the_keys_of_one_format_are_refused_on_another(tmp_path):
    from servoid.data import ExperimentSpec

    doc = {"data": {"file": "r.mat", "delimiter": ";", "skip_rows": 1},
           "channels": {"y": {"role": "y"}}}
    with pytest.raises(FileFormatError, match=r"delimiter, skip_rows apply to CSV files only, "
                       r"this is mat$"):
        ExperimentSpec.from_dict(doc, base_dir=tmp_path)


def test_the_command_line_lists_the_formats_without_numpy():
    code = ("import sys; from servoid.data import RigFormat; print(RigFormat.writable('tdms'), "
            "'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == ["('tdms',", "'csv')", "False"]


def test_the_experiment_file_page_lists_the_registry():
    from pathlib import Path

    page = Path(__file__).resolve().parents[2] / "docs" / "experiment-file.md"
    rows = {}
    for line in page.read_text(encoding="utf-8").splitlines():
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if len(cells) == 5 and cells[0] in RIG_FORMATS:
            rows[cells[0]] = cells
    assert list(rows) == list(RIG_FORMATS)
    for name, (_, suffixes, writes, keys, bounds) in rows.items():
        fmt = RIG_FORMATS[name]
        assert suffixes.split("`, `") == list(fmt.suffixes)
        assert writes.startswith("yes") == (fmt.writer is not None)
        assert [k for k in keys.split("`, `") if k != "—"] == list(fmt.options)
        assert bounds == fmt.budget
