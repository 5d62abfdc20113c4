"""Which words a message uses for an option: the API's or the command line's.

The API and the ``servoid`` command share every check, so a message that tells
the user what to pass names the option as the caller passes it:
``overwrite=True`` from Python, ``--overwrite`` on the command line. The
command line runs each command inside :func:`command_line_words`; everything
else speaks the API.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["command_line_words", "option"]

_COMMAND_LINE: ContextVar[bool] = ContextVar("servoid_command_line_words", default=False)


@contextmanager
def command_line_words() -> Iterator[None]:
    """Let messages raised inside name options by their command-line flags."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def option(api: str, flag: str) -> str:
    """``flag`` (e.g. ``"--overwrite"``) on the command line, else ``api`` (``"overwrite=True"``)."""
    return flag if _COMMAND_LINE.get() else api
