"""Rig-file formats: one record each, and the registry every reader and writer uses.

A :class:`RigFormat` says everything servoid knows about a format: its
name, its file name extensions, its reader and writer, the ``[data]`` keys
only it takes, how its reader is told to read only the mapped channels,
and the readers' memory budget.  The experiment file, the benches, the
command line (``servoid excite --out x.csv``, ``servoid bench --format``)
and the fleet find a format here, by name or by extension, instead of
branching on suffixes of their own.

The readers and writers are imported when first called, so that the
command line lists the formats without loading numpy.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal

from .._errors import OptionError, OptionTypeError, check_option

if TYPE_CHECKING:
    from ._experiment import Experiment

__all__ = ["DEFAULT_MAX_BYTES", "FORMATS", "RIG_FORMATS", "Format", "RigFormat", "format_of",
           "read_experiment"]

Format = Literal["csv", "tdms", "mat"]

#: Default memory budget of the readers [bytes]: 2 GiB, 2.7e8 doubles (a MAT variable, a
#: TDMS channel, a CSV file's text).
DEFAULT_MAX_BYTES = 2**31

#: Reads the channels ``sources`` only: ``(path, sources, options) -> reader keywords``.
Select = Callable[[Path, Sequence[str], Mapping[str, Any]], Mapping[str, Any]]


@dataclass(frozen=True)
class RigFormat:
    """One rig-file format: its name, extensions, reader and writer.

    Parameters
    ----------
    name : str
        The format's name, as ``[data] format`` and ``--format`` give it.
    label : str
        Its name in messages (``"CSV"``).
    suffixes : tuple of str
        File name extensions, lower case with the dot (``(".csv",)``).
    reader : callable
        ``reader(path, **options) -> Experiment``.
    writer : callable or None
        ``writer(exp, path, overwrite=False) -> Path``; None: read only.
    options : tuple of str
        The ``[data]`` keys (reader keywords) that only this format takes.
    select : callable
        ``select(path, sources, options)``: the reader keywords that read
        only the channels ``sources``, given the ``options`` already set.
    time : str or None
        The time column its reader looks for when ``[data] time`` is not
        set, and the one its writer writes (None: the format carries its
        timing otherwise).
    max_bytes : int
        The reader's default memory budget [bytes] (``[data] max_bytes``).
    budget : str
        What the budget bounds, for messages (``"the file"``).
    """

    name: str
    label: str
    suffixes: tuple[str, ...]
    reader: Callable[..., Experiment]
    writer: Callable[..., Path] | None
    options: tuple[str, ...]
    select: Select
    time: str | None = None
    max_bytes: int = DEFAULT_MAX_BYTES
    budget: str = "the file"

    def __post_init__(self) -> None:
        for key in ("name", "label", "budget"):
            value = getattr(self, key)
            if not isinstance(value, str) or not value:
                raise OptionTypeError(f"RigFormat {key} must be a non-empty string, got "
                                      f"{value!r}")
        for key in ("suffixes", "options"):
            value = getattr(self, key)
            if isinstance(value, str) or not isinstance(value, (tuple, list)) or not all(
                    isinstance(v, str) and v for v in value):
                raise OptionTypeError(f"RigFormat {key} must be a tuple of strings, got "
                                      f"{value!r}")
            object.__setattr__(self, key, tuple(value))
        if not self.suffixes or not all(s.startswith(".") and s == s.lower()
                                        for s in self.suffixes):
            raise OptionError(f"RigFormat suffixes must be lower-case extensions with the dot, "
                              f"e.g. ('.csv',); got {self.suffixes!r}")
        for key in ("reader", "select"):
            if not callable(getattr(self, key)):
                raise OptionTypeError(f"RigFormat {key} must be callable, got "
                                      f"{getattr(self, key)!r}")
        if self.writer is not None and not callable(self.writer):
            raise OptionTypeError(f"RigFormat writer must be callable or None, got "
                                  f"{self.writer!r}")
        if self.time is not None and (not isinstance(self.time, str) or not self.time):
            raise OptionTypeError(f"RigFormat time must be a column name or None, got "
                                  f"{self.time!r}")
        if isinstance(self.max_bytes, bool) or not isinstance(self.max_bytes, int) \
                or self.max_bytes < 1:
            raise OptionError(f"RigFormat max_bytes must be a whole number of bytes >= 1, got "
                              f"{self.max_bytes!r}")

    @classmethod
    def named(cls, format: str | RigFormat) -> RigFormat:
        """The registered format of this name.

        Parameters
        ----------
        format : str or RigFormat
            A name of :data:`RIG_FORMATS` (a RigFormat is returned as is).

        Returns
        -------
        RigFormat
            The format.

        Raises
        ------
        OptionError
            An unknown name; the message lists the registered ones.
        """
        if isinstance(format, RigFormat):
            return format
        check_option("format", format, RIG_FORMATS)
        return RIG_FORMATS[format]  # type: ignore[index]

    @classmethod
    def of(cls, path: str | os.PathLike[str], format: str | None = None) -> RigFormat:
        """The format of a file: ``format`` if given, else from its extension.

        Parameters
        ----------
        path : path-like
            The file.
        format : str, optional
            A name of :data:`RIG_FORMATS`; overrides the extension.

        Returns
        -------
        RigFormat
            The format.
        """
        return RIG_FORMATS[format_of(path, format)]  # type: ignore[arg-type]

    @classmethod
    def find(cls, path: str | os.PathLike[str]) -> RigFormat | None:
        """The registered format whose extension ``path`` has, or None."""
        return next((f for f in RIG_FORMATS.values() if f.matches(path)), None)

    @classmethod
    def writable(cls, first: str | None = None) -> tuple[str, ...]:
        """The names of the formats servoid writes, ``first`` leading.

        Parameters
        ----------
        first : str, optional
            The name to put first (a command's default).

        Returns
        -------
        tuple of str
            Names, in registry order after ``first``.
        """
        names = tuple(name for name, fmt in RIG_FORMATS.items() if fmt.writer is not None)
        if first is not None:
            check_option("first", first, names)
            names = (first, *(n for n in names if n != first))
        return names

    def matches(self, path: str | os.PathLike[str]) -> bool:
        """True when ``path`` has one of this format's extensions."""
        return Path(path).suffix.lower() in self.suffixes

    def read(self, path: str | os.PathLike[str], **options: Any) -> Experiment:
        """Read a file of this format (``options``: the reader's keywords)."""
        return self.reader(path, **options)

    def write(self, exp: Experiment, path: str | os.PathLike[str], *,
              overwrite: bool = False) -> Path:
        """Write a record as a file of this format, atomically.

        Parameters
        ----------
        exp : Experiment
            The record.
        path : path-like
            The file to write.
        overwrite : bool
            Replace an existing file; otherwise :class:`OutputExistsError`.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        if self.writer is None:
            raise OptionError(
                f"servoid reads {self.label} files but does not write them; write one of "
                f"{', '.join(repr(n) for n in RigFormat.writable())}")
        return self.writer(exp, path, overwrite=overwrite)


def format_of(path: str | os.PathLike[str], format: str | None = None) -> Format:
    """The file format's name: ``format`` if given, else from the extension.

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
    from .._checks import as_path  # numpy: not for the command line's --help

    path = as_path("path", path)
    if format is not None:
        check_option("format", format, FORMATS)
        return format  # type: ignore[return-value]
    ext = path.suffix.lower()
    for fmt in RIG_FORMATS.values():
        if ext in fmt.suffixes:
            return fmt.name  # type: ignore[return-value]
    raise OptionError(
        f"cannot tell the format of {os.fspath(path)!r} from its extension {ext!r}; "
        f"pass format= one of {', '.join(repr(f) for f in FORMATS)} "
        f"(extensions {', '.join(s for f in RIG_FORMATS.values() for s in f.suffixes)})"
    )


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
    return RigFormat.of(path, format).read(path, **kwargs)


# -- the formats -------------------------------------------------------------------------------


def _read_csv(path: str | os.PathLike[str], **options: Any) -> Experiment:
    from ._csv import read_csv

    return read_csv(path, **options)


def _write_csv(exp: Experiment, path: str | os.PathLike[str], *,
               overwrite: bool = False) -> Path:
    from ._csv import write_csv

    return write_csv(exp, path, overwrite=overwrite)


def _select_csv(path: Path, sources: Sequence[str],
                options: Mapping[str, Any]) -> Mapping[str, Any]:
    """Convert only the mapped columns (memory on a wide logger file).

    Only when the options choose no columns themselves and each source is
    in the header once; else the reader reads all and says what is wrong.
    """
    if "columns" in options or "skip_columns" in options:
        return {}
    from ._csv import header_names

    needed = list(dict.fromkeys(sources))
    names = header_names(path, delimiter=options.get("delimiter", ","),
                         skip_rows=options.get("skip_rows", 0))
    if names is not None and all(names.count(n) == 1 for n in needed):
        return {"columns": needed}
    return {}


def _read_tdms(path: str | os.PathLike[str], **options: Any) -> Experiment:
    from ._tdms import read_tdms

    return read_tdms(path, **options)


def _write_tdms(exp: Experiment, path: str | os.PathLike[str], *,
                overwrite: bool = False) -> Path:
    from ._tdms import write_tdms

    return write_tdms(exp, path, overwrite=overwrite)


def _select_tdms(path: Path, sources: Sequence[str],
                 options: Mapping[str, Any]) -> Mapping[str, Any]:
    return {"channels": list(dict.fromkeys(sources))}


def _read_mat(path: str | os.PathLike[str], **options: Any) -> Experiment:
    from ._mat import read_mat

    return read_mat(path, **options)


def _select_mat(path: Path, sources: Sequence[str],
                options: Mapping[str, Any]) -> Mapping[str, Any]:
    return {"variables": sorted(set(sources))}


#: Every rig-file format servoid reads, by name, in the order messages list them.
RIG_FORMATS: Mapping[str, RigFormat] = MappingProxyType({f.name: f for f in (
    RigFormat("csv", "CSV", (".csv",), _read_csv, _write_csv,
              ("delimiter", "decimal", "time_unit", "columns", "skip_columns", "skip_rows"),
              _select_csv, time="time", budget="the file's text"),
    RigFormat("tdms", "TDMS", (".tdms",), _read_tdms, _write_tdms, ("group",), _select_tdms,
              budget="each channel"),
    RigFormat("mat", "MAT", (".mat",), _read_mat, None, (), _select_mat,
              budget="each variable"),
)})
#: The names of :data:`RIG_FORMATS`.
FORMATS: tuple[Format, ...] = tuple(RIG_FORMATS)  # type: ignore[assignment]
