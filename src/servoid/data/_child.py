"""Run a file reader in a child process that can be abandoned.

A compiled library that loops on a damaged file (libhdf5 has been seen to
spin at 100 % CPU forever on an 8.7 kB file) cannot be interrupted from
Python: a signal handler runs only when the C call returns. So such a read
runs in a forked child that sends its result back through a pipe, and a
heartbeat while it works (the reader calls ``beat()`` between the pieces it
reads). A child silent for :data:`STALL_SECONDS` is killed and the read is a
:class:`FileFormatError`; so is a child ended by a signal (a crash of the
library takes only the child).

Arrays come back out of band (pickle protocol 5): each is received into
its own buffer and becomes the array without another copy, so the parent
holds the data once. Forking needs ``os.fork``: on other platforms, and
when :data:`ENABLED` is False, the reader runs in the calling process with
no time limit.
"""

from __future__ import annotations

import fcntl
import os
import pickle
import select
import signal
import struct
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from .._errors import FileFormatError, ServoidError

__all__ = ["ENABLED", "STALL_SECONDS", "run_watched"]

_T = TypeVar("_T")

#: A child that sends nothing for this long [s] is taken to be stuck and killed.
STALL_SECONDS = 30.0
#: Whether readers run in a child at all (Linux); False runs them in process.
ENABLED = sys.platform.startswith("linux") and hasattr(os, "fork")

_HEADER = struct.Struct("<cQ")  # kind, length
_PIPE_BYTES = 1 << 20
_BEAT, _DATA, _DONE = b"b", b"d", b"e"
_FORK_LOCK = threading.Lock()


def run_watched(job: Callable[[Callable[[], None]], _T], path: Path, what: str) -> _T:
    """Run ``job(beat)`` in a child process; return its result or raise its error.

    Parameters
    ----------
    job : callable
        Called with ``beat``, a function to call whenever a piece of work
        is done; returns a picklable result.
    path : pathlib.Path
        The file read, for messages.
    what : str
        What the file is, for messages (``"a MAT v7.3 (HDF5) file"``).

    Returns
    -------
    object
        What ``job`` returned.

    Raises
    ------
    FileFormatError
        The child made no progress for :data:`STALL_SECONDS`, or died by a
        signal.
    ServoidError
        Whatever servoid error ``job`` raised, rebuilt in this process.
    """
    if not ENABLED:
        return job(lambda: None)
    read_end, write_end = os.pipe()
    try:  # a larger pipe: fewer switches between the processes while an array streams over
        fcntl.fcntl(write_end, getattr(fcntl, "F_SETPIPE_SZ", 1031), _PIPE_BYTES)
    except OSError:  # pragma: no cover - a lower limit in /proc/sys/fs/pipe-max-size
        pass
    pid = _fork()
    if pid == 0:  # pragma: no cover - the child; its coverage is not collected
        os.close(read_end)
        _child(job, write_end)
    os.close(write_end)
    done = False
    try:
        kind, payload = _receive(read_end, pid, path, what)
        done = True
    finally:
        os.close(read_end)
        if not done:
            _kill(pid)
        _reap(pid)
    if kind == "ok":
        return payload  # type: ignore[no-any-return]
    raise payload


def _fork() -> int:
    """``os.fork`` with h5py's lock held, so the child never inherits it locked."""
    try:
        from h5py._objects import phil
    except ImportError:  # pragma: no cover - h5py is checked before a v7.3 read
        phil = threading.Lock()
    with _FORK_LOCK, phil, warnings.catch_warnings():
        # Python 3.12 warns on fork in a process with threads: the child here runs only the
        # reader (no lock of another thread is taken but h5py's, held above).
        warnings.simplefilter("ignore", DeprecationWarning)
        return os.fork()


def _child(job: Callable[[Callable[[], None]], Any], fd: int) -> None:  # pragma: no cover
    """Run the job, send its result or error, and leave without cleanup."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends the child with the parent

        def beat() -> None:
            _write(fd, _HEADER.pack(_BEAT, 0))

        try:
            message: tuple[str, Any] = ("ok", job(beat))
        except BaseException as exc:  # noqa: BLE001 - every error goes back to the parent
            message = ("error", _portable(exc))
        buffers: list[pickle.PickleBuffer] = []
        try:
            head = pickle.dumps(message, protocol=5, buffer_callback=buffers.append)
        except Exception as exc:  # noqa: BLE001
            buffers = []
            head = pickle.dumps(("error", FileFormatError(f"{type(exc).__name__}: {exc}")),
                                protocol=5)
        for buf in buffers:
            raw = buf.raw()
            _write(fd, _HEADER.pack(_DATA, raw.nbytes))
            _write(fd, raw)
        _write(fd, _HEADER.pack(_DONE, len(head)))
        _write(fd, head)
    except BaseException:  # noqa: BLE001
        code = 3
    finally:
        os._exit(code)


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling as it is, else a FileFormatError with its words."""
    if isinstance(exc, (ServoidError, ImportError)):
        try:
            copy = pickle.loads(pickle.dumps(exc))
        except Exception:  # noqa: BLE001 - a subclass whose __init__ takes more
            copy = None
        if type(copy) is type(exc) and str(copy) == str(exc):
            return exc
        return FileFormatError(str(exc))
    return FileFormatError(f"{type(exc).__name__}: {exc}")


def _write(fd: int, data: bytes | memoryview) -> None:  # pragma: no cover - the child's
    view = memoryview(data).cast("B")
    while view:
        view = view[os.write(fd, view):]


def _receive(fd: int, pid: int, path: Path, what: str) -> tuple[str, Any]:
    """Read the child's messages until its result; watch for silence and death."""
    buffers: list[bytearray] = []
    while True:
        kind, length = _HEADER.unpack(_read_exactly(fd, _HEADER.size, pid, path, what))
        if kind == _BEAT:
            continue
        body = _read_exactly(fd, length, pid, path, what)
        if kind == _DATA:
            buffers.append(body)
            continue
        result = pickle.loads(body, buffers=buffers)
        return result  # type: ignore[no-any-return]


def _read_exactly(fd: int, n: int, pid: int, path: Path, what: str) -> bytearray:
    out = bytearray(n)
    view = memoryview(out)
    got = 0
    poller = select.poll()  # not select(): a descriptor above 1023 is refused there
    poller.register(fd, select.POLLIN | select.POLLHUP | select.POLLERR)
    while got < n:
        if not poller.poll(int(STALL_SECONDS * 1000)):
            _kill(pid)
            raise FileFormatError(
                f"{path}: reading it as {what} made no progress for {STALL_SECONDS:g} s, so it "
                "was stopped: the file library is stuck on damaged structures (or the file "
                "is on an unresponsive drive: copy it to a local disk and try again); if the "
                "file is damaged, copy or export it again"
            )
        k = os.readv(fd, [view[got:]])
        if k == 0:
            raise _died(pid, path, what)
        got += k
    return out


def _died(pid: int, path: Path, what: str) -> FileFormatError:
    """The error for a child that closed the pipe without a result."""
    _, status = _reap(pid)
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL:
        return FileFormatError(
            f"{path}: reading it as {what} was killed (SIGKILL), most likely by the system for "
            "lack of memory: lower [data] max_bytes (max_bytes=) or free memory"
        )
    if os.WIFSIGNALED(status):
        name = signal.Signals(os.WTERMSIG(status)).name
        return FileFormatError(
            f"{path}: the file library crashed ({name}) reading it as {what}: a damaged file; "
            "copy or export it again"
        )
    return FileFormatError(f"{path}: reading it as {what} ended without a result (exit "
                           f"status {os.WEXITSTATUS(status) if os.WIFEXITED(status) else status})")


def _kill(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:  # pragma: no cover - it ended meanwhile
        pass


def _reap(pid: int) -> tuple[int, int]:
    """Wait for the child to end (it exits once its result is sent); (pid, status)."""
    try:
        return os.waitpid(pid, 0)
    except ChildProcessError:  # already reaped
        return pid, 0
