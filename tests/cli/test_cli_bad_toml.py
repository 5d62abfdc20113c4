"""``servoid identify`` on experiment files with wrongly typed or malformed values.

Each case edits a copy of a working experiment file (the virtual EHSA bench's,
or the EMPS example's) and expects exit code 1, one readable message on
stderr naming the table and key, no traceback, and ``{"ok": false}`` with
``--json``.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import servoid.datasets
from servoid.cli import main

EMPS_EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "emps"
EMPS_MAT = Path(servoid.datasets.__file__).parent / "emps" / "DATA_EMPS.mat"


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The virtual EHSA bench's files: ehsa.toml (closed loop), ehsa.tdms, truth.json."""
    folder = tmp_path_factory.mktemp("rig")
    assert main(["bench", "ehsa", "--out", str(folder)]) == 0
    return folder


@pytest.fixture(scope="module")
def emps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the EMPS example with its data path made absolute."""
    folder = tmp_path_factory.mktemp("emps")
    text = (EMPS_EXAMPLE / "emps.toml").read_text(encoding="utf-8")
    text = re.sub(r'(?m)^file = ".*"$', f"file = {json.dumps(str(EMPS_MAT))}", text)
    (folder / "emps.toml").write_text(text, encoding="utf-8")
    shutil.copy(EMPS_EXAMPLE / "published.json", folder / "published.json")
    return folder


def set_key(text: str, table: str, key: str, value: str) -> str:
    """Set ``key = value`` (a TOML literal) in ``[table]``, replacing or adding the line."""
    lines = text.splitlines()
    header = re.compile(rf"\[{re.escape(table)}\]\s*(#.*)?$")
    start = next(i for i, line in enumerate(lines) if header.match(line)) + 1
    end = next((i for i in range(start, len(lines)) if lines[i].startswith("[")), len(lines))
    for i in range(start, end):
        if re.match(rf"{re.escape(key)}\s*=", lines[i]):
            lines[i] = f"{key} = {value}"
            break
    else:
        lines.insert(start, f"{key} = {value}")
    return "\n".join(lines) + "\n"


def arx(text: str) -> str:
    """The bench file turned into an open-loop ARX fit from r (its [identify] replaced)."""
    head, _, tail = text.partition("[identify]\n")
    rest = tail.split("\n[", 1)
    return head + '[identify]\nmethod = "arx"\ninput = "r"\n' + (
        "\n[" + rest[1] if len(rest) > 1 else "")


# (id, base, edits [(table, key, TOML literal)], file to replace {name: text}, message)
CASES = [
    # -- rows of the review ---------------------------------------------------------------
    ("na-str", "rig", [("identify", "na", '"three"')], {},
     "[identify] na must be an integer, got 'three' (str)"),
    ("loop-c-str", "rig", [("loop", "c", '"x"')], {},
     "[loop] c must be a number, got 'x' (str)"),
    ("loop-F-str", "rig", [("loop", "F", '"x"')], {},
     "[loop] F must be a number or a table {num = [...], den = [...]}, got 'x' (str)"),
    ("loop-F-no-den", "rig", [("loop", "F", "{num = [1.0]}")], {}, "[loop] F needs den"),
    ("horizon-str", "rig", [("identify", "horizon", '"a"')], {},
     "[identify] horizon must be an integer, got 'a' (str)"),
    ("emps-cutoff-str", "emps", [("identify", "cutoff", '"x"')], {},
     "[identify] cutoff must be a number, got 'x' (str)"),
    ("truth-not-json", "rig", [], {"truth.json": "{bad"}, "is not valid JSON"),
    ("truth-value-str", "rig", [], {"truth.json": '{"K": "abc"}'},
     "K must be a number, got 'abc' (str)"),
    # -- closed loop ----------------------------------------------------------------------
    ("na-negative", "rig", [("identify", "na", "-1")], {}, "[identify] na must be >= 0, got -1"),
    ("nb-float", "rig", [("identify", "nb", "4.0")], {},
     "[identify] nb must be an integer, got 4.0 (float)"),
    ("approach-int", "rig", [("identify", "approach", "3")], {},
     "[identify] approach must be a string or a list of strings, got 3 (int)"),
    ("prefilter-str", "rig", [("identify", "prefilter", '"fast"')], {},
     "[identify] prefilter must be a number, got 'fast' (str)"),
    ("prefilter-negative", "rig", [("identify", "prefilter", "-5.0")], {},
     "[identify] prefilter must be > 0 Hz, got -5"),
    ("discretization-int", "rig", [("identify", "discretization", "1")], {},
     "[identify] discretization must be one of 'auto', 'tustin', 'prewarp', 'zoh', 'foh', "
     "'bandlimited'; got 1"),
    ("loop-c-bool", "rig", [("loop", "c", "true")], {},
     "[loop] c must be a number, got True (bool)"),
    ("loop-c-nan", "rig", [("loop", "c", "nan")], {}, "[loop] c must be finite, got nan"),
    ("loop-F-num-str", "rig", [("loop", "F", '{num = ["a"], den = [1.0, 1.0]}')], {},
     "[loop] F.num[0] must be a number, got 'a' (str)"),
    ("loop-F-den-scalar", "rig", [("loop", "F", "{num = [1.0], den = 2.0}")], {},
     "[loop] F.den must be a list of numbers, got 2.0 (float)"),
    ("loop-F-dt-str", "rig", [("loop", "F", '{num = [0.01], den = [1.0], dt = "x"}')], {},
     "[loop] F.dt must be a number, got 'x' (str)"),
    ("loop-F-unknown", "rig", [("loop", "F", "{num = [0.01], den = [1.0], gain = 2.0}")], {},
     "unknown key(s) in [loop] F: gain"),
    ("report-truth-int", "rig", [("report", "truth", "3")], {},
     "[report] truth must be a string, got 3 (int)"),
    ("report-folder-bool", "rig", [("report", "folder", "true")], {},
     "[report] folder must be a string, got True (bool)"),
    ("truth-array", "rig", [], {"truth.json": "[1, 2]"}, "must hold a JSON object, got list"),
    ("truth-parameters-str", "rig", [],
     {"truth.json": '{"parameters": {"K": 1.0, "omega_hp": "fast", "delta_hp": 0.2}}'},
     "omega_hp must be a number, got 'fast' (str)"),
    # -- arx ------------------------------------------------------------------------------
    ("arx-na-str", "arx", [("identify", "na", '"three"')], {},
     "[identify] na must be an integer or a list of integers, got 'three' (str)"),
    ("arx-nb-list-str", "arx", [("identify", "nb", '[2, "x"]')], {},
     "[identify] nb[1] must be an integer, got 'x' (str)"),
    ("arx-nk-empty", "arx", [("identify", "nk", "[]")], {},
     "[identify] nk must have at least 1 entry, got []"),
    ("arx-horizon-zero", "arx", [("identify", "horizon", "0")], {},
     "[identify] horizon must be >= 1, got 0"),
    ("arx-output-int", "arx", [("identify", "output", "5")], {},
     "[identify] output must be a string, got 5 (int)"),
    # -- inverse dynamics (EMPS) ----------------------------------------------------------
    ("emps-order-float", "emps", [("identify", "order", "4.5")], {},
     "[identify] order must be an integer, got 4.5 (float)"),
    ("emps-decimation-zero", "emps", [("identify", "decimation", "0")], {},
     "[identify] decimation must be >= 1, got 0"),
    ("emps-trim-str", "emps", [("identify", "trim", '"1"')], {},
     "[identify] trim must be an integer, got '1' (str)"),
    ("emps-refine-str", "emps", [("identify", "refine", '"yes"')], {},
     "[identify] refine must be true or false, got 'yes' (str)"),
    ("emps-model-int", "emps", [("identify", "model", "3")], {},
     "[identify] model must be a string or a list of strings, got 3 (int)"),
    ("emps-position-int", "emps", [("identify", "position", "1")], {},
     "[identify] position must be a string, got 1 (int)"),
    ("emps-linear-orders-str", "emps", [("identify", "linear_orders", '[2, "x", 1]')], {},
     "[identify] linear_orders[1] must be an integer, got 'x' (str)"),
    ("emps-linear-orders-scalar", "emps", [("identify", "linear_orders", "2")], {},
     "[identify] linear_orders must be a list of integers, got 2 (int)"),
    ("emps-kp-str", "emps", [("loop", "kp", '"fast"')], {},
     "[loop] kp must be a number, got 'fast' (str)"),
    ("emps-kv-negative", "emps", [("loop", "kv", "-1.0")], {}, "[loop] kv must be > 0, got -1"),
    ("emps-published-not-json", "emps", [], {"published.json": "{bad"}, "is not valid JSON"),
    ("emps-published-value-str", "emps", [],
     {"published.json": '{"symmetric": {"parameters": {"M": {"value": "abc"}}}}'},
     "symmetric.parameters.M.value must be a number, got 'abc' (str)"),
    ("emps-published-loop-str", "emps", [],
     {"published.json": '{"closed_loop": {"position": "small"}}'},
     "closed_loop.position must be a number, got 'small' (str)"),
]


def _experiment(case: tuple, rig: Path, emps: Path, tmp_path: Path) -> Path:
    _, base, edits, files, _ = case
    source = emps if base == "emps" else rig
    for item in source.iterdir():  # a private copy: edits never leak between cases
        if item.is_file():
            shutil.copy(item, tmp_path / item.name)
    name = "emps.toml" if base == "emps" else "ehsa.toml"
    text = (tmp_path / name).read_text(encoding="utf-8")
    if base == "arx":
        text = arx(text)
    for table, key, value in edits:
        text = set_key(text, table, key, value)
    (tmp_path / name).write_text(text, encoding="utf-8")
    for file, content in files.items():
        (tmp_path / file).write_text(content, encoding="utf-8")
    return tmp_path / name


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_value_is_a_clear_error(case, rig, emps, tmp_path, capsys):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    toml = _experiment(case, rig, emps, run_dir)
    message = case[-1]

    code = main(["identify", str(toml)])
    out, err = capsys.readouterr()
    assert code == 1
    assert err.startswith("servoid: error: ")
    assert message in err
    assert "Traceback" not in err + out
    assert not (run_dir / "results.json").exists()

    code = main(["identify", str(toml), "--json"])
    out, err = capsys.readouterr()
    assert code == 1
    payload = json.loads(out)
    assert payload["ok"] is False
    assert message in payload["error"]


def test_arx_helper_keeps_a_working_file(rig, tmp_path, capsys):
    """The edited copies fail for the edit alone: the unedited ARX copy runs."""
    for item in rig.iterdir():
        shutil.copy(item, tmp_path / item.name)
    toml = tmp_path / "ehsa.toml"
    toml.write_text(arx(toml.read_text(encoding="utf-8")), encoding="utf-8")
    code = main(["identify", str(toml), "--out", str(tmp_path / "out"), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert json.loads(out)["ok"] is True


def test_no_traceback_from_the_command(rig, tmp_path):
    """The installed command, end to end, for one row of the review."""
    for item in rig.iterdir():
        shutil.copy(item, tmp_path / item.name)
    toml = tmp_path / "ehsa.toml"
    toml.write_text(set_key(toml.read_text(encoding="utf-8"), "loop", "F", "{num = [1.0]}"),
                    encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "servoid", "identify", str(toml), "--json"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert done.stderr.startswith("servoid: error: [loop] F needs den")
    assert json.loads(done.stdout)["ok"] is False


PNEUMATIC_CASES = [
    ("derivatives", '"fast"', "derivatives must be one of 'svf', 'measured'"),
    ("blend", '"no"', "[identify] blend must be"),
    ("mdot_limit", '"x"', "[identify] mdot_limit must be"),
    ("refine", '"yes"', "[identify] refine must be true, false or a list"),
    ("refine", '["F_haft", "mass"]', "refine must be one of"),
    ("p_krit", '"a"', "[identify] p_krit must be"),
]


@pytest.fixture(scope="module")
def pneumatic_campaign(tmp_path_factory):
    from servoid.plants.pneumatic import write_pneumatic_campaign

    folder = tmp_path_factory.mktemp("pn")
    write_pneumatic_campaign(folder, duration=0.5)
    return folder


@pytest.mark.parametrize(("key", "value", "message"), PNEUMATIC_CASES)
def test_pneumatic_bad_identify_values(capsys, pneumatic_campaign, key, value, message):
    toml = pneumatic_campaign / "pneumatic.toml"
    text = toml.read_text()
    bad = pneumatic_campaign / f"bad_{key}.toml"
    line = re.compile(rf"^{key} = .*$", re.M)
    if line.search(text):  # the bench wrote this key: change its value
        text = line.sub(lambda _: f"{key} = {value}", text, count=1)
    else:
        text = text.replace("[identify]\n", f"[identify]\n{key} = {value}\n", 1)
    bad.write_text(text)
    code = main(["identify", str(bad), "--out", str(pneumatic_campaign / f"out_{key}")])
    err = capsys.readouterr().err
    assert code == 1
    assert message in err and "Traceback" not in err
