"""The TOML experiment file: which rig file, which channels, what to do.

One TOML file describes one experiment. Paths are relative to the TOML
file's folder. Every table and key is checked; an unknown key raises
:class:`OptionError` listing the valid ones, a value of the wrong type or
range raises :class:`FileFormatError` naming the table and key.

Schema::

    [data]                    # required
    file = "bench.tdms"       # required: the rig file, relative to this file; an array of
                              # files is an estimation set (segments never joined)
    format = "tdms"           # csv | tdms | mat; default from the extension
    group = "Measurements"    # TDMS group; only for TDMS files (not needed when each source
                              # is in one group only, or is named "group/channel")
    time = "t"                # time column / channel / variable [s]
    dt = 0.0002               # [s], > 0: when there is no time column or waveform timing
    max_bytes = 4294967296    # [bytes] the readers' memory budget, default 2 GiB: a larger
                              # CSV file, TDMS channel or MAT variable is refused
    delimiter = ";"           # CSV only: field separator, default ","
    decimal = ","             # CSV only: decimal mark, default "." (needs delimiter != ",")
    time_unit = "ms"          # CSV only: unit of an unlabelled time column: s | ms | us
    skip_rows = 3             # CSV only: lines of a logger's preamble before the header
    columns = ["time", "AI0", 4]  # CSV only: the columns to read (header names or 0-based
                              # indices; the time column is always read); or
    skip_columns = ["status"] # CSV only: the columns not to read
    jitter = 0.01             # time stamps uniform within this fraction of the step (1e-3)

    [channels.y_r]            # required, at least one: the servoid channel name
    source = "AI0"            # channel in the file; default the servoid name; a TDMS channel
                              # of a group "g/AI0", a MAT struct field "run.signals.y"
    role = "r"                # r | u | y | side; default "side"
    gain = 0.0023             # value = gain·raw + offset; finite, non-zero; default 1
    offset = 0.0              # default 0
    unit = "m"                # unit after calibration; default: the file's unit when
                              # gain = 1 and offset = 0, else "" (unknown)
    limits = [-0.1, 0.1]      # the sensor's range [unit]: simulations are clipped to it

    [preprocess]              # applied in this order: lowpass, decimate, detrend
    lowpass = 200.0           # [Hz], zero-phase 4th-order Butterworth, at the file's rate
    decimate = 5              # integer factor >= 1, anti-aliased (FIR, zero phase)
    detrend = "mean"          # none | mean | linear (r, u, y channels); default "none";
                              # the estimation data's means are reused on validation data

    [validation]              # separate validation record(s): then [data] is all estimation
    file = "run02.tdms"       # or an array; same channels, calibration and preprocessing
    initial = "auto"          # auto | estimate | zero | measured: initial state of the simulation
    transient = 0             # samples at the start excluded from the metrics

    [split]                   # default: halves (not with [validation])
    fraction = 0.5            # in (0, 1); or
    index = 10000             # sample index after decimation and skipped periods
    period = 2047             # whole excitation periods [samples after decimation]
    skip_periods = 0          # leading periods to drop before splitting (needs period)

    [rig]                     # what the rig did to the signals before they were logged
    anti_alias = {order = 4, cutoff = 1000.0}  # analog Butterworth before the ADC [Hz]
    reference = "command"     # command | readback: r is the DAC command as written (a
                              # staircase: decimation subsamples it, no filter) or read back
                              # through the same anti-alias filter and ADC as y

    [loop]                    # free-form: what is known about the feedback loop
    [identify]                # free-form: which models to fit
    [report]                  # free-form: e.g. the output folder

The ``[rig]`` table lets the estimators model the rig exactly: a one-step
closed-loop fit of a ``"command"`` reference includes the declared
anti-alias filter and servoid's decimation FIR on the output; a
``"readback"`` reference shares them with the output, so they cancel.

Free-form tables hold strings, numbers, booleans, arrays of these, and
tables of these one level deep; they are returned read-only.
Channels of the rig file that are not listed under ``[channels]`` are not
loaded.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from .._atomic import atomic_path
from .._checks import as_bool, as_path, type_error
from .._errors import ChannelError, FileFormatError, OptionError, ServoidError, check_option
from ._columns import MissingChannel, existing_file
from ._csv import header_names
from ._distinct import check_distinct
from ._experiment import Channel, Experiment, ExperimentSet
from ._io import FORMATS, Format, format_of, read_experiment
from ._preprocess import decimate, lowpass, split
from ._preprocess import detrend as _detrend
from ._spec_tables import (
    _DATA_KEYS,
    _FREE_KEYS,
    _PREPROCESS_KEYS,
    _SPLIT_KEYS,
    _TOP_KEYS,
    ChannelSpec,
    PreprocessSpec,
    RigSpec,
    SplitSpec,
    ValidationSpec,
    _channels,
    _check_keys,
    _check_like,
    _csv_options,
    _file_list,
    _free,
    _integer,
    _like,
    _optional,
    _positive,
    _preprocess,
    _rig,
    _split,
    _string,
    _thaw,
    _validation,
)
from ._toml import _emit_document, read_toml

__all__ = [
    "ChannelSpec",
    "ExperimentSpec",
    "PreprocessSpec",
    "RigSpec",
    "SplitSpec",
    "ValidationSpec",
    "load_experiment_spec",
    "write_experiment_spec",
]

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
class ExperimentSpec:
    """A validated TOML experiment file.

    Build it with :func:`load_experiment_spec` or :meth:`from_dict`.

    Parameters
    ----------
    file : str
        The rig file as written, relative to ``base_dir`` unless absolute.
    format : {"csv", "tdms", "mat"}
        Its format.
    channels : tuple of ChannelSpec
        The channels to load, in order.
    group, time : str or None
        TDMS group; name of the time column.
    dt : float or None
        Sample period [s] when the file has no timing.
    max_bytes : int or None
        The readers' memory budget [bytes] (None: their default, 2 GiB).
    jitter : float or None
        Time-stamp tolerance as a fraction of the step (None: 1e-3).
    csv : mapping
        CSV reading options given in ``[data]``: ``delimiter``, ``decimal``,
        ``time_unit``, ``columns``, ``skip_columns``, ``skip_rows``.
    preprocess : PreprocessSpec
        Preprocessing steps.
    split : SplitSpec
        Estimation/validation split.
    validation : ValidationSpec
        Separate validation records (then no split).
    rig : RigSpec
        The rig's anti-alias filter and how the reference was logged.
    files : tuple of str
        Every estimation file (``file`` is the first); several make an
        estimation set.
    loop, identify, report : mapping
        Free-form read-only tables.
    base_dir : pathlib.Path
        Folder that relative paths start from (not compared).
    source : pathlib.Path or None
        The TOML file, if loaded from one (not compared).
    """

    file: str
    format: Format
    channels: tuple[ChannelSpec, ...]
    group: str | None = None
    time: str | None = None
    dt: float | None = None
    preprocess: PreprocessSpec = field(default_factory=PreprocessSpec)
    split: SplitSpec = field(default_factory=SplitSpec)
    validation: ValidationSpec = field(default_factory=ValidationSpec)
    rig: RigSpec = field(default_factory=RigSpec)
    files: tuple[str, ...] = ()
    max_bytes: int | None = None
    jitter: float | None = None
    csv: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    loop: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    identify: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    report: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    base_dir: Path = field(default=Path("."), compare=False)
    source: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if not self.files:
            object.__setattr__(self, "files", (self.file,))
        elif self.files[0] != self.file:
            raise FileFormatError(f"files must start with file {self.file!r}, got {self.files!r}")

    @classmethod
    def from_dict(
        cls,
        table: Mapping[str, Any],
        base_dir: str | os.PathLike[str] = ".",
        source: str | os.PathLike[str] | None = None,
    ) -> ExperimentSpec:
        """Validate a parsed TOML document and build the spec.

        Parameters
        ----------
        table : mapping
            The document, as from ``tomllib.load``.
        base_dir : path-like
            Folder relative paths start from.
        source : path-like, optional
            The TOML file, used in error messages.

        Returns
        -------
        ExperimentSpec
            The validated spec.
        """
        origin = os.fspath(source) if source is not None else "experiment spec"
        _check_keys(origin, "the top level", table, _TOP_KEYS, required=("data", "channels"))
        where = f"{origin}: [data]"
        data = table["data"]
        _check_keys(origin, "[data]", data, _DATA_KEYS, required=("file",))
        files = _file_list(where, "file", data["file"])
        file = files[0]
        fmt = data.get("format")
        if fmt is not None:
            _string(where, "format", fmt)
            check_option(f"{where} format", fmt, FORMATS)
        try:
            fmt = format_of(file, fmt)
            for other in files[1:]:
                if format_of(other, data.get("format")) != fmt:
                    raise OptionError(f"every file must have one format; {other!r} is not {fmt}")
        except OptionError as exc:
            raise OptionError(f"{where}: {exc}") from None
        group = _optional(where, "group", data.get("group"), _string)
        if group is not None and fmt != "tdms":
            raise FileFormatError(f"{where}: group applies to TDMS files only, this is {fmt}: "
                                  "remove group")
        time = _optional(where, "time", data.get("time"), _string)
        dt = _optional(where, "dt", data.get("dt"), _positive)
        max_bytes = _optional(where, "max_bytes", data.get("max_bytes"),
                              lambda w, k, v: _integer(w, k, v, 1))
        jitter = _optional(where, "jitter", data.get("jitter"), _positive)
        csv_options = _csv_options(where, data)
        if csv_options and fmt != "csv":
            raise FileFormatError(f"{where}: {', '.join(csv_options)} apply to CSV files only, "
                                  f"this is {fmt}")
        channels = _channels(origin, table["channels"])
        validation = _validation(origin, table.get("validation", {}), fmt)
        split_table = table.get("split", {})
        if validation.files and split_table:
            raise FileFormatError(
                f"{origin}: [split] and [validation] file both say what the validation data "
                "are; with a separate validation record the whole [data] is for estimation: "
                "remove [split]"
            )
        if len(files) > 1 and not validation.files:
            raise FileFormatError(
                f"{origin}: [data] names {len(files)} estimation files but no validation "
                "record; add [validation] file = \"<record>\""
            )
        preprocess = _preprocess(origin, table.get("preprocess", {}))
        rig = _rig(origin, table.get("rig", {}))
        if rig.reference == "command" and preprocess.lowpass is not None:
            raise FileFormatError(
                f"{origin}: [preprocess] lowpass would filter the logged command that [rig] "
                "reference = \"command\" declares a staircase, and no model of the rig covers "
                "that filter; remove lowpass (decimation keeps the command exact)"
            )
        return cls(
            file=file,
            files=files,
            validation=validation,
            rig=rig,
            format=fmt,
            channels=channels,
            group=group,
            time=time,
            dt=dt,
            max_bytes=max_bytes,
            jitter=jitter,
            csv=MappingProxyType(csv_options),
            preprocess=preprocess,
            split=_split(origin, table.get("split", {})),
            loop=_free(origin, "loop", table.get("loop", {})),
            identify=_free(origin, "identify", table.get("identify", {})),
            report=_free(origin, "report", table.get("report", {})),
            base_dir=Path(base_dir),
            source=Path(source) if source is not None else None,
        )

    @property
    def data_path(self) -> Path:
        """The rig file's path (``file`` resolved against ``base_dir``)."""
        return self.base_dir / self.file

    @property
    def data_paths(self) -> tuple[Path, ...]:
        """Every estimation file's path."""
        return tuple(self.base_dir / f for f in self.files)

    @property
    def validation_paths(self) -> tuple[Path, ...]:
        """Every separate validation file's path (empty: the record is split)."""
        return tuple(self.base_dir / f for f in self.validation.files)

    def limits(self, name: str) -> tuple[float, float] | None:
        """Declared range of channel ``name`` [its unit], or None."""
        for ch in self.channels:
            if ch.name == name:
                return ch.limits
        return None

    def to_dict(self) -> dict[str, Any]:
        """The spec as a plain TOML-shaped dictionary (defaults omitted)."""
        data: dict[str, Any] = {"file": self.file if len(self.files) == 1 else list(self.files),
                                "format": self.format}
        for key in ("group", "time", "dt", "max_bytes", "jitter"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        data.update({k: list(v) if isinstance(v, tuple) else v for k, v in self.csv.items()})
        channels: dict[str, Any] = {}
        for ch in self.channels:
            entry: dict[str, Any] = {"source": ch.source, "role": ch.role}
            if ch.gain != 1.0 or ch.offset != 0.0:
                entry.update(gain=ch.gain, offset=ch.offset)
            if ch.unit is not None:
                entry["unit"] = ch.unit
            if ch.limits is not None:
                entry["limits"] = list(ch.limits)
            channels[ch.name] = entry
        out: dict[str, Any] = {"data": data, "channels": channels}
        pre = {k: getattr(self.preprocess, k) for k in _PREPROCESS_KEYS}
        pre = {k: v for k, v in pre.items() if v is not None}
        if pre != {"decimate": 1, "detrend": "none"}:
            out["preprocess"] = pre
        spl = {k: getattr(self.split, k) for k in _SPLIT_KEYS}
        spl = {k: v for k, v in spl.items() if v is not None and (k != "skip_periods" or v)}
        if spl:
            out["split"] = spl
        val = self.validation
        if val.files:
            out["validation"] = {"file": val.files[0] if len(val.files) == 1 else list(val.files)}
            if val.initial != "auto":
                out["validation"]["initial"] = val.initial
            if val.transient:
                out["validation"]["transient"] = val.transient
        if self.rig.is_declared:
            out["rig"] = self.rig.to_dict()
        for key in _FREE_KEYS:
            if getattr(self, key):
                out[key] = _thaw(getattr(self, key))
        return out

    def load(self, path: str | os.PathLike[str] | None = None, *,
             detrend: bool = True) -> Experiment:
        """Read the rig file, calibrate and preprocess it.

        Parameters
        ----------
        path : path-like, optional
            Another rig file with the same channels (a validation record);
            default the first ``[data]`` file.
        detrend : bool
            Apply ``[preprocess] detrend`` to this record alone (False:
            leave it to :meth:`records`, which reuses the estimation data's
            means).

        Returns
        -------
        Experiment
            Channels named and ordered as in ``[channels]``, roles set,
            calibrated, then low-passed, decimated and detrended.

        Raises
        ------
        ChannelError
            A listed source channel is not in the file.
        """
        path = self.data_path if path is None else Path(path)
        exp = self._prepared(path)
        if detrend and self.preprocess.detrend != "none":
            exp = _detrend(exp, self.preprocess.detrend)
        return exp

    def _missing(self, path: Path, source: str, available: tuple[str, ...]) -> ChannelError:
        """The error for a channel the rig file lacks, in the experiment file's words."""
        names = ", ".join(available) or "no numeric channels"
        if source == self.time and all(c.source != source for c in self.channels):
            return ChannelError(f"{self._origin}: [data] time = {source!r}: no such channel in "
                                f"{path}; it has: {names}")
        spec = next((c for c in self.channels if c.source == source), None)
        if spec is None:  # not a channel of [channels]: say what the file has
            return ChannelError(f"{self._origin}: {source!r} is not in {path}; it has: {names}")
        hint = ""
        if "columns" in self.csv:
            hint = " (only the columns listed in [data] columns are read: add it there)"
        elif "skip_columns" in self.csv:
            hint = " (check [data] skip_columns)"
        elif self.format == "tdms" and "/" not in source:
            hint = " (a channel of another group is named 'group/channel')"
        return ChannelError(
            f"channel {source!r} (servoid channel {spec.name!r}) is not in {path}"
            f"{' group ' + repr(self.group) if self.group else ''}; the file has: {names}{hint}"
        )

    @property
    def _origin(self) -> str:
        """The experiment file, as error messages name it."""
        return os.fspath(self.source) if self.source is not None else "experiment spec"

    def _check_lowpass(self, exp: Experiment, path: Path) -> None:
        """Refuse a cutoff the record cannot carry, naming ``[preprocess] lowpass``."""
        cutoff = self.preprocess.lowpass
        assert cutoff is not None
        nyquist = 0.5 / exp.dt
        where = f"{self._origin}: [preprocess] lowpass = {cutoff:g} Hz"
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

    def _decimated(self, exp: Experiment, path: Path) -> Experiment:
        """Decimate; a logged command (``[rig] reference = "command"``) is subsampled."""
        q = self.preprocess.decimate
        if self.rig.reference != "command":
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

    def _prepared(self, path: Path) -> Experiment:
        """The record calibrated and preprocessed, not detrended; the last one is kept.

        A workflow reads the record for the split and again, whole, for the
        feedback test: an unchanged file (same size and modification time)
        is read and preprocessed once.  The spec holds at most one record.
        """
        try:
            st = path.stat()
            key = (str(path), st.st_mtime_ns, st.st_size)
        except OSError:
            key = None  # the reader says what is wrong with the path
        last = self.__dict__.get("_last_prepared")
        if key is not None and last is not None and last[0] == key:
            return last[1]  # type: ignore[no-any-return]
        exp = self._read_and_prepare(path)
        if key is not None:
            object.__setattr__(self, "_last_prepared", (key, exp))
        return exp

    def _read_and_prepare(self, path: Path) -> Experiment:
        """Read the rig file, calibrate its channels and preprocess them (no detrend)."""
        try:
            raw = read_experiment(path, self.format, **self._reader_options(path))
        except MissingChannel as exc:
            raise self._missing(path, exc.name, exc.available) from None
        except ServoidError as exc:  # the readers advise Python keywords: name the TOML keys
            text = str(exc)
            for old, new in _READER_WORDS.items():
                text = text.replace(old, new)
            if text == str(exc):
                raise
            raise _like(exc, text) from None
        channels = []
        for ch in self.channels:
            try:
                src = raw.channel(ch.source)
            except ChannelError:
                raise self._missing(path, ch.source, raw.names) from None
            calibrated = ch.gain * src.values + ch.offset
            unit = ch.unit
            if unit is None:
                unit = src.unit if (ch.gain == 1.0 and ch.offset == 0.0) else ""
            channels.append(Channel(ch.name, ch.role, calibrated, unit))
        if path == self.data_path and len(self.files) == 1:
            name = self.source.stem if self.source is not None else Path(self.file).stem
        else:
            name = path.stem
        exp = Experiment(tuple(channels), raw.dt, t0=raw.t0, name=name, notes=raw.notes)
        pre = self.preprocess
        if pre.lowpass is not None:
            self._check_lowpass(exp, path)
            exp = lowpass(exp, pre.lowpass, zero_phase=True)
        if pre.decimate > 1:
            if exp.n_samples <= pre.decimate:
                raise FileFormatError(
                    f"{self._origin}: [preprocess] decimate = {pre.decimate} needs at least "
                    f"{pre.decimate + 1} samples, but {path} has {exp.n_samples}: lower "
                    "decimate (the decimated record must still hold enough samples to fit and "
                    "validate), or remove it"
                )
            exp = self._decimated(exp, path)
        return exp

    def split_data(self, exp: Experiment | None = None) -> tuple[Experiment, Experiment]:
        """Estimation and validation parts as set in ``[split]``.

        Parameters
        ----------
        exp : Experiment, optional
            The result of :meth:`load`, if already at hand.

        Returns
        -------
        tuple of Experiment
            ``(estimation, validation)``.
        """
        given = exp is not None
        exp = self.load(detrend=False) if exp is None else exp
        spl = self.split
        self._check_split(exp, f"the record {exp.name!r}" if given else str(self.data_path))
        if spl.skip_periods and spl.period is not None:
            exp = exp.slice(spl.skip_periods * spl.period)
        at: float | int = spl.index if spl.index is not None else (spl.fraction or 0.5)
        estimation, validation = split(exp, at, period=spl.period)
        if given:  # the caller's record is already preprocessed
            return estimation, validation
        estimation, (validation,) = self._detrended(estimation, (validation,))
        return estimation, validation

    def _check_split(self, exp: Experiment, label: str) -> None:
        """Refuse a ``[split]`` that leaves a part too short, naming its key and the fix.

        Mirrors :func:`~servoid.data.split`: each part needs 2 samples, or
        with ``period`` a whole period; ``index`` and ``period`` count samples
        after decimation, ``index`` also after the skipped periods.
        """
        spl = self.split
        n, q = exp.n_samples, self.preprocess.decimate
        after = f" (after [preprocess] decimate = {q})" if q > 1 else ""
        record = f"{label} has {n} samples{after}"
        where = f"{self._origin}: [split]"
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
                    f"{self._origin}: {record}: too few to split into estimation and "
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

    def records(self) -> tuple[Experiment | ExperimentSet, tuple[Experiment, ...]]:
        """Estimation data and validation records as the file describes.

        With ``[validation] file`` every ``[data]`` file is estimation data
        (several make an :class:`ExperimentSet`) and each validation file
        is read with the same channels, calibration and preprocessing;
        otherwise the one ``[data]`` file is split by ``[split]``.  A
        ``"mean"`` detrend takes the means of the estimation data and
        subtracts the same values from the validation data, so a model is
        never helped by knowing the validation record's operating point.

        Returns
        -------
        tuple
            ``(estimation, validations)``.
        """
        if not self.validation.files:
            estimation, validation = self.split_data()
            return estimation, (validation,)
        parts = tuple(self.load(p, detrend=False) for p in self.data_paths)
        validations = tuple(self.load(p, detrend=False) for p in self.validation_paths)
        for v in validations:
            _check_like(parts[0], v)
        check_distinct(self._origin, self.data_paths, parts, self.validation_paths,
                       validations)
        est_parts, validations = self._detrended(parts, validations)
        est = est_parts[0] if len(est_parts) == 1 else ExperimentSet(est_parts)
        return est, validations

    def _detrended(
        self, estimation: Experiment | tuple[Experiment, ...], validations: tuple[Experiment, ...]
    ) -> tuple[Any, tuple[Experiment, ...]]:
        kind = self.preprocess.detrend
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

    def _reader_options(self, path: Path) -> dict[str, Any]:
        options: dict[str, Any] = {"dt": self.dt}
        if self.format == "csv":
            options["time"] = self.time if self.time is not None else "time"
            options.update(self.csv)
            if "columns" not in self.csv and "skip_columns" not in self.csv:
                # Only the mapped columns are converted (memory on a wide logger file),
                # when each is in the header once; else the reader reads all and says why.
                needed = list(dict.fromkeys(c.source for c in self.channels))
                names = header_names(path, delimiter=self.csv.get("delimiter", ","),
                                     skip_rows=self.csv.get("skip_rows", 0))
                if names is not None and all(names.count(n) == 1 for n in needed):
                    options["columns"] = needed
        elif self.format == "tdms":  # only the channels mapped are read
            options.update(group=self.group, time=self.time,
                           channels=list(dict.fromkeys(c.source for c in self.channels)))
        else:
            options.update(time=self.time, variables=sorted({c.source for c in self.channels}))
        if self.max_bytes is not None:
            options["max_bytes"] = self.max_bytes
        if self.jitter is not None:
            options["jitter"] = self.jitter
        return options


def load_experiment_spec(path: str | os.PathLike[str]) -> ExperimentSpec:
    """Read and validate a TOML experiment file.

    Parameters
    ----------
    path : path-like
        The TOML file; relative paths in it start from its folder.

    Returns
    -------
    ExperimentSpec
        The validated spec; call :meth:`ExperimentSpec.load` for the data.

    Raises
    ------
    FileFormatError
        Not valid TOML, or a value of the wrong type or range.
    OptionError
        An unknown key or option value.
    """
    path = existing_file(path)
    doc = read_toml(path, "experiment file", label=str(path))
    return ExperimentSpec.from_dict(doc, base_dir=path.parent, source=path)


def write_experiment_spec(
    spec: ExperimentSpec | Mapping[str, Any],
    path: str | os.PathLike[str],
    overwrite: bool = False,
) -> Path:
    """Write an experiment spec as a TOML file, atomically.

    Parameters
    ----------
    spec : ExperimentSpec or mapping
        A spec, or a TOML-shaped dictionary (validated first, with paths
        relative to the target's folder).
    path : path-like
        The TOML file to write.
    overwrite : bool
        Replace an existing file; otherwise :class:`OutputExistsError`.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    target = as_path("path", path)
    as_bool("overwrite", overwrite)
    if not isinstance(spec, (ExperimentSpec, Mapping)):
        raise type_error("spec", spec, "an ExperimentSpec or a TOML-shaped mapping")
    if not isinstance(spec, ExperimentSpec):
        spec = ExperimentSpec.from_dict(spec, base_dir=target.parent)
    doc = spec.to_dict()
    if spec.base_dir.resolve() != target.parent.resolve():
        # Keep pointing at the same rig files from the new folder.
        def moved(name: str) -> str:
            if Path(name).is_absolute():
                return name
            return Path(os.path.relpath((spec.base_dir / name).resolve(),
                                        target.parent.resolve())).as_posix()

        files = [moved(f) for f in spec.files]
        doc["data"]["file"] = files[0] if len(files) == 1 else files
        if spec.validation.files:
            vals = [moved(f) for f in spec.validation.files]
            doc["validation"]["file"] = vals[0] if len(vals) == 1 else vals
    text = _emit_document(doc)
    with atomic_path(target, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return target
