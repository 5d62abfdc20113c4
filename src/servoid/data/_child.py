"""Run a file reader in a child process that can be abandoned.

A compiled library that loops on a damaged file (libhdf5 has been seen to
spin at 100 % CPU forever on an 8.7 kB file) cannot be interrupted from
Python: a signal handler runs only when the C call returns. So such a read
runs in a forked child that sends its result back over a Unix socket, and a
heartbeat while it works (the reader calls ``beat()`` between the pieces it
reads). A child silent for :data:`STALL_SECONDS` is killed and the read is a
:class:`FileFormatError`; so is a child ended by a signal (a crash of the
library takes only the child).

Arrays come back out of band (pickle protocol 5). One of 1 MiB or more is
copied once into an anonymous shared-memory file (``memfd``) whose
descriptor is passed over the socket; this process maps it and the array
is rebuilt on the mapping, without another copy (a reader that allocates
its arrays with :func:`empty` writes them there in the first place).
Smaller ones travel through the socket. Forking needs ``os.fork``: on other platforms, and
when :data:`ENABLED` is False, the reader runs in the calling process with
no time limit.
"""

from __future__ import annotations

import array
import mmap
import os
import pickle
import select
import signal
import socket
import struct
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from .._errors import FileFormatError, ServoidError

__all__ = ["ENABLED", "STALL_SECONDS", "empty", "run_watched"]

_T = TypeVar("_T")

#: A child that sends nothing for this long [s] is taken to be stuck and killed.
STALL_SECONDS = 30.0
#: Whether readers run in a child at all (Linux); False runs them in process.
ENABLED = sys.platform.startswith("linux") and hasattr(os, "fork")

_HEADER = struct.Struct("<cQ")  # kind, length
_BEAT, _DATA, _SHARED, _DONE = b"b", b"d", b"m", b"e"
#: Buffers this large or larger go through shared memory, not the socket [bytes].
_SHARE_BYTES = 1 << 20
_SOCKET_BYTES = 1 << 20
_FORK_LOCK = threading.Lock()
_ENDING: list[int] = []  # children that sent their result and may still be exiting
_IN_CHILD = False
_REGIONS: dict[int, tuple[int, int]] = {}  # in a child: address -> (memfd, bytes) of empty()


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
    ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    for sock in (ours, theirs):
        try:  # larger buffers: fewer switches between the processes
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, _SOCKET_BYTES)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _SOCKET_BYTES)
        except OSError:  # pragma: no cover - a lower system limit
            pass
    pid = _fork()
    if pid == 0:  # pragma: no cover - the child; its coverage is not collected
        ours.close()
        _child(job, theirs)
    theirs.close()
    stream = _Stream(ours, pid, path, what)
    done = False
    try:
        kind, payload = _receive(stream)
        done = True
    finally:
        stream.close()
        if not done:
            _kill(pid)
            _reap(pid)
        else:  # it exits once its result is sent: reaped now, or by a later call
            _reap_later(pid)
    if kind == "ok":
        return payload  # type: ignore[no-any-return]
    raise payload


def empty(shape: tuple[int, ...], dtype: Any) -> np.ndarray:
    """An uninitialised array for a reader's result.

    In a watched child, an array of 1 MiB or more lives in shared memory,
    which the parent maps: the result crosses without a copy. Elsewhere it
    is :func:`numpy.empty`.

    Parameters
    ----------
    shape : tuple of int
        Its shape.
    dtype : numpy dtype
        Its type.

    Returns
    -------
    numpy.ndarray
        C-contiguous and writable.
    """
    kind = np.dtype(dtype)
    nbytes = int(np.prod(shape, dtype=np.int64)) * kind.itemsize
    if not _IN_CHILD or nbytes < _SHARE_BYTES or not hasattr(os, "memfd_create"):
        return np.empty(shape, kind)
    try:
        fd = os.memfd_create("servoid-read", getattr(os, "MFD_CLOEXEC", 0))
        os.ftruncate(fd, nbytes)
        mapped = mmap.mmap(fd, nbytes)
    except OSError:  # pragma: no cover - no shared memory: the socket carries it
        return np.empty(shape, kind)
    out = np.frombuffer(mapped, dtype=kind).reshape(shape)
    _REGIONS[out.ctypes.data] = (fd, nbytes)
    return out


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


def _child(job: Callable[[Callable[[], None]], Any],
           sock: socket.socket) -> None:  # pragma: no cover - runs in the child
    """Run the job, send its result or error, and leave without cleanup."""
    global _IN_CHILD
    code = 0
    _IN_CHILD = True
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends the child with the parent

        def beat() -> None:
            sock.sendall(_HEADER.pack(_BEAT, 0))

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
            _send_buffer(sock, buf.raw())
        sock.sendall(_HEADER.pack(_DONE, len(head)))
        sock.sendall(head)
    except BaseException:  # noqa: BLE001
        code = 3
    finally:
        os._exit(code)


def _send_buffer(sock: socket.socket, raw: memoryview) -> None:  # pragma: no cover - child
    """Send one out-of-band buffer: by shared memory when large, else through the socket."""
    if raw.nbytes >= _SHARE_BYTES:
        region = _REGIONS.get(np.frombuffer(raw, np.uint8).ctypes.data)
        if region is not None and region[1] == raw.nbytes:  # made by empty(): already shared
            sock.sendmsg([_HEADER.pack(_SHARED, raw.nbytes)],
                         [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", [region[0]]))])
            return
    if raw.nbytes >= _SHARE_BYTES and hasattr(os, "memfd_create"):
        try:
            fd = os.memfd_create("servoid-read", getattr(os, "MFD_CLOEXEC", 0))
        except OSError:
            fd = -1
        if fd >= 0:
            try:
                os.ftruncate(fd, raw.nbytes)
                with mmap.mmap(fd, raw.nbytes) as mapped:
                    mapped[:] = raw
                sock.sendmsg([_HEADER.pack(_SHARED, raw.nbytes)],
                           [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", [fd]))])
                return
            finally:
                os.close(fd)
    sock.sendall(_HEADER.pack(_DATA, raw.nbytes))
    sock.sendall(raw)


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


def _receive(stream: _Stream) -> tuple[str, Any]:
    """Read the child's messages until its result."""
    buffers: list[Any] = []
    while True:
        kind, length = _HEADER.unpack(stream.read(_HEADER.size))
        if kind == _BEAT:
            continue
        if kind == _SHARED:
            fd = stream.take_fd()
            try:
                buffers.append(mmap.mmap(fd, length))  # the array is rebuilt on the mapping
            finally:
                os.close(fd)
            continue
        body = stream.read(length)
        if kind == _DATA:
            buffers.append(body)
            continue
        return pickle.loads(body, buffers=buffers)  # type: ignore[no-any-return]


class _Stream:
    """The parent's end: exact reads with a stall limit, and the descriptors passed."""

    def __init__(self, sock: socket.socket, pid: int, path: Path, what: str) -> None:
        self.sock, self.pid, self.path, self.what = sock, pid, path, what
        self.fds: list[int] = []
        self.poller = select.poll()  # not select(): a descriptor above 1023 is refused there
        self.poller.register(sock.fileno(), select.POLLIN | select.POLLHUP | select.POLLERR)

    def read(self, n: int) -> bytearray:
        out = bytearray(n)
        view = memoryview(out)
        got = 0
        room = socket.CMSG_SPACE(4 * array.array("i").itemsize)
        while got < n:
            if not self.poller.poll(int(STALL_SECONDS * 1000)):
                _kill(self.pid)
                raise FileFormatError(
                    f"{self.path}: reading it as {self.what} made no progress for "
                    f"{STALL_SECONDS:g} s, so it was stopped: the file library is stuck on "
                    "damaged structures (or the file is on an unresponsive drive: copy it to a "
                    "local disk and try again); if the file is damaged, copy or export it again"
                )
            k, ancillary, _, _ = self.sock.recvmsg_into([view[got:]], room)
            for level, kind, data in ancillary:
                if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
                    fds = array.array("i")
                    fds.frombytes(data[: len(data) - len(data) % fds.itemsize])
                    self.fds.extend(fds)
            if k == 0:
                raise _died(self.pid, self.path, self.what)
            got += k
        return out

    def take_fd(self) -> int:
        if not self.fds:
            raise FileFormatError(f"{self.path}: reading it as {self.what}: a shared buffer "
                                  "came without its descriptor")
        return self.fds.pop(0)

    def close(self) -> None:
        for fd in self.fds:
            os.close(fd)
        self.fds.clear()
        self.sock.close()


def _died(pid: int, path: Path, what: str) -> FileFormatError:
    """The error for a child that closed the socket without a result."""
    _, status = _reap(pid)
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL:
        return FileFormatError(
            f"{path}: reading it as {what} was killed (SIGKILL), most likely by the system for "
            "lack of memory: free memory, or read fewer or shorter variables"
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


def _reap_later(pid: int) -> None:
    """Reap ``pid`` if it has ended, and any child left before; keep the others for later.

    A child that has sent its result still has to free its memory: waiting
    for that would add its teardown to every read.
    """
    with _FORK_LOCK:
        _ENDING.append(pid)
        for child in list(_ENDING):
            try:
                done, _ = os.waitpid(child, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere
                done = child
            if done:
                _ENDING.remove(child)


def _reap(pid: int) -> tuple[int, int]:
    """Wait for the child to end (it exits once its result is sent); (pid, status)."""
    try:
        return os.waitpid(pid, 0)
    except ChildProcessError:  # already reaped
        return pid, 0
