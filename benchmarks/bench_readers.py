"""Rig-file readers on the normal path: what the checks before and while reading cost.

Case
----
A CSV file of 1e6 rows (time, r, u, y written with ``repr``, 70 MB) read by
``read_csv``, and a MAT v7.3 file of the same four vectors (gzip-chunked
as MATLAB writes them, 24 MB) read by ``read_mat(time="t")``: once as
servoid reads it, in a child process that can be stopped when it makes no
progress, and once in this process (``servoid.data._child.ENABLED =
False``), the difference being the cost of the watch. ``--quick``: 1e5
rows.

Method
------
Files written once into a temporary folder; each read timed after one
warm-up (median and best of 5, 3 under ``--quick``). Besides wall time,
the CPU time per read is recorded in ``extra`` (this process and its
children, user + system): on a shared machine it moves much less than the
wall time. To compare with another commit, run this suite there too
(``git stash`` or a worktree): the files and calls are the same.
"""

from __future__ import annotations

import resource
import tempfile
from pathlib import Path

import numpy as np
from _harness import Result, time_call

from servoid.data import read_csv, read_mat

SUITE = "readers"


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _write(folder: Path, n: int) -> tuple[Path, Path]:
    import h5py

    rng = np.random.default_rng(1)
    t = np.arange(n) * 1e-4
    columns = {"t": t, "r": np.sin(t), "u": rng.standard_normal(n)}
    columns["y"] = np.cumsum(columns["u"]) * 1e-3
    csv = folder / "big.csv"
    with csv.open("w", encoding="utf-8") as f:
        f.write("time [s],r [m],u [V],y [m]\n")
        for row in np.column_stack(list(columns.values())).tolist():
            f.write(",".join(map(repr, row)) + "\n")
    mat = folder / "big73.mat"
    with h5py.File(mat, "w", userblock_size=512) as f:
        for name, values in columns.items():
            ds = f.create_dataset(name, data=values[None, :], chunks=(1, min(n, 65536)),
                                  compression="gzip")
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    with mat.open("r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(128, b" "))
    return csv, mat


def run(quick: bool = False) -> list[Result]:
    """Time read_csv and read_mat (v7.3, as servoid reads it and in process)."""
    try:
        from servoid.data import _child
    except ImportError:  # a commit before the watched reader: its normal path is in process
        _child = None
    n = 100_000 if quick else 1_000_000
    repeats = 3 if quick else 5
    rows = []
    with tempfile.TemporaryDirectory(prefix="servoid-readers-") as name:
        csv, mat = _write(Path(name), n)
        def mat_read() -> object:
            return read_mat(mat, time="t", variables=["r", "u", "y"])

        calls = [("csv", "read_csv", csv, True),
                 ("mat v7.3", "read_mat (watched child)" if _child else "read_mat", mat, True)]
        if _child is not None and _child.ENABLED:
            calls.append(("mat v7.3 in process", "read_mat, _child.ENABLED = False", mat, False))
        enabled = _child.ENABLED if _child is not None else False
        for case, method, path, watched in calls:
            call = (lambda: read_csv(csv)) if path == csv else mat_read
            if _child is not None:
                _child.ENABLED = enabled and watched
            try:
                c0 = _cpu()
                timing = time_call(call, repeats=repeats)
                cpu_ms = 1e3 * (_cpu() - c0) / (repeats + 1)  # the warm-up call included
            finally:
                if _child is not None:
                    _child.ENABLED = enabled
            note = (f"{path.stat().st_size / 1e6:.0f} MB file, 4 columns; CPU {cpu_ms:.0f} ms "
                    "per read (this process and children)")
            rows.append(Result(SUITE, case, n, method, timing.median * 1e3, timing.best * 1e3,
                               len(timing.times), note=note,
                               extra={"cpu_ms_per_read": cpu_ms}))
    return rows
