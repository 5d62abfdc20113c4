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
    MissingFileError,
    OptionError,
    ServoidError,
    check_option,
)
from ._experiment import ROLES, Channel, Experiment, _check_time

__all__ = ["DEFAULT_MAX_BYTES", "MissingChannel", "RolesArg", "build_experiment",
           "check_file_size", "check_max_bytes", "check_reader_options", "existing_file",
           "library_errors"]

RolesArg = Mapping[str, str | Sequence[str]] | None

#: Default memory budget of the readers [bytes]: 2 GiB, 2.7e8 doubles (a MAT variable, a
#: TDMS channel, a CSV file's text).
DEFAULT_MAX_BYTES = 2**31

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


def existing_file(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a Path, or raise :class:`MissingFileError` naming it.

    A path of the wrong type is an :class:`~servoid.OptionTypeError`, a
    folder or device a :class:`FileFormatError`.
    """
    path = as_path("path", path)
    if not path.exists():
        raise MissingFileError(
            f"{path}: no such file; check the path (relative paths are taken from {Path.cwd()})"
        )
    if not path.is_file():
        raise FileFormatError(f"{path} is not a regular file; pass the path of a file")
    return path


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
    """Refuse a file larger than the reader's budget before reading it."""
    size = path.stat().st_size
    if size > max_bytes:
        raise DataError(
            f"{path} has {size:,} bytes, over the budget of {max_bytes:,} bytes; if the file is "
            "what you meant to read, pass max_bytes= a larger budget"
        )


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
