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
v7.3 datasets are read only after their declared shape × item size is
checked against the memory budget.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_str_list
from .._errors import ChannelError, DataError, FileFormatError
from ._columns import (
    DEFAULT_MAX_BYTES,
    TIME_TOLERANCE,
    RolesArg,
    build_experiment,
    check_max_bytes,
    check_reader_options,
    existing_file,
    library_errors,
)
from ._experiment import Experiment
from ._mat_check import _KIND_WORDS, MatEntry, check_mat, format_bytes

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

    Returns
    -------
    Experiment
        Named after the file stem; scalars and strings are in ``notes``.

    Raises
    ------
    FileFormatError
        Not a MAT file, truncated, damaged (a declared size or type code
        that does not fit), over the memory budget, or vectors of different
        lengths.
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
    wanted = None if variables is None else {*variables, *([time] if time is not None else [])}
    if _is_hdf5(path):
        raw, listed = _load_v73(path, wanted, max_bytes)
    else:
        raw, listed = _load_v4_v5(path, wanted, max_bytes)
    vectors: dict[str, NDArray[np.float64]] = {}
    notes: dict[str, Any] = {}
    skipped: dict[str, tuple[int, ...]] = {}
    for name, value in raw.items():
        kind = _classify(value)
        if kind == "vector":
            vectors[name] = np.asarray(value, dtype=float).ravel()
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
    stamps = vectors[time] if time is not None else None
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
    path: Path, wanted: set[str] | None, max_bytes: int
) -> tuple[dict[str, Any], dict[str, MatEntry]]:
    """The checked variables of a v4/v5 file, and the entries left unread."""
    with library_errors(path, "a MAT file"):
        from scipy.io import loadmat
        from scipy.io.matlab import matfile_version

        with path.open("rb") as f:
            head = f.read(128)
        if len(head) < 128 and 0 not in head[:4]:  # scipy indexes byte 126 unchecked
            raise FileFormatError(
                f"{path}: truncated MAT file: {len(head)} bytes, a v5 header alone is 128"
            )
        version, _ = matfile_version(path, appendmat=False)
        if version not in (0, 1):
            raise FileFormatError(
                f"{path}: MAT version field says {version}.x but the file is not HDF5 (v7.3): "
                "a damaged header"
            )
        entries = check_mat(path, version, wanted, max_bytes)
        load = [e.name for e in entries.values() if e.loadable]
        loaded = loadmat(path, appendmat=False, variable_names=load, squeeze_me=False,
                         chars_as_strings=True) if load else {}
    raw = {k: v for k, v in loaded.items() if not k.startswith("__")}
    raw.update({n: e.value for n, e in entries.items() if e.value is not None})
    return raw, {n: e for n, e in entries.items() if n not in raw}


def _vector_names(vectors: dict[str, Any], listed: dict[str, MatEntry]) -> list[str]:
    """Vectors loaded, then real vectors of the file that were not loaded."""
    more = [n for n, e in listed.items()
            if e.kind == "numeric" and sum(d > 1 for d in e.shape) == 1]
    return [*vectors, *more]


def _is_hdf5(path: Path) -> bool:
    with path.open("rb") as f:
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


def _load_v73(
    path: Path, wanted: set[str] | None, max_bytes: int
) -> tuple[dict[str, Any], dict[str, MatEntry]]:
    """The datasets of a v7.3 file within the budget, and those left unread."""
    try:
        import h5py
    except ImportError as exc:
        raise ImportError(
            f"{path} is a MAT v7.3 (HDF5) file; reading it needs h5py: "
            "pip install servoid[mat73]"
        ) from exc
    out: dict[str, Any] = {}
    listed: dict[str, MatEntry] = {}
    with library_errors(path, "a MAT v7.3 (HDF5) file"), h5py.File(path, "r") as f:
        for name, obj in f.items():
            if name.startswith("#"):
                continue  # what references point to
            if not isinstance(obj, h5py.Dataset):
                if isinstance(obj, h5py.Group):  # a struct: its fields are named with dots
                    listed[name] = MatEntry(name, "struct", (1, 1))
                continue
            shape = tuple(int(d) for d in reversed(obj.shape))  # MATLAB's order
            kind: Any = _v73_kind(obj)
            cls = _v73_class(obj)
            entry = MatEntry(name, kind, shape)
            note = entry.is_note and kind in ("numeric", "char")
            if wanted is not None and name not in wanted and not note:
                listed[name] = entry
                continue
            nbytes = int(np.prod(shape, dtype=object)) * obj.dtype.itemsize
            if nbytes > max_bytes:
                if wanted is None or name in wanted:
                    raise FileFormatError(
                        f"{path}: variable {name!r} declares shape {shape} of "
                        f"{obj.dtype.itemsize}-byte values ({format_bytes(nbytes)}), over the "
                        f"{format_bytes(max_bytes)} budget: a damaged file, or pass max_bytes= "
                        "to read a variable this large"
                    )
                listed[name] = entry
                continue
            if obj.attrs.get("MATLAB_empty", 0):
                continue
            # MATLAB writes column-major arrays, so HDF5 holds them transposed.
            data = np.asarray(obj[()]).T
            if cls == "char":
                out[name] = "".join(chr(int(c)) for c in data.ravel())
            elif cls == "logical":
                out[name] = data.astype(bool)
            else:
                out[name] = data
        for name in sorted(n for n in wanted or () if "." in n):
            _v73_field(path, f, name, max_bytes, out, listed)
    return out, listed


def _v73_field(path: Path, f: Any, name: str, max_bytes: int, out: dict[str, Any],
               listed: dict[str, MatEntry]) -> None:
    """Read the struct field ``name`` (dotted) of a v7.3 file into ``out``."""
    import h5py

    parts = name.split(".")
    node = f
    for depth, part in enumerate(parts):
        here = ".".join(parts[:depth])
        if depth and not isinstance(node, h5py.Group):
            kind = _v73_kind(node)
            raise ChannelError(
                f"{path}: {here!r} is {_KIND_WORDS.get(kind, kind)}, not a struct: it has no "
                "fields to name with a dot"
            )
        if depth and any(_is_reference(node[k]) and _v73_class(node[k]) != "cell"
                         for k in node if not k.startswith("#")):
            raise FileFormatError(
                f"{path}: {here!r} is a struct array; servoid reads fields of a 1×1 struct "
                "only: save each element as its own struct (or the signals as numeric fields "
                "of one struct)"
            )
        if part not in node or part.startswith("#"):
            if depth == 0:
                return  # not in the file: the reader lists what there is
            fields = [k for k in node if not k.startswith("#")]
            raise ChannelError(
                f"variable {name!r} is not in {path}: the struct {here!r} has the field(s) "
                f"{', '.join(fields) or '(none)'}"
            )
        node = node[part]
    if isinstance(node, h5py.Group):
        listed[name] = MatEntry(name, "struct", (1, 1))
        return
    shape = tuple(int(d) for d in reversed(node.shape))
    kind = _v73_kind(node)
    if kind != "numeric":
        listed[name] = MatEntry(name, kind, shape)
        return
    nbytes = int(np.prod(shape, dtype=object)) * node.dtype.itemsize
    if nbytes > max_bytes:
        raise FileFormatError(
            f"{path}: variable {name!r} declares shape {shape} of {node.dtype.itemsize}-byte "
            f"values ({format_bytes(nbytes)}), over the {format_bytes(max_bytes)} budget: a "
            "damaged file, or pass max_bytes= to read a variable this large"
        )
    out[name] = np.zeros((0, 0)) if node.attrs.get("MATLAB_empty", 0) else \
        np.asarray(node[()]).T


def _v73_class(node: Any) -> str:
    cls = node.attrs.get("MATLAB_class", b"")
    return cls.decode(errors="replace") if isinstance(cls, bytes) else str(cls)


def _is_reference(node: Any) -> bool:
    import h5py

    return isinstance(node, h5py.Dataset) and h5py.check_dtype(ref=node.dtype) is not None


def _v73_kind(node: Any) -> str:
    """What a v7.3 dataset holds, in the words of :data:`_KIND_WORDS`."""
    cls = _v73_class(node)
    if cls in ("cell", "struct", "char"):
        return cls
    if _is_reference(node):
        return "cell"
    return "numeric" if node.dtype.kind in "biuf" else "unknown"
