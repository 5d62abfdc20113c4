"""A fleet reads regular files only, and says so by name before it reads anything.

Opening a named pipe (FIFO) waits for a writer, a device such as
``/dev/zero`` never ends, and a symbolic-link loop cannot be opened: any
of them as one record's file would stall the whole fleet before its first
record runs, while the inputs are hashed.  :func:`file_problem` tells
what a path is without opening it; :func:`open_regular` opens without
waiting (``O_NONBLOCK``) and checks the opened file again, so a file
replaced by a pipe in between is refused too.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from .._errors import DataError

__all__ = ["REGULAR_ONLY", "file_problem", "open_regular"]

REGULAR_ONLY = "servoid reads regular files only: copy the data into a file and name that"


def file_problem(path: Path) -> str | None:
    """What keeps `path` from being read as a regular file, in words; None when nothing does."""
    try:
        mode = os.stat(path).st_mode
    except ValueError:
        return "is not a usable file name (it holds a NUL character)"
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "is a loop of symbolic links"
        if exc.errno == errno.ENOENT:
            return "is a link to a missing file" if os.path.islink(path) else "does not exist"
        return f"cannot be read ({exc.strerror or exc})"
    return _kind(mode)


@contextmanager
def open_regular(path: Path) -> Iterator[BinaryIO]:
    """Open a regular file for reading, never waiting on a pipe or a device."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        problem = _kind(os.fstat(fd).st_mode)
        if problem is not None:
            raise DataError(f"{path} {problem}; {REGULAR_ONLY}")
        file = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with file:
        yield file


def _kind(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder, not a file"
    if stat.S_ISFIFO(mode):
        return "is a named pipe (FIFO), not a file: reading it would wait for a writer"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "is a device, not a file"
    if stat.S_ISSOCK(mode):
        return "is a socket, not a file"
    return "is not a regular file"
