"""The servoid command, run in process through main(argv)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import servoid
from servoid.cli import main
from servoid.data import read_csv, read_tdms


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0
    assert out.strip() == f"servoid {servoid.__version__}"


@pytest.mark.parametrize(
    "argv",
    [[], ["demo"], ["identify"], ["excite"], ["excite", "prbs"], ["excite", "multisine"],
     ["excite", "chirp"]],
)
def test_help_on_every_command(capsys, argv):
    code, out, _ = run(capsys, *argv, "--help")
    assert code == 0
    assert "usage: servoid" in out


def test_usage_error_exits_2(capsys):
    code, _, err = run(capsys, "excite", "prbs", "--dt", "0.001")
    assert code == 2
    assert "required" in err


def test_unknown_option_value_lists_valid_ones(capsys, tmp_path):
    code, _, err = run(capsys, "excite", "multisine", "--period", "100", "--f-min", "1",
                       "--f-max", "10", "--dt", "0.001", "--phases", "golden",
                       "--out", str(tmp_path / "m.csv"))
    assert code == 2
    assert "schroeder" in err and "random" in err


def test_excite_prbs_writes_csv_and_reports(capsys, tmp_path):
    out_file = tmp_path / "prbs.csv"
    code, out, _ = run(capsys, "excite", "prbs", "-n", "7", "--clock", "4", "--dt", "0.001",
                       "--amplitude", "0.5", "--periods", "2", "--out", str(out_file))
    assert code == 0
    assert "1016 samples" in out  # (2^7 − 1)·4·2
    exp = read_csv(out_file)
    values = exp["r"]
    assert values.size == 1016
    assert set(np.unique(values)) == {-0.5, 0.5}
    assert exp.dt == pytest.approx(0.001, rel=1e-9)  # time column printed at full precision


def test_excite_json_and_tdms(capsys, tmp_path):
    out_file = tmp_path / "ms.tdms"
    code, out, _ = run(capsys, "excite", "multisine", "--period", "1000", "--f-min", "2",
                       "--f-max", "40", "--dt", "0.001", "--out", str(out_file), "--json")
    assert code == 0
    info = json.loads(out)
    assert info["ok"] is True
    assert info["n_samples"] == 1000
    assert info["band_hz"] == [2.0, 40.0]
    assert read_tdms(out_file)["r"].size == 1000


def test_excite_refuses_existing_file(capsys, tmp_path):
    out_file = tmp_path / "c.csv"
    out_file.write_text("keep me\n")
    code, _, err = run(capsys, "excite", "chirp", "--duration", "1", "--f0", "1", "--f1", "5",
                       "--dt", "0.01", "--out", str(out_file))
    assert code == 1
    assert "already exists" in err and "--overwrite" in err
    assert out_file.read_text() == "keep me\n"


def test_excite_unknown_extension(capsys, tmp_path):
    code, _, err = run(capsys, "excite", "chirp", "--duration", "1", "--f0", "1", "--f1", "5",
                       "--dt", "0.01", "--out", str(tmp_path / "c.xlsx"))
    assert code == 1
    assert "'csv', 'tdms'" in err and "'xlsx'" in err


def test_excite_bad_value_is_error_not_traceback(capsys, tmp_path):
    code, _, err = run(capsys, "excite", "prbs", "-n", "40", "--dt", "0.001",
                       "--out", str(tmp_path / "p.csv"))
    assert code == 1
    assert err.startswith("servoid: error:")


def test_demo_and_identify_round_trip(capsys, tmp_path):
    folder = tmp_path / "demo"
    code, out, _ = run(capsys, "demo", "--out", str(folder), "--json")
    assert code == 0
    demo = json.loads(out)
    rows = {r["name"]: r for r in demo["parameters"]}
    assert set(rows) == {"K", "omega_hp", "delta_hp"}
    for name, row in rows.items():
        lo, hi = row["one-step"]["ci95"]
        # the numbers come from the run: truth read back from the bench's truth.json,
        # one-step within 4σ of it (prewarped Tustin; spec E4 tolerances are looser)
        assert abs(row["one-step"]["value"] - row["truth"]) < 4 * row["one-step"]["std"], name
        assert lo < row["one-step"]["value"] < hi
    assert demo["validation_fit_percent"]["one-step"] > 90  # spec E4: ≥ 90 % at 28 dB
    # the two-step bias is explained in words, not by a spec reference
    why = [n for n in demo["notes"] if n.startswith("why two-step and one-step disagree")]
    assert len(why) == 1 and "equation error" in why[0]
    assert not any("spec §" in n for n in demo["notes"])
    results = json.loads((folder / "report" / "results.json").read_text())
    assert results["parameters"] == demo["parameters"]
    assert (folder / "report" / "report.html").stat().st_size > 0

    # identify the demo's rig files again: refuses to overwrite, then writes elsewhere
    code, _, err = run(capsys, "identify", str(folder / "ehsa.toml"), "--out",
                       str(folder / "report"))
    assert code == 1 and "exists from an earlier run" in err
    code, out, _ = run(capsys, "identify", str(folder / "ehsa.toml"), "--out",
                       str(tmp_path / "again"), "--json")
    assert code == 0
    assert json.loads(out)["parameters"] == demo["parameters"]


def test_identify_missing_file(capsys, tmp_path):
    code, out, err = run(capsys, "identify", str(tmp_path / "nope.toml"), "--json")
    assert code == 1
    assert json.loads(out)["ok"] is False
    assert "nope.toml" in err


def test_demo_refuses_a_foreign_folder(capsys, tmp_path):
    (tmp_path / "mine.txt").write_text("precious")
    code, _, err = run(capsys, "demo", "--out", str(tmp_path))
    assert code == 1
    assert "holds no earlier demo" in err and "--overwrite" in err
    assert [p.name for p in tmp_path.iterdir()] == ["mine.txt"]


def test_parser_literals_match_the_bench():
    """The CLI names the bench's fidelities and tests without importing the bench."""
    from servoid.plants.ehsa import FIDELITIES
    from servoid.plants.ehsa._cli import FIDELITIES as BENCH_FIDELITIES
    from servoid.plants.pneumatic import PNEUMATIC_TESTS
    from servoid.plants.pneumatic._cli import TEST_NAMES as PNEUMATIC_TEST_NAMES

    assert BENCH_FIDELITIES == tuple(FIDELITIES)
    assert PNEUMATIC_TEST_NAMES == tuple(PNEUMATIC_TESTS)


def test_version_and_help_do_not_import_the_numerics():
    import subprocess
    import sys

    code = ("import sys; from servoid.cli import main; main(['--help']); "
            "print(sorted(m for m in ('numpy', 'scipy', 'numba', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_the_workflows_load_scipy_on_use():
    # scipy.signal, .linalg, .stats and .optimize cost ~0.9 s of every `servoid identify`
    # start when imported eagerly; the workflows reach them through servoid._lazy
    import subprocess
    import sys

    code = ("import sys, servoid.workflows; print(sorted(m for m in ('scipy.signal', "
            "'scipy.linalg', 'scipy.stats', 'scipy.optimize') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
