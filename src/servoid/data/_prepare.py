"""From an experiment file to records ready to fit: read, calibrate, preprocess, split.

:func:`prepare` is the one step between an :class:`~servoid.data.ExperimentSpec`
(plain data: what the TOML file says) and an estimator: it reads every rig
file with the reader of its :class:`~servoid.data.RigFormat`, maps and
calibrates the channels, low-passes and decimates, splits the record or
checks the validation records, removes the trend, and says what it read
(:class:`InputFile`: path, size, SHA-256).  A workflow names its inputs by
those digests, so each file is hashed once per run.

A workflow that needs the whole record again (the feedback test runs on
it) gets it without a second parse: the last record read for a spec is
kept while the spec lives and the file's size and modification time are
unchanged.
"""

from __future__ import annotations

import os
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .._checks import type_error
from .._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    OptionError,
    OptionTypeError,
    ServoidError,
)
from ._columns import MissingChannel
from ._digest import _same_file, file_status
from ._distinct import check_distinct
from ._experiment import Channel, Experiment, ExperimentSet
from ._formats import RigFormat, read_experiment
from ._preprocess import decimate, lowpass, split
from ._preprocess import detrend as _detrend
from ._spec import ExperimentSpec, load_experiment_spec
from ._spec_tables import SplitSpec, _check_like, _like

__all__ = ["InputFile", "PreparedData", "prepare", "read_record", "split_record"]

InputRole = Literal["estimation", "validation"]

# The readers' advice in Python keywords → the experiment file's keys, for their messages.
_READER_WORDS = {
    "pass dt [s] or time=<column name>": "set [data] time = \"<column name>\" (the time "
    "column), or [data] dt [s] when the file has none",
    "pass dt [s] or time=<vector name>": "set [data] time = \"<vector name>\" (the time "
    "vector), or [data] dt [s] when the file has none",
    "the file has no time information, pass dt [s]": "the file has no time information, set "
    "[data] dt [s]",
    "pass group= one of:": "set [data] group to one of:",
    "(pass group= one of them)": "(set [data] group to one of them)",
    "pass time= a channel of time stamps": "set [data] time to a channel of time stamps",
    "pass variables= to choose": "map only vectors of one length in [channels]",
    "(pass variables=)": "(as [channels.<name>] source)",
    "pass max_bytes= a larger budget": "raise [data] max_bytes",
    "pass max_bytes= to read": "raise [data] max_bytes to read",
    "pass max_bytes= if it is real": "raise [data] max_bytes if it is real",
    "pass delimiter=": "set [data] delimiter = ",
    "(pass jitter=)": "([data] jitter = <fraction of the step>)",
    "pass decimal=": "set [data] decimal = ",
    "pass skip_rows=": "set [data] skip_rows = ",
    "skip_rows=": "[data] skip_rows = ",
    "skip_columns=[": "[data] skip_columns = [",
    "skip_columns=": "[data] skip_columns",
    "columns=[": "[data] columns = [",
    "columns=": "[data] columns",
}


@dataclass(frozen=True)
class InputFile:
    """A rig file a run read: path, format, size and SHA-256.

    Parameters
    ----------
    path : pathlib.Path
        The file, as the experiment file names it (relative to its folder).
    role : {"estimation", "validation"}
        What the file is: ``[data]`` or ``[validation]``.
    format : str
        Its :class:`~servoid.data.RigFormat` name.
    size : int
        Its size when read [bytes].
    sha256 : str
        SHA-256 of its bytes, hex.
    """

    path: Path
    role: InputRole
    format: str
    size: int
    sha256: str

    def __post_init__(self) -> None:
        if not isinstance(self.path, (str, os.PathLike)):
            raise type_error("path", self.path, "a file path")
        object.__setattr__(self, "path", Path(self.path))
        if self.role not in ("estimation", "validation"):
            raise OptionTypeError(f"InputFile role must be 'estimation' or 'validation', got "
                                  f"{self.role!r}")
        RigFormat.named(self.format)
        if isinstance(self.size, bool) or not isinstance(self.size, int) or self.size < 0:
            raise OptionTypeError(f"InputFile size must be a whole number of bytes, got "
                                  f"{self.size!r}")
        if not isinstance(self.sha256, str) or len(self.sha256) != 64:
            raise OptionTypeError(f"InputFile sha256 must be 64 hexadecimal digits, got "
                                  f"{self.sha256!r}")


@dataclass(frozen=True)
class PreparedData:
    """An experiment's records, read and ready to fit.

    Build it with :func:`prepare`.

    Parameters
    ----------
    spec : ExperimentSpec
        The experiment file.
    estimation : Experiment or ExperimentSet
        The estimation data: the first part of the split record, or every
        ``[data]`` file (several make a set).
    validations : tuple of Experiment
        The held-back part, or each ``[validation]`` record.
    inputs : tuple of InputFile
        Every rig file read, ``[data]`` files first.
    """

    spec: ExperimentSpec
    estimation: Experiment | ExperimentSet
    validations: tuple[Experiment, ...]
    inputs: tuple[InputFile, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.spec, ExperimentSpec):
            raise type_error("spec", self.spec, "an ExperimentSpec")
        if not isinstance(self.estimation, (Experiment, ExperimentSet)):
            raise type_error("estimation", self.estimation, "an Experiment or ExperimentSet")
        if not isinstance(self.validations, tuple) or not self.validations or not all(
                isinstance(v, Experiment) for v in self.validations):
            raise type_error("validations", self.validations,
                             "a non-empty tuple of Experiment")
        if not isinstance(self.inputs, tuple) or not all(
                isinstance(f, InputFile) for f in self.inputs):
            raise type_error("inputs", self.inputs, "a tuple of InputFile")

    @property
    def records(self) -> tuple[Experiment | ExperimentSet, tuple[Experiment, ...]]:
        """``(estimation, validations)``, as :meth:`ExperimentSpec.records` returns them."""
        return self.estimation, self.validations

    def digest(self, path: str | os.PathLike[str]) -> str:
        """SHA-256 of an input file as it was read.

        Parameters
        ----------
        path : path-like
            One of :attr:`inputs` (compared after resolving links).

        Returns
        -------
        str
            Hex digest.
        """
        wanted = os.path.realpath(path)
        for f in self.inputs:
            if os.path.realpath(f.path) == wanted:
                return f.sha256
        raise OptionError(f"{os.fspath(path)} is not an input of this experiment; its "
                           f"inputs are {', '.join(str(f.path) for f in self.inputs)}")


def prepare(spec: ExperimentSpec | str | os.PathLike[str]) -> PreparedData:
    """Read, calibrate and preprocess an experiment's records.

    With ``[validation] file`` every ``[data]`` file is estimation data
    (several make an :class:`ExperimentSet`) and each validation file is
    read with the same channels, calibration and preprocessing; otherwise
    the one ``[data]`` file is split by ``[split]``.  A ``"mean"`` detrend
    takes the means of the estimation data and subtracts the same values
    from the validation data, so a model is never helped by knowing the
    validation record's operating point.

    Parameters
    ----------
    spec : ExperimentSpec or path-like
        The experiment, or its TOML file.

    Returns
    -------
    PreparedData
        The estimation and validation records and the files read, each
        with its size and SHA-256.

    Raises
    ------
    ChannelError
        A listed source channel is not in a file.
    FileFormatError
        A file the readers refuse, a split that leaves a part too short,
        validation records unlike the estimation data or equal to it.
    DataError
        A file that changed while it was read.
    """
    if not isinstance(spec, ExperimentSpec):
        if not isinstance(spec, (str, os.PathLike)) or isinstance(spec, bytes):
            raise type_error("spec", spec, "an ExperimentSpec or an experiment file's path")
        spec = load_experiment_spec(spec)
    inputs: list[InputFile] = []
    if not spec.validation.files:
        record = _read(spec, spec.data_path, "estimation", inputs)
        estimation, validation = _split(spec, record, str(spec.data_path), detrended=True)
        return PreparedData(spec, estimation, (validation,), tuple(inputs))
    parts = tuple(_read(spec, p, "estimation", inputs) for p in spec.data_paths)
    validations = tuple(_read(spec, p, "validation", inputs) for p in spec.validation_paths)
    for v in validations:
        _check_like(parts[0], v)
    check_distinct(_origin(spec), spec.data_paths, parts, spec.validation_paths, validations)
    est_parts, validations = _detrended(spec, parts, validations)
    est = est_parts[0] if len(est_parts) == 1 else ExperimentSet(est_parts)
    return PreparedData(spec, est, validations, tuple(inputs))


def read_record(spec: ExperimentSpec, path: str | os.PathLike[str] | None = None, *,
                detrend: bool = True) -> Experiment:
    """One rig file read, calibrated and preprocessed (:meth:`ExperimentSpec.load`)."""
    path = spec.data_path if path is None else Path(path)
    exp = _kept(spec, path)
    if detrend and spec.preprocess.detrend != "none":
        exp = _detrend(exp, spec.preprocess.detrend)
    return exp


def split_record(spec: ExperimentSpec,
                 exp: Experiment | None = None) -> tuple[Experiment, Experiment]:
    """Estimation and validation parts as ``[split]`` sets (:meth:`ExperimentSpec.split_data`)."""
    if exp is not None:  # the caller's record is already preprocessed
        return _split(spec, exp, f"the record {exp.name!r}", detrended=False)
    return _split(spec, read_record(spec, detrend=False), str(spec.data_path), detrended=True)


# -- reading -----------------------------------------------------------------------------------

# The last record read for each living spec: (a weak reference to the spec, the file's path,
# modification time and size, the record calibrated and preprocessed, not detrended).
_KEPT: dict[int, tuple[Any, tuple[str, int, int], Experiment]] = {}


def _kept(spec: ExperimentSpec, path: Path) -> Experiment:
    """The record of ``path``; an unchanged file last read for this spec is not read again.

    A workflow reads the record for the split and again, whole, for the
    feedback test: an unchanged file (same size and modification time) is
    read and preprocessed once.  At most one record is kept per spec.
    """
    try:
        st = path.stat()
        key = (str(path), st.st_mtime_ns, st.st_size)
    except OSError:
        key = None  # the reader says what is wrong with the path
    ident = id(spec)
    last = _KEPT.get(ident)
    if key is not None and last is not None and last[0]() is spec and last[1] == key:
        return last[2]
    exp = _read_and_prepare(spec, path)
    if key is not None:
        ref = weakref.ref(spec, lambda _, ident=ident: _KEPT.pop(ident, None))
        _KEPT[ident] = (ref, key, exp)
    return exp


def _read(spec: ExperimentSpec, path: Path, role: InputRole,
          inputs: list[InputFile]) -> Experiment:
    """Read a record (not detrended) and note the file with its SHA-256."""
    try:
        before: os.stat_result | None = os.stat(path)
    except OSError:
        before = None  # the reader says what is wrong with the path
    exp = _kept(spec, path)
    digest, st = file_status(path)
    if before is not None and not _same_file(before, st):
        raise DataError(f"{path} changed while servoid read it (a logger still writing?): its "
                        "digest would not describe the samples read; run again once the file "
                        "is complete")
    inputs.append(InputFile(path, role, spec.format, st.st_size, digest))
    return exp


def _read_and_prepare(spec: ExperimentSpec, path: Path) -> Experiment:
    """Read the rig file, calibrate its channels and preprocess them (no detrend)."""
    try:
        raw = read_experiment(path, spec.format, **_reader_options(spec, path))
    except MissingChannel as exc:
        raise _missing(spec, path, exc.name, exc.available) from None
    except ServoidError as exc:  # the readers advise Python keywords: name the TOML keys
        text = str(exc)
        for old, new in _READER_WORDS.items():
            text = text.replace(old, new)
        if text == str(exc):
            raise
        raise _like(exc, text) from None
    channels = []
    for ch in spec.channels:
        try:
            src = raw.channel(ch.source)
        except ChannelError:
            raise _missing(spec, path, ch.source, raw.names) from None
        calibrated = ch.gain * src.values + ch.offset
        unit = ch.unit
        if unit is None:
            unit = src.unit if (ch.gain == 1.0 and ch.offset == 0.0) else ""
        channels.append(Channel(ch.name, ch.role, calibrated, unit))
    if path == spec.data_path and len(spec.files) == 1:
        name = spec.source.stem if spec.source is not None else Path(spec.file).stem
    else:
        name = path.stem
    exp = Experiment(tuple(channels), raw.dt, t0=raw.t0, name=name, notes=raw.notes)
    pre = spec.preprocess
    if pre.lowpass is not None:
        _check_lowpass(spec, exp, path)
        exp = lowpass(exp, pre.lowpass, zero_phase=True)
    if pre.decimate > 1:
        if exp.n_samples <= pre.decimate:
            raise FileFormatError(
                f"{_origin(spec)}: [preprocess] decimate = {pre.decimate} needs at least "
                f"{pre.decimate + 1} samples, but {path} has {exp.n_samples}: lower "
                "decimate (the decimated record must still hold enough samples to fit and "
                "validate), or remove it"
            )
        exp = _decimated(spec, exp, path)
    return exp


def _reader_options(spec: ExperimentSpec, path: Path) -> dict[str, Any]:
    """The reader's keywords: the format's own ``[data]`` keys, and only the mapped channels."""
    fmt = RigFormat.named(spec.format)
    given = {k: v for k, v in _format_options(spec).items() if k in fmt.options}
    options: dict[str, Any] = {"dt": spec.dt,
                               "time": spec.time if spec.time is not None else fmt.time}
    options.update(given)
    options.update(fmt.select(path, [c.source for c in spec.channels], given))
    if spec.max_bytes is not None:
        options["max_bytes"] = spec.max_bytes
    if spec.jitter is not None:
        options["jitter"] = spec.jitter
    return options


def _format_options(spec: ExperimentSpec) -> dict[str, Any]:
    """The ``[data]`` keys that belong to one format or another, as the spec holds them."""
    out: dict[str, Any] = dict(spec.csv)
    if spec.group is not None:
        out["group"] = spec.group
    return out


def _missing(spec: ExperimentSpec, path: Path, source: str,
             available: tuple[str, ...]) -> ChannelError:
    """The error for a channel the rig file lacks, in the experiment file's words."""
    names = ", ".join(available) or "no numeric channels"
    origin = _origin(spec)
    if source == spec.time and all(c.source != source for c in spec.channels):
        return ChannelError(f"{origin}: [data] time = {source!r}: no such channel in "
                            f"{path}; it has: {names}")
    entry = next((c for c in spec.channels if c.source == source), None)
    if entry is None:  # not a channel of [channels]: say what the file has
        return ChannelError(f"{origin}: {source!r} is not in {path}; it has: {names}")
    hint = ""
    if "columns" in spec.csv:
        hint = " (only the columns listed in [data] columns are read: add it there)"
    elif "skip_columns" in spec.csv:
        hint = " (check [data] skip_columns)"
    elif "group" in RigFormat.named(spec.format).options and "/" not in source:
        hint = " (a channel of another group is named 'group/channel')"
    return ChannelError(
        f"channel {source!r} (servoid channel {entry.name!r}) is not in {path}"
        f"{' group ' + repr(spec.group) if spec.group else ''}; the file has: {names}{hint}"
    )


def _origin(spec: ExperimentSpec) -> str:
    """The experiment file, as error messages name it."""
    return os.fspath(spec.source) if spec.source is not None else "experiment spec"


# -- preprocessing -----------------------------------------------------------------------------


def _check_lowpass(spec: ExperimentSpec, exp: Experiment, path: Path) -> None:
    """Refuse a cutoff the record cannot carry, naming ``[preprocess] lowpass``."""
    cutoff = spec.preprocess.lowpass
    assert cutoff is not None
    nyquist = 0.5 / exp.dt
    where = f"{_origin(spec)}: [preprocess] lowpass = {cutoff:g} Hz"
    if cutoff >= nyquist:
        raise FileFormatError(
            f"{where} must lie below the Nyquist frequency {nyquist:g} Hz of {path} "
            f"(dt = {exp.dt:g} s; the filter runs before decimation): lower lowpass, or "
            "remove it"
        )
    lowest = 1.0 / exp.duration
    if cutoff < lowest:
        raise FileFormatError(
            f"{where} is below 1/(N·dt) = {lowest:.3g} Hz, the lowest frequency the "
            f"{exp.duration:.3g} s record {path} resolves: the filter would return little "
            "more than the mean; raise lowpass, or remove it and set [preprocess] detrend "
            "= \"mean\" or \"linear\" to remove the mean or a trend"
        )


def _decimated(spec: ExperimentSpec, exp: Experiment, path: Path) -> Experiment:
    """Decimate; a logged command (``[rig] reference = "command"``) is subsampled."""
    q = spec.preprocess.decimate
    if spec.rig.reference != "command":
        return decimate(exp, q)
    commands = [ch for ch in exp.channels if ch.role == "r"]
    for ch in commands:
        values = ch.values
        blocks = values[: values.size - values.size % q].reshape(-1, q)
        if np.any(blocks != blocks[:, :1]):
            k = int(np.argmax(np.any(blocks != blocks[:, :1], axis=1)))
            raise FileFormatError(
                f"{path}: [rig] reference = \"command\" declares {ch.name!r} a DAC command "
                f"held over each decimated period, but it changes within samples "
                f"{k * q}…{k * q + q - 1} (decimate = {q}): the command is not held at the "
                "decimated rate, or is not aligned to it; declare reference = \"readback\" "
                "to filter it like the output"
            )
    others = decimate(exp.drop(*(ch.name for ch in commands)), q) if len(commands) < len(
        exp.channels) else None
    channels = []
    for ch in exp.channels:
        if ch.role == "r":
            channels.append(ch.with_values(ch.values[::q]))
        else:
            assert others is not None
            channels.append(others.channel(ch.name))
    return exp.replace_channels(channels, dt=exp.dt * q)


def _split(spec: ExperimentSpec, exp: Experiment, label: str,
           detrended: bool) -> tuple[Experiment, Experiment]:
    """Split as ``[split]`` says; ``detrended``: then remove the trend (estimation means)."""
    spl = spec.split
    _check_split(spec, exp, label)
    if spl.skip_periods and spl.period is not None:
        exp = exp.slice(spl.skip_periods * spl.period)
    at: float | int = spl.index if spl.index is not None else (spl.fraction or 0.5)
    estimation, validation = split(exp, at, period=spl.period)
    if not detrended:
        return estimation, validation
    estimation, (validation,) = _detrended(spec, estimation, (validation,))
    return estimation, validation


def _check_split(spec: ExperimentSpec, exp: Experiment, label: str) -> None:
    """Refuse a ``[split]`` that leaves a part too short, naming its key and the fix.

    Mirrors :func:`~servoid.data.split`: each part needs 2 samples, or
    with ``period`` a whole period; ``index`` and ``period`` count samples
    after decimation, ``index`` also after the skipped periods.
    """
    spl = spec.split
    n, q = exp.n_samples, spec.preprocess.decimate
    after = f" (after [preprocess] decimate = {q})" if q > 1 else ""
    record = f"{label} has {n} samples{after}"
    where = f"{_origin(spec)}: [split]"
    longer = ("record a longer test, or name a separate validation record with "
              "[validation] file" + (" (and remove [split])" if spl != SplitSpec() else ""))
    period = spl.period
    if period is not None:
        whole = n // period
        if whole < 2:
            raise FileFormatError(
                f"{where} period = {period} samples: {record}, {whole} whole period(s); the "
                "split needs at least 2 (one to estimate, one to validate): check period "
                f"(it counts samples{' after decimation' if q > 1 else ''}), or {longer}"
            )
        if whole - spl.skip_periods < 2:
            raise FileFormatError(
                f"{where} skip_periods = {spl.skip_periods} drops "
                f"{spl.skip_periods * period} samples ({spl.skip_periods} period(s) of "
                f"{period}), but {record}, {whole} whole period(s): at least 2 must be "
                f"left to split; lower skip_periods to at most {whole - 2}"
            )
        n -= spl.skip_periods * period
        if spl.skip_periods:
            record = f"{record}, {n} after skip_periods = {spl.skip_periods}"
        low, high = period, n - period  # the split point keeps a whole period each side
    else:
        if n < 4:
            raise FileFormatError(
                f"{_origin(spec)}: {record}: too few to split into estimation and "
                f"validation parts of at least 2 samples each; {longer}"
            )
        low, high = 2, n - 2
    if spl.index is not None:
        index = spl.index
        if period is not None:
            index = index // period * period
        if not low <= index <= high:
            raise FileFormatError(
                f"{where} index = {spl.index} leaves a part with fewer than "
                f"{'a whole period' if period is not None else '2 samples'}: {record}; "
                f"choose index in {low}..{high} (it counts samples after decimation and "
                "skipped periods), or give fraction instead"
            )
        return
    fraction = spl.fraction or 0.5
    index = round(fraction * n)
    if period is not None:
        index = index // period * period
    if not low <= index <= high:
        key = "fraction" if spl.fraction is not None else "fraction (default 0.5)"
        raise FileFormatError(
            f"{where} {key} splits at sample {index} and leaves a part with fewer than "
            f"{'a whole period' if period is not None else '2 samples'}: {record}; choose "
            f"fraction between {low / n:.3g} and {high / n:.3g}"
        )


def _detrended(
    spec: ExperimentSpec, estimation: Experiment | tuple[Experiment, ...],
    validations: tuple[Experiment, ...],
) -> tuple[Any, tuple[Experiment, ...]]:
    kind = spec.preprocess.detrend
    single = isinstance(estimation, Experiment)
    parts = (estimation,) if single else tuple(estimation)
    if kind == "none":
        return (parts[0] if single else parts), validations
    if kind == "linear":  # a drift belongs to its record: each loses its own line
        parts = tuple(_detrend(p, "linear") for p in parts)
        return (parts[0] if single else parts), tuple(_detrend(v, "linear")
                                                      for v in validations)
    names = [ch.name for ch in parts[0].channels if ch.role != "side"]
    total = sum(p.n_samples for p in parts)
    means = {n: float(sum(p[n].sum() for p in parts) / total) for n in names}
    parts = tuple(_detrend(p, "offset", offsets=means) for p in parts)
    validations = tuple(_detrend(v, "offset", offsets=means) for v in validations)
    return (parts[0] if single else parts), validations
