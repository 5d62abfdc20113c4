"""Scaling with the record length: time and peak memory from N = 1e4 to 1e7.

Every cell (one method at one N) runs in a fresh Python process, so each
peak-memory reading belongs to that cell alone and nothing is warm but
numba's on-disk cache. By default N = 1e4, 1e5, 1e6 (under ``--quick`` of
run.py: 1e4 and 1e5); ``--full`` on this module's command line (or
``SERVOID_SCALING_FULL=1`` in the environment) adds 1e7.

Data
----
A white-noise input u (fixed seed) through B(q)/A(q) with poles 0.9 and
0.7, B = [0.5, 0.3] after one sample of delay: y = B/A u + e/A (equation
error, σ = 0.05) for ARX, RLS and the ARX validation; y = B/A u + v (output
error, σ = 0.05) for OE and the OE validation. Generated in the child before
anything is measured.

Methods
-------
fit_arx
    ``fit_arx(exp, 2, 2, 1)`` (the Gram route; residuals are lazy).
numpy lagged-dot ARX
    Baseline: one ``np.dot`` of lagged slices per entry of the 5×5 augmented
    Gram matrix, then ``np.linalg.solve`` of the normal equations.
fit_rls
    ``fit_rls(phi, y)``, λ = 1, Φ (N × 4, ARX(2,2,1) regressors) given.
Φ + fit_rls
    The same with Φ built (``np.column_stack`` of lagged slices) inside the
    timed call: the pair the issue measured.
plain numba RLS loop
    Baseline: the textbook recursion over arrays, compiled (q = Pφ, d = 1 + φᵀq,
    θ += q·e/d, P −= qqᵀ/d), no normalisation, guard, covariance or checks.
fit_oe
    ``fit_oe(exp, 2, 2, 1)`` (OE(2,2)).
fit_tf_greybox
    The same OE(2,2) as a grey-box transfer function: θ = (b0, b1, p1, p2),
    ``G = (b0 z + b1)/((z − p1)(z − p2))``, from θ₀ = (0.4, 0.2, 0.8, 0.6);
    from 1e5 samples it takes the streamed Gauss–Newton.
validate ARX / validate OE
    ``validate(estimate, exp)`` of the fitted ARX(2,2,1) / OE(2,2,1) on its
    own record (the same work as on fresh data): simulation, 5-step
    prediction, metrics and the residual tests (M = 25).
residual_analysis
    ``residual_analysis(e, u)`` of the ARX one-step residuals alone.
read csv / tdms / mat
    ``read_experiment`` of the record (time, u, y) written by ``write_csv``,
    ``write_tdms`` and ``scipy.io.savemat`` (v5, uncompressed), with roles.
Experiment copy / Experiment no-copy
    ``Experiment.from_arrays(dt, u=u, y=y)`` with the default ``copy=True``
    and with ``copy=False`` (read-only views of the caller's arrays).
fit_one_step
    ``servoid.plants.ehsa.fit_one_step(exp, loop, theta0=(2000, 100, 0.5))``
    on a closed-loop record of N samples: the Set-B servo (K = 3451.7 1/s,
    ω_hp = 163.3 rad/s, δ_hp = 0.249, c = F = 0.01) driven by the PRBS of the
    closed-loop suite repeated to N samples, 30 dB output noise.
servoid identify
    The whole command, ``servoid identify rec.toml --out DIR --overwrite``
    (ARX(2,2,1) on the CSV of the read rows; fit, split validation, feedback
    test, figures, report), one fresh process per call: the time includes
    start-up and imports, and the memory column is that process's own peak
    RSS (``extra.command_peak_rss_mb``), not a ΔRSS. Fewer calls per cell
    (3 up to 1e5, then 1).

Stated memory
-------------
The estimators these cells run state their memory in a ``Memory: about
k N × 8 bytes beyond the record`` line of their docstring. Each cell whose
call is one such function (``STATED``) compares its ΔRSS with that
statement: *ok* when ΔRSS <= 1.25·k·N·8 bytes + 4 MB (page and allocator
granularity), else *over* (``extra.stated_mb``, ``extra.memory``).

Measurement (in the child)
--------------------------
Each cell is a new interpreter, started through a small launcher that has
not imported numpy (Linux carries the resident high-water mark of the
process that execs into the new program, so a child forked from this runner
would report the runner's RSS as its own). The child records its RSS after
the imports ("after imports") and once the inputs are built ("inputs
ready"). The first call is timed alone ("first": it includes loading
numba's on-disk cache). Then the resident high-water mark is reset
(``/proc/self/clear_refs``) and one call is made: *ΔRSS MB* = VmHWM after it
− VmRSS before it, the memory the call itself touched. The child runs with
``MALLOC_MMAP_THRESHOLD_`` fixed at 128 KiB, so the large arrays the first
call freed are returned to the system rather than reused unseen. Then k
timed calls (median, best; k = 7 up to 1e5, 5 at 1e6, 3 at 1e7), garbage
collector off; the process CPU time of each (``time.process_time``,
``extra.cpu_median_ms``) is recorded too, a steadier measure than wall time
when other work shares the cores. *peak RSS* (``extra.peak_rss_mb``, the note) is
``resource.getrusage(RUSAGE_SELF).ru_maxrss`` at the end: the whole process
— interpreter, numpy/scipy/numba, the inputs, every call. ``extra.growth_*``
holds the factor per decade of N: median time (and ΔRSS) at N over N/10.

BLAS runs on one thread in the children unless ``OPENBLAS_NUM_THREADS``
(``run.py --blas-threads``) says otherwise: on this shared 2-vCPU VM waking
a second BLAS thread now and then costs up to ~100 ms (a 51×51 ``eigh`` of
the independence test: 0.27 ms median, 109 ms worst of 20 with two threads
under load), which would swamp the millisecond cells.

``--before [REV]`` (module command line) also runs the RLS, validation and
residual cells with ``_rls.py``, ``_residuals.py`` and ``_metrics.py`` as
committed at REV (default ``HEAD``) loaded in place of the working tree's —
a before/after comparison on the same machine; those rows carry
``[REV]`` in their method. ``--before-tree REV`` runs every selected cell
a second time, right after the first, on the whole ``src/`` tree of REV
(``git archive``, put first on the child's ``PYTHONPATH``): back-to-back
before/after pairs under the same load.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import numba
import numpy as np
from _harness import Result, machine_info

SUITE = "scaling"
SEED = 20261124
POLES = (0.9, 0.7)
B = (0.5, 0.3)
NOISE = 0.05
MAX_LAG = 25
METHODS = (
    "fit_arx",
    "numpy lagged-dot ARX",
    "fit_rls",
    "Φ + fit_rls",
    "plain numba RLS loop",
    "fit_oe",
    "fit_tf_greybox",
    "validate ARX",
    "validate OE",
    "residual_analysis",
    "read csv",
    "read tdms",
    "read mat",
    "Experiment copy",
    "Experiment no-copy",
    "fit_one_step",
    "servoid identify",
)
#: Cells whose call is one documented function: (module, qualified name) whose docstring
#: holds the "Memory: about k N × 8 bytes" statement the cell's ΔRSS is checked against.
STATED = {
    "fit_arx": ("servoid.estimate", "fit_arx"),
    "fit_rls": ("servoid.estimate", "fit_rls"),
    "fit_oe": ("servoid.estimate", "fit_oe"),
    "fit_tf_greybox": ("servoid.estimate", "fit_tf_greybox"),
    "validate ARX": ("servoid.validate", "validate"),
    "validate OE": ("servoid.validate", "validate"),
    "residual_analysis": ("servoid.validate", "residual_analysis"),
}
_BLAS_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
# Linux carries the resident high-water mark of the process that execs into the new program
# (a child forked from this runner would report the runner's RSS as its own ru_maxrss): each
# cell is therefore started from a small launcher that has not imported numpy.
_LAUNCHER = "import subprocess, sys; sys.exit(subprocess.run(sys.argv[1:]).returncode)"
#: Cells that can also run on the committed code (``--before``).
BEFORE = ("fit_rls", "Φ + fit_rls", "validate ARX", "validate OE", "residual_analysis")
_SWAPPED = {
    "estimate/_rls.py": "servoid.estimate._rls",
    "validate/_residuals.py": "servoid.validate._residuals",
    "validate/_metrics.py": "servoid.validate._metrics",
}


def run(quick: bool) -> list[Result]:
    """One fresh process per (method, N); N = 1e4…1e6, 1e7 with SERVOID_SCALING_FULL=1."""
    full = os.environ.get("SERVOID_SCALING_FULL", "") not in ("", "0")
    sizes = [10**4, 10**5] if quick else [10**4, 10**5, 10**6] + ([10**7] if full else [])
    return measure(sizes, before=False)


def measure(
    sizes: list[int], before: bool, rev: str = "HEAD", methods: tuple[str, ...] = METHODS,
    tree: tuple[str, str] | None = None,
) -> list[Result]:
    """Run every cell in a fresh process and add the growth factors per decade.

    ``tree`` = (label, src directory): each cell runs a second time, right
    after the first, with that tree first on the child's PYTHONPATH.
    """
    rows: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="servoid-scaling-") as tmp:
        for n in sizes:
            files = _write_files(Path(tmp), n)
            for method in methods:
                variants: list[tuple[str | None, tuple[str, str] | None]] = [(None, None)]
                if before and method in BEFORE:
                    variants.append((rev, None))
                if tree is not None:
                    variants.append((None, tree))
                for old, src in variants:
                    rows.append(_cell(method, n, files, old, src))
                    _check_memory(rows[-1])
                    r = rows[-1]
                    print(
                        f"#   {r.method:32s} N={n:>8d}  median {r.median_ms:10.2f} ms  "
                        f"first {r.extra.get('first_ms', float('nan')):10.2f} ms  "
                        f"ΔRSS {r.rss_mb if r.rss_mb is not None else float('nan'):8.1f} MB  "
                        f"peak RSS {r.extra.get('peak_rss_mb', float('nan')):8.1f} MB",
                        flush=True,
                    )
            for path in files.values():
                Path(path).unlink()
    _growth(rows)
    return rows


def render(payload: dict[str, object]) -> str:
    """Markdown: median time and ΔRSS per method (rows) and N (columns), growth per decade."""
    rows = [Result(**r) for r in payload["results"]]  # type: ignore[union-attr]
    for r in rows:  # against the statements of the code as it is now
        _check_memory(r)
    sizes = sorted({r.n for r in rows})
    methods = sorted({r.method for r in rows}, key=_order)
    cell = {(r.method, r.n): r for r in rows}

    def fmt(x: float | None, unit: str) -> str:
        if x is None or math.isnan(x):
            return "—"
        return f"{x:.3g} {unit}" if x < 1000 else f"{x:,.0f} {unit}"

    head = " | ".join(f"N = {n:.0e}".replace("e+0", "e") for n in sizes)
    out = []
    for title, key, unit in (
        ("median time", "median_ms", "ms"),
        ("median CPU time of the process (where recorded)", "cpu", "ms"),
        ("ΔRSS of one call", "rss_mb", "MB"),
        ("peak RSS of the process", "peak", "MB"),
    ):
        out += [
            f"**{title}**",
            "",
            f"| method | {head} | ×/decade (last) |",
            "|---|" + "---|" * (len(sizes) + 1),
        ]
        for m in methods:
            vals = []
            for n in sizes:
                r = cell.get((m, n))
                if r is None:
                    vals.append(None)
                elif key == "peak":
                    vals.append(r.extra.get("peak_rss_mb"))
                elif key == "cpu":
                    vals.append(r.extra.get("cpu_median_ms"))
                else:
                    vals.append(getattr(r, key))
            last = [v for v in vals if v is not None and not math.isnan(v)]
            if key == "cpu" and not last:  # rows measured before CPU time was recorded
                continue
            growth = f"{last[-1] / last[-2]:.1f}×" if len(last) >= 2 and last[-2] > 0 else "—"
            out.append(f"| {m} | " + " | ".join(fmt(v, unit) for v in vals) + f" | {growth} |")
        out.append("")
    checked = [m for m in methods if any("memory" in cell[m, n].extra
                                         for n in sizes if (m, n) in cell)]
    if checked:
        out += ["**ΔRSS against the docstring's Memory line** (ok: ≤ 1.25 × stated + 4 MB)",
                "", f"| method | {head} |", "|---|" + "---|" * len(sizes)]
        for m in checked:
            vals = []
            for n in sizes:
                r = cell.get((m, n))
                if r is None or "memory" not in r.extra:
                    vals.append("—")
                else:
                    vals.append(f"{fmt(r.rss_mb, 'MB')} / {fmt(r.extra['stated_mb'], 'MB')} "
                                f"{r.extra['memory']}")
            out.append(f"| {m} | " + " | ".join(vals) + " |")
        out.append("")
    return "\n".join(out)


# -- parent side -------------------------------------------------------------------------------


def _write_files(tmp: Path, n: int) -> dict[str, str]:
    import scipy.io

    from servoid.data import write_csv, write_tdms

    u, y_arx, _ = _signals(n)
    exp = _experiment(u, y_arx, "arx")
    paths = {"csv": tmp / f"rec{n}.csv", "tdms": tmp / f"rec{n}.tdms", "mat": tmp / f"rec{n}.mat"}
    write_csv(exp, paths["csv"], overwrite=True)
    write_tdms(exp, paths["tdms"], overwrite=True)
    scipy.io.savemat(paths["mat"], {"u": np.asarray(exp["u"]), "y": np.asarray(exp["y"])})
    return {k: str(v) for k, v in paths.items()}


def _stated_factor(method: str) -> float | None:
    """k of the "Memory: about k N × 8 bytes" line of the cell's function, or None."""
    import importlib
    import re

    where = STATED.get(method.split(" [")[0])
    if where is None:
        return None
    doc = getattr(importlib.import_module(where[0]), where[1]).__doc__ or ""
    found = re.search(r"Memory: about ([0-9.]+) N × 8 bytes", " ".join(doc.split()))
    return float(found.group(1)) if found else None


def _check_memory(r: Result) -> None:
    """extra.stated_mb and extra.memory (ok/over): ΔRSS against the docstring's statement."""
    k = _stated_factor(r.method)
    if k is None or r.rss_mb is None or math.isnan(r.median_ms):
        return
    stated = k * r.n * 8 / 2**20
    r.extra["stated_mb"] = round(stated, 3)
    r.extra["memory"] = "ok" if r.rss_mb <= 1.25 * stated + 4.0 else "over"


def _cell(method: str, n: int, files: dict[str, str], before: str | None,
          tree: tuple[str, str] | None = None) -> Result:
    spec = json.dumps({"method": method, "n": n, "files": files, "before": before})
    # a fixed mmap threshold: every large array is mapped and unmapped on its own, so the
    # resident high-water mark of a repeated call is that call's (glibc otherwise raises the
    # threshold after the first free and serves the next call from memory it already holds)
    env = {**os.environ, "MALLOC_MMAP_THRESHOLD_": "131072"}
    if tree is not None:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [tree[1], env.get("PYTHONPATH")]))
    for var in _BLAS_VARS:  # one BLAS thread unless the caller chose (run.py --blas-threads)
        env.setdefault(var, "1")
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            _LAUNCHER,
            sys.executable,
            str(Path(__file__).resolve()),
            "--child",
            spec,
        ],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    label = method + (f" [{before}]" if before else "") + (f" [{tree[0]}]" if tree else "")
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        return Result(
            SUITE,
            method,
            n,
            label,
            float("nan"),
            float("nan"),
            0,
            note="child failed: " + " | ".join(tail),
        )
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    times = out["times_ms"]
    return Result(
        SUITE,
        method,
        n,
        label,
        float(sorted(times)[len(times) // 2]),
        float(min(times)),
        len(times),
        # the whole command runs in its own process: its peak RSS is the memory figure
        rss_mb=out.get("extra", {}).get("command_peak_rss_mb", out["call_rss_mb"]),
        note=(
            f"peak RSS {out['peak_rss_mb']:.0f} MB (after imports {out['import_rss_mb']:.0f}, "
            f"inputs ready {out['setup_rss_mb']:.0f}); first call {out['first_ms']:.1f} ms"
        ),
        extra={
            "first_ms": out["first_ms"],
            "peak_rss_mb": out["peak_rss_mb"],
            "import_rss_mb": out["import_rss_mb"],
            "setup_rss_mb": out["setup_rss_mb"],
            "times_ms": [round(t, 4) for t in times],
            # CPU time of the process per call: less disturbed than wall time when other
            # work shares the two cores (it still counts cache and frequency effects)
            "cpu_median_ms": round(float(np.median(out["cpu_ms"])), 4),
            **out.get("extra", {}),
        },
    )


def _order(method: str) -> tuple[int, bool, str]:
    """Sort key: the METHODS order, ``[REV]`` rows after their own (by label)."""
    base = method.split(" [")[0]
    return (METHODS.index(base) if base in METHODS else len(METHODS), " [" in method, method)


def _growth(rows: list[Result]) -> None:
    by_key = {(r.method, r.n): r for r in rows}
    for r in rows:
        prev = by_key.get((r.method, r.n // 10))
        if prev is None or not prev.median_ms > 0:
            continue
        r.extra["growth_time"] = round(r.median_ms / prev.median_ms, 2)
        if r.rss_mb is not None and prev.rss_mb is not None and prev.rss_mb > 0:
            r.extra["growth_rss"] = round(r.rss_mb / prev.rss_mb, 2)


# -- child side --------------------------------------------------------------------------------


def _signals(n: int):  # type: ignore[no-untyped-def]
    """(u, y_arx, y_oe) of length n, fixed seed."""
    from scipy import signal as sps

    rng = np.random.default_rng(SEED)
    u = rng.standard_normal(n)
    a = np.real(np.poly(POLES))
    b = np.r_[0.0, B]
    clean = sps.lfilter(b, a, u)
    y_arx = clean + sps.lfilter([1.0], a, NOISE * rng.standard_normal(n))
    y_oe = clean + NOISE * rng.standard_normal(n)
    return u, y_arx, y_oe


def _experiment(u, y, name):  # type: ignore[no-untyped-def]
    from servoid.data import Experiment

    return Experiment.from_arrays(1e-3, u=u, y=y, name=name)


def _greybox_model(theta):  # type: ignore[no-untyped-def]
    """G = (b0 z + b1)/((z − p1)(z − p2)) at dt = 1 ms: the OE(2,2) of the data, as a grey box."""
    from servoid.models import TransferFunction

    b0, b1, p1, p2 = theta
    return TransferFunction([b0, b1], [1.0, -(p1 + p2), p1 * p2], 1e-3)


def _lagged_phi(u, y):  # type: ignore[no-untyped-def]
    """ARX(2,2,1) regressors [−y(t−1), −y(t−2), u(t−1), u(t−2)] and y(t), t = 2…N−1."""

    n = y.size
    return np.column_stack([-y[1 : n - 1], -y[: n - 2], u[1 : n - 1], u[: n - 2]]), y[2:]


def _numpy_arx(u, y):  # type: ignore[no-untyped-def]

    n = y.size
    cols = [-y[1 : n - 1], -y[: n - 2], u[1 : n - 1], u[: n - 2], y[2:]]
    gram = np.array([[np.dot(a, b) for b in cols] for a in cols])
    return np.linalg.solve(gram[:4, :4], gram[:4, 4])


@numba.njit(cache=True)
def _plain_rls(phi, y, p0):  # type: ignore[no-untyped-def]
    """The textbook recursion over arrays: what "an RLS loop in numba" costs."""
    n_rows, n = phi.shape
    theta = np.zeros(n)
    p = np.eye(n) * p0
    q = np.empty(n)
    for t in range(n_rows):
        d = 1.0
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += p[i, j] * phi[t, j]
            q[i] = acc
            d += phi[t, i] * acc
        e = y[t]
        for i in range(n):
            e -= phi[t, i] * theta[i]
        for i in range(n):
            theta[i] += q[i] * e / d
        for i in range(n):
            for j in range(n):
                p[i, j] -= q[i] * q[j] / d
    return theta, p


def _use_sources_of(rev: str) -> None:
    """Put the committed versions (at ``rev``) of the swapped modules in place of the tree's."""
    import importlib.util

    import servoid.estimate
    import servoid.validate
    import servoid.validate._report as report

    root = HERE.parent
    for rel, name in _SWAPPED.items():
        text = subprocess.run(
            ["git", "-C", str(root), "show", f"{rev}:src/servoid/{rel}"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        path = Path(tempfile.mkdtemp()) / Path(rel).name
        path.write_text(text)
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        sys.modules[name] = module
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    rls = sys.modules["servoid.estimate._rls"]
    residuals = sys.modules["servoid.validate._residuals"]
    metrics = sys.modules["servoid.validate._metrics"]
    servoid.estimate.fit_rls = rls.fit_rls  # type: ignore[attr-defined]
    servoid.validate.residual_analysis = residuals.residual_analysis  # type: ignore[attr-defined]
    report.residual_analysis = residuals.residual_analysis  # type: ignore[attr-defined]
    for fn in ("fit_percent", "nrmse", "rmse", "vaf", "relative_error"):
        setattr(report, fn, getattr(metrics, fn))


def _status_kb(key: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    raise KeyError(key)


def _child(spec: dict[str, object]) -> dict[str, object]:
    import gc
    import warnings

    method, n = str(spec["method"]), int(spec["n"])  # type: ignore[call-overload]
    files: dict[str, str] = spec["files"]  # type: ignore[assignment]
    if spec["before"]:
        _use_sources_of(str(spec["before"]))
    import servoid.estimate as est
    import servoid.validate as val
    from servoid.data import read_experiment

    gc.collect()
    import_kb = _status_kb("VmRSS")
    extra: dict[str, object] = {}
    call = _call_for(method, n, files, est, val, read_experiment, extra)
    gc.collect()
    setup_kb = _status_kb("VmRSS")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        call()
        first_ms = (time.perf_counter() - t0) * 1e3
        gc.collect()
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        before_kb = _status_kb("VmRSS")
        call()
        call_kb = max(_status_kb("VmHWM") - before_kb, 0)
        repeats = 7 if n <= 10**5 else (5 if n <= 10**6 else 3)
        if method == "servoid identify":  # seconds per call from 1e6 on
            repeats = 3 if n <= 10**5 else 1
        times = []
        cpu = []
        gc.disable()
        for _ in range(repeats):
            c0 = time.process_time()
            t0 = time.perf_counter()
            call()
            times.append((time.perf_counter() - t0) * 1e3)
            cpu.append((time.process_time() - c0) * 1e3)
        gc.enable()
    return {
        "times_ms": times,
        "cpu_ms": cpu,
        "first_ms": first_ms,
        "call_rss_mb": call_kb / 1024,
        "import_rss_mb": import_kb / 1024,
        "setup_rss_mb": setup_kb / 1024,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "extra": extra,
    }


def _closed_loop_record(n: int):  # type: ignore[no-untyped-def]
    """The closed-loop suite's Set-B record, its PRBS repeated to n samples."""
    from servoid.data import Experiment
    from servoid.plants.ehsa import FeedbackLoop, simulate_closed_loop
    from servoid.signals import prbs

    loop = FeedbackLoop(0.01, 0.01)
    r = np.resize(prbs(11, clock=10, amplitude=1e-3, periods=1, dt=1e-3).values, n)
    y0 = simulate_closed_loop(np.array([3451.7, 163.3, 0.249]), r, 1e-3, loop)
    noise = np.random.default_rng(SEED).normal(0.0, y0.std() / 10 ** (30 / 20), n)
    return Experiment.from_arrays(1e-3, r=r, y=y0 + noise), loop


def _identify_command(csv: str, extra: dict[str, object]):  # type: ignore[no-untyped-def]
    """A call that runs ``servoid identify`` on the CSV in a fresh process."""
    folder = Path(csv).parent
    toml = folder / "rec.toml"
    toml.write_text(
        f'[data]\nfile = "{Path(csv).name}"\n[channels.u]\nsource = "u"\nrole = "u"\n'
        '[channels.y]\nsource = "y"\nrole = "y"\n'
        '[identify]\nmethod = "arx"\nna = 2\nnb = 2\nnk = 1\n'
    )
    command = [sys.executable, "-m", "servoid", "identify", str(toml), "--out",
               str(folder / "identify-out"), "--overwrite"]

    def call() -> None:
        proc = subprocess.run(command, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise RuntimeError("servoid identify failed: " + proc.stderr[-500:])
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        extra["command_peak_rss_mb"] = round(peak, 1)

    return call


def _call_for(method, n, files, est, val, read_experiment, extra):  # type: ignore[no-untyped-def]
    """The zero-argument call a cell times, with its inputs prepared outside it."""

    if method.startswith("read "):
        fmt = method.split()[1]
        kw: dict[str, object] = {"roles": {"u": ["u"], "y": ["y"]}}
        if fmt == "mat":
            kw["dt"] = 1e-3
        path = files[fmt]
        extra["file_mb"] = round(os.path.getsize(path) / 2**20, 2)
        return lambda: read_experiment(path, **kw)
    if method == "servoid identify":
        return _identify_command(files["csv"], extra)
    if method == "fit_one_step":
        from servoid.plants.ehsa import fit_one_step

        exp, loop = _closed_loop_record(n)
        return lambda: fit_one_step(exp, loop, theta0=(2000.0, 100.0, 0.5))
    u, y_arx, y_oe = _signals(n)
    if method.startswith("Experiment "):
        from servoid.data import Experiment

        copy = method == "Experiment copy"
        return lambda: Experiment.from_arrays(1e-3, u=u, y=y_arx, name="x", copy=copy)
    if method == "numpy lagged-dot ARX":
        return lambda: _numpy_arx(u, y_arx)
    if method == "fit_rls":
        phi, rhs = _lagged_phi(u, y_arx)
        return lambda: est.fit_rls(phi, rhs)
    if method == "Φ + fit_rls":
        return lambda: est.fit_rls(*_lagged_phi(u, y_arx))
    if method == "plain numba RLS loop":
        phi, rhs = _lagged_phi(u, y_arx)
        return lambda: _plain_rls(phi, rhs, 1e8)
    arx = _experiment(u, y_arx, "arx")
    if method == "fit_arx":
        return lambda: est.fit_arx(arx, 2, 2, 1)
    if method == "validate ARX":
        model = est.fit_arx(arx, 2, 2, 1)
        extra["residuals_white"] = bool(val.validate(model, arx).residuals.is_white)
        return lambda: val.validate(model, arx)
    if method == "residual_analysis":
        e = np.asarray(est.fit_arx(arx, 2, 2, 1).model.residuals(y_arx, u))
        return lambda: val.residual_analysis(e, u, MAX_LAG)
    oe = _experiment(u, y_oe, "oe")
    if method == "fit_oe":
        return lambda: est.fit_oe(oe, 2, 2, 1)
    if method == "fit_tf_greybox":
        return lambda: est.fit_tf_greybox(oe, _greybox_model, [0.4, 0.2, 0.8, 0.6],
                                          ["b0", "b1", "p1", "p2"])
    if method == "validate OE":
        model = est.fit_oe(oe, 2, 2, 1)
        extra["residuals_white"] = bool(val.validate(model, oe).residuals.is_white)
        return lambda: val.validate(model, oe)
    raise ValueError(f"unknown method {method!r}")


# -- command line ------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--full", action="store_true", help="add N = 1e7")
    parser.add_argument(
        "--before",
        nargs="?",
        const="HEAD",
        default=None,
        metavar="REV",
        help="also run the RLS/validation cells on the sources committed at REV (default HEAD)",
    )
    parser.add_argument(
        "--before-tree",
        default=None,
        metavar="REV",
        help="also run every selected cell on the whole src/ tree of REV (git archive), "
        "each right after its own",
    )
    parser.add_argument(
        "--sizes",
        type=float,
        nargs="+",
        default=None,
        help="record lengths instead of the default grid (e.g. 1e5 1e6)",
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        choices=METHODS,
        default=list(METHODS),
        metavar="METHOD",
        help="only these cells (names as in the table)",
    )
    parser.add_argument(
        "--merge",
        action="store_true",
        help="replace the matching rows of an existing --out file instead of rewriting it",
    )
    parser.add_argument("--out", type=Path, default=HERE / "results-scaling.json")
    parser.add_argument(
        "--render",
        type=Path,
        default=None,
        metavar="JSON",
        help="print a saved results file as Markdown tables and exit",
    )
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        print(json.dumps(_child(json.loads(args.child))))
        return 0
    if args.render is not None:
        print(render(json.loads(args.render.read_text())))
        return 0
    sizes = (
        [int(s) for s in args.sizes]
        if args.sizes
        else ([10**4, 10**5, 10**6] + ([10**7] if args.full else []))
    )
    machine = machine_info()
    t0 = time.perf_counter()
    rev = None
    if args.before:
        rev = subprocess.run(
            ["git", "-C", str(HERE), "rev-parse", "--short", args.before],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    tree = None
    tree_dir = None
    if args.before_tree:
        label = subprocess.run(
            ["git", "-C", str(HERE), "rev-parse", "--short", args.before_tree],
            capture_output=True, text=True, check=True,
        ).stdout.strip()
        tree_dir = tempfile.TemporaryDirectory(prefix="servoid-before-")
        archive = subprocess.run(["git", "-C", str(HERE.parent), "archive", label, "src"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", tree_dir.name], input=archive, check=True)
        tree = (label, str(Path(tree_dir.name) / "src"))
    rows = measure(sizes, before=rev is not None, rev=rev or "HEAD", methods=tuple(args.methods),
                   tree=tree)
    if tree_dir is not None:
        tree_dir.cleanup()
    try:
        machine["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    payload = {
        "machine": machine,
        "quick": False,
        "sizes": sizes,
        "before_rev": rev,
        "elapsed_s": round(time.perf_counter() - t0, 2),
        "suites": {SUITE: {"description": (__doc__ or "").strip()}},
        "results": [r.to_dict() for r in rows],
    }
    if args.merge and args.out.exists():
        # the first run's machine and settings stay; this run is listed under "reruns"
        old = json.loads(args.out.read_text())
        fresh = {(r.method, r.n) for r in rows}
        kept = [Result(**r) for r in old["results"] if (r["method"], r["n"]) not in fresh]
        rows = sorted(kept + rows, key=lambda r: (r.n, _order(r.method)))
        _growth(rows)
        rerun = {"machine": machine, "cells": sorted(f"{m} @ {n:.0e}" for m, n in fresh)}
        payload = {
            **old,
            "reruns": [*old.get("reruns", []), rerun],
            "results": [r.to_dict() for r in rows],
        }
    args.out.write_text(json.dumps(payload, indent=1, default=float) + "\n")
    print(f"# wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
