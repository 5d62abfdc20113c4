"""LabVIEW TDMS rig files, read and written with npTDMS.

One group holds the channels of a run, or several groups do (a logger
that files each card or rate in its own group): channels are then named
``"group/channel"``, or by their bare name when only one group has it.
Each channel carries the waveform properties ``wf_increment`` (sample
period [s]), ``wf_start_offset`` (time of the first sample [s]) and
``unit_string``. servoid also writes
``servoid_role`` per channel and the experiment's simple notes as group
properties; group properties read back become ``Experiment.notes``.

A file is untrusted input, and npTDMS believes its declared sizes: a string
length is passed to ``file.read`` (which allocates it before reading) and a
value count to ``np.zeros``. So npTDMS reads through a file object whose
``read`` never asks for more than the bytes left, the metadata is read
first, and every channel's declared length is checked against the file size
before its data is read. A ``.tdms_index`` file beside the data is ignored:
it only repeats the metadata, and a stale one would describe other data.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_path
from .._checks import as_bool, as_path, as_str, as_str_list
from .._errors import ChannelError, DataError, FileFormatError, OptionError
from .._files import open_input
from ._columns import (
    DEFAULT_MAX_BYTES,
    TIME_TOLERANCE,
    MissingChannel,
    RolesArg,
    build_experiment,
    check_max_bytes,
    check_reader_options,
    check_time_unit,
    existing_file,
    library_errors,
    time_in_seconds,
)
from ._experiment import Experiment, check_experiment, timing_problem

__all__ = ["read_tdms", "write_tdms"]

_ROLE_PROPERTY = "servoid_role"
# npTDMS reports a truncated file by logging these and returning partial data.
_TRUNCATION_HINTS = ("less data than expected", "incomplete", "not a multiple")


def read_tdms(
    path: str | os.PathLike[str],
    *,
    group: str | None = None,
    roles: RolesArg = None,
    dt: float | None = None,
    time: str | None = None,
    channels: Sequence[str] | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    jitter: float = TIME_TOLERANCE,
    time_unit: str | None = None,
) -> Experiment:
    """Read channels of one or more groups of a TDMS file.

    Parameters
    ----------
    path : path-like
        The file.
    group : str, optional
        Group to read; may be omitted when the file has exactly one, or
        when ``channels`` names the channels.
    roles : mapping of str to list of str, optional
        Role to channel names, e.g. ``{"r": ["AI0"], "y": ["AI1"]}``. Channels
        not mapped become side channels. Default: the ``servoid_role``
        property written by :func:`write_tdms`, else side.
    dt : float, optional
        Sample period [s] when the channels have no ``wf_increment``;
        otherwise it must agree with it.
    time : str, optional
        A channel of time stamps [s] to use instead of waveform properties.
    channels : sequence of str, optional
        The channels to read, each ``"group/channel"`` or a bare channel
        name that only one group (or ``group``) has; the Experiment's
        channels carry these names. Default: every numeric channel of the
        group. Only these are read from the file.
    max_bytes : int
        Memory budget of one channel as float64 [bytes]; default 2 GiB. A
        channel declaring more values is refused before it is read.
    jitter : float
        Largest deviation of a time step from the mean step, as a fraction
        of it (default 1e-3); raise it for a logger with time-stamp jitter.
    time_unit : {"s", "ms", "us", "ns"}, optional
        Unit of the ``time`` channel. Without it, a time channel of integers
        (clock ticks) or of whole numbers stepping by 1 or more is refused:
        read as seconds, every result would be off by the tick's factor.

    Returns
    -------
    Experiment
        Named after the file stem; ``notes`` holds the group properties
        (as ``"group/key"`` when channels of several groups are read).

    Raises
    ------
    FileFormatError
        Not a TDMS file, truncated, channels of unequal length or period.
    OptionError
        ``group`` missing or not given when the file has several groups
        and ``channels`` is not given; a bare channel name that several
        groups have.
    ChannelError
        A channel of ``channels`` or ``time`` is not in the file.
    DataError
        A channel over the memory budget `max_bytes`.
    """
    path = existing_file(path)
    dt = check_reader_options(dt=dt, roles=roles, names={"group": group, "time": time})
    if channels is not None:
        channels = as_str_list("channels", channels, min_length=1)
    max_bytes = check_max_bytes(max_bytes)
    time_unit = check_time_unit(time_unit)
    with _truncation_watch() as warnings, library_errors(path, "TDMS"), \
            open_input(path, "file") as file:
        from nptdms import TdmsFile

        tdms = TdmsFile.open(file)  # metadata only; data below, channel by channel
        groups = {g.name: g for g in tdms.groups()}
        if warnings:
            raise _damaged(path, warnings[0])
        if channels is None:
            tdms_group = groups[_pick_group(path, list(groups), group)]
            chosen = [(ch.name, ch) for ch in tdms_group.channels() if _numeric(ch)]
            used = [tdms_group]
        else:
            if not groups:
                raise FileFormatError(f"{path}: no groups: an empty or truncated TDMS file")
            scope = list(groups.values()) if group is None else \
                [groups[_pick_group(path, list(groups), group)]]
            wanted = [*channels, *([time] if time is not None and time not in channels else [])]
            chosen = [(name, _resolve(path, name, groups, scope)) for name in wanted]
            used = list({ch.group_name: groups[ch.group_name] for _, ch in chosen}.values())
            tdms_group = used[0]
        where = f"group {tdms_group.name!r}" if len(used) == 1 else \
            f"groups {', '.join(repr(g.name) for g in used)}"
        columns: dict[str, np.ndarray] = {}
        props: dict[str, Mapping[str, Any]] = {}
        for name, ch in chosen:
            if not _numeric(ch):
                raise FileFormatError(
                    f"{path}: channel {name!r} holds {ch.dtype or 'untyped'} values, not numbers;"
                    " name a numeric channel"
                )
            if len(ch) > file.size:  # every stored value takes at least one byte
                raise FileFormatError(
                    f"{path}: channel {ch.name!r} declares {len(ch)} values but the file has "
                    f"{file.size} bytes: a damaged TDMS file (its segment metadata is wrong)"
                )
            if 8 * len(ch) > max_bytes:
                raise DataError(
                    f"{path}: channel {ch.name!r} has {len(ch):,} values, "
                    f"{8 * len(ch):,} bytes as float64, over the budget of {max_bytes:,} bytes; if "
                    "the file is what you meant to read, pass max_bytes= a larger budget"
                )
            values = ch[:]
            columns[name] = values if name == time else np.asarray(values, dtype=float)
            props[name] = dict(ch.properties)
        if warnings:
            raise _damaged(path, warnings[0])
        if len(used) == 1:
            notes = {k: _plain(v) for k, v in tdms_group.properties.items()}
        else:
            notes = {f"{g.name}/{k}": _plain(v) for g in used for k, v in g.properties.items()}
    if not columns:
        raise FileFormatError(f"{path}: group {tdms_group.name!r} has no numeric channels")
    lengths = {n: v.size for n, v in columns.items()}
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{n}: {k}" for n, k in lengths.items())
        raise FileFormatError(
            f"{path}: channels of {where} have different lengths ({listed}); "
            + ("the file may be truncated" if len(used) == 1 else
               "channels of one record must have one length: name channels of one rate")
        )
    stamps = None
    t0 = 0.0
    if time is not None:
        if time not in columns:
            raise DataError(
                f"{path}: no time channel {time!r} in group {tdms_group.name!r}; it has: "
                f"{', '.join(columns)}"
            )
        stamps = time_in_seconds(
            path, columns.pop(time), time, time_unit,
            "pass time_unit='ms' (or 'us', 'ns', or 's' if they are seconds); in an experiment "
            "file, remove [data] time to use the waveform timing, or set [data] dt [s]",
            what="time channel")
        props.pop(time)
    else:
        dt, t0 = _waveform_timing(path, props, dt, next(iter(lengths.values()), 0))
    units = {n: str(p.get("unit_string", "")) for n, p in props.items()}
    default_roles = {n: str(p[_ROLE_PROPERTY]) for n, p in props.items() if _ROLE_PROPERTY in p}
    return build_experiment(
        path, columns, units, roles=roles, default_roles=default_roles,
        dt=dt, time=stamps, t0=t0, notes=notes, jitter=jitter,
    )


def write_tdms(
    exp: Experiment,
    path: str | os.PathLike[str],
    *,
    group: str = "servoid",
    overwrite: bool = False,
) -> Path:
    """Write an Experiment as one TDMS group, atomically.

    Parameters
    ----------
    exp : Experiment
        The record.
    path : path-like
        Target file.
    group : str
        Group name.
    overwrite : bool
        Replace an existing file; otherwise :class:`OutputExistsError`.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    check_experiment(exp, "exp")
    as_path("path", path)
    as_bool("overwrite", overwrite)
    as_str("group", group)
    notes = {k: v for k, v in exp.notes.items() if _is_simple(v)}
    objects: list[Any] = [
        RootObject(properties={"name": exp.name}),
        GroupObject(group, properties=notes),
    ]
    for ch in exp.channels:
        objects.append(
            ChannelObject(
                group,
                ch.name,
                np.ascontiguousarray(ch.values),
                properties={
                    "wf_increment": exp.dt,
                    "wf_start_offset": exp.t0,
                    "wf_samples": exp.n_samples,
                    "unit_string": ch.unit,
                    _ROLE_PROPERTY: ch.role,
                },
            )
        )
    with atomic_path(path, overwrite) as tmp, TdmsWriter(str(tmp)) as writer:
        writer.write_segment(objects)
    return Path(path)


def _damaged(path: Path, warning: str) -> FileFormatError:
    # npTDMS would go on and return what it could read: part of the record.
    return FileFormatError(
        f"{path}: truncated or damaged TDMS file ({warning}); copy or export it from the logger "
        "again"
    )


def _pick_group(path: Path, names: list[str], group: str | None) -> str:
    if group is None:
        if len(names) == 1:
            return names[0]
        if not names:
            raise FileFormatError(f"{path}: no groups: an empty or truncated TDMS file")
        raise OptionError(
            f"{path} has {len(names)} groups; pass group= one of: "
            f"{', '.join(repr(n) for n in names)} (or name each channel 'group/channel')"
        )
    if group not in names:
        raise OptionError(
            f"{path} has no group {group!r}; it has: {', '.join(repr(n) for n in names)} "
            "(pass group= one of them)"
        )
    return group


def _numeric(ch: Any) -> bool:
    """Whether a channel holds numbers (timestamps and strings are not signals)."""
    return ch.data_type is not None and ch.dtype is not None and ch.dtype.kind in "biuf"


def _resolve(path: Path, name: str, groups: Mapping[str, Any], scope: list[Any]) -> Any:
    """The channel ``name`` (bare, or ``group/channel``) of the file.

    A bare name is looked for in the groups of ``scope``; a name with a
    ``/`` may also be split at any ``/`` into a group and a channel (names
    may hold ``/`` themselves). Exactly one match is accepted.
    """
    found: dict[tuple[str, str], Any] = {}
    for g in scope:
        if name in g:
            found[(g.name, name)] = g[name]
    for k, c in enumerate(name):
        if c == "/" and name[:k] in groups and name[k + 1:] in groups[name[:k]]:
            found[(name[:k], name[k + 1:])] = groups[name[:k]][name[k + 1:]]
    if len(found) == 1:
        return next(iter(found.values()))
    if found:
        listed = ", ".join(repr(f"{g}/{c}") for g, c in found)
        raise ChannelError(
            f"{path}: channel {name!r} is in {len(found)} groups; name one as 'group/channel': "
            f"{listed}"
        )
    if len(scope) == 1:
        available = [c.name for c in scope[0].channels() if _numeric(c)]
        where = f"group {scope[0].name!r} of {path}"
    else:
        available = [f"{g.name}/{c.name}" for g in scope for c in g.channels() if _numeric(c)]
        where = str(path)
    listing = ", ".join(available) or "no numeric channels"
    raise MissingChannel(f"channel {name!r} is not in {where}; it has: {listing}", name, available)


def _waveform_timing(
    path: Path, props: Mapping[str, Mapping[str, Any]], dt: float | None, n: int
) -> tuple[float | None, float]:
    incs = {n: p.get("wf_increment") for n, p in props.items()}
    have = {n: _timing_number(path, n, "wf_increment", v) for n, v in incs.items()
            if v is not None}
    if not have:
        return dt, 0.0
    if len(have) != len(incs) or len(set(have.values())) > 1:
        listed = ", ".join(f"{n}: {incs[n]}" for n in incs)
        raise FileFormatError(
            f"{path}: channels must share one wf_increment (sample period [s]); got {listed}"
        )
    dt_file = next(iter(have.values()))
    if dt_file <= 0:
        raise FileFormatError(
            f"{path}: wf_increment (the sample period) is {dt_file} s, not > 0: fix the "
            "property in the file, or pass time= a channel of time stamps"
        )
    if dt is not None and not np.isclose(dt, dt_file, rtol=1e-9):
        raise DataError(f"{path}: dt = {dt} s disagrees with wf_increment = {dt_file} s")
    offsets = {_timing_number(path, n, "wf_start_offset", p.get("wf_start_offset", 0.0))
               for n, p in props.items()}
    if len(offsets) > 1:
        raise FileFormatError(
            f"{path}: channels have different wf_start_offset values: {sorted(offsets)}"
        )
    t0 = offsets.pop()
    problem = timing_problem(dt_file, t0, n)
    if problem:
        problem = problem.replace("dt = ", "wf_increment = ", 1).replace(
            "t0 = ", "wf_start_offset = ", 1)
        raise FileFormatError(
            f"{path}: {problem}: a damaged waveform property; fix it in the file, or pass "
            "time= a channel of time stamps"
        )
    return dt_file, t0


def _timing_number(path: Path, channel: str, key: str, value: Any) -> float:
    """A waveform property as a finite float, or an error naming the fix."""
    number = None
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
            value, (bool, np.bool_)):
        number = float(value)
    if number is None or not math.isfinite(number):
        what = "sample period" if key == "wf_increment" else "time of the first sample"
        raise FileFormatError(
            f"{path}: channel {channel!r} has {key} = {value!r} ({type(value).__name__}), "
            f"expected a finite number, the {what} [s]: fix the property in the file, or "
            "pass time= a channel of time stamps"
        )
    return number


def _is_simple(value: object) -> bool:
    return isinstance(value, (str, bool, int, float, np.integer, np.floating))


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        if isinstance(value, np.datetime64):
            return str(value)
        return value.item()
    return value


@contextmanager
def _truncation_watch() -> Iterator[list[str]]:
    seen: list[str] = []

    class _Catch(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            message = record.getMessage()
            if any(hint in message for hint in _TRUNCATION_HINTS):
                seen.append(message)

    # npTDMS gives each module logger its own stderr handler: while reading, ours replaces
    # them, so a damaged file becomes one FileFormatError and no stray lines on stderr
    handler = _Catch(logging.WARNING)
    names = ["nptdms", *(n for n in list(logging.Logger.manager.loggerDict)
                         if n.startswith("nptdms."))]
    loggers = [logging.getLogger(n) for n in names]
    saved = [(lg, lg.handlers[:], lg.propagate) for lg in loggers]
    for lg in loggers:
        lg.handlers = [handler]
        lg.propagate = False
    try:
        yield seen
    finally:
        for lg, handlers, propagate in saved:
            lg.handlers = handlers
            lg.propagate = propagate
