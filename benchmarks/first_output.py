"""How long a command stays silent: time to its first output and its longest silence.

Runs a command twice — with its stdout and stderr on a pseudo-terminal (as
in an interactive shell) and on a pipe (as under CI or ``| tee``) — and
prints, for each, the time to the first byte of output, the longest gap
between two outputs (the start and the end of the run count as outputs) and
when it began, the total time and the number of lines.  The interpreter is
this one; ``PYTHONPATH`` and the environment are passed on.  The end of the
run includes the interpreter's exit, which can take a second or more after
the last line (numba, scipy and matplotlib loaded).

Usage::

    python benchmarks/first_output.py -- servoid methods
    python benchmarks/first_output.py --repeat 3 -- \
        servoid identify exp.toml --out /tmp/r --overwrite

``servoid`` as the first word runs ``python -m servoid``.  Linux/macOS only
(the terminal run needs :mod:`pty`).
"""

from __future__ import annotations

import argparse
import os
import select
import subprocess
import sys
import time


def main() -> int:
    """Parse the arguments, run the command on a terminal and on a pipe, print the times."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each kind (default 1)")
    parser.add_argument("--show", action="store_true", help="print the output with timestamps")
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args()
    command = [w for w in args.command if w != "--"] if args.command[:1] == ["--"] else \
        list(args.command)
    if not command:
        parser.error("give a command after --")
    if command[0] == "servoid":
        command = [sys.executable, "-m", "servoid", *command[1:]]
    print(f"{'output':<9} {'first (s)':>9} {'longest silence (s)':>20} {'from (s)':>8} "
          f"{'total (s)':>9} {'lines':>5}")
    for kind in ("terminal", "pipe"):
        for _ in range(args.repeat):
            chunks, total = _run(command, kind == "terminal")
            times = [t for t, _ in chunks]
            first = times[0] if times else total
            ends = list(zip([0.0, *times], [*times, total], strict=True))
            gaps = [b - a for a, b in ends]
            where = ends[gaps.index(max(gaps))][0]
            text = b"".join(c for _, c in chunks).decode(errors="replace")
            lines = text.replace("\r", "\n").count("\n")
            print(f"{kind:<9} {first:>9.2f} {max(gaps):>20.2f} {where:>8.2f} {total:>9.2f} "
                  f"{lines:>5}")
            if args.show:
                for t, chunk in chunks:
                    print(f"  {t:7.2f} {chunk.decode(errors='replace')!r}")
    return 0


def _run(command: list[str], terminal: bool) -> tuple[list[tuple[float, bytes]], float]:
    """Output chunks with their times since the start, and the total time."""
    if terminal:
        import pty

        parent, child = pty.openpty()
        start = time.monotonic()
        proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=child, stderr=child,
                                close_fds=True)
        os.close(child)
        fd = parent
    else:
        start = time.monotonic()
        proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT)
        assert proc.stdout is not None
        fd = proc.stdout.fileno()
    chunks = []
    while True:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if not ready:
            continue
        try:
            data = os.read(fd, 65536)
        except OSError:  # the terminal's other end closed
            data = b""
        if not data:
            break
        chunks.append((time.monotonic() - start, data))
    proc.wait()
    total = time.monotonic() - start
    if terminal:
        os.close(fd)
    return chunks, total


if __name__ == "__main__":
    sys.exit(main())
