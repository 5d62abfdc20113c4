#!/usr/bin/env python3
"""Set up servoid in a local virtual environment and run the demo or the tests.

    python3 dev.py demo      # create .venv, install servoid, run `servoid demo`
    python3 dev.py test      # create .venv, install servoid with test extras, run pytest

Needs only Python >= 3.11 with the standard venv module. Extra arguments
after the command go to `servoid demo` or to pytest. The install is redone
when pyproject.toml changes.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
PYTHON = BIN / ("python.exe" if os.name == "nt" else "python")


def main(argv: list[str]) -> int:
    if sys.version_info < (3, 11):
        print(f"servoid needs Python >= 3.11, this is {sys.version.split()[0]}", file=sys.stderr)
        return 2
    if not argv or argv[0] not in ("demo", "test"):
        print(__doc__, file=sys.stderr)
        return 2
    command, rest = argv[0], argv[1:]
    ensure_environment(extras="" if command == "demo" else "[test]")
    if command == "demo":
        return subprocess.call([str(BIN / "servoid"), "demo", *rest], cwd=ROOT)
    # The suite is thousands of small LAPACK calls: a multi-threaded BLAS only adds thread
    # hand-offs there, ~10x slower on a loaded 2-core machine. One thread unless the caller says.
    env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
    return subprocess.call([str(PYTHON), "-m", "pytest", *rest], cwd=ROOT, env=env)


def ensure_environment(extras: str = "[test]") -> None:
    """Create .venv and (re)install servoid (with `extras`) when pyproject.toml changed.

    The stamp remembers the extras: the demo installs servoid alone, the tests add theirs.
    """
    if not PYTHON.exists():
        print("servoid: creating .venv", flush=True)
        venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
    stamp = VENV / ".servoid-installed"
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    done = stamp.read_text().split() if stamp.exists() else []
    wanted = f"{digest}{extras}"
    if wanted in done or (not extras and any(d.startswith(digest) for d in done)):
        return  # the test install holds everything the demo needs
    print("servoid: installing servoid and its dependencies into .venv", flush=True)
    pip = [str(PYTHON), "-m", "pip", "--disable-pip-version-check", "install", "--quiet"]
    subprocess.check_call([*pip, "--upgrade", "pip"])
    subprocess.check_call([*pip, "-e", f"{ROOT}{extras}"])
    stamp.write_text(wanted + "\n")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
