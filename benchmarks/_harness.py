"""Shared benchmark machinery: timing, memory, machine description, table output.

A benchmark suite is a module with ``run(quick: bool) -> list[Result]``; see
``run.py`` for the registry.
"""

from __future__ import annotations

import datetime as _dt
import gc
import os
import platform
import statistics
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass
class Timing:
    """Wall-clock times of repeated calls [s]."""

    times: list[float]
    minor_faults_per_call: float | None = None  # page faults (fresh memory being mapped)
    sys_s_per_call: float | None = None  # kernel CPU time, mostly page zeroing

    @property
    def best(self) -> float:
        return min(self.times)

    @property
    def median(self) -> float:
        return statistics.median(self.times)


@dataclass
class Memory:
    """Peak memory of one call [bytes]: tracemalloc peak and resident-set growth."""

    tracemalloc_peak: int
    rss_peak_delta: int | None  # None when /proc/self/clear_refs is unavailable


@dataclass
class Result:
    """One row of the results table."""

    suite: str
    case: str
    n: int
    method: str
    median_ms: float
    best_ms: float
    repeats: int
    peak_mb: float | None = None
    rss_mb: float | None = None
    rel_diff: float | None = None  # max_i |θ_i − θ_ref,i| / |θ_ref,i|
    minflt: float | None = None  # minor page faults per timed call
    condition: float | None = None
    solver: str | None = None
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def time_call(fn: Callable[[], object], repeats: int, warmup: int = 1) -> Timing:
    """Call ``fn`` ``warmup`` times untimed, then ``repeats`` times timed.

    The garbage collector is off during the timed calls (as :mod:`timeit`
    does) and a collection runs before them, so a collection of earlier
    garbage does not land in one sample.
    """
    for _ in range(warmup):
        fn()
    gc.collect()
    was_enabled = gc.isenabled()
    gc.disable()
    times = []
    r0 = _rusage()
    try:
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
    finally:
        if was_enabled:
            gc.enable()
    r1 = _rusage()
    if r0 is None or r1 is None:
        return Timing(times)
    return Timing(times, (r1[0] - r0[0]) / repeats, (r1[1] - r0[1]) / repeats)


def _rusage() -> tuple[int, float] | None:
    try:
        import resource
    except ImportError:  # pragma: no cover - not on Windows
        return None
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_minflt, ru.ru_stime


def _status_kb(key: str) -> int | None:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _reset_rss_peak() -> bool:
    # Writing 5 to clear_refs resets VmHWM to the current RSS (Linux ≥ 4.0).
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def measure_memory(fn: Callable[[], object]) -> Memory:
    """Peak memory of one call of ``fn`` (call it once before to warm up).

    ``tracemalloc_peak`` counts allocations made through Python's and
    numpy's allocators during the call (numpy reports its data buffers to
    tracemalloc); memory allocated inside numba-compiled code, BLAS/LAPACK
    workspaces and other C libraries is not seen. ``rss_peak_delta`` is the
    growth of the process's resident-set high-water mark (VmHWM, reset before
    the call): it sees everything, but only pages actually touched, and is
    coarser (page granularity, allocator reuse of freed memory).
    """
    gc.collect()
    rss_ok = _reset_rss_peak()
    rss0 = _status_kb("VmRSS") if rss_ok else None
    tracemalloc.start()
    tracemalloc.reset_peak()
    base, _ = tracemalloc.get_traced_memory()
    try:
        fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    rss_delta = None
    if rss_ok and rss0 is not None:
        # Second pass without tracemalloc so its bookkeeping does not count.
        gc.collect()
        _reset_rss_peak()
        rss0 = _status_kb("VmRSS")
        fn()
        hwm = _status_kb("VmHWM")
        if hwm is not None and rss0 is not None:
            rss_delta = max(hwm - rss0, 0) * 1024
    return Memory(peak - base, rss_delta)


def rel_diff(theta, ref) -> float:  # type: ignore[no-untyped-def]
    """Largest elementwise relative difference max_i |θ_i − ref_i| / |ref_i|."""
    import numpy as np

    theta = np.asarray(theta, dtype=float)
    ref = np.asarray(ref, dtype=float)
    return float(np.max(np.abs(theta - ref) / np.maximum(np.abs(ref), np.finfo(float).tiny)))


# -- machine ---------------------------------------------------------------------------------


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _cpu_flags() -> list[str]:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    flags = line.split(":", 1)[1].split()
                    return [x for x in flags if x.startswith(("avx", "fma", "sse4"))] + (
                        ["hypervisor"] if "hypervisor" in flags else []
                    )
    except OSError:
        pass
    return []


def _ram_gib() -> float | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass
    return None


def _os_name() -> str:
    try:
        with open("/etc/os-release") as f:
            for line in f:
                if line.startswith("PRETTY_NAME="):
                    return line.split("=", 1)[1].strip().strip('"') + f" ({platform.release()})"
    except OSError:
        pass
    return platform.platform()


def _blas() -> dict[str, Any]:
    import numpy as np

    out: dict[str, Any] = {}
    try:
        cfg = np.show_config(mode="dicts")  # numpy ≥ 1.26
        deps = cfg.get("Build Dependencies", {})
        for key in ("blas", "lapack"):
            d = deps.get(key, {})
            out[key] = f"{d.get('name', '?')} {d.get('version', '')}".strip()
        out["openblas_config"] = deps.get("blas", {}).get("openblas configuration")
        simd = cfg.get("SIMD Extensions", {})
        out["numpy_simd_found"] = simd.get("found")
    except (AttributeError, TypeError, ValueError) as exc:  # pragma: no cover - numpy build
        out["error"] = repr(exc)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        if var in os.environ:
            out[var] = os.environ[var]
    return out


def _git_commit() -> str | None:
    try:
        here = os.path.dirname(os.path.abspath(__file__))
        res = subprocess.run(
            ["git", "-C", here, "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
        return res.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def _src_dirty() -> bool | None:
    """Whether src/ has uncommitted changes (the timed code is then not git_commit)."""
    try:
        here = os.path.dirname(os.path.abspath(__file__))
        res = subprocess.run(
            ["git", "-C", here, "status", "--porcelain", "--", "../src"],
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
        return bool(res.stdout.strip()) if res.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def machine_info() -> dict[str, Any]:
    """What ran the benchmarks: CPU, cores, RAM, OS, library versions, load, date."""
    import numba
    import numpy as np
    import scipy

    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        load = None
    return {
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "cpu_model": _cpu_model(),
        "cpu_flags": _cpu_flags(),
        "logical_cpus": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "ram_gib": _ram_gib(),
        "os": _os_name(),
        "python": sys.version.split()[0] + f" ({platform.python_implementation()})",
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "blas": _blas(),
        "git_commit": _git_commit(),
        "src_dirty": _src_dirty(),
        "load_average_start": load,
    }


# -- output ----------------------------------------------------------------------------------


def _fmt(x: float | None, spec: str) -> str:
    return "—" if x is None else format(x, spec)


def format_table(results: list[Result]) -> str:
    """Fixed-width table of the results."""
    head = [
        "suite",
        "case",
        "N",
        "method",
        "median ms",
        "best ms",
        "k",
        "peak MB",
        "ΔRSS MB",
        "faults",
        "rel.diff vs QR",
        "cond",
        "solver",
    ]
    rows = [
        [
            r.suite,
            r.case,
            f"{r.n:.0e}".replace("e+0", "e"),
            r.method,
            _fmt(r.median_ms, ".3f"),
            _fmt(r.best_ms, ".3f"),
            str(r.repeats),
            _fmt(r.peak_mb, ".1f"),
            _fmt(r.rss_mb, ".1f"),
            _fmt(r.minflt, ".0f"),
            _fmt(r.rel_diff, ".1e"),
            _fmt(r.condition, ".3g"),
            r.solver or "—",
        ]
        for r in results
    ]
    widths = [
        max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)
    ]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths))
    out = [line, "-" * len(line)]
    out += ["  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in rows]
    return "\n".join(out)


def format_markdown(results: list[Result]) -> str:
    """The results as a Markdown table (for BENCHMARKS.md)."""
    head = [
        "case",
        "N",
        "method",
        "median ms",
        "best ms",
        "k",
        "peak MB (tracemalloc)",
        "ΔRSS MB",
        "page faults/call",
        "rel. diff vs QR",
        "cond",
        "solver",
    ]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        out.append(
            "| "
            + " | ".join(
                [
                    r.case,
                    f"{r.n:.0e}".replace("e+0", "e"),
                    f"`{r.method}`",
                    _fmt(r.median_ms, ".3f"),
                    _fmt(r.best_ms, ".3f"),
                    str(r.repeats),
                    _fmt(r.peak_mb, ".1f"),
                    _fmt(r.rss_mb, ".1f"),
                    _fmt(r.minflt, ".0f"),
                    _fmt(r.rel_diff, ".1e"),
                    _fmt(r.condition, ".3g"),
                    r.solver or "—",
                ]
            )
            + " |"
        )
    return "\n".join(out)
