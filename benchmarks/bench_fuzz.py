"""Long fuzz run of the rig-file readers (CSV, TOML, TDMS, MAT v4/v5/v7.3).

Case
----
One row per format (``csv``, ``toml``, ``tdms``, ``mat4``, ``mat5``,
``mat5z`` = v5 with compressed elements, ``mat73``): 55 000 mutated files
in all. Each input is a valid seed file of the format
(``tests/data/fuzz_inputs.py``, the same seeds and mutations as the
suite's Hypothesis fuzzers) with one to three mutations drawn from
``random.Random(f"{SEED}:{format}:{index}")``, so any input can be rebuilt
from its index. Readers: ``read_csv``, ``load_experiment_spec``,
``read_tdms``, ``read_mat``, each in three call modes (the reader's defaults;
named variables/channels or a given ``dt``; the rig-file options: CSV
``skip_rows`` and ``skip_columns``, TDMS ``"group/channel"`` names, MAT
struct fields ``run.sig.y``).

Then one row per grammar (``grammar-csv``, ``grammar-tdms``,
``grammar-mat5``, ``grammar-mat73``): 17 000 files built field by field
from each format's grammar (``tests/data/fuzz_grammar.py``: CSV dialects
and encodings, TDMS segments written by hand, MAT v5 element fields set
inside the compressed stream, HDF5 attributes, datasets, links and
addresses), about half with one planted fault, each read with the keywords
that fit its dialect; input ``index`` is built from
``random.Random(f"{SEED}:grammar:{format}:{index}")``. A total row closes
the table.

Method
------
Inputs run in forked child processes, a batch of 500 per child, so that a
signal (SIGSEGV, SIGBUS, SIGABRT) kills only the child: the parent knows
which input was running from the child's ``start`` message, counts a
signal death, saves the input under ``$SERVOID_FUZZ_CRASHES`` (default
``/tmp/servoid-fuzz-crashes``) and starts a new child after it. Each child
runs with an address-space limit of 4 GiB (a memory blow-up shows as
``MemoryError``) and a 20 s alarm per input (a hang shows as ``timeout``;
a hang inside C code that the alarm cannot interrupt is killed by the
parent after 60 s without progress and counted as ``hang``).

Counts in ``extra``: ``inputs``, ``ok`` (a valid Experiment or spec),
``errors`` by :class:`ServoidError` class, ``unhandled`` by exception
type and the servoid/library frame it came from, ``signals`` by signal
name, ``timeouts``; ``crashes`` lists saved inputs. ``median_ms`` is the
mean wall time per input (fork, write, read). The issue's known answer:
zero unhandled exceptions and zero signal deaths. Skipped under
``--quick`` (several minutes).

Document loaders
----------------
Rows ``loader model``, ``loader results``, ``loader spec``, ``loader
fleet`` and their total ``all loaders`` (30 000 inputs): model files
(``load_model``, with and without ``allow_code``), results folders
(``load_results``, ``greybox_record``, ``rerender`` reading the manifest),
experiment files (``load_experiment_spec``, then ``records`` or a
write/read round trip) and fleet files (``load_fleet_spec``).  Each input
is a valid document mutated along its format's grammar
(``tests/hardening/loader_inputs.py``: wrong types, missing and extra
keys, edge numbers such as 10**400, NaN and a 5000-digit integer, deep
nesting, odd strings and paths, reshaped arrays, wrong kinds, then byte
damage for one in five), rebuilt from
``random.Random(f"{seed}:{loader}:{index}")``; the same forked batches,
limits and counts as above, a crash saved as a folder of its files and
``ops.txt``.
"""

from __future__ import annotations

import collections
import os
import random
import select
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

from _harness import Result

SUITE = "fuzz"
ROOT = Path(__file__).resolve().parent.parent
SEED = 20240611
#: Inputs per format: 55 000 mutated (compressed MAT v5 most, where the found crash was) and
#: 17 000 built from the grammars.
COUNTS = {"csv": 10_000, "toml": 6_000, "tdms": 9_000, "mat4": 5_000, "mat5": 10_000,
          "mat5z": 12_000, "mat73": 3_000,
          "grammar-csv": 5_000, "grammar-tdms": 5_000, "grammar-mat5": 5_000,
          "grammar-mat73": 2_000}
GRAMMAR = "grammar-"
BATCH = 500
MEMORY_LIMIT = 4 * 2**30  # [bytes] address space of a child
TIMEOUT_S = 20  # per input, by SIGALRM in the child
HANG_S = 60  # without a message from the child: killed


def _fuzz_inputs() -> Any:
    folder = str(ROOT / "tests" / "data")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    import fuzz_inputs

    return fuzz_inputs


def make_input(fmt: str, index: int) -> tuple[bytes, Any]:
    """The file of input ``index`` of ``fmt`` and its call (a mode, or reader keywords)."""
    if fmt.startswith(GRAMMAR):
        import fuzz_grammar

        _fuzz_inputs()  # puts tests/data on the path
        name = fmt[len(GRAMMAR):]
        return fuzz_grammar.grammar_input(name, random.Random(f"{SEED}:grammar:{name}:{index}"))
    fi = _fuzz_inputs()
    rng = random.Random(f"{SEED}:{fmt}:{index}")
    seeds = fi.seeds(fmt)
    seed = seeds[rng.randrange(len(seeds))]
    return fi.mutate(fmt, seed, fi.random_ops(rng)), rng.randrange(fi.N_MODES)


def read(fmt: str, data: bytes, call: Any, folder: Path) -> str:
    """Read one input: ``"ok"`` or ``"error:<class>"``; anything else propagates."""
    if fmt.startswith(GRAMMAR):
        import fuzz_grammar

        return fuzz_grammar.read_grammar(fmt[len(GRAMMAR):], data, call, folder)
    return _fuzz_inputs().read_input(fmt, data, call, folder)


def suffix(fmt: str) -> str:
    if fmt.startswith(GRAMMAR):
        name = fmt[len(GRAMMAR):]
        return ".csv" if name == "csv" else ".tdms" if name == "tdms" else ".mat"
    return _fuzz_inputs().SUFFIX[fmt]


class _Timeout(BaseException):
    """Raised by SIGALRM in a child: one input ran too long."""


def _where(exc: BaseException) -> str:
    """The innermost frame of servoid or of the library that raised."""
    frames = traceback.extract_tb(exc.__traceback__)
    for frame in reversed(frames):
        if "servoid" in frame.filename and "fuzz_inputs" not in frame.filename:
            return f"{Path(frame.filename).name}:{frame.lineno}"
    if frames:
        return f"{Path(frames[-1].filename).name}:{frames[-1].lineno}"
    return "?"


def _child(fmt: str, start: int, stop: int, wfd: int, folder: Path) -> None:  # pragma: no cover
    import logging
    import resource
    import warnings

    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)  # library warnings and log lines
    warnings.simplefilter("ignore")
    logging.getLogger("nptdms").propagate = False
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))

    def on_alarm(signum: int, frame: object) -> None:
        raise _Timeout

    signal.signal(signal.SIGALRM, on_alarm)
    for index in range(start, stop):
        os.write(wfd, f"S {index}\n".encode())
        data, call = make_input(fmt, index)
        signal.alarm(TIMEOUT_S)
        try:
            outcome = read(fmt, data, call, folder)
        except _Timeout:
            outcome = "timeout"
        except BaseException as exc:  # noqa: BLE001 - every escape is the finding
            outcome = f"unhandled:{type(exc).__name__}@{_where(exc)}"
        finally:
            signal.alarm(0)
        os.write(wfd, f"R {index} {outcome}\n".encode())
    os._exit(0)


def _run_batch(fmt: str, start: int, stop: int, outcomes: dict[int, str], folder: Path) -> None:
    """Run inputs ``start..stop-1``, restarting after each child that dies."""
    while start < stop:
        rfd, wfd = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            os.close(rfd)
            try:
                _child(fmt, start, stop, wfd, folder)
            finally:
                os._exit(3)
        os.close(wfd)
        running, buffer, killed = None, b"", False
        with os.fdopen(rfd, "rb", buffering=0) as pipe:
            while True:
                ready, _, _ = select.select([pipe], [], [], HANG_S)
                if not ready:
                    os.kill(pid, signal.SIGKILL)
                    killed = True
                    break
                chunk = pipe.read(65536)
                if not chunk:
                    break
                buffer += chunk
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    tag, index, *rest = line.decode().split(" ", 2)
                    if tag == "S":
                        running = int(index)
                    else:
                        outcomes[int(index)] = rest[0]
                        running = None
        _, status = os.waitpid(pid, 0)
        if running is None:
            return
        if killed:
            outcomes[running] = "hang"
        elif os.WIFSIGNALED(status):
            outcomes[running] = f"signal:{signal.Signals(os.WTERMSIG(status)).name}"
        else:
            outcomes[running] = f"child-exit:{os.WEXITSTATUS(status)}"
        start = running + 1


def fuzz_format(fmt: str, count: int) -> tuple[dict[str, Any], float]:
    """Fuzz one format; return the counts and the wall time [s]."""
    if not fmt.startswith(GRAMMAR):
        _fuzz_inputs().seeds(fmt)  # build the seeds once, before forking
    outcomes: dict[int, str] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="servoid-fuzz-") as scratch:
        for start in range(0, count, BATCH):
            _run_batch(fmt, start, min(start + BATCH, count), outcomes, Path(scratch))
    elapsed = time.perf_counter() - t0
    errors: collections.Counter[str] = collections.Counter()
    unhandled: collections.Counter[str] = collections.Counter()
    signals: collections.Counter[str] = collections.Counter()
    ok = timeouts = 0
    crashes = []
    folder = Path(os.environ.get("SERVOID_FUZZ_CRASHES", "/tmp/servoid-fuzz-crashes"))
    ext = suffix(fmt)
    for index, outcome in sorted(outcomes.items()):
        kind, _, detail = outcome.partition(":")
        if kind == "ok":
            ok += 1
        elif kind == "error":
            errors[detail] += 1
        elif kind == "unhandled":
            unhandled[detail] += 1
        elif kind in ("timeout", "hang"):
            timeouts += 1
        else:
            signals[detail or kind] += 1
        if kind not in ("ok", "error"):
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"{fmt}-{index}{ext}"
            path.write_bytes(make_input(fmt, index)[0])
            crashes.append(f"{path} ({outcome}, call {make_input(fmt, index)[1]!r})")
    counts = {
        "inputs": len(outcomes), "ok": ok, "errors": dict(errors.most_common()),
        "unhandled": dict(unhandled.most_common()), "signals": dict(signals),
        "timeouts": timeouts, "crashes": crashes[:50],
    }
    return counts, elapsed


def run(quick: bool = False) -> list[Result]:
    """Fuzz every format; nothing under ``quick``."""
    if quick:
        print("# fuzz: skipped under --quick", file=sys.stderr)
        return []
    scale = float(os.environ.get("SERVOID_FUZZ_SCALE", "1"))  # < 1 for a shorter trial
    rows = []
    total: dict[str, Any] = {"inputs": 0, "ok": 0, "errors": 0, "unhandled": 0, "signals": 0,
                             "timeouts": 0}
    wall = 0.0
    for fmt, count in COUNTS.items():
        n = max(1, int(count * scale))
        counts, elapsed = fuzz_format(fmt, n)
        wall += elapsed
        for key in ("inputs", "ok", "timeouts"):
            total[key] += counts[key]
        for key in ("errors", "unhandled", "signals"):
            total[key] += sum(counts[key].values())
        per_ms = 1e3 * elapsed / max(counts["inputs"], 1)
        note = (f"{counts['ok']} ok, {sum(counts['errors'].values())} servoid errors, "
                f"{sum(counts['unhandled'].values())} unhandled, "
                f"{sum(counts['signals'].values())} signal deaths, {counts['timeouts']} timeouts")
        print(f"# fuzz {fmt}: {counts['inputs']} inputs in {elapsed:.1f} s: {note}",
              file=sys.stderr)
        method = "grammar fuzz, forked batches" if fmt.startswith(GRAMMAR) else \
            "mutation fuzz, forked batches"
        rows.append(Result(SUITE, fmt, counts["inputs"], method, per_ms, per_ms, 1, note=note,
                           extra=counts))
    per_ms = 1e3 * wall / max(total["inputs"], 1)
    note = (f"{total['ok']} ok, {total['errors']} servoid errors, {total['unhandled']} "
            f"unhandled, {total['signals']} signal deaths, {total['timeouts']} timeouts")
    rows.append(Result(SUITE, "all formats", total["inputs"], "mutation and grammar fuzz",
                       per_ms, per_ms, 1, note=note, extra=total))
    rows.extend(run_loaders(scale))  # the document loaders: grammar-aware inputs
    return rows


# -- the document loaders (issue 21) -----------------------------------------------------------
#
# Model files (load_model), results folders (load_results, greybox_record, rerender and the
# manifest), experiment files (load_experiment_spec, records, a write/read round trip) and
# fleet files (load_fleet_spec): inputs from the grammar-aware generators of
# tests/hardening/loader_inputs.py, each rebuilt from its index by
# random.Random(f"{seed}:{loader}:{index}"), run in forked batches as above.

#: Inputs per loader: 30 000 in all, about 5 minutes on one core.
LOADER_COUNTS = {"model": 10_000, "results": 6_000, "spec": 10_000, "fleet": 4_000}


def _loader_inputs() -> Any:
    folder = str(ROOT / "tests" / "hardening")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    import loader_inputs

    return loader_inputs


def _loader_child(loader: str, start: int, stop: int, wfd: int,
                  folder: Path) -> None:  # pragma: no cover
    import resource
    import warnings

    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    warnings.simplefilter("ignore")
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))

    def on_alarm(signum: int, frame: object) -> None:
        raise _Timeout

    signal.signal(signal.SIGALRM, on_alarm)
    li = _loader_inputs()
    for index in range(start, stop):
        os.write(wfd, f"S {index}\n".encode())
        inp = li.make_input(loader, index, folder)
        signal.alarm(TIMEOUT_S)
        try:
            outcome = li.run_input(inp, folder)
        except _Timeout:
            outcome = "timeout"
        except BaseException as exc:  # noqa: BLE001 - every escape is the finding
            outcome = f"unhandled:{type(exc).__name__}@{_where(exc)}"
        finally:
            signal.alarm(0)
        os.write(wfd, f"R {index} {outcome}\n".encode())
    os._exit(0)


def _run_loader_batch(loader: str, start: int, stop: int, outcomes: dict[int, str],
                      folder: Path) -> None:
    """Run inputs ``start..stop-1`` of ``loader``, restarting after each child that dies."""
    while start < stop:
        rfd, wfd = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            os.close(rfd)
            try:
                _loader_child(loader, start, stop, wfd, folder)
            finally:
                os._exit(3)
        os.close(wfd)
        running, buffer, killed = None, b"", False
        with os.fdopen(rfd, "rb", buffering=0) as pipe:
            while True:
                ready, _, _ = select.select([pipe], [], [], HANG_S)
                if not ready:
                    os.kill(pid, signal.SIGKILL)
                    killed = True
                    break
                chunk = pipe.read(65536)
                if not chunk:
                    break
                buffer += chunk
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    tag, index, *rest = line.decode().split(" ", 2)
                    if tag == "S":
                        running = int(index)
                    else:
                        outcomes[int(index)] = rest[0]
                        running = None
        _, status = os.waitpid(pid, 0)
        if running is None:
            return
        if killed:
            outcomes[running] = "hang"
        elif os.WIFSIGNALED(status):
            outcomes[running] = f"signal:{signal.Signals(os.WTERMSIG(status)).name}"
        else:
            outcomes[running] = f"child-exit:{os.WEXITSTATUS(status)}"
        start = running + 1


def fuzz_loader(loader: str, count: int) -> tuple[dict[str, Any], float]:
    """Fuzz one document loader; return the counts and the wall time [s]."""
    li = _loader_inputs()
    outcomes: dict[int, str] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="servoid-fuzz-") as scratch:
        li.prepare(Path(scratch))
        for start in range(0, count, BATCH):
            _run_loader_batch(loader, start, min(start + BATCH, count), outcomes, Path(scratch))
        elapsed = time.perf_counter() - t0
        errors: collections.Counter[str] = collections.Counter()
        unhandled: collections.Counter[str] = collections.Counter()
        signals: collections.Counter[str] = collections.Counter()
        ok = timeouts = 0
        crashes = []
        saved = Path(os.environ.get("SERVOID_FUZZ_CRASHES", "/tmp/servoid-fuzz-crashes"))
        for index, outcome in sorted(outcomes.items()):
            kind, _, detail = outcome.partition(":")
            if kind == "ok":
                ok += 1
            elif kind == "error":
                errors[detail] += 1
            elif kind == "unhandled":
                unhandled[detail] += 1
            elif kind in ("timeout", "hang"):
                timeouts += 1
            else:
                signals[detail or kind] += 1
            if kind not in ("ok", "error"):
                inp = li.make_input(loader, index, Path(scratch))
                target = saved / f"{loader}-{index}"
                target.mkdir(parents=True, exist_ok=True)
                for name, data in inp.files.items():
                    (target / name).write_bytes(data)
                (target / "ops.txt").write_text("\n".join(inp.ops) + "\n", encoding="utf-8")
                crashes.append(f"{target} ({outcome}, mode {inp.mode})")
    counts = {
        "inputs": len(outcomes), "ok": ok, "errors": dict(errors.most_common()),
        "unhandled": dict(unhandled.most_common()), "signals": dict(signals),
        "timeouts": timeouts, "crashes": crashes[:50],
    }
    return counts, elapsed


def run_loaders(scale: float = 1.0) -> list[Result]:
    """One row per document loader and their total."""
    rows = []
    total: dict[str, Any] = {"inputs": 0, "ok": 0, "errors": 0, "unhandled": 0, "signals": 0,
                             "timeouts": 0}
    wall = 0.0
    for loader, count in LOADER_COUNTS.items():
        counts, elapsed = fuzz_loader(loader, max(1, int(count * scale)))
        wall += elapsed
        for key in ("inputs", "ok", "timeouts"):
            total[key] += counts[key]
        for key in ("errors", "unhandled", "signals"):
            total[key] += sum(counts[key].values())
        per_ms = 1e3 * elapsed / max(counts["inputs"], 1)
        note = (f"{counts['ok']} ok, {sum(counts['errors'].values())} servoid errors, "
                f"{sum(counts['unhandled'].values())} unhandled, "
                f"{sum(counts['signals'].values())} signal deaths, {counts['timeouts']} timeouts")
        print(f"# fuzz loader {loader}: {counts['inputs']} inputs in {elapsed:.1f} s: {note}",
              file=sys.stderr)
        rows.append(Result(SUITE, f"loader {loader}", counts["inputs"],
                           "grammar fuzz, forked batches", per_ms, per_ms, 1, note=note,
                           extra=counts))
    per_ms = 1e3 * wall / max(total["inputs"], 1)
    note = (f"{total['ok']} ok, {total['errors']} servoid errors, {total['unhandled']} "
            f"unhandled, {total['signals']} signal deaths, {total['timeouts']} timeouts")
    rows.append(Result(SUITE, "all loaders", total["inputs"], "grammar fuzz, forked batches",
                       per_ms, per_ms, 1, note=note, extra=total))
    return rows
