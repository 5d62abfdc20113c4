"""Run a fleet: every record as a task, checkpointed, resumable, on Dask or in the process.

Each finished record's outcome is stored at once as
``<folder>/records/<key>.json`` (atomically), keyed by the SHA-256 of its
inputs, the options and servoid's version (:func:`record_key`).  A re-run
of the same command reuses every stored outcome whose key is unchanged
(``force=True`` redoes them), so an interrupted batch resumes where it
stopped and gives the same table as an uninterrupted one.  The table, the
summary and the report are rebuilt from the outcomes at the end — also
after Ctrl-C, from the records finished so far.
"""

from __future__ import annotations

import json
import logging
import os
import re
import threading
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from .._atomic import atomic_path
from .._errors import OptionError, OptionTypeError
from .._progress import Progress, stage
from ._result import FleetResult, assemble
from ._spec import FleetSpec, load_fleet_spec
from ._task import identify_record, identify_records, record_inputs, record_key

__all__ = ["run_fleet"]

_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp$")
# One thread per worker process: BLAS and numba pools would only compete for the same cores.
_WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "NUMBA_NUM_THREADS": "1"}
# Set before each worker process starts (numpy reads them at import).  Not Dask's default
# MALLOC_TRIM_THRESHOLD_ = 65536: setting it turns off glibc's adaptive mmap threshold, so
# every array over 128 kB (a record's raw channels) is mapped and unmapped afresh, and a record
# took 15 % more CPU on a worker than in the serial run (94 against 81 ms, measured).  And no
# statistical profiler sampling the running record's stack every 10 ms.
_WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ": {**_WORKER_ENV,
                                                          "MALLOC_TRIM_THRESHOLD_": None},
                  "distributed.worker.profile.enabled": False}


def run_fleet(
    spec: FleetSpec | str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    force: bool = False,
    progress: bool = True,
    allow_outside: bool = False,
) -> FleetResult:
    """Identify every record of a fleet and write its table, summary and report.

    Parameters
    ----------
    spec : FleetSpec or path
        The fleet file (see :func:`load_fleet_spec`).
    out : path, optional
        Results folder; default ``[report] folder`` or ``<fleet>-results``
        beside the fleet file.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).
    workers : int, optional
        Worker processes of the local Dask cluster (default: one per
        core); ``1`` runs the records one after another in this process.
    force : bool
        Identify every record again, even those whose stored outcome has
        the same inputs and options.
    progress : bool
        Show progress on stderr.
    allow_outside : bool
        Let ``[report] folder`` point outside the fleet file's folder.

    Returns
    -------
    FleetResult
        The table and its statistics; ``interrupted`` when Ctrl-C stopped
        the batch (the files then hold the records finished so far).
    """
    if not isinstance(spec, FleetSpec):
        spec = load_fleet_spec(spec)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise OptionTypeError(f"workers must be a whole number >= 1 (--workers); got {workers!r}")
    folder = _folder(spec, out, allow_outside)
    store = folder / "records"
    _protect(spec, folder)
    store.mkdir(parents=True, exist_ok=True)
    _sweep(folder)
    _sweep(store)
    # a local cluster starts (its workers import servoid) while the inputs are hashed here,
    # unless the store looks complete (a re-run that may need no worker at all)
    early = force or sum(1 for _ in store.glob("*.json")) < len(spec.records)
    pool = _Pool(scheduler, workers, len(spec.records) if early else 0)
    try:
        keys = _keys(spec)
        bar = Progress(len(keys), "identifying", enabled=progress)
        outcomes: dict[int, dict[str, Any]] = {}
        todo = []
        for i, key in enumerate(keys):
            stored = None if force else _load(store / f"{key[:24]}.json", key)
            if stored is None:
                todo.append(i)
            else:
                outcomes[i] = stored
                bar.update(ok=stored["status"] == "ok", skipped=True)
        interrupted = False
        checked = _check_limit_names(spec, outcomes.values())
        runs = _execute(spec, todo, pool)
        try:
            if not checked and todo and spec.limits:  # one record first: limits must name its params
                i = todo.pop(0)
                outcomes[i] = _keep(store, keys[i], identify_record(str(spec.records[i].path),
                                                                     spec.identify))
                bar.update(ok=outcomes[i]["status"] == "ok")
                checked = _check_limit_names(spec, outcomes.values())
            for i, outcome in runs:
                outcomes[i] = _keep(store, keys[i], outcome)
                bar.update(ok=outcome["status"] == "ok")
                if not checked:
                    checked = _check_limit_names(spec, outcomes.values())
        except KeyboardInterrupt:
            interrupted = True
        finally:
            runs.close()  # unfinished tasks are cancelled, also when an error ends the loop
            bar.close()
            pool.release()  # the workers shut down while the table and report are written
        result = assemble(spec, outcomes, keys, folder, interrupted=interrupted)
        return result.write()
    finally:
        pool.close()


def _keys(spec: FleetSpec) -> list[str]:
    """Every record's key; the hashing runs on one thread per core (it releases the GIL)."""
    paths = [r.path for r in spec.records]
    if len(paths) < 8:
        return [record_key(p, spec.identify) for p in paths]
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as threads:
        return list(threads.map(lambda p: record_key(p, spec.identify), paths))


def _execute(spec: FleetSpec, todo: Sequence[int],
             pool: _Pool) -> Iterator[tuple[int, dict[str, Any]]]:
    """Yield (index, outcome) as records finish."""
    if not todo:
        return
    client = pool.client(len(todo))
    if client is None:
        for i in todo:
            yield i, identify_record(str(spec.records[i].path), spec.identify)
        return
    yield from _dask(client, spec, todo)


class _Pool:
    """Where the records run: this process, a local Dask cluster or a given scheduler.

    A local cluster is started at once on a background thread (when
    `n_records` > 1), so that its worker processes start (and import
    servoid) while this process hashes the inputs; :meth:`client` waits for
    it, or starts it then.  :meth:`release` shuts it down on a background
    thread, so that the workers exit while the table and the report are
    written; :meth:`close` waits for that.
    """

    def __init__(self, scheduler: str | None, workers: int | None, n_records: int) -> None:
        self.scheduler = scheduler
        self.workers = workers or os.cpu_count() or 1
        self._cluster: Any = None
        self._client: Any = None
        self._error: BaseException | None = None
        self._starting: threading.Thread | None = None
        self._closing: threading.Thread | None = None
        if scheduler is None and self.workers > 1 and n_records > 1:
            self._starting = threading.Thread(target=self._start_local,
                                              args=(min(self.workers, n_records),), daemon=True)
            self._starting.start()

    def client(self, n_todo: int) -> Any:
        """The Dask client, or None to run the records in this process."""
        if self.scheduler is None and (self.workers == 1 or n_todo == 1):
            return None
        if self.scheduler is not None:
            self._client = _connect(self.scheduler)
            return self._client
        if self._starting is None:  # not started early: start it now
            self._start_local(min(self.workers, n_todo))
        else:
            with stage("starting the Dask workers (each loads servoid once)"):
                self._starting.join()
        if isinstance(self._error, ImportError):
            raise OptionError("running a fleet in parallel needs Dask: pip install "
                              "'servoid[fleet]', or pass --workers 1 for a serial run") from None
        if self._error is not None:
            raise OptionError(f"could not start a local Dask cluster ({self._error}); run the "
                              "records in this process with --workers 1 (workers=1)") from None
        return self._client

    def _start_local(self, n: int) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError as exc:
            self._error = exc
            return
        try:
            import dask

            with dask.config.set(_WORKER_CONFIG):
                self._cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                             dashboard_address=None, silence_logs=logging.ERROR,
                                             env=_WORKER_ENV)
            self._client = Client(self._cluster)
            self._client.run(_warm_up)  # compiled kernels loaded before the first record
        except Exception as exc:  # noqa: BLE001 - reported by client() in the user's words
            self._error = exc
            self._shut()

    def release(self) -> None:
        """Start shutting the workers down (in the background)."""
        if self._starting is not None:
            self._starting.join()
        if self._closing is None and (self._client is not None or self._cluster is not None):
            self._closing = threading.Thread(target=self._shut, daemon=True)
            self._closing.start()

    def close(self) -> None:
        """Shut down and wait."""
        self.release()
        if self._closing is not None:
            self._closing.join()

    def _shut(self) -> None:
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        try:
            if client is not None:
                client.close()
        finally:
            if cluster is not None:
                cluster.close()


def _connect(scheduler: str) -> Any:
    try:
        from distributed import Client
    except ImportError:
        raise OptionError("running a fleet on a Dask scheduler needs Dask: pip install "
                          "'servoid[fleet]', or pass --workers 1 for a serial run") from None
    try:
        return Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise OptionError(f"cannot reach the Dask scheduler at {scheduler!r} ({exc}); check "
                          "that it runs and the address, or drop --scheduler to use a "
                          "local cluster") from None


_MAX_BATCH = 8


def _warm_up() -> None:
    """Import the identification and load its compiled kernels on a worker."""
    from ..closedloop import _kernels
    from ..workflows import identify  # noqa: F401 - the import is the warm-up

    _kernels.warm_up()


def _dask(client: Any, spec: FleetSpec,
          todo: Sequence[int]) -> Iterator[tuple[int, dict[str, Any]]]:
    from distributed import as_completed

    size = _batch_size(len(todo), _n_workers(client))
    batches = [list(todo[k:k + size]) for k in range(0, len(todo), size)]
    futures = {client.submit(identify_records, [str(spec.records[i].path) for i in batch],
                             spec.identify, pure=False): batch for batch in batches}
    try:
        for future in as_completed(futures):
            batch = futures[future]
            try:
                outcomes = future.result()
            except Exception as exc:  # noqa: BLE001 - the worker died (memory, signal): failed records
                outcomes = [{"status": "failed", "summary": None, "warnings": [],
                             "seconds": float("nan"),
                             "error": f"the worker running this record failed ({exc})"}] * len(batch)
            yield from zip(batch, outcomes, strict=True)
    finally:
        unfinished = [f for f in futures if not f.done()]
        if unfinished:
            client.cancel(unfinished)


def _batch_size(n_todo: int, n_workers: int) -> int:
    """Records per Dask task: a few, so the scheduler's per-task cost is shared.

    Each task costs the scheduler and this process a few milliseconds, which
    on a small machine is taken from the workers themselves; grouping up to
    eight records cuts that eightfold, while keeping at least sixteen tasks
    per worker so the last ones still balance (a record takes ~0.1 s).
    """
    return max(1, min(_MAX_BATCH, n_todo // max(16 * n_workers, 1)))


def _n_workers(client: Any) -> int:
    try:
        return max(len(client.scheduler_info().get("workers", {})), 1)
    except Exception:  # noqa: BLE001 - an unusual scheduler: assume one worker, small batches
        return 1


def _check_limit_names(spec: FleetSpec, outcomes: Any) -> bool:
    """True once a successful record showed the limits name parameters it reports."""
    for outcome in outcomes:
        if outcome["status"] != "ok":
            continue
        names = [p["name"] for p in outcome["summary"]["parameters"]]
        missing = [lim.parameter for lim in spec.limits if lim.parameter not in names]
        if missing:
            raise OptionError(
                f"[limits] names {', '.join(missing)}, which the identification does not "
                f"estimate; its parameters are {', '.join(names) or 'none'}: rename or remove "
                "the limit")
        return True
    return not spec.limits


def _keep(store: Path, key: str, outcome: dict[str, Any]) -> dict[str, Any]:
    """Store one outcome at once (atomically), so an interruption loses nothing finished."""
    outcome = {**outcome, "key": key}
    with atomic_path(store / f"{key[:24]}.json", overwrite=True) as tmp:
        tmp.write_text(json.dumps(outcome, allow_nan=True), encoding="utf-8")
    return outcome


def _load(path: Path, key: str) -> dict[str, Any] | None:
    try:
        outcome = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(outcome, dict) or outcome.get("key") != key or "status" not in outcome:
        return None
    return outcome


def _folder(spec: FleetSpec, out: str | os.PathLike[str] | None, allow_outside: bool) -> Path:
    if out is not None:
        return Path(out)
    base = spec.source.parent if spec.source else Path.cwd()
    if "folder" in spec.report:
        folder = spec.report["folder"]
        if not isinstance(folder, str):
            raise OptionTypeError(f"[report] folder must be a folder name; got {folder!r}")
        path = base / folder
        if not allow_outside and not path.resolve().is_relative_to(base.resolve()):
            raise OptionError(f"[report] folder = {folder!r} points outside the fleet file's "
                              f"folder ({base}); pass --out <folder> (or --allow-outside)")
        return path
    stem = spec.source.stem if spec.source else "fleet"
    return base / f"{stem}-results"


def _protect(spec: FleetSpec, folder: Path) -> None:
    """No output of the fleet may land on one of its inputs."""
    from .._errors import OutputExistsError

    inputs = {p.resolve() for p in (spec.source, spec.manifest) if p is not None}
    for record in spec.records:
        inputs.update(p.resolve() for p in record_inputs(record.path))
    outputs = [folder / name for name in FleetResult.FILES]
    for path in inputs:
        if path in {o.resolve() for o in outputs} or path.is_relative_to(
                (folder / "records").resolve()):
            raise OutputExistsError(f"refusing to write the fleet results into {folder}: it "
                                    f"would replace the input {path}; choose another --out")


def _sweep(folder: Path) -> None:
    if folder.is_dir():
        for path in folder.iterdir():
            if _TEMPORARY.match(path.name) and path.is_file():
                path.unlink()

