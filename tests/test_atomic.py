"""Atomic output: never a partial file, never a replaced file, never a new folder; the folder lock."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

import servoid
from servoid import OutputExistsError
from servoid._atomic import atomic_path
from servoid._lock import LOCK, hold_folder


def test_writes_with_the_users_umask(tmp_path):
    target = tmp_path / "out.txt"
    old = os.umask(0o027)
    try:
        with atomic_path(target) as tmp:
            tmp.write_text("data")
    finally:
        os.umask(old)
    assert target.read_text() == "data"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640  # 0666 & ~0027


def test_refuses_an_existing_file_and_leaves_it(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("keep")
    with pytest.raises(OutputExistsError, match="already exists"):
        with atomic_path(target) as tmp:
            tmp.write_text("new")
    assert target.read_text() == "keep"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]  # no temp file left


def test_file_appearing_while_writing_is_not_replaced(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(OutputExistsError, match="appeared while writing"):
        with atomic_path(target) as tmp:
            tmp.write_text("new")
            target.write_text("someone else")
    assert target.read_text() == "someone else"


def test_failure_leaves_nothing(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_is_an_error_not_created(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist; create it first"):
        with atomic_path(tmp_path / "typo" / "out.txt"):
            pass
    assert not (tmp_path / "typo").exists()


def test_overwrite_replaces(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with atomic_path(target, overwrite=True) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new"


# -- the folder lock ---------------------------------------------------------------------------

_ENV = {**os.environ, "PYTHONPATH": str(Path(servoid.__file__).parents[1])}
_HOLDER = """
import os, sys
from pathlib import Path
from servoid._atomic import atomic_path
from servoid._lock import hold_folder

folder = Path(sys.argv[1])
with hold_folder(folder) as lock:
    lock.claim([folder / "results.json"])
    with atomic_path(folder / "results.json") as tmp:
        tmp.write_text("half")
        print(tmp.name, flush=True)
        if sys.argv[2] == "die":
            os._exit(9)  # killed: no clean-up runs, the kernel drops the flock
        sys.stdin.readline()  # alive until told
"""


def _holder(folder, how):
    proc = subprocess.Popen([sys.executable, "-c", _HOLDER, str(folder), how], env=_ENV,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    return proc, proc.stdout.readline().strip()


def test_a_live_runs_folder_is_refused_naming_it(tmp_path):
    proc, _ = _holder(tmp_path, "live")
    try:
        with pytest.raises(OutputExistsError, match=rf"in use by another servoid run "
                                                    rf"\(process {proc.pid}"):
            with hold_folder(tmp_path):
                pass
    finally:
        proc.communicate("go\n")
    assert proc.returncode == 0 and not (tmp_path / LOCK).exists()
    with hold_folder(tmp_path):  # free again
        assert (tmp_path / LOCK).exists()
    assert not (tmp_path / LOCK).exists()


def test_a_dead_runs_lock_is_taken_over_with_its_journal(tmp_path):
    (tmp_path / ".mine.0123456789ab.tmp").write_text("a user's file named like a temporary")
    proc, tmp_name = _holder(tmp_path, "die")
    proc.wait()
    assert proc.returncode == 9 and (tmp_path / LOCK).exists() and (tmp_path / tmp_name).exists()
    with hold_folder(tmp_path) as lock:
        assert lock.inherited == {"results.json"}  # the dead run's half-done file may go
        assert not (tmp_path / tmp_name).exists()  # its temporary file, marked by its token
        assert (tmp_path / ".mine.0123456789ab.tmp").exists()  # never one merely named alike
    assert sorted(p.name for p in tmp_path.iterdir()) == [".mine.0123456789ab.tmp"]


def test_temporary_files_in_a_held_folder_carry_the_runs_token(tmp_path):
    with hold_folder(tmp_path / "new" / "out") as lock:
        with atomic_path(tmp_path / "new" / "out" / "a.txt") as tmp:
            assert lock.token in tmp.name
        with hold_folder(tmp_path / "new" / "out") as again:  # the same run: reused
            assert again is lock
    assert [p.name for p in (tmp_path / "new" / "out").iterdir()] == ["a.txt"]
    with hold_folder(tmp_path / "gone"):
        pass
    assert not (tmp_path / "gone").exists()  # a folder the lock made, left empty, goes


def test_a_lock_file_servoid_did_not_write_is_refused_never_deleted(tmp_path):
    (tmp_path / LOCK).write_text("a user's notes")
    with pytest.raises(OutputExistsError, match="not a lock servoid wrote"):
        with hold_folder(tmp_path):
            pass
    assert (tmp_path / LOCK).read_text() == "a user's notes"
    assert [p.name for p in tmp_path.iterdir()] == [LOCK]


def test_without_hard_links_the_lock_is_made_in_place(tmp_path, monkeypatch):
    def no_links(*args):
        raise PermissionError("no hard links on this file system")

    monkeypatch.setattr(os, "link", no_links)
    with hold_folder(tmp_path) as lock:
        assert lock.token in (tmp_path / LOCK).read_text()
        errors = []

        def second():  # another thread is another run
            try:
                with hold_folder(tmp_path):
                    pass
            except OutputExistsError as exc:
                errors.append(str(exc))

        worker = threading.Thread(target=second)
        worker.start()
        worker.join()
        assert len(errors) == 1 and "in use by another servoid run" in errors[0]
    assert not (tmp_path / LOCK).exists()
