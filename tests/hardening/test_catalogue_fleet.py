"""The bad-input catalogue of ``servoid fleet`` (issue 21).

Each case runs ``servoid fleet`` in process on a private copy of a working
fleet (three small ARX records, a manifest and a fleet file) with one
thing wrong, and checks what the CLI catalogue checks: exit code 1, one
message on stderr naming the problem and the fix, no traceback, the same
answer under ``--json``, and the folder exactly as it was (no results
folder from a refused run).  The classes:

- a file that is not a regular file — a named pipe (FIFO), a device
  (``/dev/null`` here: a fleet that read ``/dev/zero`` would never end,
  and this catalogue must fail, not hang, when a check is lost), a
  symbolic-link loop — as the fleet file, the manifest, a record's
  experiment file, its data file or a TLS file: refused by name before
  anything is read (a FIFO used to stall the whole fleet);
- a glob leaving the fleet file's folder (``/**`` walked the whole file
  system);
- a fleet file nested too deeply, with numbers beyond a float or of
  thousands of digits, or not in UTF-8 (a UTF-16 or Latin-1 file; a UTF-8
  byte-order mark is accepted);
- a record that is a byte-identical copy of another (it counted as a
  second unit);
- a scheduler address that is malformed, of an unsupported protocol,
  plain ``tcp://`` without ``--insecure`` or ``tls://`` without its TLS
  files, and flags that need a scheduler or a local cluster.

A last test feeds spreadsheet formulas through the manifest: the run
succeeds and ``fleet.csv`` holds them as text.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import shutil
import stat
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from servoid.cli import main

Edit = Callable[[Path], None]

EXPERIMENT = """\
[data]
file = "data.csv"
time = "time"

[channels.u]
role = "u"
unit = "V"

[channels.y]
role = "y"
unit = "m"

[identify]
method = "arx"
na = 1
nb = 1
nk = 1
"""


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three ARX records (units/U0..U2), units.csv and fleet.toml."""
    root = tmp_path_factory.mktemp("fleet")
    rows = [["path", "serial"]]
    for k in range(3):
        rng = np.random.default_rng(k)
        u = np.repeat(rng.choice([-1.0, 1.0], 41), 5)[:200]
        y = np.zeros(200)
        for i in range(1, 200):
            y[i] = 0.8 * y[i - 1] + 0.5 * u[i - 1]
        y += 0.01 * rng.standard_normal(200)
        folder = root / "units" / f"U{k}"
        folder.mkdir(parents=True)
        lines = [f"{0.01 * i!r},{float(u[i])!r},{float(y[i])!r}" for i in range(200)]
        (folder / "data.csv").write_text("time [s],u [V],y [m]\n" + "\n".join(lines) + "\n",
                                         encoding="utf-8")
        (folder / "exp.toml").write_text(EXPERIMENT, encoding="utf-8")
        rows.append([f"units/U{k}/exp.toml", f"SN-{k}"])
    with (root / "units.csv").open("w", newline="", encoding="utf-8") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    (root / "fleet.toml").write_text('[records]\nmanifest = "units.csv"\n', encoding="utf-8")
    return root


# -- edits of a copy ---------------------------------------------------------------------------

_STOP = threading.Event()
_WRITERS: list[threading.Thread] = []


@pytest.fixture(autouse=True)
def _no_writer_left():
    _STOP.clear()
    yield
    _STOP.set()
    while _WRITERS:
        _WRITERS.pop().join()


def fifo(name: str) -> Edit:
    """Replace a file of the fleet folder with a named pipe, which a writer serves from 3 s on.

    A fleet that opened the pipe would wait, then read a line and go on:
    the case fails instead of hanging the suite.
    """
    def edit(folder: Path) -> None:
        path = folder / name
        path.unlink(missing_ok=True)
        os.mkfifo(path)

        def serve() -> None:
            _STOP.wait(3.0)
            while not _STOP.is_set():
                try:
                    fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
                except OSError:  # no reader now
                    _STOP.wait(0.2)
                    continue
                with os.fdopen(fd, "w") as f:
                    f.write("x\n")

        _WRITERS.append(threading.Thread(target=serve, daemon=True))
        _WRITERS[-1].start()
    return edit


def link(name: str, target: str) -> Edit:
    """Replace a file of the fleet folder with a symbolic link."""
    def edit(folder: Path) -> None:
        path = folder / name
        path.unlink(missing_ok=True)
        path.symlink_to(target)
    return edit


def fleet_file(text: str | bytes, name: str = "fleet.toml") -> Edit:
    """Replace the fleet file (or another file of the folder)."""
    def edit(folder: Path) -> None:
        data = text if isinstance(text, bytes) else text.encode("utf-8")
        (folder / name).write_bytes(data)
    return edit


def copy_record(source: str, target: str, serial: str) -> Edit:
    """Copy a record's folder byte for byte and list the copy in the manifest."""
    def edit(folder: Path) -> None:
        shutil.copytree(folder / "units" / source, folder / "units" / target)
        with (folder / "units.csv").open("a", encoding="utf-8") as f:
            f.write(f"units/{target}/exp.toml,{serial}\n")
    return edit


GLOB = '[records]\nglob = "{}"\n'
MANIFEST = '[records]\nmanifest = "units.csv"\n'


@dataclass(frozen=True)
class Case:
    """One bad input: the flags after ``fleet FLEET``, the copy's edits, the message."""

    flags: tuple[str, ...]
    edits: tuple[Edit, ...]
    fragment: str
    fleet: str = "fleet.toml"


CASES = {
    # not a regular file, anywhere a fleet reads one
    "fifo data file": Case((), (fifo("units/U1/data.csv"),),
                           "units/U1/data.csv (of record"),
    "fifo data file named": Case((), (fifo("units/U1/data.csv"),),
                                 "is a named pipe (FIFO), not a file"),
    "device data file": Case((), (link("units/U0/data.csv", "/dev/null"),),
                             "data.csv (of record"),
    "device named": Case((), (link("units/U0/data.csv", "/dev/null"),),
                         "is a device, not a file"),
    "link loop data file": Case((), (link("units/U2/data.csv", "data.csv"),),
                                "is a loop of symbolic links"),
    "fifo experiment file": Case((), (fifo("units/U1/exp.toml"),),
                                 "U1/exp.toml is a named pipe"),
    "link loop experiment file": Case((), (link("units/U1/exp.toml", "exp.toml"),),
                                      "U1/exp.toml is a loop of symbolic links"),
    "fifo manifest": Case((), (fifo("units.csv"),), "units.csv is a named pipe"),
    "fifo fleet file": Case((), (fifo("pipe.toml"),), "pipe.toml is a named pipe",
                            fleet="pipe.toml"),
    "fifo tls file": Case(("--scheduler", "tls://127.0.0.1:8786", "--tls-ca-file",
                           "{in}/ca.pem", "--tls-cert", "{in}/ca.pem"), (fifo("ca.pem"),),
                          "ca.pem' is not a regular file"),
    # globs leave the fleet file's folder
    "glob of the whole file system": Case((), (fleet_file(GLOB.format("/**")),),
                                          "is outside the fleet file's folder"),
    "glob of another folder": Case((), (fleet_file(GLOB.format("/tmp/*.toml")),),
                                   "write it relative to the folder"),
    "glob up the tree": Case((), (fleet_file(GLOB.format("../**/*.toml")),),
                             "leaves the fleet file's folder with '..'"),
    "glob finding a fifo": Case((), (fleet_file(GLOB.format("units/*/*.toml")),
                                     fifo("units/U0/x.toml")),
                                "x.toml is a named pipe"),
    # what the fleet file holds: nesting, numbers, encodings
    "deeply nested array": Case((), (fleet_file("[records]\nglob = " + "[" * 100_000
                                                + "]" * 100_000 + "\n"),),
                                "are nested too deeply to read"),
    "deeply nested tables": Case((), (fleet_file("a = " + "{b=" * 3000 + "1" + "}" * 3000
                                                 + "\n"),),
                                 "are nested too deeply to read"),
    "limit beyond a float": Case((), (fleet_file(MANIFEST + "[limits.a1]\nmin = 1"
                                                 + "0" * 400 + "\n"),),
                                 "min must be a finite number (at most about 1.8e308)"),
    "integer of 5000 digits": Case((), (fleet_file(MANIFEST + "[limits.a1]\nmin = 1"
                                                   + "0" * 5000 + "\n"),),
                                   "(4300 digits) for integer string conversion"),
    "tolerance beyond a float": Case((), (fleet_file(MANIFEST + "[limits.a1]\nnominal = 1e308"
                                                     "\ntolerance_percent = 100\n"),),
                                     "nominal ± tolerance finite"),
    "utf-16 fleet file": Case((), (fleet_file(MANIFEST.encode("utf-16")),),
                              "is UTF-16 text"),
    "latin-1 fleet file": Case((), (fleet_file(("# café\n" + MANIFEST).encode("latin-1")),),
                               "is not UTF-8 text: invalid continuation byte at byte 5 (line 1); "
                               "save it as UTF-8"),
    "utf-16 manifest": Case((), (fleet_file("path,serial\nunits/U0/exp.toml,A\n".encode(
                                "utf-16"), "units.csv"),),
                            "units.csv is UTF-16 text"),
    # a copy of a record is not a second unit
    "byte-identical record": Case((), (copy_record("U1", "U9", "SN-9"),),
                                  "SN-9 (" ),
    "byte-identical record fix": Case((), (copy_record("U1", "U9", "SN-9"),),
                                      "remove the copies from the fleet"),
    # scheduler addresses and the security they need
    "ucx scheduler": Case(("--scheduler", "ucx://127.0.0.1:8786"), (),
                          "ucx:// (UCX, websockets, in-process) is not supported"),
    "websocket scheduler": Case(("--scheduler", "ws://127.0.0.1:8786"), (),
                                "ws:// (UCX, websockets, in-process) is not supported"),
    "port out of range": Case(("--scheduler", "tls://127.0.0.1:99999"), (),
                              "a port from 1 to 65535"),
    "port not a number": Case(("--scheduler", "tls://127.0.0.1:port"), (),
                              "a port from 1 to 65535"),
    "no host": Case(("--scheduler", "tls://:8786"), (), "is not an address"),
    "empty address": Case(("--scheduler", ""), (), "is not an address"),
    "address with a path": Case(("--scheduler", "tls://h:1/x"), (), "is not an address"),
    "plain tcp": Case(("--scheduler", "tcp://127.0.0.1:8786"), (), "pass --insecure"),
    "no scheme is plain tcp": Case(("--scheduler", "127.0.0.1:8786"), (), "pass --insecure"),
    "tls without files": Case(("--scheduler", "tls://127.0.0.1:8786"), (),
                              "give --tls-ca-file, --tls-cert and --tls-key"),
    "tls files for tcp": Case(("--scheduler", "tcp://h:1", "--insecure", "--tls-ca-file",
                               "{in}/units.csv", "--tls-cert", "{in}/units.csv"), (),
                              "write the address as tls://host:port"),
    "missing tls file": Case(("--scheduler", "tls://h:1", "--tls-ca-file", "{in}/none.pem",
                              "--tls-cert", "{in}/units.csv"), (),
                             "none.pem' cannot be read"),
    "insecure without scheduler": Case(("--insecure",), (), "apply to a scheduler given"),
    "tls files without scheduler": Case(("--tls-cert", "{in}/units.csv"), (),
                                        "are for a scheduler given with --scheduler"),
    "dashboard of no cluster": Case(("--dashboard", "--workers", "1"), (),
                                    "runs the records in this process without one"),
    "dashboard of a remote scheduler": Case(("--dashboard", "--scheduler", "tls://h:1"), (),
                                            "serves its own dashboard"),
}


def _tree(root: Path) -> dict[str, str]:
    """Every path under `root`: a regular file's SHA-256, else its kind (never opened)."""
    out = {}
    for path in sorted(root.rglob("*")):
        mode = path.lstat().st_mode
        kind = ("link " + os.readlink(path) if stat.S_ISLNK(mode) else "dir" if
                stat.S_ISDIR(mode) else "fifo" if stat.S_ISFIFO(mode) else None)
        out[path.relative_to(root).as_posix()] = kind or hashlib.sha256(
            path.read_bytes()).hexdigest()
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_bad_fleet_input(name, base, tmp_path, capsys, monkeypatch):
    case = CASES[name]
    folder = tmp_path / "fleet"
    shutil.copytree(base, folder)
    for edit in case.edits:
        edit(folder)
    argv = ["fleet", str(folder / case.fleet), "--workers", "1",
            *[flag.format(**{"in": folder}) for flag in case.flags]]
    if "--scheduler" in case.flags:
        argv.remove("--workers")
        argv.remove("1")
    monkeypatch.chdir(tmp_path)
    before = _tree(tmp_path)
    for json_flag in ([], ["--json"]):
        code = main([*argv, *json_flag])
        out, err = capsys.readouterr()
        assert code == 1, err
        assert err.startswith("servoid: error: ") and case.fragment in err, err
        assert "Traceback" not in out + err
        if json_flag:
            payload = json.loads(out)
            assert payload["ok"] is False and case.fragment in payload["error"]
    assert _tree(tmp_path) == before


def test_spreadsheet_formulas_reach_fleet_csv_as_text(base, tmp_path, capsys):
    """Manifest cells that a spreadsheet would run are written with a leading quote."""
    folder = tmp_path / "fleet"
    shutil.copytree(base, folder)
    formulas = ['=HYPERLINK("http://example.com","x")', "+1+1", "-2+3+cmd|' /C calc'!A0",
                "@SUM(A1)"]
    rows = list(csv.reader((folder / "units.csv").open(encoding="utf-8")))
    with (folder / "units.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow([*rows[0], "=note"])
        for row, formula in zip(rows[1:], formulas, strict=False):
            writer.writerow([*row, formula])
    assert main(["fleet", str(folder / "fleet.toml"), "--workers", "1", "--quiet"]) == 0
    capsys.readouterr()
    table = list(csv.reader((folder / "fleet-results" / "fleet.csv").open(encoding="utf-8")))
    assert "'=note" in table[0]
    cells = [row[table[0].index("'=note")] for row in table[1:]]
    assert cells == ["'" + f for f in formulas[:3]]
