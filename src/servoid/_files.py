"""Opening a file a user named: checked before it is read, bounded while read.

Every input servoid reads (rig files, experiment files, results and model
files) may be anything a path can name: a named pipe whose ``open`` blocks
until a writer comes, a link to ``/dev/zero`` that never ends, a symbolic
link loop, a name holding a NUL byte, a file larger than the memory budget
or one that is still growing. So an input is

* **checked before it is read:** the path must name a regular file (a
  folder, FIFO, device or socket is refused by name, a symbolic link loop
  or a dangling link too) no larger than the caller's budget;
* **opened without blocking** (``O_NONBLOCK``: a FIFO swapped in after the
  check cannot hang ``open``) and checked again on the opened descriptor,
  so what is read is what was checked;
* **bounded while read:** the file object returned never reads past the
  size the check saw, so a file that grows (a logger still writing, a
  ``/proc`` file) costs no more than it did when it was checked.

:func:`check_input_file` only checks (for a path a library opens by name);
:func:`open_input` checks and opens (to stream a large file);
:func:`read_input_bytes` and :func:`read_input_text` read a whole small
file (an experiment, results, model or fleet file) within a budget, the
text decoded as UTF-8 with a message naming any other encoding it finds.
Code that hashes a file and then uses it should hash and use the same
bytes, from one :func:`read_input_bytes`.
"""

from __future__ import annotations

import errno
import io
import os
import stat
from pathlib import Path
from typing import Any

from ._errors import DataError, FileFormatError, MissingFileError, OptionTypeError

__all__ = [
    "TEXT_MAX_BYTES",
    "BoundedFile",
    "check_input_file",
    "check_path",
    "describe_encoding",
    "format_bytes",
    "open_input",
    "read_input_bytes",
    "read_input_text",
]

#: Budget of a text input servoid reads whole (experiment, results or model file) [bytes].
TEXT_MAX_BYTES = 64 * 2**20

_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)

# Byte-order marks, longest first (UTF-32 LE starts with the UTF-16 LE mark).
_BOMS = (
    (b"\xff\xfe\x00\x00", "UTF-32 (little-endian)"),
    (b"\x00\x00\xfe\xff", "UTF-32 (big-endian)"),
    (b"\xff\xfe", "UTF-16 (little-endian)"),
    (b"\xfe\xff", "UTF-16 (big-endian)"),
)


_CODECS = {"UTF-32 (little-endian)": "utf-32-le", "UTF-32 (big-endian)": "utf-32-be",
           "UTF-16 (little-endian)": "utf-16-le", "UTF-16 (big-endian)": "utf-16-be"}


def format_bytes(n: int) -> str:
    """A byte count for a message: ``"74.5 GiB"``, ``"8 bytes"``."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


def check_path(path: object, what: str = "file") -> Path:
    """``path`` as a Path, refusing a wrong type, an empty string or a NUL byte.

    Parameters
    ----------
    path : str or path-like
        The path as the user gave it.
    what : str
        What the file is, for messages (``"data file"``).

    Returns
    -------
    pathlib.Path
        The path.

    Raises
    ------
    OptionTypeError
        Not a str or path-like.
    DataError
        An empty path, or one holding a NUL byte (no file name can).
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise OptionTypeError(f"the {what} must be a file path (str or pathlib.Path), got "
                              f"{path!r} ({type(path).__name__})")
    text = os.fspath(path)
    if isinstance(text, bytes):
        raise OptionTypeError(f"the {what} must be a file path (str or pathlib.Path), got "
                              f"{path!r} ({type(path).__name__})")
    if not text.strip():
        raise DataError(f"the {what} must be a file path, got an empty string")
    if "\0" in text:
        raise DataError(
            f"the {what} {text!r} holds a NUL byte ('\\x00' at character {text.index(chr(0))}), "
            "which no file name can contain: check how the path was written (an escape "
            "sequence such as \\u0000 in a TOML string, or a generated name)"
        )
    return Path(text)


def check_input_file(path: object, what: str = "file", *,
                     max_bytes: int | None = None) -> os.stat_result:
    """Check that ``path`` names a regular file within the budget, unread.

    Parameters
    ----------
    path : str or path-like
        The file.
    what : str
        What the file is, for messages (``"data file"``, ``"results file"``).
    max_bytes : int, optional
        Largest size accepted [bytes]; None: any size.

    Returns
    -------
    os.stat_result
        The file's status (symbolic links followed).

    Raises
    ------
    MissingFileError
        Nothing at the path, a dangling symbolic link, or a part of the path
        that is a file rather than a folder.
    FileFormatError
        A folder, named pipe, device or socket, a symbolic link loop, or a
        name too long for the file system.
    DataError
        The file is larger than ``max_bytes``, a NUL byte in the path.
    """
    path = check_path(path, what)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _stat_error(path, what, exc) from None
    _check_status(path, what, st, max_bytes)
    return st


def open_input(path: object, what: str = "file", *,
               max_bytes: int | None = None) -> BoundedFile:
    """Open a regular file for binary reading, checked and bounded.

    The file is opened without blocking and its descriptor checked as
    :func:`check_input_file` checks a path; reads stop at the size seen
    then. Use it as a context manager.

    Parameters
    ----------
    path : str or path-like
        The file.
    what : str
        What the file is, for messages.
    max_bytes : int, optional
        Largest size accepted [bytes]; None: any size.

    Returns
    -------
    BoundedFile
        A buffered binary file; ``size`` is the size checked.
    """
    path = check_path(path, what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | \
        getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    try:
        st = os.stat(path)  # first: a FIFO is refused by name before it is opened
        _check_status(path, what, st, max_bytes)
        fd = os.open(path, flags)
    except OSError as exc:
        raise _stat_error(path, what, exc) from None
    try:
        st = os.fstat(fd)  # what was opened, if the path changed since
        _check_status(path, what, st, max_bytes)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return BoundedFile(io.FileIO(fd, "rb", closefd=True), st.st_size, str(path))


def read_input_bytes(path: object, what: str = "file", *,
                     max_bytes: int = TEXT_MAX_BYTES) -> bytes:
    """The whole content of a small input file, checked and bounded.

    Parameters
    ----------
    path : str or path-like
        The file.
    what : str
        What the file is, for messages.
    max_bytes : int
        Largest size accepted [bytes]; default :data:`TEXT_MAX_BYTES`.

    Returns
    -------
    bytes
        At most ``max_bytes`` bytes.
    """
    with open_input(path, what, max_bytes=max_bytes) as f:
        return f.read()


def read_input_text(path: object, what: str = "file", *,
                    max_bytes: int = TEXT_MAX_BYTES) -> str:
    """The whole content of a small UTF-8 text file, checked and bounded.

    A UTF-8 byte-order mark is dropped. Text in another encoding (UTF-16
    or UTF-32, told by its byte-order mark or its NUL bytes) or bytes that
    are not text raise a :class:`FileFormatError` naming the encoding and
    the fix.

    Parameters
    ----------
    path : str or path-like
        The file.
    what : str
        What the file is, for messages (``"experiment file"``).
    max_bytes : int
        Largest size accepted [bytes]; default :data:`TEXT_MAX_BYTES`.

    Returns
    -------
    str
        The text.
    """
    data = read_input_bytes(path, what, max_bytes=max_bytes)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        found = describe_encoding(data[:4096])
        if found:
            raise FileFormatError(f"{what} {path}: {found}; servoid reads UTF-8 text: save it "
                                  "as UTF-8 (e.g. iconv -t UTF-8)") from None
        raise FileFormatError(f"{what} {path} is not UTF-8 text: {exc.reason} at byte "
                              f"{exc.start}") from None


def describe_encoding(head: bytes) -> str | None:
    """Name a text encoding other than UTF-8 that ``head`` starts in, or None.

    Parameters
    ----------
    head : bytes
        The first bytes of a file (a few hundred are enough).

    Returns
    -------
    str or None
        E.g. ``"UTF-16 (little-endian) text, with a byte-order mark"``;
        None when the head looks like neither UTF-16 nor UTF-32.
    """
    for mark, name in _BOMS:
        if head.startswith(mark):
            if not _looks_like_text(head[len(mark):], _CODECS[name]):
                return None  # a binary file that happens to start like a mark
            return f"{name} text, with a byte-order mark ({mark.hex(' ').upper()})"
    sample = head[: len(head) - len(head) % 4][:1024]
    if len(sample) >= 8:
        # ASCII text in UTF-16 has a NUL in every other byte, in UTF-32 three of four.
        quads = [sample[k:k + 4] for k in range(0, len(sample), 4)]
        if all(q[1:] == b"\0\0\0" and q[0] for q in quads):
            return "UTF-32 (little-endian) text, without a byte-order mark"
        if all(q[:3] == b"\0\0\0" and q[3] for q in quads):
            return "UTF-32 (big-endian) text, without a byte-order mark"
        odd, even = sample[1::2], sample[0::2]
        if odd.count(0) == len(odd) and even.count(0) == 0:
            return "UTF-16 (little-endian) text, without a byte-order mark"
        if even.count(0) == len(even) and odd.count(0) == 0:
            return "UTF-16 (big-endian) text, without a byte-order mark"
    return None


def _looks_like_text(data: bytes, codec: str) -> bool:
    """Whether ``data`` decodes in ``codec`` to mostly printable ASCII (names and numbers)."""
    unit = 4 if "32" in codec else 2
    text = data[: len(data) - len(data) % unit][:2048].decode(codec, errors="replace")
    if not text:
        return True
    printable = sum(c.isascii() and (c.isprintable() or c in "\t\r\n") for c in text)
    return printable >= 0.9 * len(text) and "\ufffd" not in text


class BoundedFile(io.BufferedReader):
    """A buffered binary file that never reads past ``size`` bytes.

    Its raw file ends at the size checked at open (a file that grows while
    it is read ends where it ended when it was checked), and ``read(n)``
    asks for no more than is left, so a declared length read from the file
    allocates at most the file's size (``BufferedReader.read(n)`` allocates
    ``n`` bytes before reading). The other methods are the buffered
    reader's own, in C.

    Parameters
    ----------
    raw : io.FileIO
        The opened file.
    size : int
        Bytes that may be read [bytes].
    name : str
        The path, for messages.
    """

    def __init__(self, raw: io.FileIO, size: int, name: str = "") -> None:
        super().__init__(_BoundedRaw(raw, size), buffer_size=1 << 16)
        self.size = size
        self.path = name

    def read(self, n: int | None = -1) -> bytes:
        if n is not None and n > 0:
            n = min(n, max(0, self.size - self.tell()))
            if n == 0:
                return b""
        return super().read(n)

    def fileno(self) -> int:
        return self.raw.fileno()


class _BoundedRaw(io.RawIOBase):
    """A raw file that reports the end of the file at ``size`` bytes."""

    def __init__(self, raw: io.FileIO, size: int) -> None:
        super().__init__()
        self._raw, self._size = raw, size

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._raw.fileno()

    def tell(self) -> int:
        return self._raw.tell()

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._raw.seek(offset, whence)

    def readinto(self, b: Any) -> int:
        view = memoryview(b).cast("B")
        left = max(0, self._size - self._raw.tell())
        return self._raw.readinto(view[:left]) if left else 0

    def close(self) -> None:
        self._raw.close()
        super().close()


def _check_status(path: Path, what: str, st: os.stat_result, max_bytes: int | None) -> None:
    mode = st.st_mode
    if not stat.S_ISREG(mode):
        kind = next((word for test, word in _KINDS if test(mode)), "not a regular file")
        link = _link_words(path)
        if stat.S_ISDIR(mode):
            raise FileFormatError(f"{what} {path}{link} is a folder, not a regular file; pass "
                                  "the path of a file")
        raise FileFormatError(
            f"{what} {path}{link} is {kind}, not a regular file: servoid reads only regular "
            "files, whose size it can check before reading; save the data to a file and "
            "pass its path"
        )
    if max_bytes is not None and st.st_size > max_bytes:
        raise DataError(
            f"{path} has {st.st_size:,} bytes, over the budget of {max_bytes:,} bytes; if the "
            "file is what you meant to read, pass max_bytes= a larger budget"
        )


def _link_words(path: Path) -> str:
    """`` (a symbolic link to X)`` when ``path`` is a link, else ``""``."""
    try:
        if path.is_symlink():
            return f" (a symbolic link to {os.readlink(path)})"
    except (OSError, ValueError):
        pass
    return ""


def _stat_error(path: Path, what: str, exc: OSError) -> Exception:
    """A clear error for an ``os.stat`` or ``os.open`` of ``path`` that failed."""
    code = exc.errno
    if code == errno.ENOENT:
        link = _link_words(path)
        if link:
            return MissingFileError(f"{what} {path}{link}: no such file at the link's end; fix "
                                    "the link or pass the file itself")
        return MissingFileError(f"{what} {path}: no such file; check the path (relative paths "
                                f"are taken from {Path.cwd()})")
    if code == errno.ELOOP:
        return FileFormatError(f"{what} {path} is a symbolic link that loops (it leads back to "
                               "itself through one or more links): fix the link or pass the "
                               "file itself")
    if code == errno.ENOTDIR:
        return MissingFileError(f"{what} {path}: no such file: a part of the path before the "
                                "file name is a file, not a folder; check the path")
    if code == errno.ENAMETOOLONG:
        return FileFormatError(f"the {what} path is too long for the file system "
                               f"({len(os.fspath(path))} characters, {path!s:.80}…): check "
                               "how it was written")
    if code in (errno.ENXIO, errno.EAGAIN, errno.EWOULDBLOCK):
        return FileFormatError(f"{what} {path} cannot be opened as a regular file ({exc.strerror})")
    return exc  # permission and I/O errors stay OSError: the system's words are the clearest
