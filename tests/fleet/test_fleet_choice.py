"""A fleet that chooses per unit: [identify] method = [...] or "auto" in the fleet file."""

from __future__ import annotations

import csv
import dataclasses
import time
import warnings
from contextlib import contextmanager
from types import MappingProxyType

import numpy as np
import pytest
from _arx_fleet import write_pem
from scipy.signal import lfilter

from servoid.data import Experiment, load_experiment_spec, write_csv, write_experiment_spec
from servoid.fleet import run_fleet
from servoid.workflows import identify


def _unit(folder, seed):
    # ARX(1, 1) data for one unit, another for the next: each unit's choice is its own
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(600)
    y = lfilter([0.0, 0.5], [1.0, -0.8], u) + 0.02 * rng.standard_normal(u.size)
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), folder / f"unit{seed}.csv", overwrite=True)
    path = folder / f"unit{seed}.toml"
    write_experiment_spec({"data": {"file": f"unit{seed}.csv"},
                           "channels": {"u": {"source": "u", "role": "u"},
                                        "y": {"source": "y", "role": "y"}},
                           "split": {"fraction": 0.5}}, path, overwrite=True)
    return path


@contextmanager
def _on_private_cluster(tmp_path):
    """The fleet's own private 2-worker TLS cluster: (a client, run_fleet on it)."""
    pytest.importorskip("distributed")
    pytest.importorskip("cryptography")
    import servoid.fleet._run as fleet_run
    from servoid.fleet import tls_security

    pool = fleet_run._Pool(None, 2, 2)
    client = pool.client(2)
    try:
        pem = write_pem(client, tmp_path)

        def run(out):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return run_fleet(tmp_path / "fleet.toml", out, progress=False,
                                 scheduler=pool._cluster.scheduler_address,
                                 security=tls_security(pem["ca"], pem["cert"], pem["key"]))

        yield client, run
    finally:
        pool.close()


def test_a_fleet_with_a_method_list_shows_the_chosen_candidate_per_unit(tmp_path):
    [_unit(tmp_path, k) for k in range(2)]
    (tmp_path / "fleet.toml").write_text(
        '[records]\nglob = "unit*.toml"\n\n'
        '[identify]\nmethod = ["arx", "oe"]\n\n[identify.arx]\nna = 1\nnb = 1\n\n'
        "[identify.oe]\nnb = 2\nnf = 2\n", encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = run_fleet(tmp_path / "fleet.toml", workers=1, progress=False)
    assert result.count("ok") == 2, [r["error"] for r in result.rows]
    # each unit's row names the candidate identify chooses on that record alone (ARX(1, 1), the
    # true structure, and OE(2, 2), which contains it, score within tenths of a point here)
    alone = []
    for row in result.rows:
        spec = load_experiment_spec(tmp_path / row["record"])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            alone.append(identify(dataclasses.replace(spec, identify=MappingProxyType(
                {"method": ["arx", "oe"], "arx": {"na": 1, "nb": 1}, "oe": {"nb": 2, "nf": 2}})),
                write=False).label)
    assert [r["candidate"] for r in result.rows] == alone
    assert [r["method"] for r in result.rows] == [a.split(" ")[0] for a in alone]
    with open(result.folder / "fleet.csv", encoding="utf-8") as fh:
        header = next(csv.reader(fh))
    assert header[header.index("method") + 1] == "candidate"


def test_a_fleet_on_dask_scores_each_units_candidates_as_cluster_tasks(tmp_path):
    [_unit(tmp_path, k) for k in range(2)]
    (tmp_path / "fleet.toml").write_text(
        '[records]\nglob = "unit*.toml"\n\n[identify]\nmethod = ["arx", "oe", "tf"]\n\n'
        "[identify.arx]\nna = 1\nnb = 1\n\n[identify.oe]\nnb = 2\nnf = 2\n", encoding="utf-8")
    with _on_private_cluster(tmp_path) as (client, run):
        served = run(tmp_path / "dask")

        def done(dask_scheduler):  # tasks that finished, by their key's prefix
            return {name: p.state_counts["memory"]
                    for name, p in dask_scheduler.task_prefixes.items()}

        tasks = client.run_on_scheduler(done)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        serial = run_fleet(tmp_path / "fleet.toml", tmp_path / "serial", workers=1,
                           progress=False)
    assert served.count("ok") == 2, [r["error"] for r in served.rows]
    # 2 units × 3 candidates scored, each its own task on the cluster; then the 2 candidates
    # not chosen of each unit fitted on the whole record for its leaderboard, as tasks too
    tasks.pop("identify_records_on_cluster")  # the records' own tasks
    assert tasks.pop("score_on") == 6
    assert sum(tasks.values()) == 4, tasks  # the whole-data fits, whatever their function's name
    # the same choice as the serial run: where a candidate is scored does not change its score
    assert [r["candidate"] for r in served.rows] == [r["candidate"] for r in serial.rows]


def test_a_dask_fleet_row_counts_the_cpu_of_its_candidate_tasks(tmp_path):
    _unit(tmp_path, 0)  # one unit: every task on the cluster is its record's or a candidate's
    (tmp_path / "fleet.toml").write_text(
        '[records]\nglob = "unit*.toml"\n\n[identify]\nmethod = ["oe", "tf", "bj"]\n\n'
        "[identify.oe]\nnb = 2\nnf = 2\n\n[identify.tf]\nn_poles = 2\n", encoding="utf-8")
    with _on_private_cluster(tmp_path) as (client, run):
        before = client.run(time.process_time)
        result = run(tmp_path / "dask")
        after = client.run(time.process_time)
    row = result.rows[0]
    assert row["status"] == "ok", row["error"]
    workers = sum(after[w] - before[w] for w in after)  # every task's CPU, and the workers' own
    # the candidates ran on both workers; the row counted only its own worker's share before
    # (0.42 of the workers' CPU, measured); now every task once: the rest is the workers' event
    # loops (3 % measured), and the tasks that ran beside the waiting record are not counted twice
    assert 0.75 * workers <= row["cpu_seconds"] <= workers + 0.05, (row["cpu_seconds"], workers)
    with open(result.folder / "fleet.csv", encoding="utf-8") as fh:
        header = next(csv.reader(fh))
    assert header[header.index("seconds") + 1] == "cpu_seconds"


def test_a_serial_fleet_row_counts_the_cpu_of_its_local_candidate_processes(tmp_path):
    import resource

    import servoid.fleet._run as fleet_run  # the function a serial fleet calls per record

    def children():  # CPU time of this process's ended children
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    path = _unit(tmp_path, 0)
    identify = {"method": ["oe", "tf"], "workers": 2, "oe": {"nb": 2, "nf": 2},
                "tf": {"n_poles": 2}}  # the candidates scored in two forked processes
    start, forks = time.process_time(), children()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = fleet_run.identify_record(str(path), identify)
    here, forked = time.process_time() - start, children() - forks
    assert out["status"] == "ok", out["error"]
    assert forked > 0.05  # they ran there (two candidates fitted and scored)
    # this process's CPU and its children's, and nothing else ran meanwhile: both are the
    # record's (the bounds: the few statements outside the record's own timing)
    assert 0.95 * (here + forked) <= out["cpu_seconds"] <= here + forked, (out, here, forked)
