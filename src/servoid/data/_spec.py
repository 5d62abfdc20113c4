"""The TOML experiment file: which rig file, which channels, what to do.

One TOML file describes one experiment. Paths are relative to the TOML
file's folder. Every table and key is checked; an unknown key raises
:class:`OptionError` listing the valid ones, a value of the wrong type or
range raises :class:`FileFormatError` naming the table and key.

Schema::

    [data]                    # required
    file = "bench.tdms"       # required: the rig file, relative to this file
    format = "tdms"           # csv | tdms | mat; default from the extension
    group = "Measurements"    # TDMS group; only for TDMS files
    time = "t"                # time column / channel / variable [s]
    dt = 0.0002               # [s], > 0: when there is no time column or waveform timing

    [channels.y_r]            # required, at least one: the servoid channel name
    source = "AI0"            # channel in the file; default the servoid name
    role = "r"                # r | u | y | side; default "side"
    gain = 0.0023             # value = gain·raw + offset; finite, non-zero; default 1
    offset = 0.0              # default 0
    unit = "m"                # unit after calibration; default: the file's unit when
                              # gain = 1 and offset = 0, else "" (unknown)

    [preprocess]              # applied in this order: lowpass, decimate, detrend
    lowpass = 200.0           # [Hz], zero-phase 4th-order Butterworth, at the file's rate
    decimate = 5              # integer factor >= 1, anti-aliased (FIR, zero phase)
    detrend = "mean"          # none | mean | linear (r, u, y channels); default "none"

    [split]                   # default: halves
    fraction = 0.5            # in (0, 1); or
    index = 10000             # sample index after decimation and skipped periods
    period = 2047             # whole excitation periods [samples after decimation]
    skip_periods = 0          # leading periods to drop before splitting (needs period)

    [loop]                    # free-form: what is known about the feedback loop
    [identify]                # free-form: which models to fit
    [report]                  # free-form: e.g. the output folder

Free-form tables hold strings, numbers, booleans, arrays of these, and
tables of these one level deep; they are returned read-only.
Channels of the rig file that are not listed under ``[channels]`` are not
loaded.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

from .._atomic import atomic_path
from .._errors import ChannelError, FileFormatError, OptionError, check_option
from ._columns import existing_file
from ._experiment import ROLES, Channel, Experiment, Role
from ._io import FORMATS, Format, format_of, read_experiment
from ._preprocess import decimate, detrend, lowpass, split

__all__ = [
    "ChannelSpec",
    "ExperimentSpec",
    "PreprocessSpec",
    "SplitSpec",
    "load_experiment_spec",
    "write_experiment_spec",
]

DetrendSpec = Literal["none", "mean", "linear"]
_DETRENDS: tuple[DetrendSpec, ...] = ("none", "mean", "linear")
_TOP_KEYS = ("data", "channels", "preprocess", "split", "loop", "identify", "report")
_DATA_KEYS = ("file", "format", "group", "time", "dt")
_CHANNEL_KEYS = ("source", "role", "gain", "offset", "unit")
_PREPROCESS_KEYS = ("lowpass", "decimate", "detrend")
_SPLIT_KEYS = ("fraction", "index", "period", "skip_periods")
_FREE_KEYS = ("loop", "identify", "report")
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


@dataclass(frozen=True)
class ChannelSpec:
    """One servoid channel: where it comes from and its calibration.

    Parameters
    ----------
    name : str
        The servoid channel name.
    source : str
        The channel's name in the rig file.
    role : {"r", "u", "y", "side"}
        Role in the experiment.
    gain : float
        Calibration gain: ``value = gain·raw + offset``.
    offset : float
        Calibration offset [unit after calibration].
    unit : str or None
        Unit after calibration; None: the file's unit if uncalibrated, else "".
    """

    name: str
    source: str
    role: Role = "side"
    gain: float = 1.0
    offset: float = 0.0
    unit: str | None = None


@dataclass(frozen=True)
class PreprocessSpec:
    """Preprocessing steps, applied as lowpass, decimate, detrend.

    Parameters
    ----------
    lowpass : float or None
        Zero-phase Butterworth cutoff [Hz].
    decimate : int
        Decimation factor (1: none).
    detrend : {"none", "mean", "linear"}
        Trend removed from the r, u and y channels.
    """

    lowpass: float | None = None
    decimate: int = 1
    detrend: DetrendSpec = "none"


@dataclass(frozen=True)
class SplitSpec:
    """How to split into estimation and validation data.

    Parameters
    ----------
    fraction : float or None
        Fraction of the record for estimation; default 0.5 when no index.
    index : int or None
        Sample index of the split (after decimation and skipped periods).
    period : int or None
        Excitation period [samples after decimation]; parts hold whole periods.
    skip_periods : int
        Leading periods dropped first.
    """

    fraction: float | None = None
    index: int | None = None
    period: int | None = None
    skip_periods: int = 0


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
    preprocess : PreprocessSpec
        Preprocessing steps.
    split : SplitSpec
        Estimation/validation split.
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
    preprocess: PreprocessSpec = PreprocessSpec()
    split: SplitSpec = SplitSpec()
    loop: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    identify: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    report: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    base_dir: Path = field(default=Path("."), compare=False)
    source: Path | None = field(default=None, compare=False)

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
        file = _string(where, "file", data["file"])
        fmt = data.get("format")
        if fmt is not None:
            _string(where, "format", fmt)
            check_option(f"{where} format", fmt, FORMATS)
        try:
            fmt = format_of(file, fmt)
        except OptionError as exc:
            raise OptionError(f"{where}: {exc}") from None
        group = _optional(where, "group", data.get("group"), _string)
        if group is not None and fmt != "tdms":
            raise FileFormatError(f"{where}: group applies to TDMS files only, this is {fmt}")
        time = _optional(where, "time", data.get("time"), _string)
        dt = _optional(where, "dt", data.get("dt"), _positive)
        channels = _channels(origin, table["channels"])
        return cls(
            file=file,
            format=fmt,
            channels=channels,
            group=group,
            time=time,
            dt=dt,
            preprocess=_preprocess(origin, table.get("preprocess", {})),
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

    def to_dict(self) -> dict[str, Any]:
        """The spec as a plain TOML-shaped dictionary (defaults omitted)."""
        data: dict[str, Any] = {"file": self.file, "format": self.format}
        for key in ("group", "time", "dt"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        channels: dict[str, Any] = {}
        for ch in self.channels:
            entry: dict[str, Any] = {"source": ch.source, "role": ch.role}
            if ch.gain != 1.0 or ch.offset != 0.0:
                entry.update(gain=ch.gain, offset=ch.offset)
            if ch.unit is not None:
                entry["unit"] = ch.unit
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
        for key in _FREE_KEYS:
            if getattr(self, key):
                out[key] = _thaw(getattr(self, key))
        return out

    def load(self) -> Experiment:
        """Read the rig file, calibrate and preprocess it.

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
        path = self.data_path
        raw = read_experiment(path, self.format, **self._reader_options())
        channels = []
        for ch in self.channels:
            try:
                src = raw.channel(ch.source)
            except ChannelError:
                raise ChannelError(
                    f"channel {ch.source!r} (servoid channel {ch.name!r}) is not in {path}"
                    f"{' group ' + repr(self.group) if self.group else ''}; the file has: "
                    f"{', '.join(raw.names)}"
                ) from None
            calibrated = ch.gain * src.values + ch.offset
            unit = ch.unit
            if unit is None:
                unit = src.unit if (ch.gain == 1.0 and ch.offset == 0.0) else ""
            channels.append(Channel(ch.name, ch.role, calibrated, unit))
        name = self.source.stem if self.source is not None else Path(self.file).stem
        exp = Experiment(tuple(channels), raw.dt, t0=raw.t0, name=name, notes=raw.notes)
        pre = self.preprocess
        if pre.lowpass is not None:
            exp = lowpass(exp, pre.lowpass, zero_phase=True)
        if pre.decimate > 1:
            exp = decimate(exp, pre.decimate)
        if pre.detrend != "none":
            exp = detrend(exp, pre.detrend)
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
        exp = self.load() if exp is None else exp
        spl = self.split
        if spl.skip_periods and spl.period is not None:
            exp = exp.slice(spl.skip_periods * spl.period)
        at: float | int = spl.index if spl.index is not None else (spl.fraction or 0.5)
        return split(exp, at, period=spl.period)

    def _reader_options(self) -> dict[str, Any]:
        options: dict[str, Any] = {"dt": self.dt}
        if self.format == "csv":
            options["time"] = self.time if self.time is not None else "time"
        elif self.format == "tdms":
            options.update(group=self.group, time=self.time)
        else:
            options.update(time=self.time, variables=sorted({c.source for c in self.channels}))
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
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{path}: not a valid TOML file ({exc})") from None
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
    target = Path(path)
    if not isinstance(spec, ExperimentSpec):
        spec = ExperimentSpec.from_dict(spec, base_dir=target.parent)
    doc = spec.to_dict()
    file = Path(spec.file)
    if not file.is_absolute() and spec.base_dir.resolve() != target.parent.resolve():
        # Keep pointing at the same rig file from the new folder.
        doc["data"]["file"] = Path(
            os.path.relpath(spec.data_path.resolve(), target.parent.resolve())
        ).as_posix()
    text = _emit_document(doc)
    with atomic_path(target, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return target


# -- validation --------------------------------------------------------------------------------


def _check_keys(
    origin: str,
    where: str,
    table: object,
    valid: tuple[str, ...],
    required: tuple[str, ...] = (),
) -> None:
    if not isinstance(table, Mapping):
        raise FileFormatError(f"{origin}: {where} must be a table, got {_kind(table)}")
    unknown = [k for k in table if k not in valid]
    if unknown:
        raise OptionError(
            f"{origin}: unknown key(s) in {where}: {', '.join(repr(k) for k in unknown)}; "
            f"valid keys: {', '.join(valid)}"
        )
    missing = [k for k in required if k not in table]
    if missing:
        raise FileFormatError(
            f"{origin}: {where} is missing the required key(s) {', '.join(missing)}"
        )


def _kind(value: object) -> str:
    return f"{type(value).__name__} {value!r}"


def _optional(where: str, key: str, value: Any, check: Any) -> Any:
    return None if value is None else check(where, key, value)


def _string(where: str, key: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise FileFormatError(f"{where} {key} must be a non-empty string, got {_kind(value)}")
    return value


def _number(where: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FileFormatError(f"{where} {key} must be a finite number, got {_kind(value)}")
    return float(value)


def _positive(where: str, key: str, value: Any) -> float:
    number = _number(where, key, value)
    if number <= 0:
        raise FileFormatError(f"{where} {key} must be > 0, got {value!r}")
    return number


def _integer(where: str, key: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise FileFormatError(f"{where} {key} must be an integer >= {minimum}, got {_kind(value)}")
    return value


def _channels(origin: str, table: Any) -> tuple[ChannelSpec, ...]:
    if not isinstance(table, Mapping) or not table:
        raise FileFormatError(
            f"{origin}: [channels] must hold at least one table [channels.<name>], "
            f"got {_kind(table)}"
        )
    out = []
    for name, entry in table.items():
        where = f"{origin}: [channels.{name}]"
        _check_keys(origin, f"[channels.{name}]", entry, _CHANNEL_KEYS)
        role = entry.get("role", "side")
        check_option(f"{where} role", role, ROLES)
        gain = _number(where, "gain", entry.get("gain", 1.0))
        if gain == 0:
            raise FileFormatError(f"{where} gain must be non-zero, got {entry['gain']!r}")
        unit = entry.get("unit")
        if unit is not None and not isinstance(unit, str):
            raise FileFormatError(f"{where} unit must be a string, got {_kind(unit)}")
        out.append(
            ChannelSpec(
                name=name,
                source=_string(where, "source", entry.get("source", name)),
                role=role,
                gain=gain,
                offset=_number(where, "offset", entry.get("offset", 0.0)),
                unit=unit,
            )
        )
    return tuple(out)


def _preprocess(origin: str, table: Any) -> PreprocessSpec:
    _check_keys(origin, "[preprocess]", table, _PREPROCESS_KEYS)
    where = f"{origin}: [preprocess]"
    kind = table.get("detrend", "none")
    check_option(f"{where} detrend", kind, _DETRENDS)
    return PreprocessSpec(
        lowpass=_optional(where, "lowpass", table.get("lowpass"), _positive),
        decimate=_integer(where, "decimate", table.get("decimate", 1), 1),
        detrend=kind,
    )


def _split(origin: str, table: Any) -> SplitSpec:
    _check_keys(origin, "[split]", table, _SPLIT_KEYS)
    where = f"{origin}: [split]"
    if "fraction" in table and "index" in table:
        raise FileFormatError(f"{where}: give fraction or index, not both")
    fraction = table.get("fraction")
    if fraction is not None:
        fraction = _number(where, "fraction", fraction)
        if not 0 < fraction < 1:
            raise FileFormatError(f"{where} fraction must lie in (0, 1), got {fraction!r}")
    index = _optional(where, "index", table.get("index"), lambda w, k, v: _integer(w, k, v, 2))
    period = _optional(where, "period", table.get("period"), lambda w, k, v: _integer(w, k, v, 2))
    skip = _integer(where, "skip_periods", table.get("skip_periods", 0), 0)
    if skip and period is None:
        raise FileFormatError(f"{where}: skip_periods needs period")
    return SplitSpec(fraction=fraction, index=index, period=period, skip_periods=skip)


def _free(origin: str, key: str, table: Any, depth: int = 0) -> Mapping[str, Any]:
    where = f"{origin}: [{key}]"
    if not isinstance(table, Mapping):
        raise FileFormatError(f"{where} must be a table, got {_kind(table)}")
    out: dict[str, Any] = {}
    for k, v in table.items():
        if isinstance(v, Mapping):
            if depth >= 1:
                raise FileFormatError(f"{where}: table {k!r} is nested more than one level deep")
            out[k] = _free(origin, f"{key}.{k}", v, depth + 1)
        elif isinstance(v, (list, tuple)):
            if not all(_is_scalar(x) for x in v):
                raise FileFormatError(
                    f"{where} {k}: arrays may hold only strings, numbers and booleans"
                )
            out[k] = tuple(v)
        elif _is_scalar(v):
            out[k] = v
        else:
            raise FileFormatError(
                f"{where} {k}: unsupported value {_kind(v)}; use a string, number, boolean, "
                "array or table"
            )
    return MappingProxyType(out)


def _is_scalar(value: object) -> bool:
    return isinstance(value, (str, bool, int, float))


def _thaw(table: Mapping[str, Any]) -> dict[str, Any]:
    return {
        k: _thaw(v) if isinstance(v, Mapping) else list(v) if isinstance(v, tuple) else v
        for k, v in table.items()
    }


# -- TOML emitter ----------------------------------------------------------------------------


def _emit_document(doc: Mapping[str, Any]) -> str:
    parts = [_emit_table(["data"], doc["data"])]
    for name, entry in doc["channels"].items():
        parts.append(_emit_table(["channels", name], entry))
    for key in ("preprocess", "split", *_FREE_KEYS):
        if key in doc:
            parts.append(_emit_table([key], doc[key]))
    return "\n".join(parts)


def _emit_table(header: list[str], table: Mapping[str, Any]) -> str:
    lines = [f"[{'.'.join(_emit_key(h) for h in header)}]"]
    nested = []
    for k, v in table.items():
        if isinstance(v, Mapping):
            nested.append((k, v))
        else:
            lines.append(f"{_emit_key(k)} = {_emit_value(v)}")
    text = "\n".join(lines) + "\n"
    for k, v in nested:
        text += "\n" + _emit_table([*header, k], v)
    return text


def _emit_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else _emit_string(key)


def _emit_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        # repr is the shortest text that reads back as the same double; inf/nan are TOML too.
        return repr(value)
    if isinstance(value, str):
        return _emit_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_emit_value(v) for v in value) + "]"
    raise FileFormatError(f"cannot write {_kind(value)} to TOML")


def _emit_string(text: str) -> str:
    escapes = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b",
               "\f": "\\f"}
    out = []
    for c in text:
        if c in escapes:
            out.append(escapes[c])
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'
