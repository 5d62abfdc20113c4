"""Progress on stderr, so that no command is silent for more than about 2 s.

Three forms, all silent until :func:`configure` switches them on (the
command line does; the Python API stays silent):

- :func:`stage` names a step ("fitting the one-step model … 0:07");
- :class:`Progress` counts the items of a batch (a bar, counts, an ETA);
- :func:`notice` queues a line (a warning the command line shows while the
  run goes on, instead of after its results).

The rule: once the output has been quiet for 2 s, the innermost running
stage is shown; a step that starts and ends within 2 s of other output says
nothing.  The command line wraps each command in a stage of its own name, so
its start-up (loading the numerical libraries) is covered too.

On a terminal: one line redrawn in place each second; a stage opened inside
a showing one takes the line over after half a second, and the outer one
comes back when it ends.  On a pipe or a file (CI, ``| tee``): plain lines,
no carriage returns — one when a stage is first shown, one every 2 s while
it runs (a log then shows that the run is alive, and where it is) and one
when it ends, if it ran 2 s or more.

One background thread draws while a stage is open; every write goes
through one lock, so a stage line, a batch bar and a notice never tear one
another.  Tests drive :func:`_tick` with a fake clock (:func:`_now`) instead
of the thread.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO

__all__ = ["Progress", "configure", "is_verbose", "notice", "stage", "take_notices",
           "watch_compiles"]

_WIDTH = 24
_MIN_INTERVAL = 0.2  # s between redraws of a batch bar on a terminal
_LINE_INTERVAL = 2.0  # s between plain lines of a batch
_STAGE_DELAY = 2.0  # s of quiet output after which the running stage is shown
_SWITCH = 0.5  # s an inner stage runs before it takes a showing terminal line over
_REDRAW = 1.0  # s between redraws of a stage's terminal line
_EVERY = 2.0  # s between plain lines of a running stage
_NOTICE_DELAY = 1.0  # s a notice waits (a run that ends at once prints it with its results)
_TICK = 0.1  # s between looks of the background thread


def _now() -> float:
    return time.monotonic()


def _clock(seconds: float) -> str:
    seconds = max(int(seconds), 0)  # a running clock: 0:00 during the first second
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def live_stream(stream: Any) -> bool:
    """True for a terminal, a pipe or a file; False for an in-memory buffer (a test's capture)."""
    try:
        if stream.isatty():
            return True
        stream.fileno()
    except (AttributeError, OSError, ValueError):
        return False
    return True


# -- shared state ----------------------------------------------------------------------------
class _State:
    def __init__(self) -> None:
        self.enabled = False
        self.verbose = False
        self.stream: TextIO | None = None
        self.tty = False
        self.quiet_since = 0.0  # the last output that told the user something
        self.line: object | None = None  # who owns an unfinished terminal line
        self.ticker: threading.Thread | None = None
        self.notices: list[tuple[float, str]] = []
        self.watching = False


class _Stage:
    __slots__ = ("label", "shown", "start", "told")

    def __init__(self, label: str, start: float) -> None:
        self.label, self.start = label, start
        self.shown = False
        self.told = start  # when its line was last written


_S = _State()
_OPEN: list[_Stage] = []  # the stages now running, innermost last
_LOCK = threading.RLock()


def configure(enabled: bool, stream: TextIO | None = None, *, verbose: bool = False) -> None:
    """Switch the output on or off (the command line does at each command).

    Parameters
    ----------
    enabled : bool
        Show stages, default-enabled batch bars and notices.
    stream : file, optional
        Where; default ``sys.stderr`` now.  A terminal gets a redrawn line,
        anything else plain lines.
    verbose : bool
        ``-v``: other libraries' logging and warnings are shown
        (:func:`is_verbose`).
    """
    with _LOCK:
        _S.enabled, _S.verbose = bool(enabled), bool(verbose)
        _S.stream = stream if stream is not None else sys.stderr
        _S.tty = bool(getattr(_S.stream, "isatty", lambda: False)())
        _S.quiet_since = _now()
        _S.line = None
        _S.notices = []


def is_verbose() -> bool:
    """True when the command line was given ``-v``/``--verbose``."""
    return _S.verbose


@contextmanager
def stage(label: str) -> Iterator[None]:
    """Name a step: ``servoid: <label> … 0:12`` on stderr while it runs, when it runs long.

    Off unless :func:`configure` switched it on.  Shown once the output has
    been quiet for 2 s (see the module's docstring); a stage opened inside
    another takes the line over while it runs.
    """
    if not _S.enabled:
        yield
        return
    with _LOCK:
        me = _Stage(label, _now())
        _OPEN.append(me)
        _start_ticker()
    ok = False
    try:
        yield
        ok = True
    finally:
        _close(me, _now(), ok)


def notice(text: str) -> None:
    """Queue a line to show while the run goes on (after 1 s, unless the run ended first)."""
    if not _S.enabled:
        return
    with _LOCK:
        _S.notices.append((_now(), text))
        _start_ticker()


def take_notices() -> list[str]:
    """The queued lines not shown yet, now removed from the queue."""
    with _LOCK:
        texts = [text for _, text in _S.notices]
        _S.notices = []
    return texts


class Progress:
    """Count done and failed items of `total` and show it.

    Parameters
    ----------
    total : int
        Items to do.
    label : str
        What is being done ("identifying").
    stream : file, optional
        Default: where :func:`configure` points, else ``sys.stderr``.
    enabled : bool, optional
        False prints nothing; default: as :func:`configure` set it (on at
        the command line, off in the API).
    failures : bool
        Count failed items (False: a batch whose items cannot fail).
    """

    def __init__(self, total: int, label: str, *, stream: TextIO | None = None,
                 enabled: bool | None = None, failures: bool = True) -> None:
        self.total, self.label = max(int(total), 0), label
        self.failures = failures
        if stream is None:
            stream = _S.stream if _S.stream is not None else sys.stderr
        self.stream = stream
        self.enabled = _S.enabled if enabled is None else bool(enabled)
        self.tty = self.enabled and bool(getattr(self.stream, "isatty", lambda: False)())
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
        parts = [f"{self.label} {self.done}/{self.total}",
                 *([f"{self.failed} failed"] if self.failures else []), f"{remaining} remaining"]
        if self.skipped:
            parts.insert(1, f"{self.skipped} unchanged")
        parts.append(f"elapsed {_clock(elapsed)}")
        if remaining and run:
            parts.append(f"ETA {_clock(eta)}")
        return ", ".join(parts)

    def close(self) -> None:
        """End the line on a terminal."""
        with _LOCK:
            if self.tty and self._drawn >= 0:
                self.stream.write("\n")
                self.stream.flush()
                self._drawn = -1.0
                if _S.line is self:
                    _S.line = None

    def _show(self, final: bool) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        with _LOCK:
            shared = self.stream is _S.stream and _S.enabled
            if self.tty:
                if not final and now - self._drawn < _MIN_INTERVAL:
                    return
                filled = int(_WIDTH * self.done / self.total) if self.total else _WIDTH
                bar = "#" * filled + "." * (_WIDTH - filled)
                self.stream.write(f"\r[{bar}] {self.text()}\x1b[K")
                self.stream.flush()
                self._drawn = now
                if shared:
                    _S.line, _S.quiet_since = self, _now()
                if final:
                    self.close()
                return
            step = int(10 * self.done / self.total) if self.total else 10
            if final or (step > self._line_step and now - self._line_at >= _LINE_INTERVAL):
                self.stream.write(self.text() + "\n")
                self.stream.flush()
                self._line_step, self._line_at = step, now
                if shared:
                    _S.line, _S.quiet_since = (None if final else self), _now()


def watch_compiles() -> None:
    """Name numba's first-use compilations in a stage line (once installed).

    numba loads a kernel from its on-disk cache without compiling; only a
    real compilation (a fresh install, a changed kernel, a user's model
    file) raises the event this listens to, so the line appears when one
    lasts.
    """
    if not _S.enabled or _S.watching:
        return
    from numba.core import event

    class _Compiles(event.Listener):  # type: ignore[misc]
        def __init__(self) -> None:
            self.depth = 0
            self.open: Any = None

        def on_start(self, ev: Any) -> None:
            self.depth += 1
            if self.depth == 1:
                dispatcher = ev.data.get("dispatcher")
                func = getattr(dispatcher, "py_func", None)
                where = getattr(func, "__module__", "") or ""
                name = f"{where.rsplit('.', 1)[-1].lstrip('_')}.{getattr(func, '__name__', '?')}"
                cached = type(getattr(dispatcher, "_cache", None)).__name__ not in ("NullCache",
                                                                                   "NoneType")
                self.open = stage(f"compiling {name}"
                                  + (" (first use; cached for later runs)" if cached else ""))
                self.open.__enter__()

        def on_end(self, ev: Any) -> None:
            self.depth -= 1
            if self.depth == 0 and self.open is not None:
                failed = (RuntimeError, RuntimeError("numba could not compile it"), None)
                self.open.__exit__(*(failed if ev.is_failed else (None, None, None)))
                self.open = None

    event.register("numba:compile", _Compiles())
    _S.watching = True


# -- drawing ---------------------------------------------------------------------------------
def _start_ticker() -> None:
    """Start the background thread unless it runs (called under the lock)."""
    if _S.ticker is not None and _S.ticker.is_alive():
        return
    _S.ticker = threading.Thread(target=_run_ticker, name="servoid-progress", daemon=True)
    _S.ticker.start()


def _run_ticker() -> None:
    while True:
        time.sleep(_TICK)
        with _LOCK:
            if (not _OPEN and not _S.notices) or not _S.enabled:
                _S.ticker = None
                return
            _tick(_now())


def _tick(now: float) -> None:
    """Show what is due at time ``now``: notices, then the running stage."""
    with _LOCK:
        if not _S.enabled:
            return
        while _S.notices and now - _S.notices[0][0] >= _NOTICE_DELAY:
            _, text = _S.notices.pop(0)
            _write(None, text, now, final=True)
        # a batch that moves speaks for itself: of the stages, only one opened since it spoke
        held = isinstance(_S.line, Progress) and \
            now - _S.quiet_since < _STAGE_DELAY
        target = _target(now, after=_S.quiet_since if held else None)
        if target is None:
            return
        if _S.tty:
            if _S.line is target and now - target.told < _REDRAW:
                return
        elif target.shown and now - max(target.told, _S.quiet_since) < _EVERY:
            return
        _write(target, f"servoid: {target.label} … {_clock(now - target.start)}", now,
               final=not _S.tty)
        target.shown, target.told = True, now


def _target(now: float, after: float | None = None) -> _Stage | None:
    """The innermost stage that is showing or due to be shown (opened ``after``, if given)."""
    for st in reversed(_OPEN):
        if after is not None:
            if st.start <= after:
                return None
            if now - st.start >= _SWITCH:
                return st
        elif st.shown or now - st.start >= _STAGE_DELAY or \
                now - _S.quiet_since >= _STAGE_DELAY:
            return st
        elif _S.tty and isinstance(_S.line, _Stage) and now - st.start >= _SWITCH:
            return st
    return None


def _close(me: _Stage, now: float, ok: bool) -> None:
    with _LOCK:
        if me in _OPEN:
            _OPEN.remove(me)
        if not _S.enabled:
            return
        if me.shown and now - me.start >= _STAGE_DELAY:
            end = "done in" if ok else "stopped after"
            _write(me, f"servoid: {me.label} {end} {_clock(now - me.start)}", now, final=True)
        elif _S.line is me:  # shown briefly: clear it; an outer stage takes the line back
            _S.stream.write("\r\x1b[K")  # type: ignore[union-attr]
            _S.stream.flush()  # type: ignore[union-attr]
            _S.line = None


def _write(owner: object | None, text: str, now: float, *, final: bool) -> None:
    """Write a line (``final``: a whole line; else a terminal line to redraw), under the lock."""
    stream = _S.stream
    assert stream is not None
    if _S.tty:
        if _S.line is not None and _S.line is not owner and not isinstance(_S.line, _Stage):
            stream.write("\n")  # a batch bar keeps its line
        stream.write(f"\r{text}\x1b[K" + ("\n" if final else ""))
        _S.line = None if final else owner
    else:
        stream.write(text + "\n")
    stream.flush()
    _S.quiet_since = now
