"""MATLAB MAT rig files: v4 and v5 via scipy, v7.3 (HDF5) via h5py.

Every real row or column vector becomes a channel (all must have the same
length), every real scalar and every string becomes an entry of
``Experiment.notes``; matrices, structs and cells are not loaded. For
example the EMPS benchmark file holds the vectors ``t``, ``qm``, ``qg``,
``vir`` and the scalars ``kp``, ``kv``, ``gtau``.

A vector inside a struct (MATLAB's ``data.signals.y``) is named with dots,
in ``variables``, ``time`` or ``roles``: only the fields named are read. A
struct array or a cell array on the way is refused, naming the path.

A file is untrusted input. v4 and v5 files are walked by
:func:`~servoid.data._mat_check.check_mat` first, and scipy then reads only
the variables that passed it: the ones asked for, and scalars and one-row
strings for the notes. scipy's compiled v5 reader trusts type codes and
sizes, so a damaged variable it parsed could end the process with SIGSEGV.
A compressed variable is inflated only as far as its header and declared
data need, and never one nobody asked for. v7.3 (HDF5) files are read by
:mod:`~servoid.data._mat73` in a child process that is stopped when it
makes no progress; links out of the file are refused unless allowed.

A time vector of integers (int64 nanoseconds from a logger) or of whole
numbers stepping by 1 or more is refused unless ``time_unit`` says what
it counts: read as seconds it would make every result wrong by that factor.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_str_list
from .._errors import ChannelError, DataError, FileFormatError
from .._files import BoundedFile, open_input
from ._columns import (
    DEFAULT_MAX_BYTES,
    TIME_TOLERANCE,
    RolesArg,
    build_experiment,
    check_max_bytes,
    check_reader_options,
    check_time_unit,
    existing_file,
    library_errors,
    time_in_seconds,
)
from ._experiment import Experiment
from ._mat73 import load_v73
from ._mat_check import _KIND_WORDS, MatEntry, check_mat

__all__ = ["DEFAULT_MAX_BYTES", "read_mat"]


_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
# HDF5 looks for its signature at 0, 512, 1024, 2048, ...; MATLAB uses a 512-byte userblock.
_HDF5_OFFSETS = (0, 512, 1024, 2048, 4096)


def read_mat(
    path: str | os.PathLike[str],
    *,
    variables: Sequence[str] | None = None,
    time: str | None = None,
    dt: float | None = None,
    roles: RolesArg = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    jitter: float = TIME_TOLERANCE,
    time_unit: str | None = None,
    allow_external: bool = False,
) -> Experiment:
    """Read the vectors of a MAT file into an Experiment.

    Parameters
    ----------
    path : path-like
        The file (v4, v5/v7 or v7.3).
    variables : sequence of str, optional
        Vectors to load as channels; default all top-level vectors in the
        file. A field of a (nested) struct is named with dots:
        ``"data.signals.y"``. Only these and ``time`` are read, besides
        scalars and one-row strings for ``notes``: damage elsewhere in the
        file does not matter.
    time : str, optional
        A vector of time stamps [s]; it gives ``dt`` and ``t0``.
    dt : float, optional
        Sample period [s] when there is no ``time`` vector.
    roles : mapping of str to list of str, optional
        Role to variable names, e.g. ``{"u": ["vir"], "y": ["qm"]}``; the
        others become side channels.
    max_bytes : int
        Memory budget of one variable [bytes]; default 2 GiB. It bounds
        what compressed (v7) and HDF5 (v7.3) variables may declare, which
        the file's own size does not.
    jitter : float
        Largest deviation of a time step from the mean step, as a fraction
        of it (default 1e-3); raise it for a logger with time-stamp jitter.
    time_unit : {"s", "ms", "us", "ns"}, optional
        Unit of the ``time`` vector. Without it, a time vector of integers
        (clock ticks) or of whole numbers stepping by 1 or more is refused.
    allow_external : bool
        Follow a v7.3 file's external links and external or virtual
        storage, which read other files; default False: refused.

    Returns
    -------
    Experiment
        Named after the file stem; scalars and strings are in ``notes``.

    Raises
    ------
    FileFormatError
        Not a MAT file, truncated, damaged (a declared size or type code
        that does not fit), over the memory budget, vectors of different
        lengths, a time vector of integer ticks without ``time_unit``, a
        link out of the file, or a v7.3 read that stopped making progress.
    ChannelError
        A variable or struct field named in ``variables``, ``time`` or
        ``roles`` is missing (the message lists what there is).
    ImportError
        A v7.3 file and h5py is not installed.
    """
    path = existing_file(path)
    dt = check_reader_options(dt=dt, roles=roles, names={"time": time})
    if variables is not None:
        variables = as_str_list("variables", variables)
    max_bytes = check_max_bytes(max_bytes)
    time_unit = check_time_unit(time_unit)
    allow_external = as_bool("allow_external", allow_external)
    wanted = None if variables is None else {*variables, *([time] if time is not None else [])}
    with open_input(path, "file") as f:
        if _is_hdf5(f):
            f.close()  # read in a child process, by path: checked above to be a regular file
            raw, listed = load_v73(path, wanted, max_bytes, allow_external)
        else:
            raw, listed = _load_v4_v5(path, f, wanted, max_bytes)
    vectors: dict[str, NDArray[np.float64]] = {}
    notes: dict[str, Any] = {}
    skipped: dict[str, tuple[int, ...]] = {}
    for name, value in raw.items():
        kind = _classify(value)
        if kind == "vector":
            vectors[name] = np.asarray(value).ravel() if name == time else \
                np.asarray(value, dtype=float).ravel()
        elif kind == "scalar":
            notes[name] = np.asarray(value).ravel()[0].item()
        elif kind == "string":
            flat = np.asarray(value).ravel()
            notes[name] = value if isinstance(value, str) else (str(flat[0]) if flat.size else "")
        else:
            skipped[name] = np.shape(value)
    chosen = list(variables) if variables is not None else [n for n in vectors if n != time]
    for name in [*chosen, *([time] if time is not None else [])]:
        if name in vectors:
            continue
        if name in skipped or name in notes:
            shape = skipped.get(name, (1, 1))
            raise FileFormatError(
                f"{path}: variable {name!r} has shape {shape}, not a vector"
            )
        if name in listed:
            entry = listed[name]
            fix = {"struct": f"name one of its fields with a dot, e.g. '{name}.<field>'",
                   "cell": "servoid reads numeric vectors: store the signal as a numeric "
                           "variable or struct field, not in a cell"}.get(
                entry.kind, "name a numeric vector instead")
            raise FileFormatError(
                f"{path}: variable {name!r} is {_KIND_WORDS[entry.kind]} of shape "
                f"{entry.shape}, not a real vector; {fix}"
            )
        structs = [n for n, e in listed.items() if e.kind == "struct" and "." not in n]
        hint = (f" (and the struct(s) {', '.join(structs)}: name a field with dots, e.g. "
                f"'{structs[0]}.<field>')") if structs else ""
        raise ChannelError(
            f"variable {name!r} is not in {path}; its vectors are: "
            f"{', '.join(_vector_names(vectors, listed)) or 'none'}{hint}"
        )
    used = {n: vectors[n] for n in chosen}
    stamps = None
    if time is not None:
        stamps = time_in_seconds(
            path, vectors[time], time, time_unit,
            "pass time_unit='ns' (or 'us', 'ms', or 's' if they are seconds); in an "
            "experiment file, remove [data] time and give [data] dt [s] instead",
            what="time vector")
    lengths = {n: v.size for n, v in used.items()}
    if stamps is not None:
        lengths[str(time)] = stamps.size
    if len(set(lengths.values())) > 1:
        sizes = ", ".join(f"{n}: {k}" for n, k in lengths.items())
        raise FileFormatError(
            f"{path}: vectors have different lengths ({sizes}); pass variables= to choose"
        )
    if not used:
        structs = [n for n, e in listed.items() if e.kind == "struct"]
        hint = (f"; the vectors of a struct are named with dots, e.g. '{structs[0]}.<field>' "
                "(pass variables=)") if structs else ""
        raise FileFormatError(
            f"{path}: no vectors to load (variables: {', '.join([*raw, *listed])}){hint}"
        )
    if time is None and dt is None:
        raise DataError(
            f"{path}: no sample period: pass dt [s] or time=<vector name> "
            f"(vectors: {', '.join(_vector_names(vectors, listed))})"
        )
    return build_experiment(
        path, used, {}, roles=roles, dt=dt, time=stamps, notes=notes, jitter=jitter,
    )


def _load_v4_v5(
    path: Path, f: BoundedFile, wanted: set[str] | None, max_bytes: int
) -> tuple[dict[str, Any], dict[str, MatEntry]]:
    """The checked variables of a v4/v5 file, and the entries left unread."""
    with library_errors(path, "a MAT file"):
        from scipy.io import loadmat
        from scipy.io.matlab import matfile_version

        f.seek(0)
        head = f.read(128)
        if len(head) < 128 and 0 not in head[:4]:  # scipy indexes byte 126 unchecked
            raise FileFormatError(
                f"{path}: truncated MAT file: {len(head)} bytes, a v5 header alone is 128"
            )
        f.seek(0)
        version, _ = matfile_version(f, appendmat=False)
        if version not in (0, 1):
            raise FileFormatError(
                f"{path}: MAT version field says {version}.x but the file is not HDF5 (v7.3): "
                "a damaged header"
            )
        entries = check_mat(path, version, wanted, max_bytes, f)
        load = [e for e in entries.values() if e.loadable and e.span is not None]
        # scipy is shown the checked elements alone: it parses nothing else (it inflated a
        # compressed variable it was not asked for, to check its stream was consumed)
        spans = [(0, 128)] * (version == 1) + [e.span for e in load if e.span is not None]
        loaded = loadmat(_Spliced(f, spans), appendmat=False,
                         variable_names=[e.name for e in load], squeeze_me=False,
                         chars_as_strings=True) if load else {}
    raw = {k: v for k, v in loaded.items() if not k.startswith("__")}
    raw.update({n: e.value for n, e in entries.items() if e.value is not None})
    return raw, {n: e for n, e in entries.items() if n not in raw}


class _Spliced(io.RawIOBase):
    """A read-only file made of byte ranges of another, in order.

    Parameters
    ----------
    f : binary file
        The file, seekable.
    spans : list of (start, stop)
        The ranges shown, in bytes of ``f``.
    """

    def __init__(self, f: BoundedFile, spans: list[tuple[int, int]]) -> None:
        super().__init__()
        self.f = f
        self.spans = spans
        self.starts = np.cumsum([0] + [b - a for a, b in spans]).tolist()
        self.pos = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self.pos

    def seek(self, offset: int, whence: int = 0) -> int:
        base = (0, self.pos, self.starts[-1])[whence]
        self.pos = max(0, base + offset)
        return self.pos

    def readinto(self, b: Any) -> int:
        view = memoryview(b).cast("B")
        done = 0
        while done < len(view) and self.pos < self.starts[-1]:
            k = int(np.searchsorted(self.starts, self.pos, side="right")) - 1
            a, stop = self.spans[k]
            at = a + self.pos - self.starts[k]
            n = min(len(view) - done, stop - at)
            self.f.seek(at)
            got = self.f.readinto(view[done:done + n])
            if not got:
                break
            done += got
            self.pos += got
        return done


def _vector_names(vectors: dict[str, Any], listed: dict[str, MatEntry]) -> list[str]:
    """Vectors loaded, then real vectors of the file that were not loaded."""
    more = [n for n, e in listed.items()
            if e.kind == "numeric" and sum(d > 1 for d in e.shape) == 1]
    return [*vectors, *more]


def _is_hdf5(f: BoundedFile) -> bool:
    f.seek(0)
    head = f.read(max(_HDF5_OFFSETS) + 8)
    if head.startswith(b"MATLAB 7.3"):
        return True
    return any(head[k : k + 8] == _HDF5_SIGNATURE for k in _HDF5_OFFSETS)


def _classify(value: Any) -> str:
    if isinstance(value, str):
        return "string"
    arr = np.asarray(value)
    if arr.dtype.kind in "US":
        return "string" if arr.size <= 1 else "other"
    if arr.dtype.kind not in "biuf":
        return "other"
    if arr.size == 1:
        return "scalar"
    if arr.ndim >= 1 and arr.size > 1 and sum(d > 1 for d in arr.shape) == 1:
        return "vector"
    return "other"
