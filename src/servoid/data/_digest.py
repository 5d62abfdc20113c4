"""SHA-256 of an input file, computed once while the file is unchanged.

A run names its inputs by their SHA-256 in several places (``results.json``,
the report's provenance, ``manifest.json``, a fleet's record key); each
asks :func:`file_sha256`, which reads the file once and answers again from
memory while the file's identity — device, inode, size, modification and
change times — is the one it hashed.

A file modified within :data:`_RACY` seconds before it was hashed is not
remembered: a second write within the file system's timestamp resolution
(up to 2 s on FAT) could leave every one of those fields as they were, the
"racy" case git's index guards against the same way.  Such a file is hashed
again on every call, which costs time, never a wrong digest.
"""

from __future__ import annotations

import hashlib
import os
import threading
import time
from collections import OrderedDict

from .._files import check_path, open_input

__all__ = ["file_sha256", "file_status"]

#: Seconds a file must have been left alone before its digest is remembered.
_RACY = 3.0
#: Digests remembered (the least recently used go first).
_SIZE = 256
_BLOCK = 1 << 20

_Key = tuple[int, int, int, int, int]
_MEMO: OrderedDict[_Key, str] = OrderedDict()
_LOCK = threading.Lock()


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file, hex; read once while it is unchanged.

    Parameters
    ----------
    path : path-like
        A regular file (a folder, pipe or device is refused unread).

    Returns
    -------
    str
        64 hexadecimal digits.

    Raises
    ------
    MissingFileError
        Nothing at the path.
    FileFormatError
        Not a regular file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     p = pathlib.Path(tmp) / "x.csv"
    ...     _ = p.write_text("time,u\\n")
    ...     file_sha256(p)[:16]
    'bd0e5dbc22156152'
    """
    return file_status(path)[0]


def file_status(path: str | os.PathLike[str]) -> tuple[str, os.stat_result]:
    """The SHA-256 of a file (see :func:`file_sha256`) and the status it belongs to."""
    path = check_path(path)
    try:
        st = os.stat(path)
    except OSError:
        st = None  # open_input names what is wrong
    if st is not None:
        with _LOCK:
            digest = _MEMO.get(_key(st))
            if digest is not None:
                _MEMO.move_to_end(_key(st))
                return digest, st
    started = time.time_ns()
    h = hashlib.sha256()
    with open_input(path) as f:
        st = os.fstat(f.fileno())
        while block := f.read(_BLOCK):
            h.update(block)
    digest = h.hexdigest()
    if started - max(st.st_mtime_ns, st.st_ctime_ns) > _RACY * 1e9:
        with _LOCK:
            _MEMO[_key(st)] = digest
            while len(_MEMO) > _SIZE:
                _MEMO.popitem(last=False)
    return digest, st


def _key(st: os.stat_result) -> _Key:
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _forget() -> None:
    """Drop every remembered digest (tests)."""
    with _LOCK:
        _MEMO.clear()


def _same_file(a: os.stat_result, b: os.stat_result) -> bool:
    """True when two statuses are of one file with the same content (size and mtime)."""
    return (a.st_dev, a.st_ino, a.st_size, a.st_mtime_ns) == \
        (b.st_dev, b.st_ino, b.st_size, b.st_mtime_ns)
