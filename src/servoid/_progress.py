"""Progress on stderr for work that takes more than a couple of seconds.

On a terminal: one line redrawn in place (a bar, counts, elapsed time and
an ETA).  When stderr is not a terminal: a plain line now and then (every
tenth of the work, at most every few seconds).  ``enabled=False`` (under
``--json`` or ``--quiet``) prints nothing.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["Progress"]

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
