"""``servoid bench fleet`` and ``servoid fleet`` from the command line."""

from __future__ import annotations

import json

import pytest

from servoid.cli import main


def test_bench_fleet_then_fleet(tmp_path, capsys):
    out = tmp_path / "batch"
    assert main(["bench", "fleet", "--out", str(out), "--units", "6", "--bad-every", "3",
                 "--register", "7", "--json"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made["bad"] == ["SN-0003", "SN-0006"] and made["corrupt"] == ["SN-0007"]
    assert main(["fleet", str(out / "fleet.toml"), "--workers", "1", "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["ok"] and summary["failing_units"] == ["SN-0003", "SN-0006"]
    assert summary["failed"] == 1 and "truncated" in summary["failed_records"][0]["error"]
    assert "identifying" not in captured.err  # --json keeps stderr free of progress
    assert (out / "fleet-results" / "fleet.csv").is_file()
    # the same command again: every record is reused, the same answer
    assert main(["fleet", str(out / "fleet.toml"), "--workers", "1"]) == 0
    text = capsys.readouterr()
    assert "fail a limit (SN-0003, SN-0006)" in text.out
    assert "7/7" in text.err and "7 unchanged" in text.err


@pytest.mark.parametrize(
    ("argv", "code", "fragment"),
    [
        (["fleet", "missing.toml"], 1, "fleet file missing.toml not found"),
        (["fleet", "{fleet}", "--workers", "0"], 1, "--workers"),
        (["fleet", "{fleet}", "--workers", "2", "--scheduler", "tcp://x:1"], 1, "give one"),
        (["fleet"], 2, "required"),
        (["bench", "fleet", "--units", "2"], 1, "--units"),
        (["bench", "fleet", "--drift", "nan"], 1, "--drift"),
        (["bench", "fleet", "--register", "40"], 1, "--register"),
    ],
)
def test_bad_fleet_commands(tmp_path, capsys, monkeypatch, argv, code, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "f.toml").write_text('[records]\nglob = "*.toml"\n', encoding="utf-8")
    argv = [a.replace("{fleet}", str(tmp_path / "f.toml")) for a in argv]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(argv) == code
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_cluster_flags_reach_run_fleet(tmp_path, monkeypatch, capsys):
    pytest.importorskip("distributed")
    import servoid.fleet

    seen = {}

    def fake(*args, **kwargs):
        seen.update(kwargs)
        raise KeyboardInterrupt  # stop here: only the wiring is tested

    monkeypatch.setattr(servoid.fleet, "run_fleet", fake)
    (tmp_path / "ca.pem").write_text("x", encoding="utf-8")
    pem = str(tmp_path / "ca.pem")
    assert main(["fleet", "f.toml", "--scheduler", "tls://h:1", "--tls-ca-file", pem,
                 "--tls-cert", pem, "-v", "--allow-duplicates"]) == 130
    assert seen["scheduler"] == "tls://h:1" and seen["verbose"] and seen["allow_duplicates"]
    assert seen["security"].tls_ca_file == pem and not seen["insecure"]
    assert main(["fleet", "f.toml", "--dashboard"]) == 130
    assert seen["dashboard"] and seen["security"] is None and not seen["verbose"]
