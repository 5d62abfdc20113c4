"""The fleet table: one row per record, written as CSV and Parquet.

Columns, in order: ``record``, the manifest's metadata, ``status``,
``error``, ``method``, ``seconds`` (wall), ``cpu_seconds`` (the CPU time
the record cost, its candidate tasks included), ``fit_percent``, ``white``,
``independent``, ``structure_rejected``, ``flags``, then per parameter
``<p>``, ``<p>_std``, ``<p>_ci_low``, ``<p>_ci_high``, then per limit
``pass_<p>``, then ``outlier`` (the parameters whose robust z-score
exceeds the cut-off) and ``pass``.  Values the record has not (a failed
record, a parameter another method estimates) are empty.

A text cell that a spreadsheet would run as a formula (one starting with
``=``, ``+``, ``-``, ``@``, a tab or a carriage return, such as a manifest
serial ``=HYPERLINK(...)``) is written with a leading ``'``, which shows
the text as it is (:mod:`servoid._spreadsheet`); numbers are written as
they are.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from .._atomic import atomic_path
from .._spreadsheet import neutralise

__all__ = ["columns", "write_csv", "write_parquet"]

_FIXED = ("status", "error", "method", "seconds", "cpu_seconds", "fit_percent", "white",
          "independent", "structure_rejected", "flags")


def columns(meta: Sequence[str], parameters: Sequence[str], limited: Sequence[str]) -> list[str]:
    """The table's column names."""
    out = ["record", *meta, *_FIXED]
    for p in parameters:
        out += [p, f"{p}_std", f"{p}_ci_low", f"{p}_ci_high"]
    out += [f"pass_{p}" for p in limited]
    return [*out, "outlier", "pass"]


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    if isinstance(value, int):
        return str(value)
    return neutralise(str(value))


def write_csv(rows: Sequence[Mapping[str, Any]], names: Sequence[str],
              path: str | os.PathLike[str]) -> None:
    """Write the table as CSV (UTF-8, a header row, empty cells for missing values)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([neutralise(str(c)) for c in names])
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in names])
    with atomic_path(path, overwrite=True) as tmp:
        Path(tmp).write_text(buffer.getvalue(), encoding="utf-8")


def write_parquet(rows: Sequence[Mapping[str, Any]], names: Sequence[str],
                  path: str | os.PathLike[str]) -> bool:
    """Write the table as Parquet; False (nothing written) when pyarrow is not installed."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    data = {}
    for c in names:
        values = [row.get(c) for row in rows]
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {float, int} and kinds and kinds != {int}:
            values = [None if v is None else float(v) for v in values]
        elif kinds - {str, bool, int, float} or len(kinds) > 1:
            values = [None if v is None else str(v) for v in values]
        data[c] = values
    table = pa.table(data)
    with atomic_path(path, overwrite=True) as tmp:
        pq.write_table(table, tmp)
    return True
