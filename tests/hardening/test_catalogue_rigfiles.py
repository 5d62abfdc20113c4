"""The bad-input catalogue of rig files as they come (issue 13, item 4).

The new ``[data]`` keys and channel names of the rig-file readers, through
``servoid identify`` in process: CSV ``skip_rows``, ``columns`` and
``skip_columns``; TDMS ``group`` and ``"group/channel"`` sources; MAT
struct fields named with dots (v5 written by scipy, v7.3 by h5py). Each
case copies a working experiment folder, breaks one thing and checks what
``test_catalogue_cli`` checks: exit code 1, one message on stderr naming the
key and the fix, the same under ``--json``, no traceback, and every input
unchanged with no stray file. The edit helpers and the runner's pieces are
those of ``test_catalogue_cli``; only the working folders are new.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_catalogue_cli import Case, _run, _tree, arx_record, case, del_, set_

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
