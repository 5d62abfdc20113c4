"""Shared helpers of the rig-file readers: named columns to an Experiment."""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_mapping, as_path, as_str, type_error
from .._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    OptionError,
    ServoidError,
    ServoidWarning,
    check_option,
)
from .._files import check_input_file
from .._warn import warn
from ._experiment import ROLES, Channel, Experiment, _check_time
from ._formats import DEFAULT_MAX_BYTES

__all__ = ["DEFAULT_MAX_BYTES", "TIME_UNITS", "MissingChannel", "RolesArg", "build_experiment",
           "check_file_size", "check_max_bytes", "check_reader_options", "check_time_unit",
           "existing_file", "library_errors", "time_in_seconds"]

RolesArg = Mapping[str, str | Sequence[str]] | None


#: Units a time column or vector may be given in, with their scale to seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9}

#: Relative deviation of a time step from the mean step accepted in a time column;
#: the same default as :meth:`Experiment.from_arrays`.
TIME_TOLERANCE = 1e-3


class MissingChannel(ChannelError):
    """A channel asked of a reader is not in the file.

    Carries what the file offers, so that the experiment file can say it
    in its own words (``[channels.<name>] source``).

    Parameters
    ----------
    message : str
        The reader's message.
    name : str
        The channel asked for.
    available : sequence of str
        The names the file offers.
    """

    def __init__(self, message: str, name: str, available: Sequence[str]) -> None:
        super().__init__(message)
        self.name = name
        self.available = tuple(available)


def existing_file(path: str | os.PathLike[str], what: str = "file") -> Path:
    """Return ``path`` as a Path once it names a regular file, or raise naming it.

    Checked before anything opens it (:func:`servoid._files.check_input_file`):
    a path of the wrong type is an :class:`~servoid.OptionTypeError`, a
    missing file or a dangling link a :class:`MissingFileError`; a folder,
    named pipe, device, socket or symbolic link loop a
    :class:`FileFormatError` naming what it is; a NUL byte a
    :class:`DataError`.
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        as_path("path", path)  # the house message for a wrong type
    check_input_file(path, what)
    return Path(path)


def check_reader_options(
    *,
    dt: object = None,
    roles: object = None,
    names: Mapping[str, object] | None = None,
) -> float | None:
    """Check the options every reader shares; return ``dt`` as a float or None.

    ``dt`` must be None or a positive number of seconds, ``roles`` None or a
    mapping of role to a name or a list of names; ``names`` holds further
    options that must be None or a string (``time``, ``group``).
    """
    out = None if dt is None else as_float("dt", dt, positive=True, unit="s")
    if roles is not None:
        as_mapping("roles", roles)
        for role, listed in roles.items():  # type: ignore[attr-defined]
            check_option("role", role, ROLES)
            items = [listed] if isinstance(listed, str) else listed
            if isinstance(items, (bytes, Mapping)) or not isinstance(items, Sequence) or \
                    not all(isinstance(n, str) for n in items):
                raise type_error(f"roles[{role!r}]", listed, "a channel name or a list of names")
    for key, value in (names or {}).items():
        if value is not None:
            as_str(key, value)
    return out


def check_max_bytes(max_bytes: object) -> int:
    """Return a reader's memory budget ``max_bytes``, or raise :class:`OptionError`."""
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes <= 0:
        raise OptionError(f"max_bytes must be a positive whole number of bytes, got {max_bytes!r}")
    return max_bytes


def check_file_size(path: Path, max_bytes: int) -> None:
    """Refuse a file larger than the reader's budget before opening it."""
    check_input_file(path, "file", max_bytes=max_bytes)


@contextmanager
def library_errors(path: Path, what: str) -> Iterator[None]:
    """Turn any exception of a parsing library into a :class:`FileFormatError`.

    Our own errors pass through; permission problems stay ``OSError``.
    """
    try:
        yield
    except (ServoidError, PermissionError, MemoryError):
        raise
    except Exception as exc:
        raise FileFormatError(
            f"{path}: cannot be read as {what} ({type(exc).__name__}: {exc}); if it is one, it "
            "is damaged: copy or export it again"
        ) from exc


def check_time_unit(time_unit: object) -> str | None:
    """A reader's ``time_unit`` option checked: None or one of :data:`TIME_UNITS`."""
    if time_unit is not None and (not isinstance(time_unit, str) or time_unit not in TIME_UNITS):
        raise DataError(f"time_unit must be one of {', '.join(repr(u) for u in TIME_UNITS)}, "
                        f"got {time_unit!r}")
    return time_unit


def time_in_seconds(path: Path, stamps: NDArray[Any], name: str, unit: str | None,
                    fix: str, *, what: str = "time column") -> NDArray[np.float64]:
    """Time stamps as seconds [s], refusing integer ticks read without a unit.

    With ``unit`` (the file's or the caller's) the stamps are scaled by it.
    Without one, stamps stored as integers (int64 nanoseconds from a logger),
    or whole numbers stepping by 1 or more (milliseconds written as 0, 1, 2,
    …) are a :class:`FileFormatError` naming ``fix``: read as seconds they
    give a dt 1000 or 10⁹ times too long and every result would be off by
    that factor. Stamps stepping by 0.1 s or more over hundreds of samples
    draw a :class:`~servoid.ServoidWarning`, before any result is computed.

    Parameters
    ----------
    path : pathlib.Path
        The file, for messages.
    stamps : numpy.ndarray
        The time stamps as stored (any real dtype).
    name : str
        The column, channel or variable.
    unit : str or None
        A key of :data:`TIME_UNITS`, or None: not stated.
    fix : str
        How to state the unit, in the reader's words.
    what : str
        ``"time column"``, ``"time vector"``, ``"time channel"``.

    Returns
    -------
    numpy.ndarray
        float64 seconds.
    """
    if unit is not None:
        scale = TIME_UNITS[unit]
        values = np.asarray(stamps, dtype=float)
        return values * scale if scale != 1.0 else values
    integer = stamps.dtype.kind in "iu"
    values = np.asarray(stamps, dtype=float)
    if values.size < 2:
        return values  # the Experiment says why it needs two
    head = values[:1001]
    step = float(np.median(np.diff(head)))
    whole = bool(np.all(np.isfinite(head))) and bool(np.all(head == np.round(head)))
    if integer or (whole and step >= 1.0):
        kind = f"holds integers ({stamps.dtype})" if integer else "holds whole numbers"
        guess = ("clock ticks (nanoseconds or microseconds?)" if step >= 1000 else
                 "likely milliseconds or a sample count")
        raise FileFormatError(
            f"{path}: {what} {name!r} has no unit and {kind} stepping by {step:g}: "
            f"{guess}, not seconds (read as seconds, dt would be {step:g} s and every result "
            f"off by that factor); give the unit: {fix}"
        )
    if step >= 0.1 and values.size >= 200:
        warn(f"{path}: {what} {name!r} has no unit and steps by {step:g} s, a slow rate for a "
             f"servo test ({1 / step:g} Hz); if it is in another unit, say so: {fix}",
             ServoidWarning)
    return values


def build_experiment(
    path: Path,
    columns: Mapping[str, NDArray[Any]],
    units: Mapping[str, str],
    *,
    roles: RolesArg = None,
    default_roles: Mapping[str, str] | None = None,
    dt: float | None = None,
    time: NDArray[np.float64] | None = None,
    t0: float = 0.0,
    notes: Mapping[str, Any] | None = None,
    jitter: float = TIME_TOLERANCE,
) -> Experiment:
    """Assemble an Experiment from the named columns of a file.

    Time stamps must be uniform within ``jitter`` (a fraction of the mean
    step); the nominal dt is then their mean step.

    Channels mapped in ``roles`` come first (role order r, u, y, side, then the
    order listed), the others follow as side channels in file order. Errors
    from validation are prefixed with the file name.
    """
    table = _role_table(path, list(columns), roles, default_roles)
    order = sorted(columns, key=lambda n: (ROLES.index(table[n]), _listed_rank(n, roles)))
    try:
        channels = tuple(Channel(n, table[n], columns[n], units.get(n, "")) for n in order)
        n = channels[0].values.size if channels else 0
        if not channels:
            raise DataError("no numeric channels found")
        if time is not None:
            dt_t, t0 = _check_time(np.asarray(time, dtype=float), n, check_jitter(jitter))
            if dt is not None and not np.isclose(dt, dt_t, rtol=max(jitter, TIME_TOLERANCE)):
                raise DataError(f"dt = {dt} s disagrees with the time stamps (mean step {dt_t} s)")
            dt = dt_t
        if dt is None:
            raise DataError("no sample period: the file has no time information, pass dt [s]")
        return Experiment(channels, dt, t0=t0, name=path.stem, notes=dict(notes or {}))
    except FileFormatError:
        raise
    except DataError as exc:
        raise DataError(f"{path}: {exc}") from exc


def check_jitter(jitter: float) -> float:
    """The time-stamp tolerance as a fraction of the step, in (0, 0.5]."""
    if isinstance(jitter, bool) or not isinstance(jitter, (int, float)) or not 0 < jitter <= 0.5:
        raise DataError(f"jitter must be a fraction of the sample period in (0, 0.5], got "
                        f"{jitter!r}")
    return float(jitter)


def _listed_rank(name: str, roles: RolesArg) -> int:
    for listed in (roles or {}).values():
        names = [listed] if isinstance(listed, str) else list(listed)
        if name in names:
            return names.index(name)
    return 0


def _role_table(
    path: Path,
    names: list[str],
    roles: RolesArg,
    default_roles: Mapping[str, str] | None,
) -> dict[str, str]:
    if roles is None:
        table = {n: "side" for n in names}
        for n, role in (default_roles or {}).items():
            if n in table and role in ROLES:
                table[n] = role
        return table
    table = {n: "side" for n in names}
    seen: dict[str, str] = {}
    for role, listed in roles.items():
        check_option("role", role, ROLES)
        for n in [listed] if isinstance(listed, str) else list(listed):
            if n not in table:
                raise ChannelError(
                    f"channel {n!r} (role {role!r}) is not in {path}; the file has: "
                    f"{', '.join(names)}"
                )
            if n in seen and seen[n] != role:
                raise DataError(f"channel {n!r} is given two roles: {seen[n]!r} and {role!r}")
            seen[n] = role
            table[n] = role
    return table
