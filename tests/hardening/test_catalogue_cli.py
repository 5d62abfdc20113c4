"""The bad-input catalogue through the command line (issue 10, item 8).

Every case runs ``servoid`` in process through :func:`servoid.cli.main` on a
private copy of a working experiment folder with one thing wrong, and checks
what a user at a terminal sees:

1. the exit code: 1 for a servoid or file error, 2 for a usage error of the
   argument parser;
2. one message on stderr naming the fix (the TOML ``[table] key``, the flag
   or the file to change), and no traceback anywhere;
3. with ``--json`` (where the command has it), ``{"ok": false, ...}`` on
   stdout naming the same fix;
4. the inputs unchanged (SHA-256 of every file), and
5. no stray file or folder: the tree under the case's folder is exactly what
   it was (no ``.tmp``, no half-written results folder).

The working folders are made once per module: a small ARX record written
here, the virtual EHSA bench (closed loop, CSV and TDMS), a small MAT file,
an ARX folder with a complete earlier run, and a one-test pneumatic
campaign; a case copies one of them.  The damaged rig files are those of
``tests/data/corrupt/``.

A case whose fix belongs outside the command line's packages is a strict
``xfail`` whose reason names the file to fix; it flips to a failure once
fixed, so the mark is removed with the fix.  Two more tests close the
catalogue: ``$`` (matplotlib's math text) in channel names, units and the
file name must give a complete results folder, and a few cases run as
``python -m servoid`` to prove there is no traceback at process level.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from servoid.cli import main

ROOT = Path(__file__).resolve().parents[2]
CORRUPT = ROOT / "tests" / "data" / "corrupt"

Edit = Callable[[Path], None]

# -- the working folders -----------------------------------------------------------------------

ARX_TOML = """\
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
na = 2
nb = 2
nk = 1
"""

MAT_TOML = """\
[data]
file = "data.mat"
time = "t"

[channels.u]
role = "u"

[channels.y]
role = "y"

[identify]
method = "arx"
"""

N_ARX = 300  # samples of the small ARX record: 1.5 s of fitting per full run at most
DT_ARX = 0.01


def arx_record(n: int = N_ARX) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time, input and output of a first-order plant driven by a random binary signal."""
    rng = np.random.default_rng(1)
    u = np.repeat(rng.choice([-1.0, 1.0], n // 5 + 1), 5)[:n]
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1]
    y += 0.01 * rng.standard_normal(n)
    return DT_ARX * np.arange(n), u, y


def csv_text(t: Sequence[float], *columns: Sequence[float],
             header: str = "time [s],u [V],y [m]") -> str:
    rows = (",".join(repr(float(v)) for v in row) for row in zip(t, *columns, strict=True))
    return header + "\n" + "\n".join(rows) + "\n"


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Working experiment folders, made once: name → folder."""
    import scipy.io

    from servoid.plants.pneumatic import write_pneumatic_campaign

    root = tmp_path_factory.mktemp("bases")
    out: dict[str, Path] = {}

    arx = root / "arx"
    arx.mkdir()
    (arx / "data.csv").write_text(csv_text(*arx_record()), encoding="utf-8")
    (arx / "exp.toml").write_text(ARX_TOML, encoding="utf-8")
    out["arx"] = arx

    mat = root / "mat"
    mat.mkdir()
    t, u, y = arx_record()
    scipy.io.savemat(mat / "data.mat", {"t": t[:, None], "u": u[:, None], "y": y[:, None]})
    (mat / "exp.toml").write_text(MAT_TOML, encoding="utf-8")
    out["mat"] = mat

    # the EHSA bench, short: PRBS n = 7 at 4 samples per bit is 508 samples at 1 kHz
    for name, fmt in (("ehsa", "csv"), ("tdms", "tdms")):
        folder = root / name
        assert main(["bench", "ehsa", "--out", str(folder), "--format", fmt, "-n", "7",
                     "--clock", "4"]) == 0
        out[name] = folder

    # an ARX folder with a complete earlier run in exp-results/
    done = root / "done"
    shutil.copytree(arx, done)
    assert main(["identify", str(done / "exp.toml")]) == 0
    out["done"] = done

    pn = root / "pneumatic"
    write_pneumatic_campaign(pn, duration=0.3, tests=("valve",), format="csv")
    out["pneumatic"] = pn
    return out


# -- edits of a copy -----------------------------------------------------------------------------

TOML_NAME = {"arx": "exp.toml", "mat": "exp.toml", "done": "exp.toml", "ehsa": "ehsa.toml",
             "tdms": "ehsa.toml", "pneumatic": "pneumatic.toml"}


def _edit_toml(folder: Path, change: Callable[[str], str]) -> None:
    path = folder / "input.toml"
    path.write_text(change(path.read_text(encoding="utf-8")), encoding="utf-8")


def _table_span(lines: list[str], table: str) -> tuple[int, int] | None:
    header = re.compile(rf"\[{re.escape(table)}\]\s*(#.*)?$")
    start = next((i for i, line in enumerate(lines) if header.match(line)), None)
    if start is None:
        return None
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("[")),
               len(lines))
    return start, end


def set_(table: str, key: str, literal: str) -> Edit:
    """Set ``key = literal`` in ``[table]`` (the table is added when missing)."""
    def edit(folder: Path) -> None:
        def change(text: str) -> str:
            lines = text.splitlines()
            span = _table_span(lines, table)
            if span is None:
                return text + f"\n[{table}]\n{key} = {literal}\n"
            start, end = span
            for i in range(start + 1, end):
                if re.match(rf"{re.escape(key)}\s*=", lines[i]):
                    lines[i] = f"{key} = {literal}"
                    break
            else:
                lines.insert(start + 1, f"{key} = {literal}")
            return "\n".join(lines) + "\n"
        _edit_toml(folder, change)
    return edit


def del_(table: str, key: str) -> Edit:
    """Remove ``key`` from ``[table]``."""
    def edit(folder: Path) -> None:
        def change(text: str) -> str:
            lines = text.splitlines()
            start, end = _table_span(lines, table) or (0, 0)
            kept = [line for i, line in enumerate(lines)
                    if not (start < i < end and re.match(rf"{re.escape(key)}\s*=", line))]
            assert kept != lines, f"no {key} in [{table}]"
            return "\n".join(kept) + "\n"
        _edit_toml(folder, change)
    return edit


def drop(table: str) -> Edit:
    """Remove ``[table]`` and its sub-tables."""
    def edit(folder: Path) -> None:
        def change(text: str) -> str:
            lines = text.splitlines()
            out, skipping = [], False
            for line in lines:
                if line.startswith("["):
                    name = line.strip("[] \t").split("#")[0].strip("[] ")
                    skipping = name == table or name.startswith(table + ".")
                if not skipping:
                    out.append(line)
            assert out != lines, f"no [{table}]"
            return "\n".join(out) + "\n"
        _edit_toml(folder, change)
    return edit


def toml(content: str | bytes) -> Edit:
    """Replace the experiment file."""
    def edit(folder: Path) -> None:
        path = folder / "input.toml"
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    return edit


def sub(pattern: str, repl: str) -> Edit:
    """Regular-expression substitution in the experiment file (must match)."""
    def edit(folder: Path) -> None:
        def change(text: str) -> str:
            new, n = re.subn(pattern, repl, text, flags=re.MULTILINE)
            assert n, f"{pattern!r} not in the experiment file"
            return new
        _edit_toml(folder, change)
    return edit


def write(name: str, content: str | bytes) -> Edit:
    """Write a file of the input folder."""
    def edit(folder: Path) -> None:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    return edit


def copy_in(source: str | Path, name: str) -> Edit:
    """Copy a file of the input folder (a relative name) or from elsewhere into it."""
    def edit(folder: Path) -> None:
        shutil.copy(folder / source if isinstance(source, str) else source, folder / name)
    return edit


def halve(name: str) -> Edit:
    """Cut a file of the input folder to its first half."""
    def edit(folder: Path) -> None:
        path = folder / name
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    return edit


def corrupt_edits(path: Path) -> tuple[Edit, ...]:
    """Point the ARX experiment at a damaged rig file of tests/data/corrupt."""
    if path.suffix == ".tdms":  # one channel u of group g
        channels = '[channels.u]\nsource = "u"\nrole = "u"\n\n[channels.y]\nsource = "u"\n'\
                   'role = "y"\n\n'
        data_table = f'[data]\nfile = "{path.name}"\ngroup = "g"\ndt = 0.001\n\n'
    else:  # variables x (and y), or the char array c
        var = "c" if "_char_" in path.stem else "x"
        channels = f'[channels.u]\nsource = "{var}"\nrole = "u"\n\n[channels.y]\n'\
                   f'source = "{var}"\nrole = "y"\n\n'
        data_table = f'[data]\nfile = "{path.name}"\ndt = 0.001\n\n'
    return (copy_in(path, path.name), rm("data.csv"),
            toml(data_table + channels + '[identify]\nmethod = "arx"\n'))


def rm(name: str) -> Edit:
    """Delete a file of the input folder."""
    def edit(folder: Path) -> None:
        (folder / name).unlink()
    return edit


def data(change: Callable[[list[str]], list[str]], name: str = "data.csv",
         newline: bool = True) -> Edit:
    """Rewrite the lines of a CSV rig file."""
    def edit(folder: Path) -> None:
        path = folder / name
        lines = change(path.read_text(encoding="utf-8").splitlines())
        path.write_text("\n".join(lines) + ("\n" if newline else ""), encoding="utf-8")
    return edit


def record(t: Sequence[float], u: Sequence[float], y: Sequence[float],
           header: str = "time [s],u [V],y [m]") -> Edit:
    """Replace the ARX rig file with these samples."""
    return write("data.csv", csv_text(t, u, y, header=header))


def cell(row: int, column: int, value: str) -> Edit:
    """Set one cell of data.csv (row 0 is the first sample)."""
    def change(lines: list[str]) -> list[str]:
        fields = lines[row + 1].split(",")
        fields[column] = value
        lines[row + 1] = ",".join(fields)
        return lines
    return data(change)


# -- the cases -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One bad input: the command line, the copy's edits and what the user must see."""

    argv: tuple[str, ...]
    fragment: str
    base: str | None = "arx"
    edits: tuple[Edit, ...] = ()
    code: int = 1
    json: bool = True


def case(id: str, argv: str | Sequence[str], fragment: str, *edits: Edit,
         base: str | None = "arx", code: int = 1, json: bool | None = None,
         xfail: str | None = None) -> object:
    """A parameter of the catalogue.

    ``argv`` is a string split on spaces or a list; ``{toml}`` is the copied
    experiment file (``input.toml``), ``{in}`` the input folder and
    ``{out}`` an output folder that does not exist yet.
    """
    words = tuple(argv.split()) if isinstance(argv, str) else tuple(argv)
    entry = Case(words, fragment, base, edits, code, code == 1 if json is None else json)
    marks = [pytest.mark.xfail(strict=True, reason=xfail)] if xfail else []
    return pytest.param(entry, id=id, marks=marks)


ID = "identify {toml} --out {out}"

t_arx, u_arx, y_arx = arx_record()
t15, u15, y15 = arx_record(15)

USAGE = [
    case("no-command", [], "required: COMMAND", base=None, code=2),
    case("unknown-command", "identfy {toml}", "invalid choice: 'identfy'", code=2),
    case("unknown-flag", "identify {toml} --frobnicate", "unrecognized arguments: --frobnicate",
         code=2),
    case("identify-no-file", "identify", "required: experiment", base=None, code=2),
    case("identify-two-files", "identify {toml} {toml}", "unrecognized arguments", code=2),
    case("identify-out-no-value", "identify {toml} --out", "argument --out: expected one argument",
         code=2),
    case("methods-extra", "methods arx oe", "unrecognized arguments: oe", base=None, code=2),
    case("bench-no-rig", "bench", "required: RIG", base=None, code=2),
    case("bench-unknown-rig", "bench hydraulic --out {out}", "invalid choice: 'hydraulic'",
         base=None, code=2),
    case("bench-no-out", "bench ehsa", "required: --out", base=None, code=2),
    case("bench-fs-text", "bench ehsa --out {out} --fs fast", "argument --fs: invalid float",
         base=None, code=2),
    case("bench-seed-float", "bench ehsa --out {out} --seed 1.5", "argument --seed: invalid int",
         base=None, code=2),
    case("bench-set-D", "bench ehsa --out {out} --set D", "argument --set: invalid choice: 'D'",
         base=None, code=2),
    case("bench-format-xlsx", "bench ehsa --out {out} --format xlsx",
         "argument --format: invalid choice: 'xlsx'", base=None, code=2),
    case("bench-reference", "bench ehsa --out {out} --reference dac",
         "argument --reference: invalid choice", base=None, code=2),
    case("pneumatic-duration-text", "bench pneumatic --out {out} --duration long",
         "argument --duration: invalid float", base=None, code=2),
    case("excite-no-signal", "excite", "required: SIGNAL", base=None, code=2),
    case("excite-unknown-signal", "excite square --dt 0.001 --out {out}/s.csv",
         "invalid choice: 'square'", base=None, code=2),
    case("prbs-no-register", "excite prbs --dt 0.001 --out {out}/s.csv",
         "required: --register/-n", base=None, code=2),
    case("prbs-register-text", "excite prbs -n seven --dt 0.001 --out {out}/s.csv",
         "argument --register/-n: invalid int", base=None, code=2),
    case("prbs-no-dt", "excite prbs -n 7 --out {out}/s.csv", "required: --dt", base=None,
         code=2),
    case("random-multisine-no-size", "excite random-multisine --f-min 1 --f-max 10 --dt 0.001 "
         "--out {out}/s.csv", "one of the arguments --period --resolution is required",
         base=None, code=2),
    case("chirp-method", "excite chirp --duration 1 --f0 1 --f1 10 --dt 0.001 --method cubic "
         "--out {out}/s.csv", "argument --method: invalid choice: 'cubic'", base=None, code=2),
    case("multisine-phases", "excite multisine --period 100 --f-min 1 --f-max 10 --dt 0.001 "
         "--phases golden --out {out}/s.csv", "argument --phases: invalid choice", base=None,
         code=2),
    case("demo-seed-text", "demo --out {out} --seed x", "argument --seed: invalid int",
         base=None, code=2),
    case("usage-json", "identify {toml} --json --bogus", "unrecognized arguments: --bogus",
         code=2, json=True),
    case("identify-max-bytes-text", "identify {toml} --max-bytes lots",
         "argument --max-bytes: invalid int", code=2),
]

METHODS = [
    case("methods-unknown", "methods nosuch", "[identify] method must be one of", base=None),
    case("methods-typo", "methods OE", "'oe'", base=None),
]

def excite(id: str, args: str, fragment: str, *, out: str = "{out}.csv", base: str = "arx",
           edits: tuple[Edit, ...] = (), xfail: str | None = None) -> object:
    """A case of ``servoid excite``: ``args`` without ``--out`` (and ``--dt`` 1 ms by default)."""
    kind, _, rest = args.partition(" ")
    dt = "" if "--dt" in rest else "--dt 0.001 "
    argv = f"excite {kind} {dt}{rest} --out {out}"
    return case(id, argv, fragment, *edits, base=base, xfail=xfail)


EXCITE_CASES = [
    excite("random-multisine-short-test", "random-multisine --f-min 1 --f-max 10 --period 1000 "
           "--test-time 1", "--test-time = 1 s holds 1 period"),
    excite("random-multisine-band", "random-multisine --f-min 50 --f-max 10 --period 1000",
           "--f-min must be <= f_max (--f-max) = 10 Hz"),
    excite("random-multisine-plan-exists", "random-multisine --f-min 1 --f-max 10 --period 1000",
           "--overwrite", out="{in}/ms.csv", edits=(write("ms.plan.json", "{}"),)),
    excite("prbs-n31", "prbs -n 31", "raise --max-samples"),
    excite("prbs-n32", "prbs -n 32", "--register/-n must be in 2..31"),
    excite("prbs-n1", "prbs -n 1", "--register/-n must be in 2..31"),
    excite("prbs-n-negative", "prbs -n -3", "--register/-n must be in 2..31"),
    excite("prbs-clock-0", "prbs -n 7 --clock 0", "--clock must be a positive"),
    excite("prbs-periods-0", "prbs -n 7 --periods 0", "--periods must be a positive"),
    excite("prbs-periods-huge", "prbs -n 20 --periods 100000", "raise --max-samples"),
    excite("prbs-dt-0", "prbs -n 7 --dt 0", "--dt must be > 0"),
    excite("prbs-dt-negative", "prbs -n 7 --dt -0.001", "--dt must be > 0"),
    excite("prbs-dt-nan", "prbs -n 7 --dt nan", "--dt must be finite"),
    excite("prbs-dt-inf", "prbs -n 7 --dt inf", "--dt must be finite"),
    excite("prbs-amplitude-nan", "prbs -n 7 --amplitude nan", "--amplitude must be finite"),
    excite("prbs-amplitude-inf", "prbs -n 7 --amplitude inf", "--amplitude must be finite"),
    excite("prbs-offset-inf", "prbs -n 7 --offset inf", "--offset must be finite"),
    excite("prbs-max-samples-0", "prbs -n 7 --max-samples 0", "--max-samples must be a positive"),
    excite("prbs-max-samples-small", "prbs -n 7 --max-samples 10", "raise --max-samples"),
    excite("prbs-extension", "prbs -n 7", "from its extension, one of 'csv', 'tdms'",
           out="{out}.txt"),
    excite("prbs-no-extension", "prbs -n 7", "from its extension, one of 'csv', 'tdms'",
           out="{in}/signal"),
    excite("prbs-mat", "prbs -n 7", "from its extension, one of 'csv', 'tdms'; got 'mat'",
           out="{out}.mat"),
    excite("prbs-missing-folder", "prbs -n 7", "does not exist", out="{in}/no/such/s.csv"),
    excite("prbs-exists", "prbs -n 7", "--overwrite", out="{in}/data.csv"),
    excite("prbs-exists-tdms", "prbs -n 7", "--overwrite", out="{in}/ehsa.tdms", base="tdms"),
    excite("prbs-out-is-folder", "prbs -n 7 --overwrite", "directory", out="{in}/sub.csv",
           edits=(write("sub.csv/keep", "x"),)),
    excite("prbs-out-is-input-folder", "prbs -n 7 --overwrite", "is a directory, not a file",
           out="{in}"),
    excite("prbs-plant-unknown", "prbs -n 7 --unit m --plant rocket",
           "--plant 'rocket': the plants with limits to check are ehsa"),
    excite("prbs-plant-volts", "prbs -n 7 --plant ehsa", "pass --unit m"),
    excite("prbs-plant-set", "prbs -n 7 --unit m --amplitude 1e-4 --plant ehsa --set Z",
           "--set 'Z': the EHSA's parameter sets are B, C"),
    excite("prbs-channel-empty", "prbs -n 7 --channel=", "--channel must be a non-empty string"),
    excite("prbs-channel-time", "prbs -n 7 --channel time", "choose another --channel"),
    excite("prbs-unit-bracket", "prbs -n 7 --unit ]", "--unit"),
    excite("chirp-duration-1e9", "chirp --duration 1e9 --f0 1 --f1 10", "raise --max-samples"),
    excite("chirp-duration-0", "chirp --duration 0 --f0 1 --f1 10", "--duration must be > 0"),
    excite("chirp-duration-negative", "chirp --duration -1 --f0 1 --f1 10",
           "--duration must be > 0"),
    excite("chirp-duration-nan", "chirp --duration nan --f0 1 --f1 10",
           "--duration must be finite"),
    excite("chirp-duration-inf", "chirp --duration inf --f0 1 --f1 10",
           "--duration must be finite"),
    excite("chirp-negative-fs", "chirp --duration 1 --f0 1 --f1 10 --dt -0.001",
           "--dt must be > 0"),
    excite("chirp-f1-above-nyquist", "chirp --duration 1 --f0 1 --f1 600",
           "--f1 must be below the Nyquist"),
    excite("chirp-f0-negative", "chirp --duration 1 --f0 -1 --f1 10", "--f0 must be >= 0"),
    excite("chirp-log-from-0", "chirp --duration 1 --f0 0 --f1 10 --method logarithmic",
           "--f0 must be > 0"),
    excite("chirp-f0-nan", "chirp --duration 1 --f0 nan --f1 10", "--f0 must be finite"),
    excite("multisine-period-0", "multisine --period 0 --f-min 1 --f-max 10",
           "--period must be an integer >= 4"),
    excite("multisine-period-1", "multisine --period 1 --f-min 1 --f-max 10",
           "--period must be an integer >= 4"),
    excite("multisine-period-huge", "multisine --period 1000000000 --f-min 1 --f-max 10",
           "--max-samples"),
    excite("multisine-fmin-above-fmax", "multisine --period 1000 --f-min 50 --f-max 10",
           "--f-min"),
    excite("multisine-fmax-nyquist", "multisine --period 1000 --f-min 1 --f-max 900",
           "--f-max must be below the Nyquist"),
    excite("multisine-fmin-negative", "multisine --period 1000 --f-min -1 --f-max 10",
           "--f-min must be >= 0"),
    excite("multisine-band-empty", "multisine --period 10 --f-min 1 --f-max 2",
           "lengthen --period"),
    excite("multisine-periods-0", "multisine --period 100 --f-min 10 --f-max 100 --periods 0",
           "--periods must be a positive"),
]

BENCH = "bench ehsa --out {out} -n 7 --clock 4"

BENCH_CASES = [
    case("bench-fs-0", BENCH + " --fs 0", "--fs must be a finite number > 0", base=None),
    case("bench-fs-negative", BENCH + " --fs -1000", "--fs must be a finite number > 0", base=None),
    case("bench-fs-nan", BENCH + " --fs nan", "--fs must be a finite number > 0", base=None),
    case("bench-fs-inf", BENCH + " --fs inf", "--fs must be a finite number > 0", base=None),
    case("bench-fs-huge", BENCH + " --fs 1e12", "--fs", base=None),
    case("bench-facq-not-multiple", BENCH + " --facq 5500",
         "--facq = 5500 Hz must be an integer multiple of f_s (--fs)", base=None),
    case("bench-facq-below-fs", BENCH + " --facq 500",
         "--facq = 500 Hz must be an integer multiple", base=None),
    case("bench-facq-negative", BENCH + " --facq -5000", "--facq must be a finite number > 0",
         base=None),
    case("bench-seed-negative", BENCH + " --seed -1", "--seed must be an integer >= 0", base=None),
    case("bench-fidelity", BENCH + " --fidelity exact", "--fidelity must be one of", base=None),
    case("bench-clock-0", BENCH + " --clock 0", "--clock must be >= 1", base=None),
    case("bench-register-1", "bench ehsa --out {out} -n 1", "--register/-n must be in 2..31",
         base=None),
    case("bench-register-40", "bench ehsa --out {out} -n 40", "--register/-n must be in 2..31",
         base=None),
    case("bench-periods-0", BENCH + " --periods 0", "--periods must be a positive", base=None),
    case("bench-periods-huge", BENCH + " --periods 1000000000", "raise --max-samples", base=None),
    case("bench-amplitude-0", BENCH + " --amplitude 0", "--amplitude must be > 0", base=None),
    case("bench-amplitude-nan", BENCH + " --amplitude nan", "--amplitude must be a finite",
         base=None),
    case("bench-amplitude-stroke", BENCH + " --amplitude 1", "lower the amplitude (--amplitude)",
         base=None),
    case("bench-snr-nan", BENCH + " --snr nan", "--snr must be a finite", base=None),
    case("bench-bits-4", BENCH + " --bits 4", "--bits must lie in 8..24", base=None),
    case("bench-bits-40", BENCH + " --bits 40", "--bits must lie in 8..24", base=None),
    case("bench-out-is-file", "bench ehsa --out {in}/data.csv -n 7 --clock 4",
         "give --out a folder"),
    case("bench-out-exists", "bench ehsa --out {in} -n 7 --clock 4 --format csv",
         "choose another name or pass --overwrite", base="ehsa"),
    case("bench-out-exists-tdms", "bench ehsa --out {in} -n 7 --clock 4 --format tdms",
         "--overwrite", base="ehsa"),
    case("pneumatic-test-unknown", "bench pneumatic --out {out} --tests valve leak",
         "--tests must be one of", base=None),
    case("pneumatic-duration-0", "bench pneumatic --out {out} --duration 0",
         "--duration must be a finite", base=None),
    case("pneumatic-duration-negative", "bench pneumatic --out {out} --duration -1",
         "--duration must be a finite", base=None),
    case("pneumatic-duration-1e9", "bench pneumatic --out {out} --duration 1e9",
         "lower the acquisition rate (--facq)", base=None),
    case("pneumatic-facq-0", "bench pneumatic --out {out} --facq 0", "--facq must be a finite",
         base=None),
    case("pneumatic-facq-negative", "bench pneumatic --out {out} --facq -10000",
         "--facq must be a finite", base=None),
    case("pneumatic-snr-inf", "bench pneumatic --out {out} --snr inf", "--snr must be a finite",
         base=None),
    case("pneumatic-seed-negative", "bench pneumatic --out {out} --seed -1 --duration 0.1",
         "--seed must be an integer >= 0", base=None),
]


def add(table: str, body: str) -> Edit:
    """Append a table to the experiment file."""
    def edit(folder: Path) -> None:
        _edit_toml(folder, lambda text: text + f"\n[{table}]\n{body}\n")
    return edit


def method(name: str) -> Edit:
    """Replace ``[identify]`` by ``method = name`` alone."""
    return sub(r"^\[identify\][^\[]*", f'[identify]\nmethod = "{name}"\n\n')


VALIDATION_CSV = csv_text(t_arx[:100], u_arx[:100], y_arx[:100])
JUNK = bytes((7 * k + 3) % 256 for k in range(512))  # deterministic binary junk


def truncated(lines: list[str]) -> list[str]:
    """The last number cut short, as an interrupted logger leaves it (no final newline)."""
    lines[-1] = lines[-1][:-6]
    return lines


TOML_CASES = [
    # -- the file itself ---------------------------------------------------------------------
    case("toml-missing", "identify {in}/nope.toml --out {out}", "nope.toml: no such file"),
    case("toml-is-folder", "identify {in} --out {out}", "not a regular file"),
    case("toml-empty", ID, "missing the required key(s) data, channels", toml("")),
    case("toml-binary", ID, "is not UTF-8 text", toml(JUNK)),
    case("toml-non-utf8", ID, "is not UTF-8 text: invalid continuation byte at byte 18 (line 2); "
         "save it as UTF-8",
         toml('[data]\nfile = "caf\xe9.csv"\n'.encode("latin-1"))),
    case("toml-unclosed-table", ID, "not a valid TOML file", sub(r"^\[data\]$", "[data")),
    case("toml-duplicate-key", ID, "not a valid TOML file",
         sub(r'^file = "data.csv"$', 'file = "data.csv"\nfile = "data.csv"')),
    case("toml-duplicate-table", ID, "not a valid TOML file", add("identify", "na = 3")),
    case("toml-bad-string", ID, "not a valid TOML file", sub(r'^file = "data.csv"$',
                                                             'file = "data.csv')),
    case("toml-unknown-table", ID, "unknown key(s) in the top level: 'output'",
         add("output", 'folder = "x"')),
    case("toml-no-data", ID, "missing the required key(s) data", drop("data")),
    case("toml-no-channels", ID, "missing the required key(s) channels", drop("channels")),
    # -- [data] ------------------------------------------------------------------------------
    case("data-scalar", ID, "[data] must be a table",
         sub(r"^\[data\]\n[^\[]*", "data = 3\n\n")),
    case("data-no-file", ID, "[data] is missing the required key(s) file", del_("data", "file")),
    case("data-file-int", ID, "[data] file must be a non-empty string", set_("data", "file", "3")),
    case("data-file-empty", ID, "[data] file must be a non-empty string",
         set_("data", "file", '""')),
    case("data-file-empty-list", ID, "[data] file must name at least one file",
         set_("data", "file", "[]")),
    case("data-file-list-int", ID, "[data] file must be a non-empty string",
         set_("data", "file", '["data.csv", 3]')),
    case("data-file-missing", ID, "nope.csv: no such file", set_("data", "file", '"nope.csv"')),
    case("data-file-is-folder", ID, "not a regular file", set_("data", "file", '"sub.csv"'),
         write("sub.csv/keep.txt", "x")),
    case("data-file-extension", ID, "cannot tell the format of 'data.txt'", set_("data", "file",
                                                                                 '"data.txt"'),
         copy_in("data.csv", "data.txt")),
    case("data-format-unknown", ID, "[data] format must be one of",
         set_("data", "format", '"xls"')),
    case("data-format-int", ID, "[data] format must be a non-empty string",
         set_("data", "format", "3")),
    case("data-format-wrong", ID, "data.csv: cannot be read as TDMS", set_("data", "format",
                                                                           '"tdms"')),
    case("data-group-csv", ID, "group applies to TDMS files only", set_("data", "group", '"g"')),
    case("data-dt-zero", ID, "[data] dt must be > 0", set_("data", "dt", "0")),
    case("data-dt-negative", ID, "[data] dt must be > 0", set_("data", "dt", "-0.01")),
    case("data-dt-text", ID, "[data] dt must be a finite number", set_("data", "dt", '"fast"')),
    case("data-dt-nan", ID, "[data] dt must be a finite number", set_("data", "dt", "nan")),
    case("data-dt-inf", ID, "[data] dt must be a finite number", set_("data", "dt", "inf")),
    case("data-dt-disagrees", ID, "dt = 0.02 s disagrees with the time stamps", set_("data", "dt",
                                                                                     "0.02")),
    case("data-time-int", ID, "[data] time must be a non-empty string", set_("data", "time", "5")),
    case("data-time-missing", ID, "[data] time", set_("data", "time", '"t"')),
    case("data-unknown-key", ID, "unknown key(s) in [data]: 'separator'",
         set_("data", "separator", '";"')),
    # -- [channels] --------------------------------------------------------------------------
    case("channels-empty", ID, "[channels] must hold at least one table",
         sub(r"^\[channels\.u\]\n[^\[]*\[channels\.y\]\n[^\[]*", "[channels]\n\n")),
    case("channel-scalar", ID, "[channels.u] must be a table",
         sub(r"^\[channels\.u\]\nrole = \"u\"\nunit = \"V\"\n\n\[channels\.y\]",
             "[channels]\nu = 5\n\n[channels.y]")),
    case("channel-role-bad", ID, "[channels.u] role must be one of",
         set_("channels.u", "role", '"input"')),
    case("channel-role-int", ID, "[channels.u] role must be one of",
         set_("channels.u", "role", "1")),
    case("channel-gain-zero", ID, "[channels.u] gain must be non-zero",
         set_("channels.u", "gain", "0")),
    case("channel-gain-text", ID, "[channels.u] gain must be a finite number",
         set_("channels.u", "gain", '"2"')),
    case("channel-gain-inf", ID, "[channels.u] gain must be a finite number",
         set_("channels.u", "gain", "inf")),
    case("channel-offset-nan", ID, "[channels.y] offset must be a finite number",
         set_("channels.y", "offset", "nan")),
    case("channel-unit-int", ID, "[channels.y] unit must be a string",
         set_("channels.y", "unit", "3")),
    case("channel-limits-short", ID, "[channels.y] limits must be [low, high]",
         set_("channels.y", "limits", "[1.0]")),
    case("channel-limits-reversed", ID, "low < high", set_("channels.y", "limits", "[1.0, -1.0]")),
    case("channel-limits-text", ID, "[channels.y] limits must be a finite number",
         set_("channels.y", "limits", '["a", "b"]')),
    case("channel-source-empty", ID, "[channels.y] source must be a non-empty string",
         set_("channels.y", "source", '""')),
    case("channel-source-int", ID, "[channels.y] source must be a non-empty string",
         set_("channels.y", "source", "3")),
    case("channel-source-absent", ID, "channel 'pos' (servoid channel 'y') is not in",
         set_("channels.y", "source", '"pos"')),
    case("channel-unknown-key", ID, "unknown key(s) in [channels.u]: 'scale'",
         set_("channels.u", "scale", "2.0")),
    case("channel-no-output", ID, 'role = "y"', drop("channels.y")),
    case("channel-no-input", ID, "[identify] input = 'u' needs a channel", drop("channels.u")),
    case("channel-two-outputs", ID, "[identify] output",
         add("channels.y2", 'source = "y"\nrole = "y"')),
    # -- [preprocess] ------------------------------------------------------------------------
    case("lowpass-1e-6", ID, "[preprocess] lowpass", set_("preprocess", "lowpass", "1e-6")),
    case("lowpass-zero", ID, "[preprocess] lowpass must be > 0",
         set_("preprocess", "lowpass", "0")),
    case("lowpass-negative", ID, "[preprocess] lowpass must be > 0",
         set_("preprocess", "lowpass", "-5.0")),
    case("lowpass-text", ID, "[preprocess] lowpass must be a finite number",
         set_("preprocess", "lowpass", '"fast"')),
    case("lowpass-above-nyquist", ID, "[preprocess] lowpass",
         set_("preprocess", "lowpass", "60.0")),
    case("lowpass-at-nyquist", ID, "[preprocess] lowpass", set_("preprocess", "lowpass", "50.0")),
    case("decimate-zero", ID, "[preprocess] decimate must be an integer >= 1",
         set_("preprocess", "decimate", "0")),
    case("decimate-float", ID, "[preprocess] decimate must be an integer >= 1",
         set_("preprocess", "decimate", "2.5")),
    case("decimate-text", ID, "[preprocess] decimate must be an integer >= 1",
         set_("preprocess", "decimate", '"2"')),
    case("decimate-beyond-record", ID, "[preprocess] decimate",
         set_("preprocess", "decimate", "1000")),
    case("detrend-bad", ID, "[preprocess] detrend must be one of",
         set_("preprocess", "detrend", '"quadratic"')),
    case("preprocess-unknown-key", ID, "unknown key(s) in [preprocess]: 'filter'",
         set_("preprocess", "filter", "3")),
    case("preprocess-scalar", ID, "[preprocess] must be a table",
         sub(r"^\[data\]", "preprocess = 3\n\n[data]")),
    # -- [split] -----------------------------------------------------------------------------
    case("split-fraction-0", ID, "[split] fraction must lie in (0, 1)",
         set_("split", "fraction", "0.0")),
    case("split-fraction-1", ID, "[split] fraction must lie in (0, 1)",
         set_("split", "fraction", "1.0")),
    case("split-fraction-1.5", ID, "[split] fraction must lie in (0, 1)",
         set_("split", "fraction", "1.5")),
    case("split-fraction-text", ID, "[split] fraction must be a finite number",
         set_("split", "fraction", '"half"')),
    case("split-fraction-and-index", ID, "[split]: give fraction or index, not both",
         set_("split", "fraction", "0.5"), set_("split", "index", "100")),
    case("split-index-1", ID, "[split] index must be an integer >= 2",
         set_("split", "index", "1")),
    case("split-index-beyond-record", ID, "[split] index", set_("split", "index", "1000000000")),
    case("split-period-1", ID, "[split] period must be an integer >= 2",
         set_("split", "period", "1")),
    case("split-period-beyond-record", ID, "[split] period", set_("split", "period", "100000")),
    case("split-skip-without-period", ID, "[split]: skip_periods needs period",
         set_("split", "skip_periods", "1")),
    case("split-skip-negative", ID, "[split] skip_periods must be an integer >= 0",
         set_("split", "skip_periods", "-1")),
    case("split-skip-all", ID, "[split] skip_periods", set_("split", "period", "50"),
         set_("split", "skip_periods", "6")),
    case("split-unknown-key", ID, "unknown key(s) in [split]: 'ratio'",
         set_("split", "ratio", "0.5")),
    # -- [validation] ------------------------------------------------------------------------
    case("validation-missing", ID, "nope.csv: no such file",
         add("validation", 'file = "nope.csv"')),
    case("validation-no-file", ID, "[validation] needs file",
         add("validation", 'initial = "zero"')),
    case("validation-other-format", ID, "the validation record must be written like the "
         "estimation one", add("validation", 'file = "v.tdms"')),
    case("validation-figure", ID, "cannot tell the format of 'out/validation.png'",
         add("validation", 'file = "out/validation.png"')),
    case("validation-initial-bad", ID, "[validation] initial must be one of",
         add("validation", 'file = "val.csv"\ninitial = "rest"'), write("val.csv", VALIDATION_CSV)),
    case("validation-transient-negative", ID, "[validation] transient must be an integer >= 0",
         add("validation", 'file = "val.csv"\ntransient = -1'), write("val.csv", VALIDATION_CSV)),
    case("validation-transient-beyond", ID, "[validation] transient must lie",
         add("validation", 'file = "val.csv"\ntransient = 100000'),
         write("val.csv", VALIDATION_CSV)),
    case("validation-and-split", ID, "remove [split]", add("validation", 'file = "val.csv"'),
         add("split", "fraction = 0.5"), write("val.csv", VALIDATION_CSV)),
    case("validation-empty-csv", ID, "empty CSV file", add("validation", 'file = "val.csv"'),
         write("val.csv", "")),
    case("validation-other-dt", ID, "record both at one rate",
         add("validation", 'file = "val.csv"'),
         write("val.csv", csv_text(2 * t_arx[:100], u_arx[:100], y_arx[:100]))),
    case("validation-channel-absent", ID, "channel 'y' (servoid channel 'y') is not in",
         add("validation", 'file = "val.csv"'),
         write("val.csv", csv_text(t_arx[:100], u_arx[:100], y_arx[:100],
                                   header="time [s],u [V],pos [m]"))),
    case("validation-three-samples", ID, "the 3-sample validation record", add("validation",
                                                                               'file = "val.csv"'),
         write("val.csv", csv_text(t_arx[:3], u_arx[:3], y_arx[:3]))),
    case("data-two-files-no-validation", ID, "add [validation] file",
         set_("data", "file", '["data.csv", "data.csv"]')),
    case("validation-unused-by-method", ID, "[validation] table",
         method("pneumatic-multistep"), add("validation", 'file = "val.csv"'),
         write("val.csv", VALIDATION_CSV)),
    # -- [identify] --------------------------------------------------------------------------
    case("method-unknown", ID, "[identify] method must be one of",
         set_("identify", "method", '"nosuch"')),
    case("method-int", ID, "[identify] method must be one of", set_("identify", "method", "3")),
    case("identify-unknown-key", ID, "unknown key(s) in [identify]: foo",
         set_("identify", "foo", "1")),
    case("identify-scalar", ID, "[identify] must be a table",
         sub(r"^\[identify\]\n[^\[]*", "") , sub(r"^\[data\]", "identify = 3\n\n[data]")),
    case("identify-nested", ID, "nested more than one level deep",
         add("identify.grid", "deep = {a = 1}")),
    case("identify-array-of-tables", ID, "arrays may hold only strings, numbers and booleans",
         set_("identify", "runs", "[{a = 1}]")),
    case("na-negative", ID, "[identify] na", set_("identify", "na", "-1")),
    case("nb-zero", ID, "[identify] nb", set_("identify", "nb", "0")),
    case("nk-negative", ID, "[identify] nk", set_("identify", "nk", "-1")),
    case("na-text", ID, "[identify] na must be an integer", set_("identify", "na", '"two"')),
    case("na-float", ID, "[identify] na must be an integer", set_("identify", "na", "2.5")),
    case("na-beyond-record", ID, "(na=1000, nb=2, nk=1)", set_("identify", "na", "1000")),
    case("nb-beyond-record", ID, "lower orders", set_("identify", "nb", "500")),
    case("nk-beyond-record", ID, "lower orders", set_("identify", "nk", "10000")),
    case("na-grid-negative", ID, "[identify] na", set_("identify", "na", "[1, -1]")),
    case("na-grid-empty", ID, "[identify] na", set_("identify", "na", "[]")),
    case("horizon-1e9", ID, "[identify] horizon must be an integer",
         set_("identify", "horizon", "1e9")),
    case("horizon-beyond-record", ID, "[identify] horizon",
         set_("identify", "horizon", "1000000000")),
    case("horizon-zero", ID, "[identify] horizon must be >= 1", set_("identify", "horizon", "0")),
    case("criterion-bad", ID, "[identify] criterion must be one of",
         set_("identify", "criterion", '"best"')),
    case("input-bad", ID, "[identify] input", set_("identify", "input", '"y"')),
    case("output-absent", ID, "[identify] output = 'pos' is not a channel",
         set_("identify", "output", '"pos"')),
    case("inverse-position-absent", ID, "[identify] position = 'pos' is not a channel",
         method("inverse-dynamics"), set_("identify", "position", '"pos"')),
    case("frf-reference-absent", ID, "[identify] reference = 'r' is not a channel", method("frf"),
         set_("identify", "reference", '"r"')),
    case("oe-nf-negative", ID, "[identify] nf", method("oe"), set_("identify", "nf", "-1")),
    case("oe-multistart-negative", ID, "[identify] multistart", method("oe"),
         set_("identify", "multistart", "-1")),
    case("oe-max-iter-zero", ID, "[identify] max_iter", method("oe"),
         set_("identify", "max_iter", "0")),
    case("oe-tol-negative", ID, "[identify] tol", method("oe"), set_("identify", "tol", "-1.0")),
    case("oe-covariance-bad", ID, "[identify] covariance must be one of", method("oe"),
         set_("identify", "covariance", '"exact"')),
    case("oe-initial-bad", ID, "[identify] initial must be one of", method("oe"),
         set_("identify", "initial", '"rest"')),
    case("oe-seed-negative", ID, "[identify] seed", method("oe"),
         set_("identify", "seed", "-1")),
    case("tf-poles-zero", ID, "[identify] n_poles", method("tf"),
         set_("identify", "n_poles", "0")),
    case("tf-zeros-above-poles", ID, "lower n_zeros or raise n_poles", method("tf"),
         set_("identify", "n_poles", "2"), set_("identify", "n_zeros", "5")),
    case("tf-delay-negative", ID, "[identify] delay", method("tf"),
         set_("identify", "delay", "-0.01")),
    case("tf-intersample-bad", ID, "[identify] intersample must be one of", method("tf"),
         set_("identify", "intersample", '"linear"')),
    case("n4sid-order-zero", ID, "[identify] order", method("n4sid"),
         set_("identify", "order", "0")),
    case("n4sid-order-beyond-record", ID, "or a lower order", method("n4sid"),
         set_("identify", "order", "500")),
    case("n4sid-weighting-bad", ID, "[identify] weighting must be one of", method("n4sid"),
         set_("identify", "weighting", '"pca"')),
    case("n4sid-blocks-short", ID, "[identify] horizon_blocks", method("n4sid"),
         set_("identify", "horizon_blocks", "[1]")),
    case("frf-nperseg-1", ID, "[identify] nperseg", method("frf"),
         set_("identify", "nperseg", "1")),
    case("frf-nperseg-beyond-record", ID, "pass nperseg <= 75", method("frf"),
         set_("identify", "nperseg", "100000")),
    case("frf-estimator-bad", ID, "[identify] estimator must be one of", method("frf"),
         set_("identify", "estimator", '"fft"')),
    case("frf-f-max-negative", ID, "[identify] f_max", method("frf"),
         set_("identify", "f_max", "-1.0")),
    # -- [report] and where outputs go -------------------------------------------------------
    case("report-folder-escapes", "identify {toml}", "pass --out <folder> (or --allow-outside)",
         add("report", 'folder = "../../x"')),
    case("report-folder-parent", "identify {toml}", "points outside the experiment file's folder",
         add("report", 'folder = ".."')),
    case("report-unknown-key", ID, "unknown key(s) in [report]: format",
         add("report", 'format = "pdf"')),
    case("report-folder-int", ID, "[report] folder must be a string", add("report", "folder = 3")),
    case("out-is-file", "identify {toml} --out {in}/data.csv", "is a file, not a folder"),
    case("out-earlier-results", "identify {toml} --out {in}/exp-results",
         "exists from an earlier run; pass --overwrite", base="done"),
    case("out-over-data", "identify {toml} --out {in} --overwrite", "it is an input of this run",
         set_("data", "file", '"results.json"'), set_("data", "format", '"csv"'),
         copy_in("data.csv", "results.json"), rm("data.csv")),
    case("out-over-figure", "identify {toml} --out {in} --overwrite",
         "it is an input of this run", set_("data", "file", '"validation.png"'),
         set_("data", "format", '"csv"'), copy_in("data.csv", "validation.png"), rm("data.csv")),
    case("max-bytes-small", ID + " --max-bytes 100", "--max-bytes"),
    case("max-bytes-zero", ID + " --max-bytes 0", "--max-bytes must be an integer >= 1"),
    case("max-bytes-negative", ID + " --max-bytes -5", "--max-bytes must be an integer >= 1"),
    case("max-bytes-toml", ID, "over the budget", set_("data", "max_bytes", "100")),
    # -- rig files ---------------------------------------------------------------------------
    case("csv-missing", ID, "data.csv: no such file", rm("data.csv")),
    case("csv-empty", ID, "empty CSV file", write("data.csv", "")),
    case("csv-blank-lines", ID, "empty CSV file", write("data.csv", "\n\n# a comment\n\n")),
    case("csv-header-only", ID, "header but no data rows", write("data.csv",
                                                                 "time [s],u [V],y [m]\n")),
    case("csv-nan", ID, "channel 'y' has 1 non-finite value(s)", cell(10, 2, "nan")),
    case("csv-inf", ID, "channel 'u' has 1 non-finite value(s)", cell(10, 1, "inf")),
    case("csv-text-cell", ID, "data.csv, line 12, column 2", cell(10, 1, "abc")),
    case("csv-time-jitter", ID, "time stamps are not uniform", cell(100, 0, "1.005")),
    case("csv-time-backwards", ID, "time stamps are not uniform", cell(100, 0, "0.5")),
    case("csv-time-repeated", ID, "time stamps are not uniform", cell(100, 0, "0.99")),
    case("csv-truncated", ID, "looks truncated", data(truncated, newline=False)),
    case("csv-ragged", ID, "2 field(s), the header has 3", data(lambda ls: [*ls[:50], "0.49,1.0",
                                                                            *ls[51:]])),
    case("csv-channel-names", ID, "channel 'u' (servoid channel 'u') is not in",
         data(lambda ls: ["time [s],in [V],out [m]", *ls[1:]])),
    case("csv-one-sample", ID, "1 sample(s), need >= 2", record(t_arx[:1], u_arx[:1], y_arx[:1])),
    case("csv-two-samples", ID, "data.csv", record(t_arx[:2], u_arx[:2], y_arx[:2])),
    case("csv-15-samples", ID, "validation", record(t15, u15, y15)),
    case("csv-constant-input", ID, "persistently exciting",
         record(t_arx, np.ones(N_ARX), y_arx)),
    case("csv-zero-input", ID, "persistently exciting", record(t_arx, np.zeros(N_ARX), y_arx)),
    case("csv-values-1e160", ID, "Rescale the channel", record(t_arx, 1e160 * u_arx,
                                                               1e160 * y_arx)),
    case("csv-non-utf8", ID, "not a text CSV file", write("data.csv", b"time [s],u [\xb5V]\n")),
    case("csv-binary", ID, "data.csv: not a text CSV file", write("data.csv", JUNK)),
    case("csv-time-hours", ID, "time column 'time' has unit 'h'",
         data(lambda ls: ["time [h],u [V],y [m]", *ls[1:]])),
    case("csv-semicolons", ID, "separated by ';': set [data] delimiter = ';'",
         data(lambda ls: [x.replace(",", ";") for x in ls])),
    case("csv-decimal-comma", ID, "use a decimal comma: set [data] decimal = ','",
         set_("data", "delimiter", '";"'),
         data(lambda ls: [x.replace(",", ";").replace(".", ",") for x in ls])),
    case("csv-duplicate-column", ID, "channel name 'u' is repeated",
         data(lambda ls: ["time [s],u [V],u [m]", *ls[1:]])),
    case("csv-empty-header-cell", ID, "column 2: empty channel name",
         data(lambda ls: ["time [s],,y [m]", *ls[1:]])),
    case("csv-corrupt-fixture", ID, "csv_truncated_last_number.csv",
         set_("data", "file", '"csv_truncated_last_number.csv"'),
         copy_in(CORRUPT / "csv_truncated_last_number.csv", "csv_truncated_last_number.csv")),
    case("mat-junk", ID, "data.mat: cannot be read as a MAT file", write("data.mat", JUNK),
         base="mat"),
    case("mat-empty", ID, "data.mat: truncated MAT file", write("data.mat", b""), base="mat"),
    case("mat-half", ID, "a truncated or damaged MAT file", halve("data.mat"), base="mat"),
    case("mat-variable-absent", ID, "variable 'pos' is not in", set_("channels.y", "source",
                                                                     '"pos"'), base="mat"),
    case("mat-time-absent", ID, "variable 'clock' is not in", set_("data", "time", '"clock"'),
         base="mat"),
    case("tdms-junk", ID, "ehsa.tdms: cannot be read as TDMS", write("ehsa.tdms", JUNK),
         base="tdms"),
    case("tdms-empty", ID, "ehsa.tdms: cannot be read as TDMS", write("ehsa.tdms", b""),
         base="tdms"),
    case("tdms-half", ID, "ehsa.tdms: truncated or damaged TDMS file", halve("ehsa.tdms"),
         base="tdms"),
    case("tdms-group-absent", ID, "has no group 'nosuch'", set_("data", "group", '"nosuch"'),
         base="tdms"),
    case("tdms-channel-absent", ID, "channel 'AI9' (servoid channel 'y_pos') is not in",
         set_("channels.y_pos", "source", '"AI9"'), base="tdms"),
    *(case(f"corrupt-{path.stem}", ID, path.name, *corrupt_edits(path))
      for path in sorted(CORRUPT.glob("*.mat")) + sorted(CORRUPT.glob("*.tdms"))),
]

CL = "identify {toml} --out {out}"  # the closed-loop bench experiment: errors before the fit
# the campaign made here has the valve test alone: every test names its file
PN_TESTS = tuple(set_("identify", test, '"valve.toml"')
                 for test in ("thermo", "flow", "friction", "validation"))

CLOSED_LOOP_CASES = [
    case("truth-missing", CL, "[report] truth file", set_("report", "truth", '"nope.json"'),
         base="ehsa"),
    case("truth-not-json", CL, "is not valid JSON", write("truth.json", "{bad"), base="ehsa"),
    case("truth-binary", CL, "is not UTF-8 text", write("truth.json", JUNK), base="ehsa"),
    case("truth-folder", CL, "is a folder, not a regular file; pass the path of a file", set_("report", "truth", '"."'), base="ehsa"),
    case("truth-is-rig-file", CL, "is not valid JSON", set_("report", "truth", '"ehsa.csv"'),
         base="ehsa"),
    case("truth-is-output", "identify {toml} --out {in} --overwrite",
         "it is an input of this run", set_("report", "truth", '"results.json"'),
         copy_in("truth.json", "results.json"), base="ehsa"),
    case("loop-missing", CL, "add [loop] with c =", drop("loop"), base="ehsa"),
    case("loop-c-zero", CL, "[loop] c", set_("loop", "c", "0.0"), base="ehsa"),
    case("loop-c-text", CL, "[loop] c must be a number", set_("loop", "c", '"x"'), base="ehsa"),
    case("loop-F-nan", CL, "[loop] F", set_("loop", "F", "nan"), base="ehsa"),
    case("approach-bad", CL, "[identify] approach must be one of",
         set_("identify", "approach", '"guess"'), base="ehsa"),
    case("approach-empty", CL, "[identify] approach is empty",
         set_("identify", "approach", "[]"), base="ehsa"),
    case("nominal-bad", CL, "[identify] nominal must be one of",
         set_("identify", "nominal", '"Z"'), base="ehsa"),
    case("refine-bad-name", CL, "[identify] refine", set_("identify", "refine", '["mass"]'),
         base="ehsa"),
    case("structure-test-text", CL, "[identify] structure_test must be true or false",
         set_("identify", "structure_test", '"yes"'), base="ehsa"),
    case("prefilter-zero", CL, "[identify] prefilter must be > 0",
         set_("identify", "prefilter", "0.0"), base="ehsa"),
    case("cl-na-beyond-record", CL, "lower orders", set_("identify", "na", "100000"), base="ehsa"),
    case("rig-order-0", CL, "[rig] anti_alias order must be an integer >= 1",
         set_("rig.anti_alias", "order", "0"), base="ehsa"),
    case("rig-order-20", CL, "[rig] anti_alias order must be an analog Butterworth order 1..10",
         set_("rig.anti_alias", "order", "20"), base="ehsa"),
    case("rig-cutoff-negative", CL, "[rig] anti_alias cutoff must be > 0",
         set_("rig.anti_alias", "cutoff", "-1000.0"), base="ehsa"),
    case("rig-cutoff-missing", CL, "[rig] anti_alias is missing the required key(s) cutoff",
         del_("rig.anti_alias", "cutoff"), base="ehsa"),
    case("rig-reference-bad", CL, "[rig] reference must be one of",
         set_("rig", "reference", '"dac"'), base="ehsa"),
    case("rig-unknown-key", CL, "unknown key(s) in [rig]: 'adc'", set_("rig", "adc", "16"),
         base="ehsa"),
    case("rig-command-lowpass", CL, "remove lowpass", set_("rig", "reference", '"command"'),
         set_("preprocess", "lowpass", "100.0"), base="ehsa"),
    case("ehsa-channel-role-swapped", CL, "Map the command channel to role 'r'",
         set_("channels.yr_cmd", "role", '"side"'), base="ehsa"),
    case("pneumatic-sub-missing", CL, "[identify] thermo = \"<thermo.toml>\" is needed",
         base="pneumatic"),
    case("pneumatic-sub-nope", CL, "nope.toml", *PN_TESTS,
         set_("identify", "valve", '"nope.toml"'), base="pneumatic"),
    case("pneumatic-sub-self", CL, "names this campaign file itself", *PN_TESTS,
         set_("identify", "valve", '"input.toml"'), base="pneumatic"),
    case("pneumatic-sub-broken", CL, "valve.toml", *PN_TESTS, write("valve.toml", "[data"),
         base="pneumatic"),
    case("pneumatic-derivatives", CL, "derivatives must be one of", *PN_TESTS,
         set_("identify", "derivatives", '"fast"'), base="pneumatic"),
    case("pneumatic-known-text", CL, "[identify.known] m_k must be a number", *PN_TESTS,
         set_("identify.known", "m_k", '"heavy"'), base="pneumatic"),
    case("demo-foreign-folder", "demo --out {in}", "holds no earlier demo"),
    case("demo-out-is-file", "demo --out {in}/data.csv", "give --out a folder"),
    case("demo-seed-negative", "demo --out {out} --seed -1", "--seed", base=None),
]

ALL = USAGE + METHODS + EXCITE_CASES + BENCH_CASES + TOML_CASES + CLOSED_LOOP_CASES


# -- the runner ------------------------------------------------------------------------------------


def _tree(root: Path) -> dict[str, str]:
    """Every file (its SHA-256) and folder ("dir") under ``root``."""
    out = {}
    for path in sorted(root.rglob("*")):
        key = path.relative_to(root).as_posix()
        out[key] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _prepare(entry: Case, bases: dict[str, Path], tmp_path: Path) -> dict[str, str]:
    # two levels deep, so that "../../x" from the experiment file stays inside tmp_path
    folder = tmp_path / "lab" / "rig"
    folder.parent.mkdir()
    if entry.base is None:
        folder.mkdir()
    else:
        source = bases[entry.base]
        shutil.copytree(source, folder)
        toml_name = TOML_NAME[entry.base]
        (folder / toml_name).rename(folder / "input.toml")
    for edit in entry.edits:
        edit(folder)
    return {"toml": str(folder / "input.toml"), "in": str(folder), "out": str(tmp_path / "out")}


def _run(capsys: pytest.CaptureFixture[str], argv: Sequence[str]) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("entry", ALL)
def test_bad_input(entry: Case, bases, tmp_path, capsys, monkeypatch):
    places = _prepare(entry, bases, tmp_path)
    argv = [word.format(**places) for word in entry.argv]
    monkeypatch.chdir(tmp_path)  # anything written relative to the working folder stays here
    before = _tree(tmp_path)

    code, out, err = _run(capsys, argv)
    assert code == entry.code, err
    assert entry.fragment in err, err
    assert "Traceback" not in out + err
    if entry.code == 1:
        assert err.startswith("servoid: error: "), err
    if entry.json:
        code, out, err = _run(capsys, [*argv, "--json"] if "--json" not in argv else argv)
        assert code == entry.code
        payload = json.loads(out)
        assert payload["ok"] is False
        assert entry.fragment in payload["error"]
        assert "Traceback" not in out + err

    assert _tree(tmp_path) == before


# -- math text: valid input that used to end in a traceback ------------------------------------

MATH_CSV_HEADER = "time [s],$u^$ [$V$],$y^$ [$\\frac$]"
MATH_TOML = """\
[data]
file = "data.csv"
time = "time"

[channels."$u^$"]
role = "u"

[channels."$y^$"]
role = "y"

[identify]
method = "{method}"
"""


@pytest.mark.parametrize("method", ["arx", "frf", "n4sid"])
def test_math_text_in_names_units_and_titles(method, bases, tmp_path, capsys, monkeypatch):
    """``$`` in channel names, units and the file name reaches every figure as typed.

    Matplotlib reads ``$x^$`` as broken math text and raises while saving;
    the run must succeed and write a complete results folder.
    """
    folder = tmp_path / "rig"
    folder.mkdir()
    (folder / "data.csv").write_text(csv_text(*arx_record(), header=MATH_CSV_HEADER),
                                     encoding="utf-8")
    toml_path = folder / "$exp^$.toml"  # the record's name titles the validation figure
    order = "order = 2\n" if method == "n4sid" else ""  # no order search: a faster run
    toml_path.write_text(MATH_TOML.format(method=method) + order, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    inputs = _tree(folder)

    code, out, err = _run(capsys, ["identify", str(toml_path), "--out", str(tmp_path / "out"),
                                   "--json"])
    assert code == 0, err
    assert "Traceback" not in out + err
    payload = json.loads(out)
    assert payload["ok"] is True
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text(encoding="utf-8"))
    names = {f["name"] for f in manifest["files"]}
    assert {"results.json", "report.html"} <= names
    assert any(name.endswith(".png") for name in names)
    assert {p.name for p in (tmp_path / "out").iterdir()} == names | {"manifest.json"}
    assert _tree(folder) == inputs


# -- the installed command, as a process --------------------------------------------------------

PROCESS_CASES = [
    (["identify", "{toml}", "--json"], 1, "is not UTF-8 text", toml(JUNK)),
    (["bench", "ehsa", "--out", "{out}", "--fs", "-1", "--json"], 1, "--fs must be", None),
    (["excite", "prbs", "-n", "31", "--dt", "0.001", "--out", "{out}.csv", "--json"], 1,
     "raise --max-samples", None),
    (["identify", "{toml}", "--frobnicate", "--json"], 2, "unrecognized arguments", None),
]


@pytest.mark.parametrize(("argv", "code", "fragment", "edit"), PROCESS_CASES,
                         ids=["toml-binary", "bench-fs", "prbs-n31", "usage"])
def test_no_traceback_from_the_process(argv, code, fragment, edit, bases, tmp_path):
    """``python -m servoid``: the exit code and a JSON answer, not a traceback."""
    entry = Case(tuple(argv), fragment, "arx", (edit,) if edit else (), code)
    places = _prepare(entry, bases, tmp_path)
    before = _tree(tmp_path)
    done = subprocess.run([sys.executable, "-m", "servoid",
                           *(word.format(**places) for word in argv)],
                          capture_output=True, text=True, timeout=120, check=False,
                          cwd=tmp_path)
    assert done.returncode == code, done.stderr
    assert "Traceback" not in done.stdout + done.stderr
    assert fragment in done.stderr
    payload = json.loads(done.stdout)
    assert payload["ok"] is False and fragment in payload["error"]
    assert _tree(tmp_path) == before


def test_a_failure_while_writing_leaves_no_half_written_results(bases, tmp_path, capsys,
                                                                 monkeypatch):
    """A figure that fails after others were written: the run's files all go, folders too."""
    import servoid.workflows._lti as lti
    from servoid import DataError

    def broken(*args: object, **kwargs: object) -> None:
        raise DataError("the residual figure failed")

    places = _prepare(Case(("identify",), ""), bases, tmp_path)
    monkeypatch.setattr(lti, "plot_residuals", broken)  # written after the validation figure
    monkeypatch.chdir(tmp_path)
    before = _tree(tmp_path)
    code, out, err = _run(capsys, ["identify", places["toml"], "--out",
                                   f"{places['out']}/deep/results"])
    assert code == 1
    assert "the residual figure failed" in err and "Traceback" not in out + err
    assert _tree(tmp_path) == before
