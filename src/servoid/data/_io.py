"""Read any supported rig file, choosing the reader by format or extension."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, Literal

from .._checks import as_path
from .._errors import OptionError, check_option
from ._csv import read_csv
from ._experiment import Experiment
from ._mat import read_mat
from ._tdms import read_tdms

__all__ = ["FORMATS", "Format", "format_of", "read_experiment"]

Format = Literal["csv", "tdms", "mat"]
FORMATS: tuple[Format, ...] = ("csv", "tdms", "mat")
_EXTENSIONS: dict[str, Format] = {".csv": "csv", ".tdms": "tdms", ".mat": "mat"}
_READERS: dict[str, Callable[..., Experiment]] = {
    "csv": read_csv,
    "tdms": read_tdms,
    "mat": read_mat,
}


def format_of(path: str | os.PathLike[str], format: Format | None = None) -> Format:
    """The file format: ``format`` if given, else from the extension.

    Parameters
    ----------
    path : path-like
        The file.
    format : {"csv", "tdms", "mat"}, optional
        Explicit format; overrides the extension.

    Returns
    -------
    str
        One of :data:`FORMATS`.
    """
    path = as_path("path", path)
    if format is not None:
        check_option("format", format, FORMATS)
        return format
    ext = path.suffix.lower()
    if ext not in _EXTENSIONS:
        raise OptionError(
            f"cannot tell the format of {os.fspath(path)!r} from its extension {ext!r}; "
            f"pass format= one of {', '.join(repr(f) for f in FORMATS)} "
            f"(extensions {', '.join(_EXTENSIONS)})"
        )
    return _EXTENSIONS[ext]


def read_experiment(
    path: str | os.PathLike[str], format: Format | None = None, **kwargs: Any
) -> Experiment:
    """Read a rig file with the reader for its format.

    Parameters
    ----------
    path : path-like
        A ``.csv``, ``.tdms`` or ``.mat`` file.
    format : {"csv", "tdms", "mat"}, optional
        Overrides the extension.
    **kwargs
        Passed to :func:`read_csv`, :func:`read_tdms` or :func:`read_mat`.

    Returns
    -------
    Experiment
        The record.
    """
    return _READERS[format_of(path, format)](path, **kwargs)
