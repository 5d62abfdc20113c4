"""Fleets end to end on virtual fleets whose truth is known.

The virtual fleet's good units lie within 2.5σ of the manufacturing
scatter and inside the limits with room for their intervals; its bad units
lie far outside; so exactly the bad units must fail the CI-inside-limit
rule, and the corrupt record must be a failed row.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import servoid.fleet._run as fleet_run
from servoid import DataError, OptionError, OutputExistsError
from servoid.fleet import load_fleet_spec, run_fleet
from servoid.plants.ehsa import SET_B
from servoid.plants.ehsa._fleet import write_virtual_fleet


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory):
    """12 units, every 4th bad (valve, air, seal), one corrupt record."""
    return write_virtual_fleet(tmp_path_factory.mktemp("batch"), units=12, bad_every=4,
                               corrupt=1, seed=3)


@pytest.fixture(scope="module")
def batch_result(batch):
    return run_fleet(batch.fleet_file, workers=1, progress=False)


def _table(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_exactly_the_bad_units_fail(batch, batch_result):
    assert batch.bad == ("SN-0004", "SN-0008", "SN-0012")
    assert batch_result.failing_units == batch.bad
    assert batch_result.count("failed") == 1
    failed = next(r for r in batch_result.rows if r["status"] == "failed")
    assert failed["serial"] == "SN-0013" and "truncated" in failed["error"]
    assert failed["pass"] is False


def test_estimates_agree_with_the_truth_of_each_unit(batch, batch_result):
    """Good units: K, ω_hp, δ_hp within 5σ of each unit's truth (reduced bench, rig chain)."""
    truth = {r["serial"]: r for r in _table(batch.truth_file)}
    for row in batch_result.rows:
        if row["status"] != "ok":
            continue
        for name in ("K", "omega_hp", "delta_hp"):
            z = (row[name] - float(truth[row["serial"]][name])) / row[f"{name}_std"]
            assert abs(z) < 5, (row["serial"], name, z)


def test_table_files_agree_and_parse(batch_result):
    folder = batch_result.folder
    rows = _table(folder / "fleet.csv")
    assert [r["serial"] for r in rows] == [f"SN-{k:04d}" for k in range(1, 14)]
    assert {"K", "K_std", "K_ci_low", "pass_omega_hp", "pass", "outlier", "date"} <= set(rows[0])
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(folder / "fleet.parquet").to_pylist()
    assert [r["serial"] for r in table] == [r["serial"] for r in rows]
    np.testing.assert_allclose([r["K"] for r in table if r["status"] == "ok"],
                               [float(r["K"]) for r in rows if r["status"] == "ok"], rtol=1e-15)
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert "Acceptance rule" in html and "SN-0008" in html and "Failed records" in html


def test_rerun_skips_unchanged_records_and_redoes_a_changed_one(batch, batch_result, monkeypatch):
    calls = []
    real = fleet_run.identify_record
    monkeypatch.setattr(fleet_run, "identify_record",
                        lambda path, identify: calls.append(path) or real(path, identify))
    again = run_fleet(batch.fleet_file, workers=1, progress=False)
    assert calls == []
    assert _same(again.rows, batch_result.rows)
    toml = batch.folder / "units" / "SN-0002" / "ehsa.toml"
    original = toml.read_text(encoding="utf-8")
    try:
        toml.write_text(original + "\n# edited\n", encoding="utf-8")
        run_fleet(batch.fleet_file, workers=1, progress=False)
        assert [Path(p).parent.name for p in calls] == ["SN-0002"]
    finally:
        toml.write_text(original, encoding="utf-8")


def test_interrupted_run_resumes_to_the_same_table(batch, batch_result, tmp_path, monkeypatch):
    real = fleet_run.identify_record
    count = [0]

    def interrupt_at_five(path, identify):
        count[0] += 1
        if count[0] == 5:
            raise KeyboardInterrupt
        return real(path, identify)

    monkeypatch.setattr(fleet_run, "identify_record", interrupt_at_five)
    out = tmp_path / "run"
    first = run_fleet(batch.fleet_file, out, workers=1, progress=False)
    assert first.interrupted and first.count("not run") == 13 - 4
    assert len(list((out / "records").glob("*.json"))) == 4
    assert _table(out / "fleet.csv")[5]["status"] == "not run"  # a consistent table on disk
    monkeypatch.setattr(fleet_run, "identify_record", real)
    second = run_fleet(batch.fleet_file, out, workers=1, progress=False)
    assert not second.interrupted
    assert _same(second.rows, batch_result.rows)


@pytest.mark.parametrize("per_task", [None, 4])
def test_dask_and_serial_give_identical_numbers(batch, batch_result, tmp_path, monkeypatch,
                                                per_task):
    pytest.importorskip("distributed")
    if per_task is not None:  # records grouped into tasks, as a large fleet is
        monkeypatch.setattr(fleet_run, "_batch_size", lambda n_todo, n_workers: per_task)
    parallel = run_fleet(batch.fleet_file, tmp_path / "dask", workers=2, progress=False)
    assert _same(parallel.rows, batch_result.rows)


def test_records_are_grouped_into_tasks_only_when_there_are_many():
    assert fleet_run._batch_size(13, 2) == 1  # the test fleet: one record per task
    assert fleet_run._batch_size(100, 2) == 3
    assert fleet_run._batch_size(1000, 2) == 8  # at most eight, ≥ 16 tasks per worker
    assert fleet_run._batch_size(1000, 64) == 1


def test_dask_run_records_each_task_cpu_and_resume_starts_no_cluster(batch, batch_result,
                                                                      tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    out = tmp_path / "dask"
    run_fleet(batch.fleet_file, out, workers=2, progress=False)
    stored = [json.loads(p.read_text(encoding="utf-8")) for p in (out / "records").glob("*.json")]
    assert len(stored) == 13
    # a record's CPU time on its worker is at most its wall time (one thread per worker)
    assert all(0 < s["cpu_seconds"] <= s["seconds"] * 1.05 + 0.05 for s in stored)
    starts = []
    monkeypatch.setattr(fleet_run._Pool, "_start_local", lambda self, n: starts.append(n))
    again = run_fleet(batch.fleet_file, out, workers=2, progress=False)
    assert starts == []  # every outcome was stored: no worker was started, none needed
    assert _same(again.rows, batch_result.rows)


def test_ageing_drift_is_found_with_the_right_sign(tmp_path):
    """Leakage +300 % per 100 days over 10 daily tests: δ_hp rises; the slope CI covers it."""
    fleet = write_virtual_fleet(tmp_path, units=10, bad_every=0, corrupt=0, drift=3.0, seed=5)
    result = run_fleet(fleet.fleet_file, workers=1, progress=False)
    delta = next(p for p in result.parameters if p.name == "delta_hp").drift
    assert delta.significant and delta.slope > 0
    # injected slope: δ_hp of the mean unit as its leakage grows 3 % a day
    nominal = SET_B.delta_hp
    later = SET_B.with_(K_ce=SET_B.K_ce * 1.03).delta_hp
    assert delta.ci_low <= later - nominal <= delta.ci_high
    omega = next(p for p in result.parameters if p.name == "omega_hp").drift
    assert not omega.significant


def test_bad_fleet_files_fail_before_any_work(batch, tmp_path):
    def fleet(text: str) -> Path:
        path = tmp_path / "f.toml"
        path.write_text(text, encoding="utf-8")
        return path

    units = batch.folder / "units.csv"
    shutil.copy(units, tmp_path / "units.csv")
    rows = (tmp_path / "units.csv").read_text(encoding="utf-8").splitlines()
    absolute = [rows[0]] + [f"{batch.folder / r.split(',')[0]},{r.split(',', 1)[1]}"
                            for r in rows[1:]]
    (tmp_path / "abs.csv").write_text("\n".join(absolute) + "\n", encoding="utf-8")
    (tmp_path / "dup.csv").write_text("\n".join(absolute + absolute[1:2]) + "\n",
                                      encoding="utf-8")
    with pytest.raises(DataError, match="do not exist"):
        load_fleet_spec(fleet('[records]\nmanifest = "units.csv"\n'))
    with pytest.raises(DataError, match="appears twice on"):
        load_fleet_spec(fleet('[records]\nmanifest = "dup.csv"\n'))
    with pytest.raises(OptionError, match="exactly one of glob"):
        load_fleet_spec(fleet('[records]\nmanifest = "abs.csv"\nglob = "*.toml"\n'))
    with pytest.raises(OptionError, match="unknown key"):
        load_fleet_spec(fleet('[records]\nmanifest = "abs.csv"\n[identify]\nmethod = '
                              '"closedloop"\nfoo = 1\n'))
    with pytest.raises(OptionError, match="tolerance must be > 0"):
        load_fleet_spec(fleet('[records]\nmanifest = "abs.csv"\n[limits.K]\nnominal = 1\n'
                              'tolerance = 0\n'))
    spec = fleet('[records]\nmanifest = "abs.csv"\n[identify]\nmethod = "closedloop"\n'
                 'approach = "one-step"\nstructure_test = false\n[limits.zeta]\nmax = 1\n')
    with pytest.raises(OptionError, match="zeta, which the identification does not estimate"):
        run_fleet(spec, tmp_path / "out", workers=1, progress=False)
    assert len(list((tmp_path / "out" / "records").glob("*.json"))) == 1  # only the probe
    with pytest.raises(OptionError, match="cannot connect to the Dask scheduler"):
        pytest.importorskip("distributed")
        run_fleet(batch.fleet_file, tmp_path / "o2", scheduler="tcp://127.0.0.1:9",
                  insecure=True, progress=False, force=True)


def test_outputs_never_replace_an_input(batch, tmp_path):
    """A manifest called fleet.csv in the results folder is an input, not an old output."""
    (tmp_path / "fleet.csv").write_text(batch.manifest.read_text(encoding="utf-8").replace(
        "units/", f"{batch.folder}/units/"), encoding="utf-8")
    (tmp_path / "f.toml").write_text('[records]\nmanifest = "fleet.csv"\n', encoding="utf-8")
    before = (tmp_path / "fleet.csv").read_bytes()
    with pytest.raises(OutputExistsError, match="would replace the input"):
        run_fleet(tmp_path / "f.toml", tmp_path, workers=1, progress=False)
    assert (tmp_path / "fleet.csv").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.toml", "fleet.csv"]


def _same(a, b) -> bool:
    """Rows equal in every column but the run time, its CPU time and the worker's memory."""
    skip = ("seconds", "cpu_seconds", "peak_rss_mb")
    strip = [{k: v for k, v in r.items() if k not in skip} for r in a]
    return strip == [{k: v for k, v in r.items() if k not in skip} for r in b]


def test_the_report_opens_with_the_batch_verdict(batch, batch_result):
    from servoid.fleet._report import fleet_verdict

    verdict = fleet_verdict(batch_result)
    assert verdict.decision == "reject"  # three bad units leave their limits
    limits = [c for c in verdict.checks if c.name.startswith("limit ")]
    failing = sorted(s for c in limits if c.outcome == "fail"
                     for s in c.meaning.split(":")[0].split(", "))
    assert failing == list(batch.bad)  # the same units the table fails
    identified = next(c for c in verdict.checks if c.name == "identified")
    assert identified.value == "12 of 13" and "SN-0013" in identified.meaning
    units = {row[0]: row for row in verdict.tables[0].rows}
    assert units["reject: outside a limit"][2] == ", ".join(batch.bad)
    assert units["not judged: not identified"][2] == "SN-0013"
    # the units' own conditions: one row per kind of record, their rate and length
    assert [c.record for c in verdict.conditions] == ["estimation: 12 units",
                                                      "validation: 12 units"]
    html = (batch_result.folder / "report.html").read_text(encoding="utf-8")
    assert html.index('<div class="box reject">') < html.index("<h2>Summary</h2>")
    assert verdict.line() in html
    inside = sum(bool(r["pass"]) for r in batch_result.rows)
    assert f"<b>inside every limit:</b> {inside}" in html
