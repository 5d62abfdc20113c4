"""Progress on stderr for work that takes more than a couple of seconds.

Two forms: :class:`Progress` counts items of a batch; :func:`stage` shows
one step ("fitting the one-step model … 0:07") once it has run 2 s.

On a terminal: one line redrawn in place (a bar, counts, elapsed time and
an ETA).  When stderr is not a terminal: a plain line now and then (every
tenth of the work, at most every few seconds).  ``enabled=False`` (under
``--json`` or ``--quiet``) prints nothing.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO

__all__ = ["Progress", "configure", "stage", "watch_compiles"]

_WIDTH = 24
_MIN_INTERVAL = 0.2  # s between redraws on a terminal
_LINE_INTERVAL = 5.0  # s between plain lines


def _clock(seconds: float) -> str:
    seconds = max(round(seconds), 0)
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """Count done and failed items of `total` and show it.

    Parameters
    ----------
    total : int
        Items to do.
    label : str
        What is being done ("identifying").
    stream : file, optional
        Default ``sys.stderr``.
    enabled : bool
        False prints nothing.
    """

    def __init__(self, total: int, label: str, *, stream: TextIO | None = None,
                 enabled: bool = True) -> None:
        self.total, self.label = max(int(total), 0), label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = enabled and bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = self.failed = self.skipped = 0
        self._start = time.monotonic()
        self._drawn = -1.0
        self._line_at = 0.0
        self._line_step = -1

    def update(self, *, ok: bool = True, skipped: bool = False) -> None:
        """One more item finished (``ok=False``: it failed; ``skipped``: reused)."""
        self.done += 1
        self.failed += not ok
        self.skipped += skipped
        self._show(final=self.done >= self.total)

    def text(self) -> str:
        """The current state in words."""
        elapsed = time.monotonic() - self._start
        remaining = self.total - self.done
        run = self.done - self.skipped
        eta = elapsed / run * remaining if run and remaining else 0.0
        parts = [f"{self.label} {self.done}/{self.total}", f"{self.failed} failed",
                 f"{remaining} remaining"]
        if self.skipped:
            parts.insert(1, f"{self.skipped} unchanged")
        parts.append(f"elapsed {_clock(elapsed)}")
        if remaining and run:
            parts.append(f"ETA {_clock(eta)}")
        return ", ".join(parts)

    def close(self) -> None:
        """End the line on a terminal."""
        if self.tty and self._drawn >= 0:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = -1.0

    def _show(self, final: bool) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if self.tty:
            if not final and now - self._drawn < _MIN_INTERVAL:
                return
            filled = int(_WIDTH * self.done / self.total) if self.total else _WIDTH
            bar = "#" * filled + "." * (_WIDTH - filled)
            self.stream.write(f"\r[{bar}] {self.text()}\x1b[K")
            self.stream.flush()
            self._drawn = now
            if final:
                self.close()
            return
        step = int(10 * self.done / self.total) if self.total else 10
        if final or (step > self._line_step and now - self._line_at >= _LINE_INTERVAL):
            self.stream.write(self.text() + "\n")
            self.stream.flush()
            self._line_step, self._line_at = step, now


# -- stage lines -----------------------------------------------------------------------------
_STAGES: dict[str, Any] = {"enabled": False, "stream": None}
_OPEN: list[object] = []  # the stages now running, innermost last
_LOCK = threading.Lock()
_STAGE_DELAY = 2.0  # s: a stage shorter than this prints nothing


def configure(enabled: bool, stream: TextIO | None = None) -> None:
    """Switch stage lines on (the command line does, on a terminal without --json/--quiet)."""
    _STAGES["enabled"], _STAGES["stream"] = enabled, stream


@contextmanager
def stage(label: str) -> Iterator[None]:
    """Show ``servoid: <label> … 12 s`` on stderr while a step longer than 2 s runs.

    Off unless :func:`configure` switched it on (the API stays silent); the
    line is redrawn each second by a background thread and cleared at the end.
    A stage opened inside another (a compilation inside a simulation) takes
    the line over until it ends.
    """
    if not _STAGES["enabled"]:
        yield
        return
    stream = _STAGES["stream"] or sys.stderr
    done = threading.Event()
    start = time.monotonic()
    me = object()
    _OPEN.append(me)

    def tick() -> None:
        shown = False
        while not done.wait(_STAGE_DELAY if not shown else 1.0):
            if _OPEN and _OPEN[-1] is not me:  # an inner stage has the line
                continue
            with _LOCK:
                stream.write(f"\rservoid: {label} … {_clock(time.monotonic() - start)}\x1b[K")
                stream.flush()
            shown = True
        if shown:
            with _LOCK:
                stream.write(f"\rservoid: {label} … done in "
                             f"{_clock(time.monotonic() - start)}\x1b[K\n")
                stream.flush()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        _OPEN.remove(me)


def watch_compiles() -> None:
    """Name numba's first-use compilations in a stage line (once installed).

    numba loads a kernel from its on-disk cache without compiling; only a
    real compilation (a fresh install, a changed kernel) raises the event
    this listens to, so the line appears once per install, when it lasts.
    """
    if not _STAGES["enabled"] or _STAGES.get("watching"):
        return
    from numba.core import event

    class _Compiles(event.Listener):  # type: ignore[misc]
        def __init__(self) -> None:
            self.depth = 0
            self.open: Any = None

        def on_start(self, ev: Any) -> None:
            self.depth += 1
            if self.depth == 1:
                func = getattr(ev.data.get("dispatcher"), "py_func", None)
                where = getattr(func, "__module__", "") or ""
                name = f"{where.rsplit('.', 1)[-1].lstrip('_')}.{getattr(func, '__name__', '?')}"
                self.open = stage(f"compiling {name} (first use; cached for later runs)")
                self.open.__enter__()

        def on_end(self, ev: Any) -> None:
            self.depth -= 1
            if self.depth == 0 and self.open is not None:
                self.open.__exit__(None, None, None)
                self.open = None

    event.register("numba:compile", _Compiles())
    _STAGES["watching"] = True
