"""Atomic output: never a partial file, never a replaced file, never a new folder."""

from __future__ import annotations

import os
import stat

import pytest

from servoid import OutputExistsError
from servoid._atomic import atomic_path


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
