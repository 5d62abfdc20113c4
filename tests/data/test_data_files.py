"""Rig files: CSV, TDMS and MAT round trips, dispatch and malformed input."""

from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from servoid import (
    ChannelError,
    DataError,
    Experiment,
    FileFormatError,
    OptionError,
    OutputExistsError,
)
from servoid.data import (
    read_csv,
    read_experiment,
    read_mat,
    read_tdms,
    write_csv,
    write_tdms,
)


def _bench(n: int = 200, dt: float = 2e-4, t0: float = 0.0) -> Experiment:
    rng = np.random.default_rng(1)
    return Experiment.from_arrays(
        dt,
        r=rng.standard_normal(n) * 1e-3,
        u=np.sin(np.arange(n) / 7.0) / 3.0,
        y=rng.standard_normal(n) * 1e5,
        side={"p_A": 1e5 + rng.standard_normal(n)},
        names={"r": "y_r", "u": "i_v", "y": "y_p"},
        units={"y_r": "m", "i_v": "A", "y_p": "m", "p_A": "Pa"},
        t0=t0,
        name="bench",
    )


def _same_signals(a: Experiment, b: Experiment) -> None:
    assert a.names == b.names
    assert [c.unit for c in a.channels] == [c.unit for c in b.channels]
    for name in a.names:
        np.testing.assert_array_equal(a[name], b[name])


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


ROLES = {"r": ["y_r"], "u": ["i_v"], "y": ["y_p"]}

# -- CSV -------------------------------------------------------------------------------------


def test_csv_round_trip(tmp_path: Path) -> None:
    exp = _bench(t0=1.5)
    path = write_csv(exp, tmp_path / "run.csv")
    assert path.read_text().splitlines()[0] == "time [s],y_r [m],i_v [A],y_p [m],p_A [Pa]"
    back = read_csv(path, roles=ROLES)
    _same_signals(exp, back)
    assert [c.role for c in back.channels] == [c.role for c in exp.channels]
    # dt is recomputed from the written stamps t0 + k·dt: equal up to their rounding.
    assert back.dt == pytest.approx(exp.dt, rel=1e-12)
    assert back.t0 == exp.t0 and back.name == "run"


def test_csv_without_time_column(tmp_path: Path) -> None:
    exp = _bench()
    path = write_csv(exp, tmp_path / "run.csv", time=False)
    with pytest.raises(DataError, match=r"no column 'time'; pass dt \[s\]"):
        read_csv(path)
    back = read_csv(path, dt=exp.dt, time=None)
    _same_signals(exp, back)
    assert back.dt == exp.dt and back.t0 == 0.0
    assert set(back.names_of("side")) == set(exp.names)  # unmapped columns are side channels


def test_csv_time_column_other_name_and_ms(tmp_path: Path) -> None:
    path = tmp_path / "a.csv"
    path.write_text("t [ms];pos [mm]\n0;1.5\n2;1.6\n4;1.7\n")
    exp = read_csv(path, time="t", delimiter=";", roles={"y": "pos"})
    # 0.002 s from stamps in ms: one division and one product of rounding.
    assert exp.dt == pytest.approx(0.002, rel=1e-15)
    assert exp.names_of("y") == ("pos",) and exp.unit("pos") == "mm"


def test_csv_roles_errors(tmp_path: Path) -> None:
    path = write_csv(_bench(), tmp_path / "run.csv")
    with pytest.raises(ChannelError, match=r"'x' \(role 'y'\) is not in .*run.csv; the file has: "
                       r"y_r, i_v, y_p, p_A"):
        read_csv(path, roles={"y": ["x"]})
    with pytest.raises(OptionError, match="role must be one of"):
        read_csv(path, roles={"q": ["y_r"]})


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", r"empty CSV file"),
        ("a,b\n", r"header but no data rows"),
        ("a,b\n1,2\n3,4\n5", (r"line 4: 1 field\(s\), the header has 2 \(the last line, with no "
         r"line end: the file looks truncated")),
        ("a,b\n1,2\n3\n5,6\n", r"line 3: 1 field\(s\), the header has 2 \(truncated line\?\)"),
        ("a,b\n1,2\n3,4,5\n", r"line 3: 3 field\(s\), the header has 2"),
        ("a,b\n1,2\n3,x\n", r"line 3, column 2: 'x' is not a number"),
        ("1,2\n3,4\n", r"the first row holds numbers"),
        ("a,a\n1,2\n3,4\n", r"channel name 'a' is repeated"),
        ("a,,c\n1,2,3\n4,5,6\n", r"line 1, column 2: empty channel name"),
        ("time [h],a\n0,1\n1,2\n", r"time column 'time' has unit 'h'"),
    ],
)
def test_csv_malformed(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    digest = _digest(path)
    with pytest.raises(FileFormatError, match=message) as info:
        read_csv(path, dt=0.1)
    assert "bad.csv" in str(info.value)
    assert _digest(path) == digest  # reading never modifies the file


def test_csv_binary_garbage(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(bytes(range(128, 256)) * 4)
    with pytest.raises(FileFormatError, match="bad.csv: not a text CSV file"):
        read_csv(path, dt=0.1)


def test_csv_nan_cell_is_data_error(tmp_path: Path) -> None:
    path = tmp_path / "nan.csv"
    path.write_text("a\n1\nnan\n3\n")
    with pytest.raises(DataError, match=r"nan.csv: channel 'a' has 1 non-finite"):
        read_csv(path, dt=0.1)


def test_csv_comments_and_blank_lines(tmp_path: Path) -> None:
    path = tmp_path / "c.csv"
    path.write_text("# rig 7\n\na [V]\n1\n\n# pause\n2\n")
    exp = read_csv(path, dt=0.5)
    np.testing.assert_array_equal(exp["a"], [1.0, 2.0])


# -- TDMS ------------------------------------------------------------------------------------


def test_tdms_round_trip(tmp_path: Path) -> None:
    exp = _bench(t0=0.25)
    exp = Experiment(exp.channels, exp.dt, t0=exp.t0, notes={"kp": 12.5, "rig": "B7"})
    path = write_tdms(exp, tmp_path / "run.tdms", group="Measurements")
    back = read_tdms(path)
    _same_signals(exp, back)
    assert [c.role for c in back.channels] == [c.role for c in exp.channels]  # servoid_role
    assert back.dt == exp.dt and back.t0 == exp.t0  # stored as float64 properties: exact
    assert back.notes == {"kp": 12.5, "rig": "B7"}
    mapped = read_tdms(path, group="Measurements", roles={"y": ["p_A"]})
    assert mapped.names_of("y") == ("p_A",) and mapped.names_of("r") == ()


def _tdms_file(path: Path, channels: dict[str, tuple[np.ndarray, dict]], groups=("g",)) -> Path:
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    with TdmsWriter(str(path)) as w:
        objs: list = [GroupObject(g) for g in groups]
        objs += [ChannelObject(groups[0], n, v, properties=p) for n, (v, p) in channels.items()]
        w.write_segment(objs)
    return path


def test_tdms_group_choice(tmp_path: Path) -> None:
    path = _tdms_file(tmp_path / "two.tdms", {"a": (np.ones(5), {"wf_increment": 0.1})},
                      groups=("g", "h"))
    with pytest.raises(OptionError, match=r"has 2 groups; pass group= one of: 'g', 'h'"):
        read_tdms(path)
    with pytest.raises(OptionError, match=r"has no group 'x'; it has: 'g', 'h'"):
        read_tdms(path, group="x")
    assert read_tdms(path, group="g").dt == 0.1


def test_tdms_timing_errors(tmp_path: Path) -> None:
    mixed = _tdms_file(tmp_path / "m.tdms", {
        "a": (np.ones(5), {"wf_increment": 0.1}), "b": (np.ones(5), {"wf_increment": 0.2})})
    with pytest.raises(FileFormatError, match="share one wf_increment.*a: 0.1, b: 0.2"):
        read_tdms(mixed)
    ragged = _tdms_file(tmp_path / "r.tdms", {
        "a": (np.ones(5), {"wf_increment": 0.1}), "b": (np.ones(4), {"wf_increment": 0.1})})
    with pytest.raises(FileFormatError, match=r"different lengths \(a: 5, b: 4\)"):
        read_tdms(ragged)
    bare = _tdms_file(tmp_path / "b.tdms", {"a": (np.arange(5, dtype=np.int16), {})})
    with pytest.raises(DataError, match="no time information, pass dt"):
        read_tdms(bare)
    exp = read_tdms(bare, dt=0.01)
    assert exp["a"].dtype == np.float64 and exp.dt == 0.01
    with pytest.raises(DataError, match="disagrees with wf_increment"):
        read_tdms(write_tdms(_bench(), tmp_path / "ok.tdms"), dt=0.5)


def test_tdms_time_channel(tmp_path: Path) -> None:
    path = _tdms_file(tmp_path / "t.tdms", {
        "t": (0.5 + 0.01 * np.arange(6), {}), "a": (np.ones(6), {"unit_string": "V"})})
    exp = read_tdms(path, time="t")
    assert exp.names == ("a",) and exp.unit("a") == "V" and exp.t0 == 0.5
    assert exp.dt == pytest.approx(0.01, rel=1e-12)  # mean of rounded stamps


@pytest.mark.parametrize("cut", [7, 60, 200, -9])
def test_tdms_truncated(tmp_path: Path, cut: int) -> None:
    good = write_tdms(_bench(n=50), tmp_path / "good.tdms")
    data = good.read_bytes()
    bad = tmp_path / "bad.tdms"
    bad.write_bytes(data[:cut])
    digest = _digest(bad)
    with pytest.raises(FileFormatError, match="bad.tdms"):
        read_tdms(bad)
    assert _digest(bad) == digest


def test_tdms_garbage(tmp_path: Path) -> None:
    bad = tmp_path / "junk.tdms"
    bad.write_bytes(b"this is not a TDMS file at all" * 10)
    with pytest.raises(FileFormatError, match=r"junk.tdms: cannot be read as TDMS"):
        read_tdms(bad)


# -- MAT -------------------------------------------------------------------------------------


def _emps_like(n: int = 300) -> dict[str, np.ndarray | float]:
    t = 1e-3 * np.arange(n)
    return {
        "t": t[:, None],  # column vector, as MATLAB saves it
        "qm": np.sin(t)[:, None],
        "qg": np.cos(t)[None, :],  # row vector
        "vir": (0.1 * t)[:, None],
        "kp": 160.18,
        "kv": 243.45,
        "gtau": 35.15,
    }


@pytest.mark.parametrize("fmt", ["4", "5"])
def test_mat_v4_v5_round_trip(tmp_path: Path, fmt: str) -> None:
    src = _emps_like()
    path = tmp_path / "emps.mat"
    scipy.io.savemat(path, src, format=fmt)
    exp = read_mat(path, time="t", roles={"u": ["vir"], "y": ["qm"]})
    assert exp.names == ("vir", "qm", "qg")
    np.testing.assert_array_equal(exp["qm"], np.ravel(src["qm"]))
    np.testing.assert_array_equal(exp["qg"], np.ravel(src["qg"]))
    assert exp.notes == {"kp": 160.18, "kv": 243.45, "gtau": 35.15}
    assert exp.dt == pytest.approx(1e-3, rel=1e-12) and exp.t0 == 0.0  # mean of rounded stamps
    only = read_mat(path, variables=["qm"], dt=1e-3)
    assert only.names == ("qm",) and only.dt == 1e-3


def _write_v73(path: Path, arrays: dict[str, np.ndarray], userblock: bool = True) -> Path:
    """A MAT v7.3-like file: HDF5 with the 512-byte MATLAB header, arrays transposed."""
    with h5py.File(path, "w", userblock_size=512 if userblock else 0) as f:
        for name, value in arrays.items():
            arr = np.atleast_2d(np.asarray(value))
            ds = f.create_dataset(name, data=arr.T)  # MATLAB is column-major
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    if userblock:
        header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 2024 HDF5"
        with path.open("r+b") as f:
            f.write(header.ljust(128, b" "))
    return path


@pytest.mark.parametrize("userblock", [True, False])
def test_mat_v73_round_trip(tmp_path: Path, userblock: bool) -> None:
    src = _emps_like()
    src["K"] = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])  # a matrix: not loaded
    path = _write_v73(tmp_path / "emps73.mat", src, userblock)
    exp = read_mat(path, time="t", roles={"u": ["vir"], "y": ["qm"]})
    assert exp.names == ("vir", "qm", "qg")
    np.testing.assert_array_equal(exp["vir"], np.ravel(src["vir"]))
    assert exp.notes == {"kp": 160.18, "kv": 243.45, "gtau": 35.15}
    with pytest.raises(FileFormatError, match=r"'K' has shape \(2, 3\), not a vector"):
        read_mat(path, variables=["K"], dt=0.1)  # MATLAB's shape, not HDF5's (3, 2)


def test_mat_errors(tmp_path: Path) -> None:
    path = tmp_path / "m.mat"
    scipy.io.savemat(path, {"a": np.ones(5), "b": np.ones(4), "k": 2.0})
    with pytest.raises(FileFormatError, match=r"different lengths \(a: 5, b: 4\)"):
        read_mat(path, dt=0.1)
    with pytest.raises(ChannelError, match=r"'x' is not in .*m.mat; its vectors are: a, b"):
        read_mat(path, variables=["x"], dt=0.1)
    with pytest.raises(DataError, match=r"pass dt \[s\] or time="):
        read_mat(path, variables=["a"])
    with pytest.raises(FileFormatError, match=r"'k' has shape \(1, 1\), not a vector"):
        read_mat(path, variables=["k"], dt=0.1)


@pytest.mark.parametrize("kind", ["v5", "v73"])
def test_mat_truncated_and_garbage(tmp_path: Path, kind: str) -> None:
    good = tmp_path / "good.mat"
    if kind == "v5":
        scipy.io.savemat(good, _emps_like())
    else:
        _write_v73(good, _emps_like())
    data = good.read_bytes()
    for name, content in (("cut.mat", data[: len(data) // 2]), ("junk.mat", b"\x00junk" * 50)):
        bad = tmp_path / name
        bad.write_bytes(content)
        digest = _digest(bad)
        with pytest.raises(FileFormatError, match=name):
            read_mat(bad, time="t")
        assert _digest(bad) == digest


def test_mat_v73_without_h5py(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _write_v73(tmp_path / "x.mat", {"a": np.ones(4)})
    monkeypatch.setitem(__import__("sys").modules, "h5py", None)
    with pytest.raises(ImportError, match=r"pip install servoid\[mat73\]"):
        read_mat(path, dt=0.1)


# -- dispatch, missing files, existing outputs ----------------------------------------------


def test_read_experiment_dispatch(tmp_path: Path) -> None:
    exp = _bench()
    csv_path = write_csv(exp, tmp_path / "a.csv")
    tdms_path = write_tdms(exp, tmp_path / "a.tdms")
    scipy.io.savemat(tmp_path / "a.mat", {"y_p": exp["y_p"]})
    _same_signals(read_experiment(csv_path), read_experiment(tdms_path))
    assert read_experiment(tmp_path / "a.mat", dt=exp.dt).names == ("y_p",)
    other = tmp_path / "a.dat"
    other.write_bytes(csv_path.read_bytes())
    with pytest.raises(OptionError, match=r"pass format= one of 'csv', 'tdms', 'mat'"):
        read_experiment(other)
    assert read_experiment(other, format="csv").names == exp.names
    with pytest.raises(OptionError, match=r"format must be one of 'csv', 'tdms', 'mat'; got 'xls'"):
        read_experiment(other, format="xls")  # type: ignore[arg-type]


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nothing.csv: no such file"):
        read_csv(tmp_path / "nothing.csv", dt=0.1)


@pytest.mark.parametrize("writer", [write_csv, write_tdms])
def test_existing_output_is_refused_and_kept(tmp_path: Path, writer) -> None:
    path = tmp_path / "out.bin"
    path.write_bytes(b"precious")
    with pytest.raises(OutputExistsError, match="already exists"):
        writer(_bench(), path)
    assert path.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]  # no temp file left
    writer(_bench(), path, overwrite=True)
    assert path.read_bytes() != b"precious"
