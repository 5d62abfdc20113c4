"""MATLAB MAT rig files: v4 and v5 via scipy, v7.3 (HDF5) via h5py.

Every real row or column vector becomes a channel (all must have the same
length), every real scalar and every string becomes an entry of
``Experiment.notes``; matrices, structs and cells are not loaded. For
example the EMPS benchmark file holds the vectors ``t``, ``qm``, ``qg``,
``vir`` and the scalars ``kp``, ``kv``, ``gtau``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ChannelError, DataError, FileFormatError
from ._columns import RolesArg, build_experiment, existing_file, library_errors
from ._experiment import Experiment

__all__ = ["read_mat"]

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
) -> Experiment:
    """Read the vectors of a MAT file into an Experiment.

    Parameters
    ----------
    path : path-like
        The file (v4, v5/v7 or v7.3).
    variables : sequence of str, optional
        Vectors to load as channels; default all vectors in the file.
    time : str, optional
        A vector of time stamps [s]; it gives ``dt`` and ``t0``.
    dt : float, optional
        Sample period [s] when there is no ``time`` vector.
    roles : mapping of str to list of str, optional
        Role to variable names, e.g. ``{"u": ["vir"], "y": ["qm"]}``; the
        others become side channels.

    Returns
    -------
    Experiment
        Named after the file stem; scalars and strings are in ``notes``.

    Raises
    ------
    FileFormatError
        Not a MAT file, truncated, or vectors of different lengths.
    ChannelError
        A variable named in ``variables``, ``time`` or ``roles`` is missing.
    ImportError
        A v7.3 file and h5py is not installed.
    """
    path = existing_file(path)
    if _is_hdf5(path):
        raw = _load_v73(path)
    else:
        with library_errors(path, "a MAT file"):
            from scipy.io import loadmat

            loaded = loadmat(path, squeeze_me=False, chars_as_strings=True)
            raw = {k: v for k, v in loaded.items() if not k.startswith("__")}
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
    wanted = list(variables) if variables is not None else [n for n in vectors if n != time]
    for name in [*wanted, *([time] if time is not None else [])]:
        if name in vectors:
            continue
        if name in skipped or name in notes:
            shape = skipped.get(name, (1, 1))
            raise FileFormatError(
                f"{path}: variable {name!r} has shape {shape}, not a vector"
            )
        raise ChannelError(
            f"variable {name!r} is not in {path}; its vectors are: {', '.join(vectors) or 'none'}"
        )
    used = {n: vectors[n] for n in wanted}
    stamps = vectors[time] if time is not None else None
    lengths = {n: v.size for n, v in used.items()}
    if stamps is not None:
        lengths[str(time)] = stamps.size
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{n}: {k}" for n, k in lengths.items())
        raise FileFormatError(
            f"{path}: vectors have different lengths ({listed}); pass variables= to choose"
        )
    if not used:
        raise FileFormatError(f"{path}: no vectors to load (variables: {', '.join(raw)})")
    if time is None and dt is None:
        raise DataError(
            f"{path}: no sample period: pass dt [s] or time=<vector name> "
            f"(vectors: {', '.join(vectors)})"
        )
    return build_experiment(
        path, used, {}, roles=roles, dt=dt, time=stamps, notes=notes,
    )


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


def _load_v73(path: Path) -> dict[str, Any]:
    try:
        import h5py
    except ImportError as exc:
        raise ImportError(
            f"{path} is a MAT v7.3 (HDF5) file; reading it needs h5py: "
            "pip install servoid[mat73]"
        ) from exc
    out: dict[str, Any] = {}
    with library_errors(path, "a MAT v7.3 (HDF5) file"), h5py.File(path, "r") as f:
        for name, obj in f.items():
            if name.startswith("#") or not isinstance(obj, h5py.Dataset):
                continue  # references, structs and cells
            cls = obj.attrs.get("MATLAB_class", b"")
            cls = cls.decode() if isinstance(cls, bytes) else str(cls)
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
    return out
