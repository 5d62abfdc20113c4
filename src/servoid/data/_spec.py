"""The TOML experiment file: which rig file, which channels, what to do.

One TOML file describes one experiment. Paths are relative to the TOML
file's folder. Every table and key is checked; an unknown key raises
:class:`OptionError` listing the valid ones, a value of the wrong type or
range raises :class:`FileFormatError` naming the table and key.

:class:`ExperimentSpec` is plain data: the file's tables, checked when
built.  Reading, calibration and preprocessing are one step of their own,
:func:`servoid.data.prepare`; which keys a rig-file format takes is its
:class:`~servoid.data.RigFormat`'s to say.

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
from typing import TYPE_CHECKING, Any

from .._atomic import atomic_path
from .._checks import as_bool, as_path, type_error
from .._errors import FileFormatError, OptionError, check_option
from ._columns import existing_file
from ._formats import FORMATS, RIG_FORMATS, Format, format_of
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
    _csv_options,
    _file_list,
    _format_keys,
    _free,
    _integer,
    _names,
    _optional,
    _positive,
    _preprocess,
    _real,
    _rig,
    _split,
    _string,
    _text,
    _thaw,
    _validation,
    _whole,
)
from ._toml import _emit_document, read_toml

if TYPE_CHECKING:
    from ._experiment import Experiment, ExperimentSet

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

#: The tables an ExperimentSpec holds, with their types, checked on construction.
_TABLES = (("preprocess", PreprocessSpec), ("split", SplitSpec),
           ("validation", ValidationSpec), ("rig", RigSpec))


@dataclass(frozen=True)
class ExperimentSpec:
    """A validated TOML experiment file.

    Build it with :func:`load_experiment_spec` or :meth:`from_dict`; read
    its records with :func:`~servoid.data.prepare`.  Built directly, every
    field is checked as the file's keys are.

    Parameters
    ----------
    file : str
        The rig file as written, relative to ``base_dir`` unless absolute.
    format : {"csv", "tdms", "mat"}
        Its format (a name of :data:`~servoid.data.RIG_FORMATS`).
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
        set_ = object.__setattr__  # frozen: each field is stored once, checked
        _text("ExperimentSpec", "file", self.file)
        if not isinstance(self.format, str):
            raise type_error("ExperimentSpec format", self.format, "a format name")
        check_option("ExperimentSpec format", self.format, FORMATS)
        if not self.files:
            set_(self, "files", (self.file,))
        else:
            set_(self, "files", _names("ExperimentSpec", "files", self.files))
            if self.files[0] != self.file:
                raise FileFormatError(f"files must start with file {self.file!r}, got "
                                      f"{self.files!r}")
        if isinstance(self.channels, (str, bytes)) or not isinstance(
                self.channels, (tuple, list)) or not all(
                isinstance(c, ChannelSpec) for c in self.channels):
            raise type_error("ExperimentSpec channels", self.channels, "a tuple of ChannelSpec")
        set_(self, "channels", tuple(self.channels))
        names = [c.name for c in self.channels]
        if not names or len(set(names)) != len(names):
            raise FileFormatError(f"ExperimentSpec channels must name at least one channel, "
                                  f"each once; got {names}")
        for key in ("group", "time"):
            if getattr(self, key) is not None:
                _text("ExperimentSpec", key, getattr(self, key))
        for key in ("dt", "jitter"):
            if getattr(self, key) is not None:
                set_(self, key, _real("ExperimentSpec", key, getattr(self, key), positive=True))
        if self.max_bytes is not None:
            _whole("ExperimentSpec", "max_bytes", self.max_bytes, 1)
        for key, kind in _TABLES:
            if not isinstance(getattr(self, key), kind):
                raise type_error(f"ExperimentSpec {key}", getattr(self, key),
                                 f"a {kind.__name__}")
        for key in ("csv", *_FREE_KEYS):
            value = getattr(self, key)
            if not isinstance(value, Mapping):
                raise type_error(f"ExperimentSpec {key}", value, "a mapping")
            if not isinstance(value, MappingProxyType):
                set_(self, key, MappingProxyType(dict(value)))
        unknown = [k for k in self.csv if k not in RIG_FORMATS["csv"].options]
        if unknown:
            raise OptionError(f"ExperimentSpec csv holds unknown option(s) {', '.join(unknown)}; "
                              f"valid: {', '.join(RIG_FORMATS['csv'].options)}")
        given = {**self.csv, **({"group": self.group} if self.group is not None else {})}
        _format_keys(f"{self._origin}: [data]", self.format, given)
        set_(self, "base_dir", as_path("base_dir", self.base_dir))
        if self.source is not None:
            set_(self, "source", as_path("source", self.source))
        self._check_combination()

    def _check_combination(self) -> None:
        """Refuse tables that contradict each other, naming the file and the fix."""
        origin = self._origin
        if self.validation.files and self.split != SplitSpec():
            raise FileFormatError(
                f"{origin}: [split] and [validation] file both say what the validation data "
                "are; with a separate validation record the whole [data] is for estimation: "
                "remove [split]"
            )
        if len(self.files) > 1 and not self.validation.files:
            raise FileFormatError(
                f"{origin}: [data] names {len(self.files)} estimation files but no validation "
                "record; add [validation] file = \"<record>\""
            )
        if self.rig.reference == "command" and self.preprocess.lowpass is not None:
            raise FileFormatError(
                f"{origin}: [preprocess] lowpass would filter the logged command that [rig] "
                "reference = \"command\" declares a staircase, and no model of the rig covers "
                "that filter; remove lowpass (decimation keeps the command exact)"
            )

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
        time = _optional(where, "time", data.get("time"), _string)
        dt = _optional(where, "dt", data.get("dt"), _positive)
        max_bytes = _optional(where, "max_bytes", data.get("max_bytes"),
                              lambda w, k, v: _integer(w, k, v, 1))
        jitter = _optional(where, "jitter", data.get("jitter"), _positive)
        csv_options = _csv_options(where, data)
        _format_keys(where, fmt, {**csv_options, **({"group": group} if group else {})})
        channels = _channels(origin, table["channels"])
        return cls(
            file=file,
            files=files,
            validation=_validation(origin, table.get("validation", {}), fmt),
            preprocess=_preprocess(origin, table.get("preprocess", {})),
            rig=_rig(origin, table.get("rig", {})),
            split=_split(origin, table.get("split", {})),
            format=fmt,
            channels=channels,
            group=group,
            time=time,
            dt=dt,
            max_bytes=max_bytes,
            jitter=jitter,
            csv=MappingProxyType(csv_options),
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
        from ._prepare import read_record

        return read_record(self, path, detrend=detrend)

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
        from ._prepare import split_record

        return split_record(self, exp)

    def records(self) -> tuple[Experiment | ExperimentSet, tuple[Experiment, ...]]:
        """Estimation data and validation records: :func:`~servoid.data.prepare`'s.

        Kept for one release; ``prepare(spec)`` also says what was read,
        with each file's SHA-256.

        Returns
        -------
        tuple
            ``(estimation, validations)``.
        """
        from ._prepare import prepare

        return prepare(self).records

    @property
    def _origin(self) -> str:
        """The experiment file, as error messages name it."""
        return os.fspath(self.source) if self.source is not None else "experiment spec"


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
