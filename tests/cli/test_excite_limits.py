"""``servoid excite --plant``: the designed test checked against the actuator's limits."""

from __future__ import annotations

import json

from servoid.cli import main


def test_excite_says_where_the_planned_test_saturates(capsys, tmp_path):
    argv = ["excite", "prbs", "-n", "9", "--clock", "10", "--dt", "1e-3", "--unit", "m",
            "--plant", "ehsa", "--out", str(tmp_path / "r.csv")]
    assert main([*argv, "--amplitude", "1e-3"]) == 0
    out = capsys.readouterr().out
    # the ±1 mm PRBS of the issue: about 35 MPa of load pressure from a 21 MPa supply
    assert "ehsa set B: the planned test (amplitude ±1 mm) asks more than the actuator" in out
    assert "load pressure" in out and "largest amplitude within every limit" in out
    assert (tmp_path / "r.csv").exists()  # written all the same: the check advises
    assert main([*argv, "--amplitude", "1e-4", "--overwrite", "--json"]) == 0
    limits = json.loads(capsys.readouterr().out)["limits"]
    assert limits["plant"] == "ehsa" and limits["set"] == "B" and limits["feasible"]
    assert limits["binding"] == "load pressure" and 1e-4 < limits["largest_amplitude"] < 3e-4


def test_without_plant_no_check(capsys, tmp_path):
    assert main(["excite", "prbs", "-n", "7", "--dt", "1e-3", "--out",
                 str(tmp_path / "r.csv"), "--json"]) == 0
    assert "limits" not in json.loads(capsys.readouterr().out)


def test_random_multisine_is_checked_once(capsys, tmp_path):
    assert main(["excite", "random-multisine", "--f-min", "1", "--f-max", "40", "--period",
                 "1000", "--dt", "1e-3", "--amplitude", "1e-4", "--unit", "m", "--plant", "ehsa",
                 "--set", "C", "--out", str(tmp_path / "ms.csv")]) == 0
    out = capsys.readouterr().out
    assert out.count("ehsa set C: within every limit") == 1 and "plan written to" in out
