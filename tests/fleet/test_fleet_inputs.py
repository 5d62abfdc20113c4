"""A fleet's inputs checked before they are read: regular files, confined globs, no copies.

And its table safe to open in a spreadsheet.  Each refusal must come
before any record runs and name the file and the fix.
"""

from __future__ import annotations

import codecs
import csv
import os
import shutil
import threading
from pathlib import Path

import pytest
from _arx_fleet import write_fleet, write_record

from servoid import DataError, OptionError
from servoid.fleet import load_fleet_spec, run_fleet


@pytest.fixture
def fifo():
    """Make named pipes that a writer serves, from 3 s on, to whoever opens them.

    Code that opens one waits, then reads a line and goes on, so a fleet
    without the check fails the test instead of waiting for ever.
    """
    stop = threading.Event()
    writers = []

    def make(path: Path) -> Path:
        os.mkfifo(path)

        def serve() -> None:
            stop.wait(3.0)
            while not stop.is_set():
                try:
                    fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
                except OSError:  # no reader now
                    stop.wait(0.2)
                    continue
                with os.fdopen(fd, "w") as f:
                    f.write("x\n")

        writers.append(threading.Thread(target=serve, daemon=True))
        writers[-1].start()
        return path

    yield make
    stop.set()
    for writer in writers:
        writer.join()


def test_a_fifo_as_a_data_file_is_refused_by_name_before_any_record(tmp_path, fifo):
    fleet = write_fleet(tmp_path, ["A", "B", "C"])
    data = tmp_path / "units" / "U1" / "data.csv"
    data.unlink()
    fifo(data)
    with pytest.raises(DataError, match=r"U1/data\.csv \(of record .*\) is a named pipe "
                                        r"\(FIFO\).*regular files only"):
        run_fleet(fleet, workers=1, progress=False)
    assert not (tmp_path / "fleet-results").exists()  # the refused run left no folder


@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda p: p.symlink_to("/dev/null"), "is a device, not a file"),
        (lambda p: p.symlink_to(p.name), "is a loop of symbolic links"),
        (lambda p: p.mkdir(), "is a folder, not a file"),
    ],
)
def test_other_data_files_that_are_not_files(tmp_path, make, fragment):
    fleet = write_fleet(tmp_path, ["A", "B"])
    data = tmp_path / "units" / "U0" / "data.csv"
    data.unlink()
    make(data)
    with pytest.raises(DataError, match=fragment):
        run_fleet(fleet, workers=1, progress=False)


def test_fleet_file_manifest_and_experiment_files_must_be_regular(tmp_path, fifo):
    fleet = write_fleet(tmp_path, ["A", "B"])
    fifo(tmp_path / "pipe.toml")
    with pytest.raises(DataError, match=r"fleet file .*pipe\.toml is a named pipe"):
        load_fleet_spec(tmp_path / "pipe.toml")
    (tmp_path / "units.csv").rename(tmp_path / "saved.csv")
    fifo(tmp_path / "units.csv")
    with pytest.raises(DataError, match=r"manifest .*units\.csv is a named pipe"):
        load_fleet_spec(fleet)
    (tmp_path / "units.csv").unlink()
    (tmp_path / "saved.csv").rename(tmp_path / "units.csv")
    toml = tmp_path / "units" / "U1" / "exp.toml"
    toml.unlink()
    fifo(toml)
    with pytest.raises(DataError, match=r"names 1 path\(s\) that are not regular files: "
                                        r".*U1/exp\.toml is a named pipe"):
        load_fleet_spec(fleet)


def test_globs_stay_in_the_fleet_files_folder(tmp_path, fifo):
    for k in range(2):
        write_record(tmp_path / "runs" / f"r{k}", seed=k)
    fleet = tmp_path / "fleet.toml"

    def spec(pattern: str):
        fleet.write_text(f"[records]\nglob = {pattern!r}\n", encoding="utf-8")
        return load_fleet_spec(fleet)

    assert [r.path.parent.name for r in spec("runs/*/exp.toml").records] == ["r0", "r1"]
    assert len(spec("**/exp.toml").records) == 2
    assert len(spec(str(tmp_path / "runs" / "*" / "exp.toml")).records) == 2  # absolute, inside
    with pytest.raises(OptionError, match="is outside the fleet file's folder"):
        spec("/**")
    with pytest.raises(OptionError, match="is outside the fleet file's folder"):
        spec(str(tmp_path.parent / "*" / "exp.toml"))
    with pytest.raises(OptionError, match="leaves the fleet file's folder with '..'"):
        spec("runs/../../**/*.toml")
    # a link loop and a link out of the folder: ** does not follow linked folders
    (tmp_path / "runs" / "loop").symlink_to(tmp_path / "runs")
    (tmp_path / "runs" / "out").symlink_to(tmp_path.parent)
    assert len(spec("**/exp.toml").records) == 2
    # hidden files only when the pattern names them
    write_record(tmp_path / ".old" / "r9", seed=9)
    assert len(spec("**/exp.toml").records) == 2
    assert len(spec(".old/*/exp.toml").records) == 1
    fifo(tmp_path / "runs" / "r0" / "x.toml")
    with pytest.raises(DataError, match=r"finds 1 path\(s\) that are not regular files: "
                                        r".*x\.toml is a named pipe"):
        spec("runs/*/*.toml")


def test_a_copy_of_a_record_is_not_a_second_unit(tmp_path):
    fleet = write_fleet(tmp_path, ["A", "B", "C"])
    shutil.copytree(tmp_path / "units" / "U1", tmp_path / "units" / "U9")
    with (tmp_path / "units.csv").open("a", encoding="utf-8") as f:
        f.write("units/U9/exp.toml,D\n")
    with pytest.raises(DataError, match=r"1 record\(s\) hold byte-identical copies of another "
                                        r"record's data: D \(.*U9/exp\.toml\) repeats B"):
        run_fleet(fleet, workers=1, progress=False)
    assert not (tmp_path / "fleet-results").exists()
    # another experiment file reading the same data file is the same test too
    (tmp_path / "units" / "U9" / "exp.toml").write_text(
        (tmp_path / "units" / "U1" / "exp.toml").read_text(encoding="utf-8").replace(
            '"data.csv"', '"../U1/data.csv"') + "\n# another file\n", encoding="utf-8")
    with pytest.raises(DataError, match="repeats B"):
        run_fleet(fleet, workers=1, progress=False)
    result = run_fleet(fleet, workers=1, progress=False, allow_duplicates=True)
    assert result.count("ok") == 4


def test_spreadsheet_formulas_in_fleet_csv_are_neutralised(tmp_path):
    hostile = '=HYPERLINK("http://x","click")'
    fleet = write_fleet(tmp_path, [hostile, "+1-2", "@SUM(A1)"])
    rows = list(csv.reader((tmp_path / "units.csv").open(encoding="utf-8")))
    with (tmp_path / "units.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow([*rows[0], "=cmd|' /C calc'!A0", "temperature"])
        writer.writerows([*r, "\tx", "-5"] for r in rows[1:])
    result = run_fleet(fleet, workers=1, progress=False)
    table = list(csv.reader((result.folder / "fleet.csv").open(encoding="utf-8")))
    header, first = table[0], table[1]
    assert "'=cmd|' /C calc'!A0" in header
    assert first[header.index("serial")] == "'" + hostile
    assert [r[header.index("serial")] for r in table[2:]] == ["'+1-2", "'@SUM(A1)"]
    assert first[header.index("temperature")] == "-5"  # a number stays a number
    assert first[header.index("'=cmd|' /C calc'!A0")] == "'\tx"
    assert float(first[header.index("a1")]) < 0  # negative estimates untouched
    assert result.rows[0]["serial"] == hostile  # the data themselves are not changed


def test_a_manifest_with_a_byte_order_mark_reads_as_without(tmp_path):
    """Spreadsheets save "CSV UTF-8" with a BOM; its first column is still ``path``."""
    fleet = write_fleet(tmp_path, ["A", "B"])
    manifest = tmp_path / "units.csv"
    manifest.write_bytes(codecs.BOM_UTF8 + manifest.read_bytes())
    assert [r.serial for r in load_fleet_spec(fleet).records] == ["A", "B"]


def test_a_record_whose_experiment_file_nests_too_deeply_is_a_failed_row(tmp_path):
    fleet = write_fleet(tmp_path, ["A", "B"])
    (tmp_path / "units" / "U1" / "exp.toml").write_text(
        "[data]\nfile = " + "[" * 100_000 + "]" * 100_000 + "\n", encoding="utf-8")
    result = run_fleet(fleet, workers=1, progress=False)
    assert [r["status"] for r in result.rows] == ["ok", "failed"]
