"""What every plant's virtual fleet is made of: unit scatter, damaged files, the fleet's tables.

A virtual fleet is many units of one actuator, each with its parameters scattered about the
nominal set (truncated normal factors), some with a defect, a few with a damaged rig file,
written with a manifest (``units.csv``), the truth (``truth.csv``) and a fleet file.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from .._atomic import atomic_path

__all__ = ["TRUNCATE", "damage_file", "scattered", "truncated_normal", "write_rows"]

#: Scatter factors are drawn from a standard normal truncated at ±TRUNCATE.
TRUNCATE = 2.5

_P = TypeVar("_P")


def truncated_normal(gen: np.random.Generator) -> float:
    """One standard normal draw within ±:data:`TRUNCATE` (drawn again until it is)."""
    while True:
        z = float(gen.standard_normal())
        if abs(z) <= TRUNCATE:
            return z


def scattered(base: _P, factors: Mapping[str, float]) -> _P:
    """``base`` with each named parameter multiplied by its factor (``base.with_``)."""
    return base.with_(**{name: getattr(base, name) * f  # type: ignore[attr-defined]
                         for name, f in factors.items()})


def damage_file(path: Path) -> None:
    """Keep the first third of a rig file: a record the fleet must report as unreadable."""
    data = path.read_bytes()
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_bytes(data[: len(data) // 3])


def write_rows(path: Path, rows: Sequence[Mapping[str, Any]], overwrite: bool) -> Path:
    """Write ``rows`` (the first one's keys as the header) as a CSV table, atomically."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(path, overwrite=overwrite) as tmp:
        tmp.write_text(buffer.getvalue(), encoding="utf-8")
    return path
