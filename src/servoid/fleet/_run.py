"""Run a fleet: every record as a task, checkpointed, resumable, on Dask or in the process.

Each finished record's outcome is stored at once as
``<folder>/records/<key>.json`` (atomically), keyed by the SHA-256 of its
inputs, the options and servoid's version (:func:`record_key`).  A re-run
of the same command reuses every stored outcome whose key is unchanged
(``force=True`` redoes them), so an interrupted batch resumes where it
stopped and gives the same table as an uninterrupted one.  The table, the
summary and the report are rebuilt from the outcomes at the end — also
after Ctrl-C, from the records finished so far.

The local Dask cluster is private to the user who runs the fleet, and a
scheduler given by address is used only with the security the user gives
(:mod:`servoid.fleet._cluster`).
"""

from __future__ import annotations

import json
import os
import sys
import threading
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from .._atomic import atomic_path
from .._checks import as_bool
from .._errors import DataError, OptionError, OptionTypeError
from .._lock import FolderLock, hold_folder, ledger, sha256_file, write_ledger
from .._progress import Progress, stage
from .._words import option
from ..workflows import listed_methods
from ._cluster import check_scheduler, connect, dashboard_link, quiet_dask, start_local
from ._result import FleetResult, assemble
from ._spec import FleetRecord, FleetSpec, load_fleet_spec
from ._task import identify_record, identify_records_on_cluster, record_hashes, record_inputs

__all__ = ["run_fleet"]

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
    overwrite: bool = False,
    security: Any = None,
    insecure: bool = False,
    dashboard: bool = False,
    verbose: bool = False,
    allow_duplicates: bool = False,
    allow_code: bool = False,
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
        Address of a running Dask scheduler: ``tls://host:8786`` (with
        `security`, or the TLS files in Dask's configuration), or plain
        ``tcp://host:8786`` with ``insecure=True``.
    workers : int, optional
        Worker processes of the local Dask cluster (default: one per
        core); ``1`` runs the records one after another in this process.
        The local cluster listens on 127.0.0.1 only, over TLS with
        credentials generated for this run.
    force : bool
        Identify every record again, even those whose stored outcome has
        the same inputs and options.
    progress : bool
        Show progress on stderr.
    allow_outside : bool
        Let ``[report] folder`` point outside the fleet file's folder.
    overwrite : bool
        Replace files in the folder that an earlier ``servoid fleet`` did
        not write (or that changed since); without it they are refused
        before any record runs.  The fleet's inputs are never written.
    security : distributed.security.Security, optional
        TLS settings for a ``tls://`` `scheduler` (see
        :func:`servoid.fleet.tls_security`); default: Dask's configuration.
    insecure : bool
        Accept a plain ``tcp://`` `scheduler`, which lets anyone who can
        reach it run code as you.
    dashboard : bool
        Serve Dask's dashboard of the local cluster on 127.0.0.1 (port
        8787 when free; the address is printed on stderr).
    verbose : bool
        Let Dask log as it is configured to; default: quiet.
    allow_duplicates : bool
        Accept records whose data are byte-identical copies of another's
        (otherwise refused: a copy would count as a second unit).
    allow_code : bool
        Let a record whose method runs the user's Python code (``method =
        "greybox"``) run it, as ``servoid identify --allow-code`` does;
        without it such a record fails, naming the flag.  The code is not
        among the inputs a stored outcome is keyed by, so with it every
        record is identified again (as with ``force``).

    Returns
    -------
    FleetResult
        The table and its statistics; ``interrupted`` when Ctrl-C stopped
        the batch (the files then hold the records finished so far).
    """
    _check_flags(workers, verbose, dashboard, allow_duplicates)
    allow_code = as_bool("allow_code", allow_code)
    if scheduler is not None:
        if dashboard:
            raise OptionError("dashboard=True (--dashboard) shows the local cluster; a "
                              "scheduler given by address serves its own dashboard")
        scheduler = check_scheduler(scheduler, security, insecure)
    elif security is not None or insecure is not False:
        raise OptionError("security and insecure (--tls-*, --insecure) apply to a scheduler "
                          "given by address (--scheduler); the local cluster is always private")
    if not isinstance(spec, FleetSpec):
        spec = load_fleet_spec(spec)
    overwrite = as_bool("overwrite", overwrite)
    with quiet_dask(verbose, scheduler is not None or workers != 1):
        folder = _folder(spec, out, allow_outside)
        _protect(spec, folder)
        with hold_folder(folder, subfolders=("records",)) as lock:  # one fleet run owns it
            _refuse_foreign(folder, overwrite, lock)
            return _run_locked(spec, folder, lock, scheduler=scheduler, workers=workers,
                               force=force or allow_code, progress=progress,
                               security=security, dashboard=dashboard, verbose=verbose,
                               allow_duplicates=allow_duplicates, allow_code=allow_code)


def _run_locked(spec: FleetSpec, folder: Path, lock: FolderLock, *, scheduler: str | None,
                workers: int | None, force: bool, progress: bool, security: Any,
                dashboard: bool, verbose: bool, allow_duplicates: bool,
                allow_code: bool = False) -> FleetResult:
    """:func:`run_fleet` in a folder it holds."""
    store = folder / "records"
    made = [] if store.exists() else [store]  # removed if the records are refused below
    store.mkdir(exist_ok=True)
    # a local cluster starts (its workers import servoid) while the inputs are hashed here,
    # unless the store looks complete (a re-run that may need no worker at all)
    early = force or sum(1 for _ in store.glob("*.json")) < len(spec.records)
    pool = _Pool(scheduler, workers, len(spec.records) if early else 0, security=security,
                 dashboard=dashboard, verbose=verbose,
                 methods=() if spec.identify is None else listed_methods(spec.identify))
    try:
        try:
            keys = _keys(spec, allow_duplicates)
        except DataError:
            _remove_empty(made)
            raise
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
        runs = _execute(spec, todo, pool, allow_code)
        try:
            if not checked and todo and spec.limits:  # one record first: limits must name its params
                i = todo.pop(0)
                outcomes[i] = _keep(store, keys[i], _one(spec, i, allow_code))
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
        lock.claim([folder / name for name in FleetResult.FILES])
        written = result.write()
        write_ledger(folder, written.files, "servoid fleet")
        return written
    finally:
        pool.close()


def _check_flags(workers: Any, verbose: Any, dashboard: Any, allow_duplicates: Any) -> None:
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise OptionTypeError(f"workers must be a whole number >= 1 (--workers); got {workers!r}")
    for name, value in (("verbose", verbose), ("dashboard", dashboard),
                        ("allow_duplicates", allow_duplicates)):
        if not isinstance(value, bool):
            raise OptionTypeError(f"{name} must be True or False; got {value!r}")
    if dashboard and workers == 1:
        raise OptionError("dashboard=True (--dashboard) shows the local Dask cluster, but "
                          "workers=1 (--workers 1) runs the records in this process without one")


def _keys(spec: FleetSpec, allow_duplicates: bool = False) -> list[str]:
    """Every record's key, each file read once; the hashing runs on one thread per core.

    Refuses, naming them, records with a file that is not a regular file,
    and (unless `allow_duplicates`) records that repeat another's data.
    """
    def one(path: Path) -> tuple[str, str | None] | str:
        try:
            return record_hashes(path, spec.identify)
        except DataError as exc:
            return str(exc)

    paths = [r.path for r in spec.records]
    if len(paths) < 8:
        hashes = [one(p) for p in paths]
    else:
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as threads:
            hashes = list(threads.map(one, paths))
    refused = [h for h in hashes if isinstance(h, str)]
    if refused:
        more = f"; and {len(refused) - 3} more" if len(refused) > 3 else ""
        raise DataError(f"{len(refused)} record(s) name a file that servoid will not read: "
                        + "; ".join(refused[:3]) + more)
    pairs = [h for h in hashes if not isinstance(h, str)]
    if not allow_duplicates:
        _check_copies(spec.records, [data for _, data in pairs])
    return [key for key, _ in pairs]


def _check_copies(records: Sequence[FleetRecord], data: Sequence[str | None]) -> None:
    """Refuse records whose data (bytes and channels) repeat an earlier record's."""
    first: dict[str, FleetRecord] = {}
    copies = []
    for record, digest in zip(records, data, strict=True):
        if digest is None:
            continue
        if digest in first:
            copies.append(f"{record.serial} ({record.path}) repeats {first[digest].serial} "
                          f"({first[digest].path})")
        else:
            first[digest] = record
    if copies:
        more = f"; and {len(copies) - 3} more" if len(copies) > 3 else ""
        raise DataError(
            f"{len(copies)} record(s) hold byte-identical copies of another record's data: "
            + "; ".join(copies[:3]) + more + ". A copy would count as a second unit and "
            "narrow the fleet's scatter: remove the copies from the fleet (or pass "
            "--allow-duplicates, allow_duplicates=True, when repeating a record is intended)")


def _execute(spec: FleetSpec, todo: Sequence[int], pool: _Pool,
             allow_code: bool = False) -> Iterator[tuple[int, dict[str, Any]]]:
    """Yield (index, outcome) as records finish."""
    if not todo:
        return
    client = pool.client(len(todo))
    if client is None:
        for i in todo:
            yield i, _one(spec, i, allow_code)
        return
    yield from _dask(client, spec, todo, allow_code)


def _one(spec: FleetSpec, i: int, allow_code: bool) -> dict[str, Any]:
    """Identify record ``i`` in this process."""
    path = str(spec.records[i].path)
    if allow_code:
        return identify_record(path, spec.identify, allow_code=True)
    return identify_record(path, spec.identify)


class _Pool:
    """Where the records run: this process, a local Dask cluster or a given scheduler.

    A local cluster is started at once on a background thread (when
    `n_records` > 1), so that its worker processes start (and import
    servoid) while this process hashes the inputs; :meth:`client` waits for
    it, or starts it then.  :meth:`release` shuts it down on a background
    thread, so that the workers exit while the table and the report are
    written; :meth:`close` waits for that.
    """

    def __init__(self, scheduler: str | None, workers: int | None, n_records: int, *,
                 security: Any = None, dashboard: bool = False, verbose: bool = False,
                 methods: Sequence[str] = ()) -> None:
        self.scheduler = scheduler
        self.methods = tuple(methods)  # whose compiled kernels the workers load first
        self.workers = workers or os.cpu_count() or 1
        self.security, self.dashboard, self.verbose = security, dashboard, verbose
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
            self._client = connect(self.scheduler, self.security)
            return self._client
        if self._starting is None:  # not started early: start it now
            self._start_local(min(self.workers, n_todo))
        else:
            with stage("starting the Dask workers (each loads servoid once)"):
                self._starting.join()
        if isinstance(self._error, ImportError):
            raise OptionError("running a fleet in parallel needs Dask: pip install "
                              "'servoid[fleet]', or pass --workers 1 for a serial run") from None
        if isinstance(self._error, OptionError):
            raise self._error
        if self._error is not None:
            raise OptionError(f"could not start a local Dask cluster ({self._error}); run the "
                              "records in this process with --workers 1 (workers=1)") from None
        if self.dashboard:
            print(f"Dask dashboard: {dashboard_link(self._cluster)}", file=sys.stderr)
        return self._client

    def _start_local(self, n: int) -> None:
        try:
            import distributed  # noqa: F401 - only whether it is installed
        except ImportError as exc:
            self._error = exc
            return
        try:
            self._cluster, self._client = start_local(
                n, dashboard=self.dashboard, verbose=self.verbose, config=_WORKER_CONFIG,
                env=_WORKER_ENV)
            # compiled kernels loaded before the first record
            self._client.run(_warm_up, self.methods)
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


_MAX_BATCH = 8


def _warm_up(methods: Sequence[str] = ()) -> None:
    """Import the identification and load the methods' compiled kernels on a worker."""
    from ..workflows import get_method, identify  # noqa: F401 - the import is the warm-up

    for name in methods:
        warm = get_method(name).warm_up
        if warm is not None:
            warm()


def _dask(client: Any, spec: FleetSpec, todo: Sequence[int],
          allow_code: bool = False) -> Iterator[tuple[int, dict[str, Any]]]:
    from distributed import as_completed

    size = _batch_size(len(todo), _n_workers(client))
    batches = [list(todo[k:k + size]) for k in range(0, len(todo), size)]
    futures = {client.submit(identify_records_on_cluster, [str(spec.records[i].path) for i in batch],
                             spec.identify, allow_code, pure=False): batch
               for batch in batches}
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
        if not allow_outside and not _real(path).is_relative_to(_real(base)):
            raise OptionError(f"[report] folder = {folder!r} points outside the fleet file's "
                              f"folder ({base}); pass --out <folder> (or --allow-outside)")
        return path
    stem = spec.source.stem if spec.source else "fleet"
    return base / f"{stem}-results"


def _protect(spec: FleetSpec, folder: Path) -> None:
    """No output of the fleet may land on one of its inputs."""
    from .._errors import OutputExistsError

    inputs = {_real(p) for p in (spec.source, spec.manifest) if p is not None}
    for record in spec.records:
        inputs.update(_real(p) for p in record_inputs(record.path))
    outputs = {_real(folder / name) for name in FleetResult.FILES}
    for path in inputs:
        if path in outputs or path.is_relative_to(_real(folder / "records")):
            raise OutputExistsError(f"refusing to write the fleet results into {folder}: it "
                                    f"would replace the input {path}; choose another --out")


def _real(path: Path) -> Path:
    """The path with its links resolved; a link loop stays as it is (the checks name it)."""
    return Path(os.path.realpath(path))


def _remove_empty(folders: Sequence[Path]) -> None:
    """Remove the folders a refused run made (innermost first), if nothing was put in them."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


def _refuse_foreign(folder: Path, overwrite: bool, lock: FolderLock) -> None:
    """Refuse outputs that an earlier fleet run here did not write, unless ``overwrite``."""
    from .._errors import OutputExistsError

    if overwrite:
        return
    ours = ledger(folder)
    for name in FleetResult.FILES:
        path = folder / name
        if not (path.exists() or path.is_symlink()) or name in lock.inherited:
            continue
        if name not in ours or not path.is_file() or sha256_file(path) != ours[name]:
            raise OutputExistsError(
                f"{path} exists and is not a file an earlier servoid fleet wrote here (or it "
                f"changed since): servoid replaces it only with "
                f"{option('overwrite=True', '--overwrite')}; or choose another "
                f"{option('out', '--out')}")
