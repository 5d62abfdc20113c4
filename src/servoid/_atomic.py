"""Atomic file output: write to a temporary file, then rename into place.

A temporary file is named ``.<target>.<random>.tmp``.  In a folder this
process owns (:func:`servoid._lock.hold_folder`) the random part is the
run's token, recorded in the folder's lock, followed by a counter: a later
run that finds the lock of a dead run deletes exactly those files.  Nothing
is ever deleted because its name merely looks like a temporary file.
"""

from __future__ import annotations

import itertools
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ._errors import MissingFileError, OutputExistsError
from ._lock import temporary_token
from ._words import option

__all__ = ["atomic_path", "check_writable"]

_COUNTER = itertools.count()


def check_writable(path: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Refuse an existing ``path`` unless ``overwrite``; return it as a Path."""
    path = Path(path)
    if path.is_dir():  # first: overwriting would not help
        raise OutputExistsError(f"{path} is a directory, not a file; name a file (inside it, "
                                "or elsewhere)")
    if path.exists() and not overwrite:
        raise OutputExistsError(
            f"{path} already exists; choose another name or pass "
            f"{option('overwrite=True', '--overwrite')}"
        )
    return path


@contextmanager
def atomic_path(path: str | os.PathLike[str], overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it onto ``path`` on success.

    A failure leaves no partial file behind and the old ``path`` (if any)
    untouched. The parent folder must exist: a mistyped folder is an error,
    not a new directory. Without ``overwrite`` the final step is a hard link,
    which fails if ``path`` appeared meanwhile, so nothing is ever replaced.
    """
    target = check_writable(path, overwrite)
    if not target.parent.is_dir():
        raise MissingFileError(
            f"cannot write {target}: the folder {target.parent} does not exist; create it first"
        )
    token = temporary_token(target.parent)
    mark = secrets.token_hex(8) if token is None else f"{token}.{next(_COUNTER)}"
    tmp = target.parent / f".{target.name}.{mark}.tmp"
    # O_EXCL: never reuse a name; mode 0666 lets the kernel apply the user's umask.
    os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
    try:
        yield tmp
        if overwrite:
            os.replace(tmp, target)
        else:
            _move_no_replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()


def _move_no_replace(tmp: Path, target: Path) -> None:
    try:
        os.link(tmp, target)
    except FileExistsError:
        raise OutputExistsError(f"{target} appeared while writing; not overwritten") from None
    except OSError:  # a file system without hard links: check, then rename
        if target.exists():
            raise OutputExistsError(f"{target} appeared while writing; not overwritten") from None
        os.replace(tmp, target)
