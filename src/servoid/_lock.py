"""One run owns its output folder: a lock file, its journal, and what a dead run left.

A command that writes several files into a folder (``identify``, ``report``,
``fleet``) holds :func:`hold_folder` for the whole run.  The lock is the
file ``.servoid.lock`` in the folder:

- it appears whole and already locked: it is written and ``flock``-ed under
  a unique temporary name, then hard-linked into place, which fails if a
  lock is there (the ``O_EXCL`` of a link);
- while the run lives, the kernel holds the ``flock``; when the process
  dies (even by SIGKILL) the kernel releases it, so a lock whose ``flock``
  can be taken is *stale*: its run is dead;
- it records the run (process id, host, command, start) and its *token*,
  the random part of every temporary file name the run uses in the folder,
  and the journal of the files the run set out to write (:meth:`FolderLock.claim`).

A run that finds a stale lock takes it over: it deletes the temporary files
named with the dead run's token — files that carry servoid's own mark, never
files recognised by the shape of their name — and inherits the dead run's
journal (:attr:`FolderLock.inherited`), the files an interrupted run may
have left half done, which the new run may replace.  The lock is removed
when the run ends, whatever the way.

Without ``flock`` (Windows, some network file systems) a lock found in
place is taken for a live run's: the message names the file to delete when
no servoid runs there.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import socket
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ._errors import OutputExistsError

try:
    import fcntl
except ImportError:  # pragma: no cover — Windows
    fcntl = None  # type: ignore[assignment]

__all__ = ["LEDGER", "LOCK", "FolderLock", "hold_folder", "ledger", "sha256_file",
           "temporary_token", "write_ledger"]

#: The lock file's name in a folder a run owns.
LOCK = ".servoid.lock"
#: Files a command wrote in a folder, with their SHA-256 (for commands without a manifest).
LEDGER = ".servoid-files.json"

_HELD: dict[Path, FolderLock] = {}  # folder (resolved) → this process's lock on it
_GUARD = threading.Lock()


@dataclass
class FolderLock:
    """This process's ownership of a folder (see the module docstring).

    Attributes
    ----------
    folder : Path
        The folder, as given.
    token : str
        The random part of this run's temporary file names in the folder.
    inherited : frozenset of str
        Files (names relative to the folder) a dead run's journal listed:
        left by an interrupted run, they may be replaced.
    made : list of Path
        Folders the lock created, outermost first (removed at release when
        they are empty).
    """

    folder: Path
    token: str
    inherited: frozenset[str] = frozenset()
    made: list[Path] = field(default_factory=list)
    _fd: int = -1
    _old_fds: list[int] = field(default_factory=list)
    _info: dict[str, Any] = field(default_factory=dict)
    _depth: int = 0
    _thread: int = 0

    def claim(self, paths: Sequence[Path]) -> None:
        """Journal ``paths`` as files this run is about to write (before writing them)."""
        names = set(self._info.get("files", ()))
        names.update(_relative(self.folder, Path(p)) for p in paths)
        self._info["files"] = sorted(names)
        data = json.dumps(self._info, indent=1).encode()
        # the journal only grows: written over the old one, then cut to length, it is never
        # an empty file (a run killed in between leaves the old or the new journal)
        os.pwrite(self._fd, data, 0)
        os.ftruncate(self._fd, len(data))
        os.fsync(self._fd)


def temporary_token(folder: Path) -> str | None:
    """The token of this process's lock on ``folder`` or a folder above it, if held."""
    with _GUARD:
        if not _HELD:
            return None
        resolved = folder.resolve()
        for path in (resolved, *resolved.parents):
            lock = _HELD.get(path)
            if lock is not None:
                return lock.token
    return None


@contextmanager
def hold_folder(folder: str | os.PathLike[str], *,
                subfolders: Sequence[str] = ()) -> Iterator[FolderLock]:
    """Own ``folder`` for a run: create it if needed, lock it, release it at the end.

    A lock this thread already holds on the folder is reused (a run that
    calls another step writing into the same folder).

    Parameters
    ----------
    folder : path
        The output folder.
    subfolders : sequence of str
        Folders inside it where the run writes temporary files too (swept
        of a dead run's temporary files along with the folder).

    Raises
    ------
    OutputExistsError
        Another live run holds the folder (its process id and command are
        named), or the folder is a file.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"{folder} is a file, not a folder; results go into a folder: "
                                "give --out a folder")
    resolved = folder.resolve()
    with _GUARD:
        held = _HELD.get(resolved)
        if held is not None and held._thread == threading.get_ident():
            held._depth += 1
        else:
            held = None
    if held is not None:
        try:
            yield held
        finally:
            with _GUARD:
                held._depth -= 1
        return
    made = _missing_folders(folder)
    try:
        lock = _acquire(folder, subfolders, made)
    except BaseException:
        for path in reversed(made):
            with suppress(OSError):
                path.rmdir()  # only an empty folder goes
        raise
    with _GUARD:
        _HELD[resolved] = lock
    try:
        yield lock
    finally:
        with _GUARD:
            _HELD.pop(resolved, None)
        _release(lock)


def ledger(folder: Path) -> dict[str, str]:
    """Name → SHA-256 of the files a servoid command recorded writing in ``folder``."""
    try:
        data = json.loads((folder / LEDGER).read_text(encoding="utf-8"))
        files = data["files"]
        return {str(k): str(v) for k, v in files.items()} if isinstance(files, dict) else {}
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError):
        return {}


def write_ledger(folder: Path, paths: Sequence[Path], command: str) -> None:
    """Record ``paths`` (in ``folder``) as written by ``command``, with their SHA-256."""
    from ._atomic import atomic_path

    files = {p.name: sha256_file(p) for p in paths if p.is_file()}
    with atomic_path(folder / LEDGER, overwrite=True) as tmp:
        tmp.write_text(json.dumps({"written_by": command, "files": files}, indent=1),
                       encoding="utf-8")


def sha256_file(path: Path) -> str:
    """The SHA-256 of a file's bytes, read in chunks."""
    import hashlib

    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while chunk := handle.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


# -- private ------------------------------------------------------------------------------


def _acquire(folder: Path, subfolders: Sequence[str], made: list[Path]) -> FolderLock:
    token = secrets.token_hex(8)
    info = {"servoid_lock": 1, "pid": os.getpid(), "host": socket.gethostname(),
            "command": " ".join(sys.argv)[:500], "started": time.time(), "token": token,
            "folders": [".", *subfolders], "files": []}
    path = folder / LOCK
    for _ in range(50):  # each turn ends in a lock, a refusal or a race lost to a run that ended
        folder.mkdir(parents=True, exist_ok=True)
        fd = _new_lock(folder, info)
        try:
            os.link(_tmp_name(folder, token), path)
        except FileExistsError:
            pass
        except OSError:  # a file system without hard links: create the lock in place
            direct = _direct_lock(path, info)
            if direct is not None:
                os.close(fd)
                return FolderLock(folder, token, made=made, _fd=direct, _info=info,
                                  _thread=threading.get_ident())
        else:
            os.unlink(_tmp_name(folder, token))
            return FolderLock(folder, token, made=made, _fd=fd, _info=info,
                              _thread=threading.get_ident())
        finally:
            with suppress(FileNotFoundError):
                os.unlink(_tmp_name(folder, token))
        # a lock is there: live (refuse) or stale (take it over)
        taken = _take_stale(path, fd, folder, info)
        if taken is None:
            os.close(fd)
            continue
        old_fd, fd, dead = taken
        # our lock already journals the dead run's files (so a run killed now passes them on)
        lock = FolderLock(folder, token, frozenset(info["files"]), made, fd, [old_fd], info,
                          _thread=threading.get_ident())
        _sweep(folder, dead)
        return lock
    raise OutputExistsError(f"{folder} keeps changing owner: another servoid run starts and "
                            "ends there; wait for it, or choose another --out")


def _new_lock(folder: Path, info: dict[str, Any]) -> int:
    """Our lock, written whole and flock-ed under its temporary name; its descriptor."""
    tmp = _tmp_name(folder, info["token"])
    fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o644)
    try:
        _flock(fd)  # our own new file: nobody else can hold it
        os.write(fd, json.dumps(info, indent=1).encode())
        os.fsync(fd)
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    return fd


def _direct_lock(path: Path, info: dict[str, Any]) -> int | None:
    """The lock created in place (O_EXCL) where links fail; None when one is there.

    For a moment it is empty: a run that finds it so takes it for a lock
    it cannot read and refuses, never deletes it.
    """
    try:
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o644)
    except FileExistsError:
        return None
    _flock(fd)
    os.write(fd, json.dumps(info, indent=1).encode())
    os.fsync(fd)
    return fd


def _take_stale(path: Path, fd: int, folder: Path,
                info: dict[str, Any]) -> tuple[int, int, dict[str, Any]] | None:
    """Take over the lock at ``path`` if its run is dead; None when it vanished meanwhile.

    ``fd`` is our own lock, written but not in place.  Returns the
    descriptor of the dead lock (kept flock-ed until we release, so no
    third run can take it over from under us), the descriptor of ours (now
    in place) and the dead lock's content.
    """
    try:
        old = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return None
    locked = _flock(old)
    if not locked:
        if not _same_file(path, old):  # the live lock we opened was replaced: look again
            os.close(old)
            return None
        dead = _read(old)
        os.close(old)
        os.close(fd)
        with suppress(FileNotFoundError):
            os.unlink(_tmp_name(folder, info["token"]))
        who = f"process {dead.get('pid', '?')}"
        if dead.get("command"):
            who += f" ({dead['command']})"
        hint = "" if locked is False else (
            f" (this file system cannot tell a live run from a dead one: if no servoid runs "
            f"there, delete {path})")
        raise OutputExistsError(
            f"{folder} is in use by another servoid run ({who}); one run owns a folder at a "
            f"time: wait for it to end, or choose another --out{hint}")
    if not _same_file(path, old):  # replaced or removed since we opened it
        os.close(old)
        return None
    dead = _read(old)
    info["files"] = sorted(str(n) for n in dead.get("files", ()) if isinstance(n, str))
    if dead.get("servoid_lock") != 1:  # not a lock servoid wrote: never ours to delete
        os.close(old)
        os.close(fd)
        with suppress(FileNotFoundError):
            os.unlink(_tmp_name(folder, info["token"]))
        raise OutputExistsError(
            f"{path} is there and is not a lock servoid wrote, so servoid cannot tell whether "
            f"another run owns {folder}: if no servoid runs there, delete {path}; or choose "
            "another --out")
    # ours replaces it: the dead lock's inode stays flock-ed by us until we release
    tmp = _tmp_name(folder, info["token"])
    os.close(fd)
    fd = _new_lock(folder, info)
    os.replace(tmp, path)
    return old, fd, dead


def _flock(fd: int) -> bool | None:
    """Take the exclusive flock of ``fd`` without waiting: True, False (held), None (no flock)."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # a file system without flock (some network mounts)
        return None
    return True


def _same_file(path: Path, fd: int) -> bool:
    try:
        now, held = os.stat(path), os.fstat(fd)
    except FileNotFoundError:
        return False
    return (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino)


def _read(fd: int) -> dict[str, Any]:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        chunks = []
        while chunk := os.read(fd, 65536):
            chunks.append(chunk)
            if sum(map(len, chunks)) > 4 << 20:
                return {}
        data = json.loads(b"".join(chunks).decode())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _release(lock: FolderLock) -> None:
    path = lock.folder / LOCK
    with suppress(OSError):
        if _same_file(path, lock._fd):
            os.unlink(path)
    os.close(lock._fd)
    for fd in lock._old_fds:
        os.close(fd)
    for folder in reversed(lock.made):
        with suppress(OSError):
            folder.rmdir()  # only an empty folder goes


def _sweep(folder: Path, dead: dict[str, Any]) -> None:
    """Delete the temporary files a dead run named with its token (and its lock's)."""
    token = dead.get("token")
    if not isinstance(token, str) or not re.fullmatch(r"[0-9a-f]{16}", token):
        return
    mark = re.compile(rf"^\..*\.{token}\.[0-9]+\.tmp$|^\.servoid\.lock\.{token}\.tmp$")
    subs = [s for s in dead.get("folders", ["."]) if isinstance(s, str)]
    for sub in subs:
        where = (folder / sub)
        if ".." in Path(sub).parts or Path(sub).is_absolute() or not where.is_dir():
            continue
        for path in where.iterdir():
            if mark.match(path.name) and path.is_file() and not path.is_symlink():
                path.unlink(missing_ok=True)


def _tmp_name(folder: Path, token: str) -> Path:
    return folder / f"{LOCK}.{token}.tmp"


def _missing_folders(folder: Path) -> list[Path]:
    missing = []
    for path in (folder, *folder.parents):
        if path.exists():
            break
        missing.append(path)
    return missing[::-1]


def _relative(folder: Path, path: Path) -> str:
    try:
        return path.resolve().relative_to(folder.resolve()).as_posix()
    except ValueError:
        return str(path.resolve())
