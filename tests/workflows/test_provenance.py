"""The report says when, by which command and from which inputs it was made, and what it wrote."""

from __future__ import annotations

import hashlib
import re

from servoid.cli import main


def test_report_names_command_seed_and_hashes(tmp_path, capsys):
    bench = tmp_path / "bench"
    assert main(["bench", "ehsa", "--out", str(bench), "--register", "8", "--seed", "7"]) == 0
    out = tmp_path / "out"
    assert main(["identify", str(bench / "ehsa.toml"), "--out", str(out)]) == 0
    capsys.readouterr()
    html = (out / "report.html").read_text(encoding="utf-8")
    meta = dict(re.findall(r"<div><b>([^<]+):</b> ([^<]*)</div>", html))
    assert meta["command"] == f"servoid identify {bench / 'ehsa.toml'} --out {out}"
    assert meta["seed"] == "7"
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d UTC", meta["generated"])
    for name in ("results.json", "validation.png"):
        digest = hashlib.sha256((out / name).read_bytes()).hexdigest()
        assert meta[f"output {name}"] == digest[:16] + "…"
    digest = hashlib.sha256((bench / "ehsa.tdms").read_bytes()).hexdigest()
    assert meta["input ehsa.tdms"] == digest[:16] + "…"
