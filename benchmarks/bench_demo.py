"""The study-1 demo end to end: virtual bench → rig files → identify → report.

``servoid.plants.ehsa.run_demo(out)`` simulates the Set-B EHSA on the virtual
bench (PRBS n = 11, 10 samples/bit, ±1 mm, 20 470 samples at 1 kHz, 30 dB
SNR, acquisition at 5 kHz), writes the TDMS file, the experiment TOML and
``truth.json``, then runs the closed-loop workflow on those files: loads and
decimates the TDMS, fits the two-step indirect and the one-step OE models,
validates both on the held-back half and writes ``report.html``,
``results.json`` and four PNG figures. Target: ≤ 10 s.

Methods
-------
run_demo (in process, warm)
    One untimed warm-up call (numba on-disk cache load, matplotlib import),
    then k timed calls, each into a fresh empty folder. ``rel_diff`` is the
    largest relative error of the one-step (K, ω_hp, δ_hp) against the
    bench's truth; the validation fits are in ``note``/``extra``.
breakdown: ...
    (full run only) The demo's stages called alone through the public API:
    the bench simulation ``bench.run``, ``write_bench_files`` (TDMS + TOML +
    truth), ``identify(toml, write=False)`` (load, fit, validate; no files)
    and ``identify(toml, out)`` (the same plus report.html, results.json and
    figures). Report writing ≈ the difference of the last two.
fresh subprocess: python -c "run_demo(...)"
    A new interpreter each time (numba's on-disk cache is warm, nothing else
    is): ``import servoid.workflows`` and the first ``run_demo`` are timed
    inside the child, the whole process (interpreter start-up included) from
    a small launcher process, whose RUSAGE_CHILDREN gives the child's peak
    RSS ("ΔRSS MB" column holds it for these rows). The first subprocess of
    the run is the one to read as "cold".
fresh subprocess, empty NUMBA_CACHE_DIR
    (full run only) The same with numba's cache pointed at an empty folder,
    so every jitted function compiles: what the very first run after
    installing costs.
CLI: servoid demo --out DIR
    (full run only) The console script, as a user runs it.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from itertools import count
from pathlib import Path

from _harness import Result, measure_memory, time_call

SUITE = "demo"
TARGET_S = 10.0
_CHILD = """
import json, os, sys, time
t0 = time.perf_counter()
from servoid.plants.ehsa import run_demo
t1 = time.perf_counter()
run_demo(out=sys.argv[1])
t2 = time.perf_counter()
with open(os.environ["SERVOID_BENCH_CHILD_OUT"], "w") as f:
    json.dump({"import_s": t1 - t0, "run_s": t2 - t1}, f)
"""


def _accuracy(demo) -> tuple[float, dict[str, float]]:  # type: ignore[no-untyped-def]
    """Largest relative one-step error vs truth, and the validation fits [%]."""
    ident = demo.identification
    errs = [
        abs(row["one-step"]["value"] - row["truth"]) / abs(row["truth"])
        for row in ident.table()
        if row.get("truth") is not None
    ]
    fits = {a: float(v.fit_percent) for a, v in ident.validations.items()}
    return max(errs), fits


# A small launcher runs the command so that the child's peak RSS is its own: on Linux a
# child's ru_maxrss starts from its parent's high-water mark at fork (~0.5 GB for this
# benchmark process), and a bare interpreter is ~10 MB.
_LAUNCHER = """
import json, resource, subprocess, sys, time
t0 = time.perf_counter()
rc = subprocess.run(sys.argv[2:], stdout=subprocess.DEVNULL).returncode
wall = time.perf_counter() - t0
with open(sys.argv[1], "w") as f:
    json.dump({"wall_s": wall, "returncode": rc,
               "maxrss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}, f)
"""


def _child(cmd: list[str], env: dict[str, str] | None = None) -> dict[str, object]:
    """Run a command; wall time, exit status, its own peak RSS, and the demo's JSON line."""
    with tempfile.TemporaryDirectory() as d:
        stats, child_out = Path(d) / "stats.json", Path(d) / "child.json"
        env = dict(os.environ if env is None else env, SERVOID_BENCH_CHILD_OUT=str(child_out))
        proc = subprocess.run([sys.executable, "-c", _LAUNCHER, str(stats), *cmd], env=env,
                              capture_output=True, text=True, check=False)
        if proc.returncode != 0 or not stats.exists():
            raise RuntimeError(f"{cmd[:3]} failed: {proc.stderr[-2000:]}")
        out = json.loads(stats.read_text())
        if out["returncode"] != 0:
            raise RuntimeError(f"{cmd[:3]} exited with {out['returncode']}: {proc.stderr[-2000:]}")
        if child_out.exists():
            out.update(json.loads(child_out.read_text()))
        return out


def _row(case: str, method: str, times_s: list[float], note: str = "", **extra) -> Result:  # type: ignore[no-untyped-def]
    r = Result(SUITE, case, 20470, method, statistics.median(times_s) * 1e3,
               min(times_s) * 1e3, len(times_s), note=note)
    r.extra.update(extra)
    r.extra["times_ms"] = [round(t * 1e3, 1) for t in times_s]
    r.extra["meets_10s_target"] = statistics.median(times_s) <= TARGET_S
    return r


def _subprocess_rows(tmp: Path, runs: int, full: bool) -> list[Result]:
    rows = []
    children = []
    for i in range(runs):
        children.append(_child([sys.executable, "-c", _CHILD, str(tmp / f"sub{i}")]))
    first = children[0]
    rows.append(_row(
        "fresh process", "fresh subprocess: python -c run_demo (wall)",
        [c["wall_s"] for c in children],
        note=(f"first: {first['wall_s']:.2f} s = import {first['import_s']:.2f} s + "
              f"run_demo {first['run_s']:.2f} s + start-up; peak RSS "
              f"{first['maxrss_mb']:.0f} MB"),
        children=children,
    ))
    rows[-1].rss_mb = first["maxrss_mb"]
    rows.append(_row("fresh process", "  of which import servoid.workflows",
                     [c["import_s"] for c in children]))
    rows.append(_row("fresh process", "  of which first run_demo",
                     [c["run_s"] for c in children]))
    if not full:
        return rows

    with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        c = _child([sys.executable, "-c", _CHILD, str(tmp / "nocache")], env)
        n_cached = sum(1 for p in Path(cache).rglob("*.nbi"))
    r = _row("fresh process, empty numba cache", "fresh subprocess: python -c run_demo (wall)",
             [c["wall_s"]],
             note=(f"import {c['import_s']:.2f} s + run_demo (JIT compile) {c['run_s']:.2f} s; "
                   f"{n_cached} cache=True numba functions compiled"),
             child=c, functions_compiled=n_cached)
    r.rss_mb = c["maxrss_mb"]
    rows.append(r)

    exe = Path(sys.executable).with_name("servoid")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "servoid"]
    clis = []
    for i in range(runs):
        clis.append(_child([*cmd, "demo", "--out", str(tmp / f"cli{i}")]))
    r = _row("CLI", "servoid demo --out DIR (wall)", [c["wall_s"] for c in clis],
             note=f"`{Path(cmd[0]).name} demo`; first "
                  f"{clis[0]['wall_s']:.2f} s, peak RSS {clis[0]['maxrss_mb']:.0f} MB",
             children=clis)
    r.rss_mb = clis[0]["maxrss_mb"]
    rows.append(r)
    return rows


def _breakdown_rows(tmp: Path, repeats: int) -> list[Result]:
    from servoid.plants.ehsa import EhsaBench, run, write_bench_files
    from servoid.signals import prbs
    from servoid.workflows import identify

    bench = EhsaBench(snr_db=30.0)
    ex = prbs(11, clock=10, amplitude=1e-3, dt=bench.dt)
    record = run(bench, ex, rng=2026)
    files = write_bench_files(record, tmp / "parts", format="tdms", overwrite=True)
    toml = next(p for p in files if p.suffix == ".toml")
    k = count()
    pieces = (
        ("breakdown: bench run (simulate + DAQ)", lambda: run(bench, ex, rng=2026)),
        ("breakdown: write_bench_files (TDMS+TOML+truth)",
         lambda: write_bench_files(record, tmp / f"w{next(k)}", format="tdms")),
        ("breakdown: identify(write=False)", lambda: identify(toml, write=False)),
        ("breakdown: identify(out) incl. report+figures",
         lambda: identify(toml, tmp / f"rep{next(k)}")),
    )
    rows = []
    for label, fn in pieces:
        t = time_call(fn, repeats, warmup=1)
        rows.append(_row("in process, warm", label, t.times))
    return rows


def run(quick: bool = False) -> list[Result]:
    """Run the demo suite; ``quick``: one timed run and one fresh subprocess."""
    from servoid.plants.ehsa import run_demo

    repeats = 1 if quick else 5
    rows: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="servoid-bench-demo-") as d:
        tmp = Path(d)
        k = count()

        def demo():  # type: ignore[no-untyped-def]
            return run_demo(out=tmp / f"run{next(k)}")

        t0 = time.perf_counter()
        result = demo()  # warm-up: numba cache load, matplotlib and report imports
        first = time.perf_counter() - t0
        timing = time_call(demo, repeats, warmup=0)
        err, fits = _accuracy(result)
        files = sorted(p.name for p in (tmp / "run0").rglob("*") if p.is_file())
        r = _row(
            "in process, warm", "run_demo(out=DIR)", timing.times,
            note=(f"≤ {TARGET_S:g} s target; validation fit one-step "
                  f"{fits.get('one-step', float('nan')):.1f} %, indirect "
                  f"{fits.get('indirect', float('nan')):.1f} %"),
            first_call_in_process_ms=round(first * 1e3, 1),
            validation_fit_percent=fits,
            files_written=files,
        )
        r.rel_diff = err
        r.solver = "one-step vs truth"
        if timing.sys_s_per_call is not None:
            r.extra["sys_ms_per_call"] = round(timing.sys_s_per_call * 1e3, 1)
        if not quick:
            mem = measure_memory(demo)
            r.peak_mb = mem.tracemalloc_peak / 2**20
            if mem.rss_peak_delta is not None:
                r.rss_mb = mem.rss_peak_delta / 2**20
        rows.append(r)
        if not quick:
            rows += _breakdown_rows(tmp, 3)
        rows += _subprocess_rows(tmp, 1 if quick else 3, full=not quick)
    return rows


if __name__ == "__main__":
    from _harness import format_table

    print(format_table(run(quick="--quick" in sys.argv)))
