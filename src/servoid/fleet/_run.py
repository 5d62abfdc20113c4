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
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from .._atomic import atomic_path
from .._errors import OptionError, OptionTypeError
from .._progress import Progress
from ._result import FleetResult, assemble
from ._spec import FleetSpec, load_fleet_spec
from ._task import identify_record, record_inputs, record_key

__all__ = ["run_fleet"]

_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp$")
_WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


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
    keys = [record_key(r.path, spec.identify) for r in spec.records]
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
    try:
        if not checked and todo and spec.limits:  # one record first: limits must name its params
            i = todo.pop(0)
            outcomes[i] = _keep(store, keys[i], identify_record(str(spec.records[i].path),
                                                                 spec.identify))
            bar.update(ok=outcomes[i]["status"] == "ok")
            checked = _check_limit_names(spec, outcomes.values())
        for i, outcome in _execute(spec, todo, scheduler, workers):
            outcomes[i] = _keep(store, keys[i], outcome)
            bar.update(ok=outcome["status"] == "ok")
            if not checked:
                checked = _check_limit_names(spec, outcomes.values())
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    result = assemble(spec, outcomes, keys, folder, interrupted=interrupted)
    return result.write()


def _execute(spec: FleetSpec, todo: Sequence[int], scheduler: str | None,
             workers: int | None) -> Iterator[tuple[int, dict[str, Any]]]:
    """Yield (index, outcome) as records finish."""
    if not todo:
        return
    if scheduler is None and (workers == 1 or len(todo) == 1):
        for i in todo:
            yield i, identify_record(str(spec.records[i].path), spec.identify)
        return
    yield from _dask(spec, todo, scheduler, workers)


def _dask(spec: FleetSpec, todo: Sequence[int], scheduler: str | None,
          workers: int | None) -> Iterator[tuple[int, dict[str, Any]]]:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise OptionError("running a fleet in parallel needs Dask: pip install 'servoid[fleet]', "
                          "or pass --workers 1 for a serial run") from None
    cluster = None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise OptionError(f"cannot reach the Dask scheduler at {scheduler!r} ({exc}); check "
                              "that it runs and the address, or drop --scheduler to use a "
                              "local cluster") from None
    else:
        n = workers or os.cpu_count() or 1
        try:
            cluster = LocalCluster(n_workers=min(n, len(todo)), threads_per_worker=1,
                                   processes=True, dashboard_address=None,
                                   silence_logs=logging.ERROR, env=_WORKER_ENV)
        except (RuntimeError, OSError) as exc:
            raise OptionError(f"could not start a local Dask cluster ({exc}); run the records "
                              "in this process with --workers 1 (workers=1)") from None
        client = Client(cluster)
    try:
        futures = {client.submit(identify_record, str(spec.records[i].path), spec.identify,
                                 pure=False): i for i in todo}
        try:
            for future in as_completed(futures):
                i = futures[future]
                try:
                    outcome = future.result()
                except Exception as exc:  # noqa: BLE001 - the worker died (memory, signal): a failed record
                    outcome = {"status": "failed", "summary": None, "warnings": [],
                               "seconds": float("nan"),
                               "error": f"the worker running this record failed ({exc})"}
                yield i, outcome
        finally:
            for future in futures:
                future.cancel()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


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

