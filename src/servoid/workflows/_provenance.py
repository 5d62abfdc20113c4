"""Where a report came from: when, by which command, from which inputs, with which outputs.

The command line records its words with :func:`set_command`; a run from
Python says so.  Hashes are SHA-256 of the bytes, shortened to 16 hex digits
on the page (``manifest.json`` keeps them whole).
"""

from __future__ import annotations

import datetime as dt
import json
import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ._common import sha256
from ._summary import input_digest

__all__ = ["provenance", "set_command"]

_COMMAND: list[str] = []


def set_command(words: Sequence[str]) -> None:
    """Record the command line of this process (``servoid identify …``)."""
    _COMMAND[:] = [str(w) for w in words]


def provenance(result: Any, outputs: Mapping[str, Path],
               output_sha256: Mapping[str, str] | None = None) -> tuple[tuple[str, str], ...]:
    """Report metadata rows: generation time, command, seed, input and output hashes.

    The inputs' hashes are the result's own (``result.digests``: each input
    hashed once per run); the outputs' are ``output_sha256`` by name when
    given (the writer hashes each output once), else computed here.
    """
    now = dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", " UTC")
    command = shlex.join(_COMMAND) if _COMMAND else "Python API (servoid.workflows.identify)"
    rows = [("generated", now), ("command", command)]
    seed = _seed(result)
    if seed is not None:
        rows.append(("seed", str(seed)))
    table = getattr(result, "digests", None)
    for path in result.inputs():
        if Path(path).is_file():
            rows.append((f"input {Path(path).name}",
                         input_digest(table if isinstance(table, dict) else None, path)[:16]
                         + "…"))
    known = output_sha256 or {}
    for name, path in outputs.items():
        if path.is_file():
            rows.append((f"output {name}", (known.get(name) or sha256(path))[:16] + "…"))
    return tuple(rows)


def _seed(result: Any) -> int | None:
    """The noise seed of a virtual-bench record, from its truth file, when there is one."""
    for path in result.inputs():
        if Path(path).suffix == ".json" and Path(path).name.startswith("truth"):
            try:
                seed = json.loads(Path(path).read_text(encoding="utf-8")).get("seed")
            except (OSError, ValueError, AttributeError):
                return None
            return seed if isinstance(seed, int) else None
    return None
