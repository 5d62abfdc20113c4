"""Every example script runs to the end and writes nothing into the current folder.

Scripts that write take the folder as their first argument (without one, a new temporary
folder); the data makers rewrite exactly the records shipped beside them. What the scripts
print is checked against the docs by ``tests/test_docs.py``, which shares these runs.
"""

from __future__ import annotations

import filecmp
import subprocess
import sys
from pathlib import Path

import docs_check
import pytest

EXAMPLES_DIR = docs_check.ROOT / "examples"
#: Python files that are models an experiment file names, not scripts.
MODEL_FILES = {"greybox/tanks.py"}
SCRIPTS = sorted(p.relative_to(EXAMPLES_DIR).as_posix() for p in EXAMPLES_DIR.rglob("*.py")
                 if p.relative_to(EXAMPLES_DIR).as_posix() not in MODEL_FILES
                 and "__pycache__" not in p.parts)
MAKERS = [s for s in SCRIPTS if s.endswith("make_data.py")]
#: What each data maker writes, shipped beside it.
MADE = {"blocks/make_data.py": ["blocks_run1.csv", "blocks_run2.csv", "truth.json"],
        "greybox/make_data.py": ["tanks.csv", "tanks_validation.csv"],
        "narx/make_data.py": ["narx_run1.csv", "narx_run2.csv", "truth.json"]}


@pytest.mark.parametrize("script", [s for s in SCRIPTS if s not in MAKERS])
def test_example_runs_and_leaves_the_current_folder_alone(script):
    done = docs_check.run(f"python examples/{script}")  # the run the docs check reuses
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip()
    assert done.left_in_cwd == [], f"{script} wrote {done.left_in_cwd} into the current folder"
    writes = "sys.argv[1]" in (EXAMPLES_DIR / script).read_text(encoding="utf-8")
    assert done.wrote_to_tmp is writes  # without a folder argument: a new temporary folder


# flexible_arm.py takes the same route and runs 40 s: once above is enough
@pytest.mark.parametrize("script", ["arx_servo.py", "emps/emps_identify.py"])
def test_writing_examples_write_into_the_folder_given(script, tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, str(EXAMPLES_DIR / script), str(out)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert any(out.iterdir())


@pytest.mark.parametrize("script", MAKERS)
def test_data_makers_reproduce_the_shipped_records(script, tmp_path):
    done = subprocess.run([sys.executable, str(EXAMPLES_DIR / script), str(tmp_path / "out")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(MADE[script])
    for name in MADE[script]:
        shipped = EXAMPLES_DIR / Path(script).parent / name
        assert filecmp.cmp(tmp_path / "out" / name, shipped, shallow=False), \
            f"{script} no longer writes the shipped {name}"


def test_every_maker_is_known():
    assert sorted(MADE) == MAKERS
