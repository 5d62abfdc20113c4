#!/usr/bin/env python3
"""Set up servoid in a local virtual environment and run the demo or the tests.

    python3 dev.py demo      # create .venv, install servoid, run `servoid demo`
    python3 dev.py test      # create .venv, install servoid with test extras, run pytest
    python3 dev.py lock      # refresh constraints.txt (newest releases, whole suite passing)

Needs only Python >= 3.11 with the standard venv module. Extra arguments
after the command go to `servoid demo` or to pytest. `demo` and `test`
install the versions pinned in constraints.txt, the ones the suite passed
with; pyproject.toml keeps the ranges a library user gets. The install is
redone when pyproject.toml or constraints.txt changes.

`lock` builds a throw-away environment with the newest releases that the
pyproject.toml ranges allow (every extra), runs the suite there, and
writes constraints.txt only when the suite passes.
"""

from __future__ import annotations

import datetime
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
LOCK = ROOT / "constraints.txt"
SCRIPTS = "Scripts" if os.name == "nt" else "bin"
EXE = "python.exe" if os.name == "nt" else "python"
PYTHON = VENV / SCRIPTS / EXE
#: The suite reads the lock file to check from here (``lock`` points it at its candidate).
LOCK_VARIABLE = "SERVOID_LOCK_FILE"


def main(argv: list[str]) -> int:
    if sys.version_info < (3, 11):
        print(f"servoid needs Python >= 3.11, this is {sys.version.split()[0]}", file=sys.stderr)
        return 2
    if not argv or argv[0] not in ("demo", "test", "lock"):
        print(__doc__, file=sys.stderr)
        return 2
    command, rest = argv[0], argv[1:]
    if command == "lock":
        return lock(rest)
    try:
        ensure_environment(extras="" if command == "demo" else "[test]")
    except subprocess.CalledProcessError:
        print("servoid: pip could not install servoid with the versions in constraints.txt. "
              "If pyproject.toml changed its requirements, refresh the lock: python3 dev.py lock",
              file=sys.stderr)
        return 1
    if command == "demo":
        return subprocess.call([str(VENV / SCRIPTS / "servoid"), "demo", *rest], cwd=ROOT)
    return subprocess.call([str(PYTHON), "-m", "pytest", *_parallel(rest)], cwd=ROOT,
                           env=_test_env())


def ensure_environment(extras: str = "[test]") -> None:
    """Create .venv and (re)install servoid (with `extras`) when its inputs changed.

    The inputs are pyproject.toml and the lock; the stamp remembers their hash and
    the extras: the demo installs servoid alone, the tests add theirs.
    """
    if not PYTHON.exists():
        print("servoid: creating .venv", flush=True)
        venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
    stamp = VENV / ".servoid-installed"
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()
                            + b"\0" + (LOCK.read_bytes() if LOCK.exists() else b"")).hexdigest()
    done = stamp.read_text().split() if stamp.exists() else []
    wanted = f"{digest}{extras}"
    if wanted in done or (not extras and any(d.startswith(digest) for d in done)):
        return  # the test install holds everything the demo needs
    print("servoid: installing servoid and its dependencies into .venv", flush=True)
    pip = [str(PYTHON), "-m", "pip", "--disable-pip-version-check", "install", "--quiet"]
    subprocess.check_call([*pip, "--upgrade", "pip"])
    if LOCK.exists():
        pip += ["-c", str(LOCK)]
    else:
        print("servoid: no constraints.txt: installing the newest releases", file=sys.stderr)
    subprocess.check_call([*pip, "-e", f"{ROOT}{extras}"])
    stamp.write_text(wanted + "\n")


def lock(pytest_args: list[str]) -> int:
    """Pin the newest allowed releases in constraints.txt if the suite passes with them."""
    import tomllib

    extras = ",".join(sorted(tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
                             ["project"].get("optional-dependencies", {})))
    scratch = Path(tempfile.mkdtemp(prefix="servoid-lock-"))
    try:
        env_dir = scratch / "venv"
        python = env_dir / SCRIPTS / EXE
        print(f"servoid: a throw-away environment in {env_dir}", flush=True)
        venv.EnvBuilder(with_pip=True).create(env_dir)
        pip = [str(python), "-m", "pip", "--disable-pip-version-check"]
        subprocess.check_call([*pip, "install", "--quiet", "--upgrade", "pip"])
        print(f"servoid: installing the newest releases for servoid[{extras}]", flush=True)
        subprocess.check_call([*pip, "install", "--quiet", "--upgrade", "--upgrade-strategy",
                               "eager", "-e", f"{ROOT}[{extras}]"])
        frozen = subprocess.run([*pip, "freeze", "--exclude-editable"], check=True,
                                capture_output=True, text=True).stdout
        pins = sorted((line.strip() for line in frozen.splitlines()
                       if line.strip() and not line.startswith(("#", "-"))),
                      key=str.lower)
        candidate = scratch / "constraints.txt"
        candidate.write_text("\n".join(pins) + "\n", encoding="utf-8")
        print(f"servoid: running the suite with {len(pins)} pinned packages", flush=True)
        code, summary = _run_and_tail([str(python), "-m", "pytest", *_parallel(pytest_args)],
                                      {**_test_env(), LOCK_VARIABLE: str(candidate)})
        if code != 0:
            print(f"servoid: the suite failed (pytest exit {code}); constraints.txt is "
                  "unchanged", file=sys.stderr)
            return code
        _write_lock(pins, extras, summary)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


def _write_lock(pins: list[str], extras: str, summary: str) -> None:
    old = set(_pins(LOCK.read_text(encoding="utf-8"))) if LOCK.exists() else set()
    libc = " ".join(platform.libc_ver()).strip()
    header = [
        "# The versions servoid's suite passed with: every package that",
        f"#     pip install -e \".[{extras}]\"",
        "# installs, pinned. `python3 dev.py demo` and `python3 dev.py test` install with",
        "# `-c constraints.txt`; pyproject.toml keeps the ranges library users get.",
        "# Do not edit: `python3 dev.py lock` rewrites it (the newest releases the ranges allow,",
        "# written only when the whole suite passes with them).",
        f"# Made on {datetime.date.today().isoformat()} with Python {platform.python_version()} "
        f"on {sysconfig.get_platform()}{' (' + libc + ')' if libc else ''},",
        "# under this machine's pip configuration (`pip config list`).",
        "# Packages a platform needs that this one did not install are not pinned.",
        f"# Suite: {summary}",
    ]
    tmp = LOCK.with_suffix(".tmp")
    tmp.write_text("\n".join(header + pins) + "\n", encoding="utf-8")
    os.replace(tmp, LOCK)
    new = set(pins)
    print(f"servoid: wrote {LOCK.name} ({len(pins)} pins)", flush=True)
    for line in sorted(new - old, key=str.lower):
        print(f"  + {line}")
    for line in sorted(old - new, key=str.lower):
        print(f"  - {line}")


def _pins(text: str) -> list[str]:
    return [line.strip() for line in text.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def _run_and_tail(command: list[str], env: dict[str, str]) -> tuple[int, str]:
    """Run `command` in ROOT, echo its output, return its exit code and last line."""
    last = ""
    with subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, bufsize=1) as process:
        assert process.stdout is not None
        for line in process.stdout:
            print(line, end="", flush=True)
            if line.strip():
                last = line.strip().strip("=").strip()
    return process.returncode, last


def _parallel(pytest_args: list[str]) -> list[str]:
    """The suite on every core (pytest-xdist), unless the arguments choose the workers.

    The tests are independent and mostly single-threaded numerics: two workers on a 2-core
    machine take about half the time of one. ``-n 0`` (or ``-p no:xdist``) runs them in one
    process, which is what a debugger wants.
    """
    chosen = any(a == "-n" or a.startswith(("-n", "--numprocesses", "--dist")) or a == "no:xdist"
                 for a in pytest_args)
    return pytest_args if chosen else ["-n", "auto", *pytest_args]


def _test_env() -> dict[str, str]:
    # The suite is thousands of small LAPACK calls: a multi-threaded BLAS only adds thread
    # hand-offs there, ~10x slower on a loaded 2-core machine. One thread unless the caller says.
    return {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
