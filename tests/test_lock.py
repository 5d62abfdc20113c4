"""constraints.txt and pyproject.toml agree: every requirement pinned once, inside its range."""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).parents[1]
# `python3 dev.py lock` checks its candidate lock before it writes constraints.txt
LOCK = Path(os.environ.get("SERVOID_LOCK_FILE", ROOT / "constraints.txt"))
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;#]+)$")
FIX = "refresh the lock: python3 dev.py lock"


def _requirements() -> list[tuple[str, Requirement]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    groups = {"": project["dependencies"], **project.get("optional-dependencies", {})}
    return [(group, Requirement(text)) for group, texts in groups.items() for text in texts]


def pins(text: str) -> dict[str, list[Version]]:
    """Name → every version the lock pins for it; raises on a line that is not a pin."""
    found: dict[str, list[Version]] = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        match = PIN.match(line)
        if match is None:
            raise AssertionError(f"{LOCK.name} line {number} is not `name==version`: {line!r}")
        found.setdefault(canonicalize_name(match[1]), []).append(Version(match[2]))
    return found


def disagreements(lock_text: str) -> list[str]:
    """What is wrong between a lock's text and pyproject.toml, in words."""
    locked = pins(lock_text)
    wrong = [f"{name} is pinned {len(versions)} times" for name, versions in locked.items()
             if len(versions) > 1]
    for group, req in _requirements():
        where = f"[{group}] " if group else ""
        if req.marker is not None and not req.marker.evaluate({"extra": group}):
            continue  # another platform's requirement
        versions = locked.get(canonicalize_name(req.name))
        if not versions:
            wrong.append(f"{where}{req} is not pinned")
        elif not req.specifier.contains(versions[0], prereleases=True):
            wrong.append(f"{where}{req} is pinned at {versions[0]}, outside its range")
    return wrong


def test_the_lock_pins_every_requirement_once_inside_its_range():
    assert LOCK.exists(), f"no {LOCK.name}: {FIX}"
    wrong = disagreements(LOCK.read_text(encoding="utf-8"))
    assert not wrong, "; ".join(wrong) + f" — {FIX}"


@pytest.mark.parametrize("edit, problem", [
    (lambda t: t.replace("\nnumpy==", "\n# numpy=="), "numpy>=1.26 is not pinned"),
    (lambda t: t + "NumPy==1.26.0\n", "numpy is pinned 2 times"),
    (lambda t: re.sub(r"\nscipy==\S+", "\nscipy==1.10.1", t), "scipy>=1.11 is pinned at 1.10.1"),
    (lambda t: re.sub(r"\nnbclient==\S+", "", t), "[test] nbclient>=0.10 is not pinned"),
    (lambda t: re.sub(r"\ncryptography==\S+", "", t), "[fleet] cryptography>=42 is not pinned"),
])
def test_each_disagreement_is_named(edit, problem):
    text = "\n" + LOCK.read_text(encoding="utf-8")
    assert not disagreements(text)
    assert any(w.startswith(problem) for w in disagreements(edit(text)))


def test_a_line_that_is_not_a_pin_is_refused():
    with pytest.raises(AssertionError, match=r"line 2 is not `name==version`: 'numpy>=2'"):
        pins("# header\nnumpy>=2\n")
