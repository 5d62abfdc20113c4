"""The bad-input catalogue of rig files as they come (issues 13 and 21).

The new ``[data]`` keys and channel names of the rig-file readers, through
``servoid identify`` in process: CSV ``skip_rows``, ``columns`` and
``skip_columns``; TDMS ``group`` and ``"group/channel"`` sources; MAT
struct fields named with dots (v5 written by scipy, v7.3 by h5py). Each
case copies a working experiment folder, breaks one thing and checks what
``test_catalogue_cli`` checks: exit code 1, one message on stderr naming the
key and the fix, the same under ``--json``, no traceback, and every input
unchanged with no stray file. The edit helpers and the runner's pieces are
those of ``test_catalogue_cli``; only the working folders are new.

Issue 21 adds what a path can name besides a regular file (a FIFO, a link to
a device, a dangling link), CSV files that are not what they
seem (UTF-16, digit grouping, a byte-order mark inside, a header cell over
the CSV limit, a delimiter that is not one), time stamps in ticks, a record
listed twice or validated on itself, and HDF5 links and unwritten datasets.
Their folders hold special files, so the tree is compared without reading
them (a FIFO would block, ``/dev/zero`` never end).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_catalogue_cli import Case, _run, _tree, arx_record, case, del_, set_
from test_catalogue_cli import copy_in as copy_

from servoid.data import load_experiment_spec

TOML_NAME = "exp.toml"
ID = "identify {toml} --out {out}"
PREAMBLE = ["Logger DL-7 firmware 2.1", "Operator:,J. Doe", "Samples:,300", ""]
IDENTIFY = '\n[identify]\nmethod = "arx"\nna = 2\nnb = 2\nnk = 1\n'

CSV_TOML = """\
[data]
file = "data.csv"
skip_rows = 4
skip_columns = ["status"]

[channels.u]
role = "u"

[channels.y]
role = "y"
""" + IDENTIFY

TDMS_TOML = """\
[data]
file = "data.tdms"

[channels.u]
source = "AI0"
role = "u"

[channels.y]
source = "measure/AI1"
role = "y"
""" + IDENTIFY

MAT_TOML = """\
[data]
file = "data.mat"
time = "run.t"

[channels.u]
source = "run.signals.u"
role = "u"

[channels.y]
source = "run.signals.y"
role = "y"
""" + IDENTIFY


def _csv(folder: Path) -> None:
    t, u, y = arx_record()
    lines = [*PREAMBLE, "time [s],u [V],status,y [m],"]
    lines += [f"{a!r},{b!r},{'OK' if k % 7 else 'WARN'},{c!r},"
              for k, (a, b, c) in enumerate(zip(t.tolist(), u.tolist(), y.tolist(), strict=True))]
    (folder / "data.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    (folder / TOML_NAME).write_text(CSV_TOML, encoding="utf-8")


def _tdms(folder: Path) -> None:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    t, u, y = arx_record()
    props = {"wf_increment": float(t[1] - t[0]), "wf_start_offset": 0.0}
    with TdmsWriter(str(folder / "data.tdms")) as writer:
        writer.write_segment([
            RootObject({"name": "run"}),
            GroupObject("command", {}),
            ChannelObject("command", "AI0", u, props),
            ChannelObject("command", "temp", 20 + 0 * u, props),
            GroupObject("measure", {}),
            ChannelObject("measure", "AI1", y, props),
            ChannelObject("measure", "temp", 21 + 0 * y, props),
            ChannelObject("measure", "label", np.array(["a", "b"]), {}),
            ChannelObject("measure", "slow", y[::10], props),
        ])
    (folder / TOML_NAME).write_text(TDMS_TOML, encoding="utf-8")


def _mat(folder: Path) -> None:
    import scipy.io

    t, u, y = arx_record()
    trials = np.empty((1, 2), dtype=[("x", object)])
    trials[0, 0]["x"], trials[0, 1]["x"] = u[:, None], y[:, None]
    cells = np.empty((1, 2), dtype=object)
    cells[0, 0], cells[0, 1] = u, y
    scipy.io.savemat(folder / "data.mat", {
        "run": {"signals": {"u": u[:, None], "y": y[:, None]}, "t": t[:, None], "fs": 100.0,
                "c": cells},
        "trials": trials,
    }, do_compression=True)
    (folder / TOML_NAME).write_text(MAT_TOML, encoding="utf-8")


def _mat73(folder: Path) -> None:
    import h5py

    t, u, y = arx_record()
    with h5py.File(folder / "data.mat", "w") as f:
        run = f.create_group("run")
        run.attrs["MATLAB_class"] = np.bytes_("struct")
        signals = run.create_group("signals")
        signals.attrs["MATLAB_class"] = np.bytes_("struct")
        signals["u"], signals["y"], run["t"] = u[None, :], y[None, :], t[None, :]
        refs = f.create_group("#refs#")
        refs["a"] = u[None, :]
        trials = f.create_group("trials")
        trials.attrs["MATLAB_class"] = np.bytes_("struct")
        trials.create_dataset("x", data=np.array([[refs["a"].ref], [refs["a"].ref]]),
                              dtype=h5py.ref_dtype)
    (folder / TOML_NAME).write_text(MAT_TOML, encoding="utf-8")


MAKERS = {"rigcsv": _csv, "rigtdms": _tdms, "rigmat": _mat, "rigmat73": _mat73}


@pytest.fixture(scope="module")
def rig_bases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Working experiment folders, made once: name → folder."""
    root = tmp_path_factory.mktemp("rigbases")
    out = {}
    for name, make in MAKERS.items():
        folder = root / name
        folder.mkdir()
        make(folder)
        out[name] = folder
    return out


def _prepare(entry: Case, bases: dict[str, Path], tmp_path: Path) -> dict[str, str]:
    folder = tmp_path / "lab" / "rig"
    folder.parent.mkdir()
    shutil.copytree(bases[str(entry.base)], folder)
    (folder / TOML_NAME).rename(folder / "input.toml")
    for edit in entry.edits:
        edit(folder)
    return {"toml": str(folder / "input.toml"), "in": str(folder), "out": str(tmp_path / "out")}


def csv_case(id: str, fragment: str, *edits, **kw) -> object:
    return case(id, ID, fragment, *edits, base="rigcsv", **kw)


def tdms_case(id: str, fragment: str, *edits, **kw) -> object:
    return case(id, ID, fragment, *edits, base="rigtdms", **kw)


def mat_case(id: str, fragment: str, *edits, base: str = "rigmat", **kw) -> object:
    return case(id, ID, fragment, *edits, base=base, **kw)


CSV_CASES = [
    csv_case("csv-preamble-unskipped", "preamble: set [data] skip_rows = 4",
             del_("data", "skip_rows")),
    csv_case("csv-preamble-part-skipped", "set [data] skip_rows = 4",
             set_("data", "skip_rows", "2")),
    csv_case("csv-skip-rows-negative", "[data] skip_rows must be an integer >= 0",
             set_("data", "skip_rows", "-1")),
    csv_case("csv-skip-rows-text", "[data] skip_rows must be an integer >= 0",
             set_("data", "skip_rows", '"4"')),
    csv_case("csv-skip-rows-float", "[data] skip_rows must be an integer >= 0",
             set_("data", "skip_rows", "4.0")),
    csv_case("csv-skip-rows-past-the-end", "[data] skip_rows = 100000 skips every line",
             set_("data", "skip_rows", "100000")),
    csv_case("csv-text-column-as-a-source", "'WARN' is not a number (column 'status'",
             del_("data", "skip_columns"), set_("channels.y", "source", '"status"')),
    csv_case("csv-skipped-column-as-a-source", "channel 'status' (servoid channel 'y') is "
             "not in", set_("channels.y", "source", '"status"')),
    csv_case("csv-text-column-in-columns", "leave it out with [data] skip_columns = [2]",
             del_("data", "skip_columns"), set_("data", "columns", '["u", "status", "y"]')),
    csv_case("csv-columns-unknown", "[data] columns names the column 'pos', which is not in "
             "the header", del_("data", "skip_columns"),
             set_("data", "columns", '["u", "pos"]')),
    csv_case("csv-columns-index-too-large", "[data] columns holds the index 9",
             del_("data", "skip_columns"), set_("data", "columns", "[1, 9]")),
    csv_case("csv-columns-negative", "[data] columns must be a non-empty array",
             del_("data", "skip_columns"), set_("data", "columns", "[1, -1]")),
    csv_case("csv-columns-string", "[data] columns must be a non-empty array",
             del_("data", "skip_columns"), set_("data", "columns", '"u"')),
    csv_case("csv-columns-float", "[data] columns must be a non-empty array",
             del_("data", "skip_columns"), set_("data", "columns", "[1.5]")),
    csv_case("csv-columns-empty", "[data] columns must be a non-empty array",
             del_("data", "skip_columns"), set_("data", "columns", "[]")),
    csv_case("csv-columns-repeated", "[data] columns lists 'u' more than once",
             del_("data", "skip_columns"), set_("data", "columns", '["u", "u", "y"]')),
    csv_case("csv-columns-and-skip-columns", "give columns (the columns to read) or "
             "skip_columns", set_("data", "columns", '["u", "y"]')),
    csv_case("csv-columns-without-a-source", "listed in [data] columns are read: add it there",
             del_("data", "skip_columns"), set_("data", "columns", '["u"]')),
    csv_case("csv-skip-columns-a-source", "check [data] skip_columns",
             set_("data", "skip_columns", '["status", "y"]')),
    csv_case("csv-skip-columns-unknown", "[data] skip_columns names the column 'state'",
             set_("data", "skip_columns", '["state"]')),
    csv_case("csv-skip-columns-table", "[data] skip_columns must be a non-empty array",
             set_("data", "skip_columns", "{ a = 1 }")),
    mat_case("csv-keys-on-a-mat-file", "skip_rows apply to CSV files only",
             set_("data", "skip_rows", "2")),
]

TDMS_CASES = [
    tdms_case("tdms-ambiguous-channel", "channel 'temp' is in 2 groups; name one as "
              "'group/channel': 'command/temp', 'measure/temp'",
              set_("channels.y", "source", '"temp"')),
    tdms_case("tdms-group-absent", "no group 'nope'; it has: 'command', 'measure' "
              "(set [data] group to one of them)", set_("data", "group", '"nope"')),
    tdms_case("tdms-group-number", "[data] group must be a non-empty string",
              set_("data", "group", "3")),
    tdms_case("tdms-group-empty", "[data] group must be a non-empty string",
              set_("data", "group", '""')),
    tdms_case("tdms-channel-in-another-group", "channel 'AI0' (servoid channel 'u') is not in",
              set_("data", "group", '"measure"'), set_("channels.y", "source", '"AI1"')),
    tdms_case("tdms-qualified-channel-absent", "channel 'measure/AI9' (servoid channel 'y') "
              "is not in", set_("channels.y", "source", '"measure/AI9"')),
    tdms_case("tdms-text-channel", "channel 'measure/label' holds",
              set_("channels.y", "source", '"measure/label"')),
    tdms_case("tdms-channels-of-two-rates", "different lengths",
              set_("channels.y", "source", '"measure/slow"')),
    tdms_case("tdms-time-absent", "[data] time = 'clock': no such channel",
              set_("data", "time", '"clock"')),
]

MAT_CASES = [
    mat_case("mat-field-absent", "the struct 'run.signals' has the field(s) u, y",
             set_("channels.y", "source", '"run.signals.pos"')),
    mat_case("mat-struct-absent", "variable 'data.y' is not in",
             set_("channels.y", "source", '"data.y"')),
    mat_case("mat-struct-array", "'trials' is a struct array",
             set_("channels.y", "source", '"trials.x"')),
    mat_case("mat-cell-array", "'run.c' is a cell array",
             set_("channels.y", "source", '"run.c"')),
    mat_case("mat-struct-not-a-vector", "name one of its fields with a dot",
             set_("channels.y", "source", '"run.signals"')),
    mat_case("mat-field-of-a-number", "'run.fs' is a numeric array of shape (1, 1), not a "
             "struct", set_("channels.y", "source", '"run.fs.x"')),
    mat_case("mat-time-field-absent", "the struct 'run' has the field(s)",
             set_("data", "time", '"run.clock"')),
    mat_case("mat-group-key", "group applies to TDMS files only", set_("data", "group", '"x"')),
    mat_case("mat73-field-absent", "the struct 'run.signals' has the field(s) u, y",
             set_("channels.y", "source", '"run.signals.pos"'), base="rigmat73"),
    mat_case("mat73-struct-array", "'trials' is a struct array",
             set_("channels.y", "source", '"trials.x"'), base="rigmat73"),
    mat_case("mat73-not-a-struct", "'run.t' is a numeric array, not a struct",
             set_("channels.y", "source", '"run.t.x"'), base="rigmat73"),
]

# -- issue 21: inputs checked before they are read -------------------------------------------------


def fifo(name: str) -> object:
    """Replace a file of the folder by a named pipe (no writer: an open would block)."""
    def edit(folder: Path) -> None:
        (folder / name).unlink(missing_ok=True)
        os.mkfifo(folder / name)
    return edit


def link(name: str, target: str) -> object:
    """Replace a file of the folder by a symbolic link to ``target``."""
    def edit(folder: Path) -> None:
        (folder / name).unlink(missing_ok=True)
        (folder / name).symlink_to(target)
    return edit


def csv_lines(change) -> object:  # type: ignore[no-untyped-def]
    """Rewrite the lines of the rig CSV (line 6 of the file is the first sample)."""
    def edit(folder: Path) -> None:
        path = folder / "data.csv"
        path.write_text("\n".join(change(path.read_text(encoding="utf-8").splitlines())) + "\n",
                        encoding="utf-8")
    return edit


def utf16(name: str) -> object:
    def edit(folder: Path) -> None:
        path = folder / name
        path.write_bytes(path.read_text(encoding="utf-8").encode("utf-16"))
    return edit


def other_record(name: str) -> object:
    """A copy of the rig CSV with one sample changed: another record of the same rig."""
    def change(lines: list[str]) -> list[str]:
        fields = lines[-1].split(",")
        fields[1] = repr(float(fields[1]) + 0.5)
        return [*lines[:-1], ",".join(fields)]

    def edit(folder: Path) -> None:
        lines = (folder / "data.csv").read_text(encoding="utf-8").splitlines()
        (folder / name).write_text("\n".join(change(lines)) + "\n", encoding="utf-8")
    return edit


def ms_time(lines: list[str]) -> list[str]:
    """The time column of the rig CSV written in milliseconds as whole numbers, no unit."""
    out = [*lines[:4], lines[4].replace("time [s]", "time")]
    out += [f"{k}," + line.split(",", 1)[1] for k, line in enumerate(lines[5:])]
    return out


def mat_ns_time(folder: Path) -> None:
    """The struct MAT file with ``run.t`` in int64 nanoseconds."""
    import scipy.io

    t, u, y = arx_record()
    ns = np.round(t * 1e9).astype(np.int64)
    scipy.io.savemat(folder / "data.mat", {"run": {"signals": {"u": u[:, None], "y": y[:, None]},
                                                   "t": ns[:, None]}}, do_compression=True)


def h5_edit(change) -> object:  # type: ignore[no-untyped-def]
    def edit(folder: Path) -> None:
        import h5py

        with h5py.File(folder / "data.mat", "a") as f:
            change(f)
    return edit


def external_link(f) -> None:  # type: ignore[no-untyped-def]
    import h5py

    f["run"]["signals"]["far"] = h5py.ExternalLink("../../secret.mat", "/y")


def unwritten(f) -> None:  # type: ignore[no-untyped-def]
    f["run"]["signals"].create_dataset("big", shape=(1, 2**27), dtype="<f8")


def tdms_offset(folder: Path) -> None:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    t, u, y = arx_record()
    props = {"wf_increment": float(t[1] - t[0]), "wf_start_offset": 1e308}
    with TdmsWriter(str(folder / "data.tdms")) as writer:
        writer.write_segment([RootObject({}), GroupObject("command", {}),
                              ChannelObject("command", "AI0", u, props),
                              GroupObject("measure", {}),
                              ChannelObject("measure", "AI1", y, props)])


TWO_RECORDS = (other_record("val.csv"), set_("validation", "file", '"val.csv"'))

HOSTILE_CASES = [
    csv_case("data-fifo", "data.csv is a named pipe (FIFO), not a regular file", fifo("data.csv")),
    csv_case("data-link-to-dev-zero", "data.csv (a symbolic link to /dev/zero) is a character "
             "device, not a regular file", link("data.csv", "/dev/zero")),
    case("toml-fifo", "identify {in}/fifo.toml --out {out}", "fifo.toml is a named pipe (FIFO)", fifo("fifo.toml"),
         base="rigcsv"),
    csv_case("data-dangling-link", "no such file", link("data.csv", "gone.csv")),
    csv_case("data-link-loop", "data.csv is a symbolic link that loops", link("data.csv",
                                                                               "data.csv")),
    csv_case("csv-utf16", "it is UTF-16 (little-endian) text, with a byte-order mark (FF FE)",
             utf16("data.csv")),
    csv_case("csv-digit-grouping", "line 9, column 2: '1_000' groups its digits with '_'",
             csv_lines(lambda ls: [*ls[:8], ls[8].split(",")[0] + ",1_000," +
                                   ",".join(ls[8].split(",")[2:]), *ls[9:]])),
    csv_case("csv-bom-inside", "holds a byte-order mark (U+FEFF)",
             csv_lines(lambda ls: [*ls, "\ufeff" + ls[-1]])),
    csv_case("csv-header-cell-140k", "the header row cannot be split into cells",
             csv_lines(lambda ls: [*ls[:4], "x" * 140_000 + "," + ls[4], *ls[5:]])),
    csv_case("csv-delimiter-narx", "got 'narx'", set_("data", "delimiter", '"narx"')),
    csv_case("csv-time-ms-no-unit", "time column 'time' has no unit and holds whole numbers "
             "stepping by 1: likely milliseconds", csv_lines(ms_time)),
    csv_case("records-same-twice", "[data] file lists the same record twice",
             copy_("data.csv", "copy.csv"), set_("data", "file", '["data.csv", "copy.csv"]'),
             *TWO_RECORDS),
    csv_case("validation-is-estimation", "holds the same samples as the estimation record",
             copy_("data.csv", "val.csv"), set_("validation", "file", '"val.csv"')),
    mat_case("mat-int64-ns-time", "time vector 'run.t' has no unit and holds integers (int64)",
             mat_ns_time),
    mat_case("mat73-external-link", "variable 'run.signals.far' is an external link",
             h5_edit(external_link), set_("channels.y", "source", '"run.signals.far"'),
             base="rigmat73"),
    mat_case("mat73-unwritten-dataset", "but stores only 0 bytes", h5_edit(unwritten),
             set_("channels.y", "source", '"run.signals.big"'), base="rigmat73"),
    tdms_case("tdms-wf-start-offset-1e308", "wf_start_offset = 1e+308 s is too large",
              tdms_offset),
]

ALL = CSV_CASES + TDMS_CASES + MAT_CASES


@pytest.mark.parametrize("base", sorted(MAKERS))
def test_the_working_folders_load(base, rig_bases, tmp_path):
    """Each folder's records load as made, so a case fails by its edit alone.

    (Loading is the stage every case fails in; a full ``identify`` of each
    folder would add 30 s for nothing more.)
    """
    places = _prepare(Case(("identify",), "", base), rig_bases, tmp_path)
    estimation, (validation,) = load_experiment_spec(places["toml"]).records()
    _, u, y = arx_record()
    # the record of the working folder, split in halves, read back exactly
    np.testing.assert_array_equal(np.concatenate([estimation["u"], validation["u"]]), u)
    np.testing.assert_array_equal(np.concatenate([estimation["y"], validation["y"]]), y)


@pytest.mark.parametrize("entry", ALL)
def test_bad_input(entry: Case, rig_bases, tmp_path, capsys, monkeypatch):
    places = _prepare(entry, rig_bases, tmp_path)
    argv = [word.format(**places) for word in entry.argv]
    monkeypatch.chdir(tmp_path)
    before = _tree(tmp_path)

    code, out, err = _run(capsys, argv)
    assert code == entry.code, err
    assert entry.fragment in err, err
    assert "Traceback" not in out + err
    assert err.startswith("servoid: error: "), err
    code, out, err = _run(capsys, [*argv, "--json"])
    assert code == entry.code
    payload = json.loads(out)
    assert payload["ok"] is False
    assert entry.fragment in payload["error"]
    assert "Traceback" not in out + err

    assert _tree(tmp_path) == before


def _safe_tree(root: Path) -> dict[str, str]:
    """Every entry under ``root``: a regular file's SHA-256, else what it is (never opened)."""
    import hashlib
    import stat

    out = {}
    for path in sorted(root.rglob("*")):
        mode = path.lstat().st_mode
        key = path.relative_to(root).as_posix()
        if stat.S_ISLNK(mode):
            out[key] = f"link -> {os.readlink(path)}"
        elif stat.S_ISREG(mode):
            out[key] = hashlib.sha256(path.read_bytes()).hexdigest()
        else:
            out[key] = "dir" if stat.S_ISDIR(mode) else f"special {stat.S_IFMT(mode):o}"
    return out


@pytest.mark.parametrize("entry", HOSTILE_CASES)
def test_hostile_input(entry: Case, rig_bases, tmp_path, capsys, monkeypatch):
    places = _prepare(entry, rig_bases, tmp_path)
    argv = [word.format(**places) for word in entry.argv]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "secret.mat").write_bytes(b"")  # what an external link might reach
    before = _safe_tree(tmp_path)
    for flags in ([], ["--json"]):
        code, out, err = _run(capsys, [*argv, *flags])
        assert code == 1, err
        assert "Traceback" not in out + err
        message = json.loads(out)["error"] if flags else err
        assert flags or err.startswith("servoid: error: "), err
        assert entry.fragment in message, message
    assert _safe_tree(tmp_path) == before
