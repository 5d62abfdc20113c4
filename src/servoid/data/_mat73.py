"""MAT v7.3 (HDF5) rig files, read in a watched child process.

libhdf5 trusts the file: a damaged one can make it loop forever or crash,
and HDF5 can point outside the file (external links, external raw storage,
virtual datasets) to any file the user can read. So a v7.3 file is read

* in a forked child (:func:`~servoid.data._child.run_watched`) that sends a
  heartbeat after each piece it reads and is killed when silent for
  :data:`~servoid.data._child.STALL_SECONDS`;
* naming only the variables asked for (and scalars and one-row strings for
  the notes), each checked before it is read: its declared shape × item
  size against the memory budget, its stored bytes against its declared
  size (a dataset that stores nothing is all fill value: 2 GiB from a few
  hundred bytes of file), its ``MATLAB_class`` attribute only when it is
  small;
* refusing external links, external raw storage and virtual datasets
  unless the caller allows them (``allow_external=True``): they read other
  files, which the user never named.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ChannelError, FileFormatError
from . import _child
from ._child import run_watched
from ._columns import library_errors
from ._mat_check import _KIND_WORDS, MatEntry, format_bytes

__all__ = ["load_v73"]

#: Bytes read between two heartbeats of the child [bytes].
_PIECE_BYTES = 4 * 2**20
#: Largest ratio of declared to stored bytes of a filtered dataset: deflate reaches
#: 1032:1; n-bit and scale-offset packing can add up to 64:1 before it.
_DEFLATE_RATIO, _PACKING_RATIO = 1100, 64
_PACKING_FILTERS = (5, 6)  # H5Z_FILTER_NBIT, H5Z_FILTER_SCALEOFFSET
#: Soft links followed in a row before the path is taken for a loop.
_MAX_HOPS = 16
#: Longest attribute servoid reads (MATLAB_class is a word, MATLAB_empty a flag) [bytes].
_ATTR_BYTES = 256


def load_v73(path: Path, wanted: set[str] | None, max_bytes: int, allow_external: bool = False,
             ) -> tuple[dict[str, Any], dict[str, MatEntry]]:
    """The datasets of a v7.3 file within the budget, and those left unread.

    Parameters
    ----------
    path : pathlib.Path
        The file, checked to be a regular file.
    wanted : set of str or None
        Variables to read (dotted for struct fields); None: every top-level one.
    max_bytes : int
        Memory budget of one variable [bytes].
    allow_external : bool
        Follow external links and read external or virtual storage.

    Returns
    -------
    tuple
        ``(values, listed)``: name → array or string, and the entries not read.
    """
    try:
        import h5py  # noqa: F401 - imported before the fork, so the child need not
    except ImportError as exc:
        raise ImportError(
            f"{path} is a MAT v7.3 (HDF5) file; reading it needs h5py: "
            "pip install servoid[mat73]"
        ) from exc

    def job(beat: Callable[[], None]) -> tuple[dict[str, Any], dict[str, MatEntry]]:
        return _Reader(path, max_bytes, allow_external, beat).read(wanted)

    return run_watched(job, path, "a MAT v7.3 (HDF5) file")


class _Reader:
    """The walk of one v7.3 file (runs in the child)."""

    def __init__(self, path: Path, max_bytes: int, allow_external: bool,
                 beat: Callable[[], None]) -> None:
        self.path, self.max_bytes, self.allow_external, self.beat = (
            path, max_bytes, allow_external, beat)

    def read(self, wanted: set[str] | None) -> tuple[dict[str, Any], dict[str, MatEntry]]:
        import h5py

        out: dict[str, Any] = {}
        listed: dict[str, MatEntry] = {}
        with library_errors(self.path, "a MAT v7.3 (HDF5) file"), \
                h5py.File(self.path, "r", locking=False) as f:
            self.beat()
            for name in list(f.keys()):
                self.beat()
                if name.startswith("#"):
                    continue  # what references point to
                named = wanted is not None and name in wanted
                asked = wanted is None or named
                try:
                    obj = self._follow(f, name, name, named)
                    if obj is None:  # a link out of the file, not named: never opened
                        listed[name] = MatEntry(name, "external", (1, 1))
                        continue
                    if not isinstance(obj, h5py.Dataset):
                        if isinstance(obj, h5py.Group):  # a struct: fields are named with dots
                            listed[name] = MatEntry(name, "struct", (1, 1))
                        continue
                    shape = tuple(int(d) for d in reversed(obj.shape))  # MATLAB's order
                    kind: Any = _kind(obj)
                except Exception:
                    if named:
                        raise
                    listed[name] = MatEntry(name, "unknown", (1, 1))  # damaged, not named: left
                    continue
                entry = MatEntry(name, kind, shape)
                note = entry.is_note and kind in ("numeric", "char")
                if not asked and not note:
                    listed[name] = entry
                    continue
                if kind not in ("numeric", "char"):
                    listed[name] = entry
                    continue
                if _small_attr(obj, "MATLAB_empty"):
                    continue  # MATLAB's [] or '': the dataset holds its dimensions
                value = self._dataset(obj, name, shape, strict=asked)
                if value is None:
                    listed[name] = entry
                else:
                    out[name] = value
            for name in sorted(n for n in wanted or () if "." in n):
                self._field(f, name, out, listed)
        return out, listed

    def _follow(self, group: Any, part: str, name: str, asked: bool, hops: int = 0) -> Any:
        """``group[part]``, refusing a link out of the file unless allowed; None: skipped.

        A soft link is followed here, component by component, so that one
        whose path runs through an external link is refused too.
        """
        import h5py

        link = group.get(part, getlink=True)
        if isinstance(link, h5py.ExternalLink) and not self.allow_external:
            if not asked:
                return None
            raise FileFormatError(
                f"{self.path}: variable {name!r} is an external link to {link.filename!r} "
                f"({link.path}): reading it would open another file, which you did not name; "
                "copy the data into this file, or pass allow_external=True if you trust it"
            )
        if not isinstance(link, h5py.SoftLink) or self.allow_external:
            return group[part]
        if hops >= _MAX_HOPS:
            raise FileFormatError(
                f"{self.path}: variable {name!r} goes through more than {_MAX_HOPS} soft links "
                "(a loop of links?): a damaged file"
            )
        node = group.file if link.path.startswith("/") else group
        for step in (s for s in link.path.split("/") if s and s != "."):
            if not isinstance(node, h5py.Group) or step not in node:
                raise FileFormatError(
                    f"{self.path}: variable {name!r} is a soft link to {link.path!r}, which is "
                    "not in the file: a damaged file"
                )
            node = self._follow(node, step, name, asked, hops + 1)
            if node is None:
                return None
        return node

    def _dataset(self, obj: Any, name: str, shape: tuple[int, ...], *,
                 strict: bool) -> Any:
        """The checked values of one dataset (MATLAB's order), or None when left out."""
        try:
            self._check_dataset(obj, name, shape)
        except FileFormatError:
            if strict:
                raise
            return None  # a damaged note nobody asked for is left out
        data = self._values(obj).T  # MATLAB writes column-major arrays: HDF5 holds them transposed
        cls = _small_attr(obj, "MATLAB_class")
        if cls == "char":
            return "".join(chr(int(c)) for c in data.ravel())
        if cls == "logical":
            return data.astype(bool)
        return data

    def _check_dataset(self, obj: Any, name: str, shape: tuple[int, ...]) -> None:
        nbytes = int(np.prod(shape, dtype=object)) * obj.dtype.itemsize
        if nbytes > self.max_bytes:
            raise FileFormatError(
                f"{self.path}: variable {name!r} declares shape {shape} of "
                f"{obj.dtype.itemsize}-byte values ({format_bytes(nbytes)}), over the "
                f"{format_bytes(self.max_bytes)} budget: a damaged file, or pass max_bytes= "
                "to read a variable this large"
            )
        if not self.allow_external and (obj.external or obj.is_virtual):
            where = ", ".join(str(e[0]) for e in obj.external or ()) or "other files"
            raise FileFormatError(
                f"{self.path}: variable {name!r} keeps its values in {where} "
                f"({'virtual dataset' if obj.is_virtual else 'external storage'}): reading it "
                "would open files you did not name; copy the data into this file, or pass "
                "allow_external=True if you trust it"
            )
        if nbytes == 0 or obj.external or obj.is_virtual or _small_attr(obj, "MATLAB_empty"):
            return
        stored = int(obj.id.get_storage_size())
        plist = obj.id.get_create_plist()
        filters = [plist.get_filter(k)[0] for k in range(plist.get_nfilters())]
        ratio = 1 if not filters else _DEFLATE_RATIO * (
            _PACKING_RATIO if any(f in _PACKING_FILTERS for f in filters) else 1)
        if stored * ratio < nbytes:
            raise FileFormatError(
                f"{self.path}: variable {name!r} declares shape {shape} "
                f"({format_bytes(nbytes)}) but stores only {format_bytes(stored)}: the rest "
                "was never written and would read as the fill value; a damaged or "
                "hand-made file (MATLAB writes every value)"
            )

    def _values(self, obj: Any) -> np.ndarray:
        """Read a dataset in pieces of :data:`_PIECE_BYTES`, beating between them."""
        if obj.ndim == 0 or obj.size == 0:
            value = np.asarray(obj[()])
            self.beat()
            return value
        out = _child.empty(obj.shape, obj.dtype)  # shared with the parent: no copy back
        axis = int(np.argmax(obj.shape))
        per = max(1, obj.size // obj.shape[axis]) * obj.dtype.itemsize
        step = max(1, _PIECE_BYTES // per)
        for lo in range(0, obj.shape[axis], step):
            sel = tuple(slice(lo, lo + step) if k == axis else slice(None)
                        for k in range(obj.ndim))
            obj.read_direct(out, source_sel=sel, dest_sel=sel)
            self.beat()
        return out

    def _field(self, f: Any, name: str, out: dict[str, Any],
               listed: dict[str, MatEntry]) -> None:
        """Read the struct field ``name`` (dotted) into ``out``."""
        import h5py

        parts = name.split(".")
        node = f
        for depth, part in enumerate(parts):
            self.beat()
            here = ".".join(parts[:depth])
            if depth and not isinstance(node, h5py.Group):
                kind = _kind(node)
                raise ChannelError(
                    f"{self.path}: {here!r} is {_KIND_WORDS.get(kind, kind)}, not a struct: it "
                    "has no fields to name with a dot"
                )
            if depth and any(_is_reference(node.get(k)) and
                             _small_attr(node.get(k), "MATLAB_class") != "cell"
                             for k in node if not k.startswith("#") and
                             not isinstance(node.get(k, getlink=True), h5py.ExternalLink)):
                raise FileFormatError(
                    f"{self.path}: {here!r} is a struct array; servoid reads fields of a 1×1 "
                    "struct only: save each element as its own struct (or the signals as "
                    "numeric fields of one struct)"
                )
            if part not in node or part.startswith("#"):
                if depth == 0:
                    return  # not in the file: the reader lists what there is
                fields = [k for k in node if not k.startswith("#")]
                raise ChannelError(
                    f"variable {name!r} is not in {self.path}: the struct {here!r} has the "
                    f"field(s) {', '.join(fields) or '(none)'}"
                )
            node = self._follow(node, part, name, True)
        if isinstance(node, h5py.Group):
            listed[name] = MatEntry(name, "struct", (1, 1))
            return
        shape = tuple(int(d) for d in reversed(node.shape))
        kind = _kind(node)
        if kind != "numeric":
            listed[name] = MatEntry(name, kind, shape)
            return
        self._check_dataset(node, name, shape)
        out[name] = np.zeros((0, 0)) if _small_attr(node, "MATLAB_empty") else \
            self._values(node).T


def _small_attr(node: Any, key: str) -> Any:
    """A scalar attribute of a few bytes (a class name, a flag), else None.

    Read only after its shape and type are known to be small: an attribute
    of a damaged file may declare any size.
    """
    try:
        if key not in node.attrs:
            return None
        attr = node.attrs.get_id(key)
        if attr.shape not in ((), (1,)) or attr.dtype.itemsize > _ATTR_BYTES or \
                attr.dtype.kind not in "SUiub":
            return None
        value = np.asarray(node.attrs[key]).ravel()
    except Exception:  # noqa: BLE001 - a damaged attribute is no class at all
        return None
    if value.size != 1:
        return None
    item = value[0]
    if isinstance(item, bytes):
        return item.decode(errors="replace")
    return item.item() if isinstance(item, np.generic) else item


def _is_reference(node: Any) -> bool:
    import h5py

    return isinstance(node, h5py.Dataset) and h5py.check_dtype(ref=node.dtype) is not None


def _kind(node: Any) -> str:
    """What a v7.3 dataset holds, in the words of :data:`_KIND_WORDS`."""
    cls = _small_attr(node, "MATLAB_class")
    if cls in ("cell", "struct", "char"):
        return str(cls)
    if _is_reference(node):
        return "cell"
    return "numeric" if node.dtype.kind in "biuf" else "unknown"
