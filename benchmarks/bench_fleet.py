"""Fleet throughput: many Set-B bench records identified on 1 and 2 Dask workers.

Case
----
``records`` experiment files of virtual EHSA units (``servoid.plants.ehsa._fleet``
scatter around Set B, reduced fidelity, 35 dB), each a PRBS test at 1 kHz:
register 11, clock 10 → 20 470 samples (``--quick``: 8 records, register 9,
5 110 samples). ``distinct`` units are simulated and copied to make up the
count, each copy its own record (its own path, so none is reused from the
checkpoint store). Identification per record: the closed-loop workflow with
``approach = ["indirect", "one-step"]`` (the two-step and the one-step), no
structure test.

Method
------
``run_fleet(..., force=True)`` in this process: ``workers=1`` (serial, in
process) and ``workers=2`` (a Dask LocalCluster of 2 single-threaded worker
processes, BLAS on one thread). Wall time includes cluster start-up and
writing the table and report. Parallel efficiency = t1 / (2·t2). Peak RSS
of a worker (``rss_mb``) is its own resident high-water mark after its last
record (for workers=1, this process's, including the table and report).
The mean CPU time of a record's task (``cpu_seconds`` of its outcome: the
worker process's CPU over the record) shows whether a record costs more on
a worker than in the serial run, whatever else the machine runs.

Before both, ``BACK_TO_BACK`` records are identified one after another in
this process with :func:`servoid.fleet._task.identify_record` (after one
warm-up record): their wall and CPU time per record.  The machine is shared,
so every row states the 1-minute load average (``os.getloadavg``) before and
after it: with a load above the 2 cores, wall times measure the other jobs
too, and the CPU time per record is the figure to compare.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from _harness import Result

from servoid.fleet import run_fleet
from servoid.fleet._task import identify_record
from servoid.plants.ehsa._fleet import write_virtual_fleet

BACK_TO_BACK = 20


def _fleet(root: Path, records: int, distinct: int, register: int) -> Path:
    fleet = write_virtual_fleet(root / "base", units=distinct, bad_every=0, corrupt=0,
                                register=register, seed=11)
    rows = fleet.manifest.read_text(encoding="utf-8").splitlines()
    header, units = rows[0], rows[1:]
    out = [header]
    for k in range(records):
        path, rest = units[k % distinct].split(",", 1)
        copy = root / "copies" / f"R{k:05d}"
        shutil.copytree((root / "base" / path).parent, copy)
        serial = f"SN-{k + 1:05d}"
        out.append(f"{(copy / 'ehsa.toml').as_posix()},{serial},{rest.split(',', 2)[1]},"
                   f"{rest.split(',', 2)[2]}")
    (root / "units.csv").write_text("\n".join(out) + "\n", encoding="utf-8")
    (root / "fleet.toml").write_text(
        '[records]\nmanifest = "units.csv"\n\n[identify]\nmethod = "closedloop"\n'
        'approach = ["indirect", "one-step"]\nstructure_test = false\n', encoding="utf-8")
    return root / "fleet.toml"


def run(quick: bool) -> list[Result]:
    records, distinct, register = (8, 4, 9) if quick else (1000, 40, 11)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        t0 = time.perf_counter()
        spec = _fleet(root, records, distinct, register)
        build = time.perf_counter() - t0
        results.append(_back_to_back(root, records, register))
        times = {}
        for workers in (1, 2):
            load0 = os.getloadavg()[0]
            t0 = time.perf_counter()
            result = run_fleet(spec, root / f"out{workers}", workers=workers, force=True,
                               progress=False, allow_duplicates=True)  # the copies
            times[workers] = time.perf_counter() - t0
            assert result.count("ok") == records, result
            per = 1e3 * times[workers] / records
            task_cpu = 1e3 * _mean_task_cpu(root / f"out{workers}" / "records")
            peak = result.peak_rss_mb
            results.append(Result(
                suite="fleet", case=f"{records} records × {2 ** register * 10 // 1000}k samples",
                n=records, method=f"run_fleet workers={workers}", median_ms=1e3 * times[workers],
                best_ms=1e3 * times[workers], repeats=1,
                rss_mb=peak,
                note=f"{per:.0f} ms per record; {task_cpu:.0f} ms CPU per record in its task; "
                     f"worker peak RSS {peak:.0f} MB; building the records took {build:.0f} s; "
                     f"load {load0:.2f} → {os.getloadavg()[0]:.2f}",
                extra={"seconds": times[workers], "ms_per_record": per,
                       "task_cpu_ms_per_record": task_cpu,
                       "worker_peak_rss_mb": peak, "load_before": load0,
                       "load_after": os.getloadavg()[0]}))
        efficiency = times[1] / (2 * times[2])
        results[-1].extra["parallel_efficiency"] = efficiency
        results[-1].note += f"; parallel efficiency {efficiency:.2f}"
    return results


def _mean_task_cpu(store: Path) -> float:
    """Mean CPU time [s] of a record's task (its worker process's, over the record)."""
    values = [json.loads(p.read_text(encoding="utf-8")).get("cpu_seconds")
              for p in store.glob("*.json")]
    values = [v for v in values if v is not None]
    return sum(values) / len(values) if values else float("nan")


def _back_to_back(root: Path, records: int, register: int) -> Result:
    """Identify the first records one after another in this process: wall and CPU per record."""
    identify = {"method": "closedloop", "approach": ["indirect", "one-step"],
                "structure_test": False}
    paths = [str(root / "copies" / f"R{k:05d}" / "ehsa.toml") for k in range(records)]
    count = min(BACK_TO_BACK, records - 1)
    identify_record(paths[0], identify)  # imports and compiled kernels, as a worker's first
    load0 = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), time.process_time()
    for path in paths[1:count + 1]:
        assert identify_record(path, identify)["status"] == "ok"
    wall = (time.perf_counter() - wall) / count
    cpu = (time.process_time() - cpu) / count
    load1 = os.getloadavg()[0]
    return Result(
        suite="fleet", case=f"{count} records back to back × {2 ** register * 10 // 1000}k samples",
        n=count, method="identify_record, in process", median_ms=1e3 * wall, best_ms=1e3 * wall,
        repeats=1,
        note=f"{1e3 * wall:.0f} ms wall, {1e3 * cpu:.0f} ms CPU per record; load {load0:.2f} → "
             f"{load1:.2f}",
        extra={"ms_per_record_wall": 1e3 * wall, "ms_per_record_cpu": 1e3 * cpu,
               "load_before": load0, "load_after": load1})
