"""``[identify] method = "ema"`` end to end: identify, report, results, fleet."""

from __future__ import annotations

import json
import shutil
import tomllib

import pytest

from servoid import OptionError
from servoid.data import write_experiment_spec
from servoid.workflows import get_method, identify, load_results


def _variant(bench_folder, tmp_path, change):
    """A copy of the bench's experiment file with ``change(doc)`` applied, beside its files."""
    for name in ("ema.tdms", "truth.json"):
        shutil.copy(bench_folder / name, tmp_path / name)
    doc = tomllib.loads((bench_folder / "ema.toml").read_text(encoding="utf-8"))
    change(doc)
    return write_experiment_spec(doc, tmp_path / "ema.toml")


def test_identify_writes_a_report_whose_results_read_back(bench_folder, tmp_path):
    result = identify(bench_folder / "ema.toml", tmp_path / "out")
    names = {p.name for p in result.files}
    assert {"results.json", "report.html", "equations.png", "validation_1.png",
            "manifest.json"} <= names
    back = load_results(tmp_path / "out" / "results.json")
    ident = result.identification
    assert back.summary.names() == ident.names
    for row, value in zip(back.summary.parameters, ident.values, strict=True):
        assert row.value == value  # the floats of the file, bit for bit
    assert back.summary.fit_percent > 90.0  # the current; the rest is the loop's noise response
    assert doc_fit(tmp_path) > 99.9  # the load position follows the reference
    assert back.summary.independent is True
    doc = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    rows = {r["name"]: r for r in doc["estimate"]["parameters"]}
    assert rows["c_s"]["identifiable"] is False and rows["c_s"]["ci_low"] is None
    assert abs(rows["k_s"]["error_in_std"]) < 4  # against truth.json
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "simulation fit" in html and "not identifiable from this record" in html
    assert "EMA identification" in str(result)


def doc_fit(tmp_path):
    doc = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    return doc["validation"]["position_fit_percent"]


def test_identify_from_the_command_line(bench_folder, tmp_path, capsys):
    from servoid.cli import main

    assert main(["identify", str(bench_folder / "ema.toml"), "--out", str(tmp_path / "cli"),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ok"] is True
    assert main(["methods", "ema"]) == 0
    text = capsys.readouterr().out
    assert "gear_ratio" in text and "reads also: [loop], [validation]" in text


def test_without_loop_there_is_no_validation_and_the_notes_say_why(bench_folder, tmp_path):
    spec = _variant(bench_folder, tmp_path, lambda d: d.pop("loop"))
    result = identify(spec, write=False)
    assert result.validations == ()
    assert any("no [loop] table" in n for n in result.notes)
    assert result.to_dict()["validation"] is None


def test_a_record_without_voltage_uses_the_given_motor_constant(bench_folder, tmp_path):
    def change(doc):
        doc["identify"].update(voltage=False, motor_constant=0.2, motor_constant_std=0.002)
    result = identify(_variant(bench_folder, tmp_path, change), write=False)
    assert result.identification.given == ("K_m",)
    assert "R" not in result.identification.names


def _set(table, **values):
    def change(doc):
        doc.setdefault(table, {}).update(values)
    return change


@pytest.mark.parametrize(("change", "match"), [
    (_set("identify", bandwith=10.0), r"unknown key\(s\) in \[identify\]: bandwith"),
    (_set("loop", kp=1.0), r"unknown key\(s\) in \[loop\]: kp"),
    (lambda d: d["loop"].pop("kp_i"), r"\[loop\] needs kp_i"),
    (lambda d: d["identify"].pop("lead"), r"\[identify\] lead is needed"),
    (_set("preprocess", decimate=5), r"remove \[preprocess\] decimate"),
    (_set("preprocess", detrend="mean"), r"detrend = \"mean\" would remove"),
    (_set("identify", current="i_a"), r"current = 'i_a' is not a channel"),
    (_set("loop", feedback="rod"), r"\[loop\].*feedback"),
    (_set("identify", voltage=3), r"voltage must be a channel name, or false"),
])
def test_bad_experiment_files_are_refused_naming_the_key(bench_folder, tmp_path, change, match):
    spec = _variant(bench_folder, tmp_path, change)
    with pytest.raises((OptionError, KeyError, TypeError, ValueError), match=match):
        identify(spec, write=False)


def test_the_method_is_registered_with_its_tables():
    method = get_method("ema")
    assert method.tables == ("loop", "validation")
    assert method.keys[:3] == ("method", "gear_ratio", "lead")


def test_a_fleet_of_emas_runs_and_flags_its_bad_units(tmp_path):
    from servoid.fleet import run_fleet
    from servoid.plants.ema import write_fleet

    fleet = write_fleet(tmp_path / "fleet", units=3, bad_every=3, duration=4.0, seed=1)
    result = run_fleet(fleet.fleet_file, workers=1, progress=False)
    assert result.count("ok") == 3
    assert set(result.failing_units) == set(fleet.bad)  # the worn screw: k_s 35 % low
