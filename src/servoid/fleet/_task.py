"""One record of a fleet, identified as a task: plain data in, plain data out.

:func:`identify_record` is what runs on a Dask worker (or in the process
for a serial run).  It never raises for a record's own problem: a damaged
file, a fit that fails or even a defect becomes a failed outcome carrying
the message, so one bad record cannot end the batch.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from types import MappingProxyType
from typing import Any

from .._errors import DataError, ServoidError
from .._version import __version__
from ._files import REGULAR_ONLY, file_problem

__all__ = ["identify_record", "identify_records", "identify_records_on_cluster", "record_hashes",
           "record_inputs", "record_key"]


def record_key(path: Path, identify: Mapping[str, Any] | None) -> str:
    """SHA-256 over the record's path and bytes, every file it reads, the options, the version.

    A record whose key is unchanged since its outcome was stored is not run again.
    """
    return record_hashes(path, identify)[0]


def record_hashes(path: Path, identify: Mapping[str, Any] | None) -> tuple[str, str | None]:
    """The record's key (see :func:`record_key`) and what identifies its measurement.

    Every file is read once.  The second hash covers the bytes of the data
    files and the channels read from them, not the experiment file's name
    or options: two records with the same one are the same test (a copy),
    whatever they are called.  It is None when the experiment file cannot
    be read (the task will report why).

    Raises
    ------
    DataError
        A file of the record is not a regular file (a FIFO, a device, a
        folder, a symbolic-link loop): reading it could wait forever.
    """
    files, spec = _inputs(path)
    h = hashlib.sha256()
    h.update(f"servoid {__version__}\n{path.resolve()}\n".encode())
    h.update(json.dumps(dict(identify) if identify is not None else None, sort_keys=True,
                        default=str).encode())
    data = None
    if spec is not None and len(files) > 1:
        data = hashlib.sha256(repr((spec.channels, spec.group, spec.time)).encode())
    for k, file in enumerate(files):
        problem = file_problem(file)
        if problem is not None and problem != "does not exist":
            raise DataError(f"{file} (of record {path}) {problem}; {REGULAR_ONLY}")
        try:
            digest = _digest(file)
        except OSError:
            digest, data = b"<unreadable>", None  # the task will report why
        h.update(f"\n{file.name}\n".encode() + digest)
        if k and data is not None:
            data.update(digest)
    return h.hexdigest(), None if data is None else data.hexdigest()


def record_inputs(path: Path) -> list[Path]:
    """The experiment file and the data files it names (as far as it can be read)."""
    return _inputs(path)[0]


def identify_records(paths: Sequence[str], identify: Mapping[str, Any] | None,
                     allow_code: bool = False) -> list[dict[str, Any]]:
    """Identify several records in turn (one Dask task); see :func:`identify_record`."""
    return [identify_record(path, identify, allow_code=allow_code) for path in paths]


def identify_records_on_cluster(paths: Sequence[str], identify: Mapping[str, Any] | None,
                                allow_code: bool = False) -> list[dict[str, Any]]:
    """:func:`identify_records` as a Dask task, each record's candidates tasks of its cluster.

    A record whose ``[identify]`` lists several methods (or ``"auto"``)
    scores each candidate as a task of the cluster this task runs on (the
    connection this worker already has; no other), while this task waits
    outside the worker's slots.  A record of one method runs here as before.
    """
    from ..workflows import candidates_on

    with candidates_on(_on_cluster):
        return identify_records(paths, identify, allow_code)


@dataclass
class _Spent:
    """CPU time [s] a record's task spent outside itself while it waited for its candidates.

    ``tasks``: the candidate tasks' own CPU, each measured in its task;
    ``others``: the CPU of this worker process during the waits, less this
    thread's: the tasks that ran in this process meanwhile (the record's
    own candidates among them, counted in ``tasks`` already).
    """

    tasks: float = 0.0
    others: float = 0.0


#: The record being identified in this thread (None outside :func:`identify_record`).
_SPENT: ContextVar[_Spent | None] = ContextVar("servoid_record_cpu", default=None)


def _on_cluster(function: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
    """``[function(x) for x in items]`` as tasks of the cluster this task runs on.

    Each task returns its CPU time with its result; the record's
    :class:`_Spent` adds them up, and takes out what else this worker
    process ran while the record waited (see :func:`identify_record`).
    """
    from dask.utils import funcname
    from distributed import worker_client

    with worker_client() as client:  # secedes: the candidates may run on this worker too
        process, thread = time.process_time(), time.thread_time()
        futures = client.map(partial(_timed, function), list(items), key=funcname(function),
                             pure=False)  # the key names the candidate's function, not _timed
        done = client.gather(futures)
        others = (time.process_time() - process) - (time.thread_time() - thread)
    spent = _SPENT.get()
    if spent is not None:
        spent.tasks += sum(cpu for _, cpu in done)
        spent.others += max(others, 0.0)
    return [result for result, _ in done]


def _timed(function: Callable[[Any], Any], item: Any) -> tuple[Any, float]:
    """``function(item)`` and the CPU time [s] of this process while it ran.

    A worker runs one task at a time in its slot (the fleet's workers have
    one thread each), so the process's CPU over the call is the task's,
    whatever threads its numerics start.
    """
    start = time.process_time()
    out = function(item)
    return out, time.process_time() - start


@contextmanager
def _counting() -> Iterator[_Spent]:
    """Count the CPU a record's candidate tasks spend, inside."""
    spent = _Spent()
    token = _SPENT.set(spent)
    try:
        yield spent
    finally:
        _SPENT.reset(token)


def _children_cpu() -> float:
    """CPU time [s] of this process's ended child processes (0 off Unix)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return 0.0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def identify_record(path: str, identify: Mapping[str, Any] | None, *,
                    allow_code: bool = False) -> dict[str, Any]:
    """Identify one record as ``servoid identify`` would, writing nothing.

    ``allow_code`` lets a method that runs the user's Python code run it
    (``servoid identify --allow-code``).

    Returns
    -------
    dict
        ``status`` ("ok" or "failed"), ``method``, ``summary`` (the result's
        :class:`RecordSummary`, ``result.summary()``, as a dict: the row
        comes from the result itself, not from its ``results.json``) or
        ``error`` (the message), ``warnings`` (their texts),
        ``seconds`` (wall), ``cpu_seconds`` (the CPU time [s] the record
        cost, which other jobs on the machine do not inflate: this
        process's over the record, with the candidates it scored elsewhere
        — the cluster's tasks, or ``[identify] workers`` local processes —
        and without the other tasks this worker ran while the record
        waited for them) and
        ``peak_rss_mb`` (the worker's memory high-water mark after this
        record).
    """
    from ..data import load_experiment_spec
    from ..workflows import identify as run
    from ..workflows import method_of

    start, cpu, children = time.perf_counter(), time.process_time(), _children_cpu()
    out: dict[str, Any] = {"status": "failed", "summary": None, "error": "", "warnings": []}
    with _counting() as spent, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            spec = load_experiment_spec(path)
            if identify is not None:
                spec = dataclasses.replace(spec, identify=MappingProxyType(dict(identify)))
            result = run(spec, write=False, allow_code=allow_code)
            summary = result.summary()
            out["summary"] = summary.to_dict()
            out["method"] = summary.method or method_of(spec.identify)
            if getattr(result, "entries", None) is not None:  # several candidates: the chosen
                out["candidate"] = result.label
            out["status"] = "ok"
        except ServoidError as exc:
            out["error"] = f"{type(exc).__name__}: {exc}"
        except MemoryError:
            out["error"] = "MemoryError: the record does not fit in this worker's memory"
        except Exception as exc:  # noqa: BLE001 - a defect in servoid: record it, never end the batch
            out["error"] = f"internal error ({type(exc).__name__}: {exc}); please report it"
    out["warnings"] = sorted({str(w.message) for w in caught})
    out["seconds"] = time.perf_counter() - start
    out["cpu_seconds"] = (time.process_time() - cpu - spent.others + spent.tasks
                          + _children_cpu() - children)
    out["peak_rss_mb"] = _peak_rss_mb()
    return out


def _peak_rss_mb() -> float | None:
    """The process's resident-set high-water mark so far [MB] (None off Unix)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return None
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _inputs(path: Path) -> tuple[list[Path], Any]:
    """The record's files and its parsed experiment file (None when it cannot be read)."""
    from ..data import load_experiment_spec

    files = [path]
    problem = file_problem(path)
    if problem is not None:
        if problem == "does not exist":
            return files, None
        raise DataError(f"{path} {problem}; {REGULAR_ONLY}")
    try:
        spec = load_experiment_spec(path)
    except Exception:  # noqa: BLE001 - the task reports why; the key still covers the file
        return files, None
    return [*files, *spec.data_paths, *spec.validation_paths], spec


def _digest(file: Path) -> bytes:
    """SHA-256 of a file: the run that identifies the record reads it from memory."""
    from ..data import file_sha256

    return bytes.fromhex(file_sha256(file))
