"""Rig files as loggers write them (issue 13, item 4).

CSV files with a preamble, unwanted columns and a trailing delimiter; TDMS
files with several groups; MAT files with the signals inside (nested)
structs, v5 (plain and compressed, written by scipy) and v7.3 (written by
h5py). Every file is written here by the writing library itself, not by
servoid, and the values read back must be the ones written: exactly, since
the CSV text holds ``repr`` of each double and the binary formats store the
doubles themselves.
"""

from __future__ import annotations

import numpy as np
import pytest

from servoid import ChannelError, DataError, FileFormatError, OptionError, OptionTypeError
from servoid.data import load_experiment_spec, read_csv, read_mat, read_tdms

N = 300
DT = 1e-3


def _signals(seed: int) -> dict[str, np.ndarray]:
    gen = np.random.default_rng(seed)
    return {"u": gen.standard_normal(N), "y": gen.standard_normal(N),
            "temp": 20 + gen.standard_normal(N)}


# -- CSV -------------------------------------------------------------------------------------

PREAMBLE = ["Logger DL-7 firmware 2.1", "Operator:,J. Doe", "Samples:,300", ""]


def _rig_csv(path, seed=0, preamble=PREAMBLE, trailing=True, sep=","):
    s = _signals(seed)
    end = sep if trailing else ""
    lines = [*preamble, sep.join(["time [s]", "u [V]", "status", "y [m]", "temp [C]"]) + end]
    for k in range(N):
        cells = [repr(k * DT), *(repr(float(s[n][k])) for n in ("u",)),
                 "OK" if k % 7 else "WARN", *(repr(float(s[n][k])) for n in ("y", "temp"))]
        lines.append(sep.join(cells) + end)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return s


@pytest.mark.parametrize("seed", [0, 1])
def test_csv_preamble_text_column_and_trailing_delimiter(tmp_path, seed):
    s = _rig_csv(tmp_path / "a.csv", seed)
    exp = read_csv(tmp_path / "a.csv", skip_rows=4, skip_columns=["status"])
    assert exp.names == ("u", "y", "temp")
    assert [c.unit for c in exp.channels] == ["V", "m", "C"]
    assert exp.dt == pytest.approx(DT, rel=1e-12)  # the mean of exact steps: ε
    for name in exp.names:
        np.testing.assert_array_equal(exp[name], s[name])  # repr round trip: exact
    by_index = read_csv(tmp_path / "a.csv", skip_rows=4, columns=[1, 3])
    assert by_index.names == ("u", "y")  # the time column is read besides
    np.testing.assert_array_equal(by_index["y"], s["y"])
    by_name = read_csv(tmp_path / "a.csv", skip_rows=4, columns=["y"], roles={"y": ["y"]})
    assert by_name.names == ("y",) and by_name.dt == pytest.approx(DT, rel=1e-12)


def test_csv_preamble_is_detected_with_the_fix(tmp_path):
    _rig_csv(tmp_path / "a.csv")
    with pytest.raises(FileFormatError, match=r"line 5 \('time \[s\],u \[V\].*preamble: "
                                              r"pass skip_rows=4"):
        read_csv(tmp_path / "a.csv", skip_columns=["status"])
    with pytest.raises(FileFormatError, match="pass skip_rows=4"):
        read_csv(tmp_path / "a.csv", skip_rows=1)  # part of it skipped: the total is named


def test_csv_units_row_is_not_mistaken_silently(tmp_path):
    (tmp_path / "a.csv").write_text("time,u,y\ns,V,m\n0,1,2\n0.1,2,3\n0.2,3,4\n",
                                    encoding="utf-8")
    with pytest.raises(FileFormatError, match="row of units"):
        read_csv(tmp_path / "a.csv")


def test_csv_text_column_names_skip_columns(tmp_path):
    _rig_csv(tmp_path / "a.csv")
    with pytest.raises(FileFormatError, match=r"'WARN' is not a number \(column 'status'; .*"
                                              r"skip_columns=\[2\]"):
        read_csv(tmp_path / "a.csv", skip_rows=4)


def test_csv_trailing_delimiter_on_the_header_only_or_rows_only(tmp_path):
    rows = "\n".join(f"{k * 0.1!r},{k},{2 * k}" for k in range(10))
    (tmp_path / "h.csv").write_text("time,u,y,\n" + rows + "\n", encoding="utf-8")
    (tmp_path / "r.csv").write_text("time,u,y\n" + rows.replace("\n", ",\n") + ",\n",
                                    encoding="utf-8")
    for name in ("h.csv", "r.csv"):
        exp = read_csv(tmp_path / name)
        assert exp.names == ("u", "y")
        np.testing.assert_array_equal(exp["y"], 2.0 * np.arange(10))


def test_csv_selected_columns_keep_the_row_checks(tmp_path):
    """A merged or cut line must fail even when its extra field is not read."""
    lines = ["time,u,y,z"] + [f"{k * 0.1!r},{k},{k},{k}" for k in range(20)]
    merged = [*lines[:5], lines[5] + ",9", *lines[6:]]
    (tmp_path / "m.csv").write_text("\n".join(merged) + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match="line 6: 5 field"):
        read_csv(tmp_path / "m.csv", columns=["u"])
    cut = [*lines[:5], "0.4,4,4", *lines[6:]]
    (tmp_path / "c.csv").write_text("\n".join(cut) + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match="line 6: 3 field"):
        read_csv(tmp_path / "c.csv", columns=["u"])


def test_csv_decimal_comma_with_selection(tmp_path):
    s = _rig_csv(tmp_path / "a.csv", sep=";")
    text = (tmp_path / "a.csv").read_text(encoding="utf-8")
    head, body = text.split("temp [C];\n")
    (tmp_path / "a.csv").write_text(head + "temp [C];\n" + body.replace(".", ","),
                                    encoding="utf-8")
    exp = read_csv(tmp_path / "a.csv", delimiter=";", decimal=",", skip_rows=4,
                   columns=["u", "temp"])
    np.testing.assert_array_equal(exp["temp"], s["temp"])


def test_csv_empty_or_repeated_names_only_matter_when_read(tmp_path):
    rows = "\n".join(f"{k * 0.1!r},{k},{k},{2 * k}" for k in range(10))
    (tmp_path / "a.csv").write_text("time,u,,u\n" + rows + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"column 3: empty channel name; .*skip_columns="
                                              r"\[2\]"):
        read_csv(tmp_path / "a.csv", skip_columns=[3])
    with pytest.raises(FileFormatError, match=r"'u' is repeated .*skip_columns=\[3\]"):
        read_csv(tmp_path / "a.csv", skip_columns=[2])
    exp = read_csv(tmp_path / "a.csv", skip_columns=[2, 3])
    assert exp.names == ("u",)
    with pytest.raises(FileFormatError, match="2 columns of that name .*give the 0-based index"):
        read_csv(tmp_path / "a.csv", columns=["u"])
    np.testing.assert_array_equal(read_csv(tmp_path / "a.csv", columns=[3])["u"],
                                  2.0 * np.arange(10))


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"columns": ["nope"]}, ChannelError, (r"column 'nope', which is not in the header .* "
                                              r"0: 'time', 1: 'u', 2: 'status'")),
        ({"columns": [9]}, ChannelError, r"index 9, but .* has 6 column\(s\), 0\.\.5"),
        ({"columns": [-1]}, DataError, "indices count from 0"),
        ({"columns": "u"}, OptionTypeError, "list of column names or 0-based"),
        ({"columns": [1.5]}, OptionTypeError, "list of column names or 0-based"),
        ({"columns": [True]}, OptionTypeError, "list of column names or 0-based"),
        ({"columns": []}, DataError, "at least one column"),
        ({"columns": ["u", "u"]}, DataError, "'u' more than once"),
        ({"skip_columns": [""]}, DataError, "empty name"),
        ({"columns": ["u"], "skip_columns": ["y"]}, OptionError, "not both"),
        ({"skip_rows": -1}, DataError, "skip_rows must be >= 0"),
        ({"skip_rows": 2.0}, OptionTypeError, "skip_rows must be an integer"),
        ({"skip_rows": 10_000}, FileFormatError, "skips every line"),
    ],
)
def test_csv_bad_selection(tmp_path, kwargs, error, match):
    _rig_csv(tmp_path / "a.csv")
    before = (tmp_path / "a.csv").read_bytes()
    kwargs = {"skip_rows": 4, **kwargs}
    with pytest.raises(error, match=match):
        read_csv(tmp_path / "a.csv", **kwargs)
    assert (tmp_path / "a.csv").read_bytes() == before


def test_csv_keys_in_the_experiment_file(tmp_path):
    s = _rig_csv(tmp_path / "a.csv", seed=3)
    toml = tmp_path / "e.toml"
    base = ('[data]\nfile = "a.csv"\n{extra}\n[channels.u]\nrole = "u"\n'
            '[channels.y]\nrole = "y"\n')
    toml.write_text(base.format(extra='skip_rows = 4\ncolumns = ["u", "y"]'), encoding="utf-8")
    spec = load_experiment_spec(toml)
    exp = spec.load()
    np.testing.assert_array_equal(exp["y"], s["y"])
    assert spec.to_dict()["data"]["columns"] == ["u", "y"]
    again = tmp_path / "again.toml"
    from servoid.data import write_experiment_spec
    write_experiment_spec(spec, again)
    assert load_experiment_spec(again) == spec
    toml.write_text(base.format(extra=""), encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"set \[data\] skip_rows = 4"):
        load_experiment_spec(toml).load()
    # without columns, only the mapped columns are converted: the text column is no matter
    toml.write_text(base.format(extra="skip_rows = 4"), encoding="utf-8")
    np.testing.assert_array_equal(load_experiment_spec(toml).load()["u"], s["u"])
    toml.write_text(base.format(extra="skip_rows = 4").replace('[channels.y]\n',
                                                             '[channels.y]\nsource = "status"\n'),
                    encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"'WARN' is not a number \(column 'status'"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra='skip_rows = 4\ncolumns = ["u"]'), encoding="utf-8")
    with pytest.raises(ChannelError, match=r"channel 'y' \(servoid channel 'y'\) is not in .*"
                                           r"listed in \[data\] columns"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra='skip_rows = 4\ncolumns = ["u", "why"]'), encoding="utf-8")
    with pytest.raises(ChannelError, match=r"\[data\] columns names the column 'why', which is not in"):
        load_experiment_spec(toml).load()


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        ("skip_rows = -1", r"\[data\] skip_rows must be an integer >= 0"),
        ('skip_rows = "4"', r"\[data\] skip_rows must be an integer >= 0"),
        ('columns = "u"', r"\[data\] columns must be a non-empty array"),
        ("columns = [-2]", r"\[data\] columns must be a non-empty array .*0-based"),
        ("skip_columns = []", r"\[data\] skip_columns must be a non-empty array"),
        ('columns = ["u"]\nskip_columns = ["y"]', "give columns .* or skip_columns"),
    ],
)
def test_csv_keys_bad_values(tmp_path, extra, match):
    toml = tmp_path / "e.toml"
    toml.write_text(f'[data]\nfile = "a.csv"\n{extra}\n[channels.y]\nrole = "y"\n',
                    encoding="utf-8")
    with pytest.raises(FileFormatError, match=match):
        load_experiment_spec(toml)


def test_csv_keys_refused_for_tdms(tmp_path):
    toml = tmp_path / "e.toml"
    toml.write_text('[data]\nfile = "a.tdms"\nskip_rows = 2\n[channels.y]\nrole = "y"\n',
                    encoding="utf-8")
    with pytest.raises(FileFormatError, match="skip_rows apply to CSV files only"):
        load_experiment_spec(toml)


# -- TDMS --------------------------------------------------------------------------------------


def _multi_tdms(path, seed=0, slow=False):
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    s = _signals(seed)
    props = {"wf_increment": DT, "wf_start_offset": 0.5, "unit_string": "V"}
    objects = [
        RootObject({"name": "run"}),
        GroupObject("command", {"card": "AO-1"}),
        ChannelObject("command", "AI0", s["u"], props),
        ChannelObject("command", "temp", s["temp"], props),
        GroupObject("measure", {"card": "AI-2"}),
        ChannelObject("measure", "AI1", s["y"], {**props, "unit_string": "m"}),
        ChannelObject("measure", "temp", -s["temp"], props),
        ChannelObject("measure", "label", np.array(["a"] * 3), {}),
    ]
    if slow:
        objects.append(ChannelObject("measure", "slow", s["u"][::10], props))
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(objects)
    return s


@pytest.mark.parametrize("seed", [0, 1])
def test_tdms_channels_of_several_groups(tmp_path, seed):
    s = _multi_tdms(tmp_path / "m.tdms", seed)
    exp = read_tdms(tmp_path / "m.tdms", channels=["AI0", "measure/AI1", "command/temp"],
                    roles={"u": "AI0", "y": "measure/AI1"})
    assert exp.names == ("AI0", "measure/AI1", "command/temp")
    np.testing.assert_array_equal(exp["AI0"], s["u"])
    np.testing.assert_array_equal(exp["measure/AI1"], s["y"])
    np.testing.assert_array_equal(exp["command/temp"], s["temp"])
    assert exp.dt == DT and exp.t0 == 0.5
    assert exp.notes == {"command/card": "AO-1", "measure/card": "AI-2"}
    assert exp.channel("measure/AI1").unit == "m"
    one = read_tdms(tmp_path / "m.tdms", group="measure", channels=["temp"])
    np.testing.assert_array_equal(one["temp"], -s["temp"])
    assert one.notes == {"card": "AI-2"}


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({}, OptionError, (r"has 2 groups; pass group= one of: 'command', 'measure' \(or name "
                          r"each channel 'group/channel'\)")),
        ({"channels": ["temp"]}, ChannelError, (r"'temp' is in 2 groups; name one as "
                                               r"'group/channel': 'command/temp', "
                                               r"'measure/temp'")),
        ({"channels": ["AI9"]}, ChannelError, (r"'AI9' is not in .*m.tdms; it has: command/AI0, "
                                              r"command/temp, measure/AI1, measure/temp, "
                                              r"measure/slow$")),
        ({"channels": ["AI0"], "group": "measure"}, ChannelError,
         r"'AI0' is not in group 'measure' of .*; it has: AI1, temp"),
        ({"channels": ["AI0"], "group": "nope"}, OptionError, (r"no group 'nope'; it has: "
                                                              r"'command', 'measure'")),
        ({"channels": ["measure/label"]}, FileFormatError, "not numbers"),
        ({"channels": ["AI0", "slow"]}, FileFormatError, "different lengths"),
        ({"channels": "AI0"}, OptionTypeError, "channels must be a list of strings"),
        ({"channels": []}, DataError, "at least 1"),
    ],
)
def test_tdms_bad_channel_names(tmp_path, kwargs, error, match):
    _multi_tdms(tmp_path / "m.tdms", slow=True)
    with pytest.raises(error, match=match):
        read_tdms(tmp_path / "m.tdms", **kwargs)


def test_tdms_groups_in_the_experiment_file(tmp_path):
    s = _multi_tdms(tmp_path / "m.tdms", seed=4)
    toml = tmp_path / "e.toml"
    base = ('[data]\nfile = "m.tdms"\n{extra}\n[channels.u]\nsource = "AI0"\nrole = "u"\n'
            '[channels.y]\nsource = "{y}"\nrole = "y"\n')
    toml.write_text(base.format(extra="", y="measure/AI1"), encoding="utf-8")
    exp = load_experiment_spec(toml).load()
    np.testing.assert_array_equal(exp["y"], s["y"])
    toml.write_text(base.format(extra="", y="temp"), encoding="utf-8")
    with pytest.raises(ChannelError, match="'command/temp', 'measure/temp'"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra='group = "measure"', y="AI1"), encoding="utf-8")
    with pytest.raises(ChannelError, match=r"channel 'AI0' \(servoid channel 'u'\) is not in "
                                           r".*group 'measure'; the file has: AI1, temp "
                                           r"\(a channel of another group is named"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra='group = "other"', y="AI1"), encoding="utf-8")
    with pytest.raises(OptionError, match=r"no group 'other'; it has: 'command', 'measure' "
                                          r"\(set \[data\] group to one of them\)"):
        load_experiment_spec(toml).load()
    toml.write_text(base.format(extra='time = "clock"', y="AI1"), encoding="utf-8")
    with pytest.raises(ChannelError, match=r"\[data\] time = 'clock': no such channel"):
        load_experiment_spec(toml).load()


# -- MAT ---------------------------------------------------------------------------------------


def _nested(s: dict[str, np.ndarray]) -> dict[str, object]:
    return {"run": {"signals": {"u": s["u"][:, None], "y": s["y"][None, :]},
                    "t": DT * np.arange(N)[:, None], "fs": 1 / DT},
            "note": "bench 3"}


@pytest.mark.parametrize("compress", [False, True])
@pytest.mark.parametrize("seed", [0, 1])
def test_mat_v5_struct_fields(tmp_path, compress, seed):
    import scipy.io

    s = _signals(seed)
    scipy.io.savemat(tmp_path / "s.mat", _nested(s), do_compression=compress)
    exp = read_mat(tmp_path / "s.mat", variables=["run.signals.u", "run.signals.y"],
                   time="run.t", roles={"u": "run.signals.u", "y": "run.signals.y"})
    np.testing.assert_array_equal(exp["run.signals.u"], s["u"])
    np.testing.assert_array_equal(exp["run.signals.y"], s["y"])
    assert exp.dt == pytest.approx(DT, rel=1e-12)  # the mean of the written steps: ε
    assert exp.notes == {"note": "bench 3"}


def _v73(path, s, *, array=False, cell=False):
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w") as f:
        run = f.create_group("run")
        run.attrs["MATLAB_class"] = np.bytes_("struct")
        sig = run.create_group("signals")
        sig.attrs["MATLAB_class"] = np.bytes_("struct")
        sig["u"] = s["u"][None, :]  # MATLAB's column vector, as HDF5 stores it
        sig["y"] = s["y"][None, :]
        run["t"] = DT * np.arange(N)[None, :]
        refs = f.create_group("#refs#")
        refs["a"] = s["u"][None, :]
        refs["b"] = s["y"][None, :]
        if array:  # a 1×2 struct array: each field a dataset of references
            arr = f.create_group("trials")
            arr.attrs["MATLAB_class"] = np.bytes_("struct")
            arr.create_dataset("x", data=np.array([[refs["a"].ref], [refs["b"].ref]]),
                               dtype=h5py.ref_dtype)
        if cell:
            c = run.create_dataset("c", data=np.array([[refs["a"].ref], [refs["b"].ref]]),
                                   dtype=h5py.ref_dtype)
            c.attrs["MATLAB_class"] = np.bytes_("cell")


def test_mat_v73_struct_fields(tmp_path):
    s = _signals(5)
    _v73(tmp_path / "h.mat", s)
    exp = read_mat(tmp_path / "h.mat", variables=["run.signals.u", "run.signals.y"],
                   time="run.t")
    np.testing.assert_array_equal(exp["run.signals.u"], s["u"])
    np.testing.assert_array_equal(exp["run.signals.y"], s["y"])
    assert exp.dt == pytest.approx(DT, rel=1e-12)  # the mean of the written steps: ε


def _v5_odd(path):
    import scipy.io

    s = _signals(0)
    trials = np.empty((1, 2), dtype=[("x", object)])
    trials[0, 0]["x"], trials[0, 1]["x"] = s["u"][:, None], s["y"][:, None]
    cells = np.empty((1, 2), dtype=object)
    cells[0, 0], cells[0, 1] = s["u"], s["y"]
    scipy.io.savemat(path, {"trials": trials, "run": {"c": cells, "gain": 2.0, "s": {"v": 1.0}},
                            "x": s["u"][:, None]})


@pytest.mark.parametrize("version", ["v5", "v73"])
@pytest.mark.parametrize(
    ("name", "error", "match"),
    [
        ("trials.x", FileFormatError, r"'trials' is a struct array"),
        ("run.c", FileFormatError, r"'run.c' is a cell array .*not in a cell"),
        ("run.nope", ChannelError, r"'run.nope' is not in .*: the struct 'run' has the field"),
        ("run", FileFormatError, (r"'run' is a struct .*name one of its fields with a dot, "
                                 r"e.g. 'run.<field>'")),
    ],
)
def test_mat_struct_errors_name_the_path(tmp_path, version, name, error, match):
    path = tmp_path / "odd.mat"
    if version == "v5":
        _v5_odd(path)
    else:
        _v73(path, _signals(0), array=True, cell=True)
    before = path.read_bytes()
    with pytest.raises(error, match=match):
        read_mat(path, variables=[name], dt=DT)
    assert path.read_bytes() == before


def test_mat_v5_field_of_a_number(tmp_path):
    _v5_odd(tmp_path / "odd.mat")
    with pytest.raises(ChannelError, match=r"'run.gain' is a numeric array of shape \(1, 1\), "
                                           "not a struct"):
        read_mat(tmp_path / "odd.mat", variables=["run.gain.x"], dt=DT)
    with pytest.raises(ChannelError, match=r"its vectors are: x \(and the struct\(s\) trials, "
                                           r"run: name a field with dots"):
        read_mat(tmp_path / "odd.mat", variables=["signals"], dt=DT)


def test_mat_struct_fields_in_the_experiment_file(tmp_path):
    import scipy.io

    s = _signals(7)
    scipy.io.savemat(tmp_path / "s.mat", _nested(s), do_compression=True)
    toml = tmp_path / "e.toml"
    toml.write_text('[data]\nfile = "s.mat"\ntime = "run.t"\n'
                    '[channels.u]\nsource = "run.signals.u"\nrole = "u"\n'
                    '[channels.y]\nsource = "run.signals.y"\nrole = "y"\n', encoding="utf-8")
    exp = load_experiment_spec(toml).load()
    np.testing.assert_array_equal(exp["y"], s["y"])
    assert exp.names == ("u", "y")


def test_mat_damaged_struct_field_is_an_error_not_a_crash(tmp_path):
    """A field's declared data size cut short inside the struct: refused by the walker."""
    import scipy.io

    s = _signals(0)
    scipy.io.savemat(tmp_path / "s.mat", {"run": {"y": s["y"][:, None]}})
    raw = bytearray((tmp_path / "s.mat").read_bytes())
    at = raw.find(np.float64(s["y"][0]).tobytes())  # first double of y
    tag = at - 8  # its data element's tag: type miDOUBLE (9), byte count
    assert raw[tag] == 9
    raw[tag + 4 : tag + 8] = (8 * N + 64).to_bytes(4, "little")  # more bytes than there are
    (tmp_path / "bad.mat").write_bytes(bytes(raw))
    with pytest.raises(FileFormatError, match="'run'.*damaged"):
        read_mat(tmp_path / "bad.mat", variables=["run.y"], dt=DT)


@pytest.mark.parametrize(("fmt", "index"), [("csv", -1), ("tdms", -1), ("mat5", 0),
                                            ("mat5z", 0), ("mat73", 0)])
def test_fuzz_seeds_read_with_the_rig_options(fmt, index, tmp_path):
    """The fuzzers' third call mode (rig-file options) starts from a valid file."""
    from fuzz_inputs import own_seeds, read_input

    assert read_input(fmt, own_seeds(fmt)[index], 2, tmp_path) == "ok"
