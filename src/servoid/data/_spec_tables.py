"""The parts of an experiment file and the checks of its TOML tables.

:class:`ChannelSpec`, :class:`PreprocessSpec`, :class:`SplitSpec`,
:class:`RigSpec` and :class:`ValidationSpec` are the validated tables that
:class:`~servoid.data.ExperimentSpec` is made of; the functions below check
one table each, naming the file and the key in every error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Literal

from .._checks import file_name_problem, type_error
from .._errors import DataError, FileFormatError, OptionError, ServoidError, check_option
from .._shown import shown
from ._experiment import ROLES, Experiment, Role
from ._formats import RIG_FORMATS, format_of

DetrendSpec = Literal["none", "mean", "linear"]
_DETRENDS: tuple[DetrendSpec, ...] = ("none", "mean", "linear")
_TOP_KEYS = ("data", "channels", "preprocess", "split", "validation", "rig", "loop",
             "acceptance", "identify", "report")
_DATA_KEYS = ("file", "format", "group", "time", "dt", "max_bytes", "jitter", "delimiter",
              "decimal", "time_unit", "columns", "skip_columns", "skip_rows")
_CSV_KEYS = RIG_FORMATS["csv"].options
_CSV_TEXT_KEYS = ("delimiter", "decimal", "time_unit")
#: The values the CSV reader takes (``read_csv``), checked when the file is loaded.
_CSV_TEXT_VALUES = {"decimal": (".", ","), "time_unit": ("s", "ms", "us", "µs")}
_NOT_DELIMITERS = ('"', "\n", "\r", ".", "-", "+", "e", "E") + tuple("0123456789")
_CHANNEL_KEYS = ("source", "role", "gain", "offset", "unit", "limits")
_VALIDATION_KEYS = ("file", "initial", "transient")
_INITIALS = ("auto", "estimate", "zero", "measured")
_PREPROCESS_KEYS = ("lowpass", "decimate", "detrend")
_RIG_KEYS = ("anti_alias", "reference")
_ANTI_ALIAS_KEYS = ("order", "cutoff")
RigReference = Literal["command", "readback"]
_RIG_REFERENCES: tuple[RigReference, ...] = ("command", "readback")
_SPLIT_KEYS = ("fraction", "index", "period", "skip_periods")
#: What to write for a required key that is missing, in the file's own syntax.
_REQUIRED_HINTS = {"data": "a [data] table with file = \"<rig file>\"",
                   "channels": "a [channels.<name>] table per channel, e.g. [channels.y] with "
                   "role = \"y\"",
                   "file": "file = \"<rig file>\" (relative to the experiment file)",
                   "order": "order = <1..10>", "cutoff": "cutoff = <Hz>"}
_FREE_KEYS = ("loop", "acceptance", "identify", "report")


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
    limits : (float, float) or None
        The sensor's range after calibration [unit]; simulations of this
        channel are clipped to it.
    """

    name: str
    source: str
    role: Role = "side"
    gain: float = 1.0
    offset: float = 0.0
    unit: str | None = None
    limits: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        _text("ChannelSpec", "name", self.name)
        _text("ChannelSpec", "source", self.source)
        check_option("ChannelSpec role", self.role, ROLES)
        _set(self, "gain", _real("ChannelSpec", "gain", self.gain))
        if self.gain == 0:
            raise DataError("ChannelSpec gain must be non-zero, got 0.0")
        _set(self, "offset", _real("ChannelSpec", "offset", self.offset))
        if self.unit is not None and not isinstance(self.unit, str):
            raise type_error("ChannelSpec unit", self.unit, "a string or None")
        if self.limits is not None:
            if isinstance(self.limits, (str, bytes)) or not isinstance(self.limits, (
                    tuple, list)) or len(self.limits) != 2:
                raise type_error("ChannelSpec limits", self.limits, "(low, high) or None")
            lo, hi = (_real("ChannelSpec", "limits", v) for v in self.limits)
            if not lo < hi:
                raise DataError(f"ChannelSpec limits must be (low, high) with low < high, got "
                                f"{self.limits!r}")
            _set(self, "limits", (lo, hi))


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

    def __post_init__(self) -> None:
        if self.lowpass is not None:
            _set(self, "lowpass", _real("PreprocessSpec", "lowpass", self.lowpass, positive=True))
        _whole("PreprocessSpec", "decimate", self.decimate, 1)
        check_option("PreprocessSpec detrend", self.detrend, _DETRENDS)


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

    def __post_init__(self) -> None:
        if self.fraction is not None:
            _set(self, "fraction", _real("SplitSpec", "fraction", self.fraction))
            if not 0 < self.fraction < 1:
                raise DataError(f"SplitSpec fraction must lie in (0, 1), got {self.fraction!r}")
            if self.index is not None:
                raise DataError("SplitSpec takes fraction or index, not both")
        if self.index is not None:
            _whole("SplitSpec", "index", self.index, 2)
        if self.period is not None:
            _whole("SplitSpec", "period", self.period, 2)
        _whole("SplitSpec", "skip_periods", self.skip_periods, 0)
        if self.skip_periods and self.period is None:
            raise DataError("SplitSpec skip_periods needs period")


@dataclass(frozen=True)
class RigSpec:
    """What the rig did to the signals before they were logged.

    Parameters
    ----------
    anti_alias_order : int or None
        Order of the analog Butterworth anti-alias filter before the ADC.
    anti_alias_cutoff : float or None
        Its -3 dB frequency [Hz].
    reference : {"command", "readback"} or None
        ``"command"``: the r channel is the DAC command as written (a
        staircase; on decimation it is subsampled, not filtered);
        ``"readback"``: r went through the same filter and ADC as y.
        None: not declared.
    """

    anti_alias_order: int | None = None
    anti_alias_cutoff: float | None = None
    reference: RigReference | None = None

    def __post_init__(self) -> None:
        if (self.anti_alias_order is None) != (self.anti_alias_cutoff is None):
            raise DataError("RigSpec takes anti_alias_order and anti_alias_cutoff together, got "
                            f"{self.anti_alias_order!r} and {self.anti_alias_cutoff!r}")
        if self.anti_alias_order is not None:
            _whole("RigSpec", "anti_alias_order", self.anti_alias_order, 1, 10)
            _set(self, "anti_alias_cutoff",
                 _real("RigSpec", "anti_alias_cutoff", self.anti_alias_cutoff, positive=True))
        if self.reference is not None:
            check_option("RigSpec reference", self.reference, _RIG_REFERENCES)

    @property
    def is_declared(self) -> bool:
        """True when the experiment file has a ``[rig]`` table."""
        return self != RigSpec()

    def to_dict(self) -> dict[str, Any]:
        """The ``[rig]`` table (empty when nothing is declared)."""
        out: dict[str, Any] = {}
        if self.anti_alias_order is not None:
            out["anti_alias"] = {"order": self.anti_alias_order,
                                 "cutoff": self.anti_alias_cutoff}
        if self.reference is not None:
            out["reference"] = self.reference
        return out


@dataclass(frozen=True)
class ValidationSpec:
    """Separate validation records and how to simulate on them.

    Parameters
    ----------
    files : tuple of str
        Validation rig files, relative to ``base_dir`` unless absolute; read
        with the experiment's channels, calibration and preprocessing.
    initial : {"auto", "estimate", "zero", "measured"}
        Initial state of the simulation (see :func:`servoid.validate.validate`).
    transient : int
        Samples at the start of each record excluded from the metrics.
    """

    files: tuple[str, ...] = ()
    initial: str = "auto"
    transient: int = 0

    def __post_init__(self) -> None:
        _set(self, "files", _names("ValidationSpec", "files", self.files))
        check_option("ValidationSpec initial", self.initial, _INITIALS)
        _whole("ValidationSpec", "transient", self.transient, 0)


# -- construction checks (a table built in Python) ---------------------------------------------


def _set(obj: object, key: str, value: Any) -> None:
    """Store a checked field of a frozen table in its canonical type (a float, a tuple)."""
    object.__setattr__(obj, key, value)


def _text(owner: str, key: str, value: Any) -> str:
    if not isinstance(value, str):
        raise type_error(f"{owner} {key}", value, "a string")
    if not value:
        raise DataError(f"{owner} {key} must be a non-empty string")
    return value


def _real(owner: str, key: str, value: Any, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise type_error(f"{owner} {key}", value, "a number")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number) or (positive and number <= 0):
        raise DataError(f"{owner} {key} must be a finite number{' > 0' if positive else ''}, "
                        f"got {value!r}")
    return number


def _whole(owner: str, key: str, value: Any, minimum: int, maximum: int = 2**63 - 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise type_error(f"{owner} {key}", value, "an integer")
    if not minimum <= value <= maximum:
        raise DataError(f"{owner} {key} must be an integer in {minimum}..{maximum}, got {value}")
    return value


def _names(owner: str, key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list)):
        raise type_error(f"{owner} {key}", value, "a tuple of file names")
    for v in value:
        _text(owner, key, v)
    return tuple(value)


def _format_keys(where: str, fmt: str, given: Mapping[str, Any]) -> None:
    """Refuse ``[data]`` keys that only another format takes (``group`` on a CSV file)."""
    own = RIG_FORMATS[fmt].options
    for other in RIG_FORMATS.values():
        keys = [k for k in other.options if k in given and k not in own]
        if not keys:
            continue
        if len(other.options) == 1:
            raise FileFormatError(f"{where}: {keys[0]} applies to {other.label} files only, "
                                  f"this is {fmt}: remove {keys[0]}")
        raise FileFormatError(f"{where}: {', '.join(keys)} apply to {other.label} files only, "
                              f"this is {fmt}")


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
            f"{origin}: unknown key(s) in {where}: {', '.join(shown(k) for k in unknown)}; "
            f"valid keys: {', '.join(valid)}"
        )
    missing = [k for k in required if k not in table]
    if missing:
        raise FileFormatError(
            f"{origin}: {where} is missing the required key(s) {', '.join(missing)}; add "
            + "; ".join(_REQUIRED_HINTS.get(k, k) for k in missing)
        )


def _kind(value: object) -> str:
    return f"{type(value).__name__} {shown(value)}"


def _like(exc: ServoidError, message: str) -> ServoidError:
    """``exc``'s kind of error with another message."""
    try:
        return type(exc)(message)
    except TypeError:  # an error class with a richer constructor keeps its family
        return ServoidError(message)

def _optional(where: str, key: str, value: Any, check: Any) -> Any:
    return None if value is None else check(where, key, value)

def _string(where: str, key: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise FileFormatError(f"{where} {key} must be a non-empty string, got {_kind(value)}")
    return value

def _csv_options(where: str, data: Mapping[str, Any]) -> dict[str, Any]:
    """The CSV reading options of ``[data]``, each checked, and how they combine."""
    options = {k: _csv_option(where, k, data[k]) for k in _CSV_KEYS if k in data}
    if "columns" in options and "skip_columns" in options:
        raise FileFormatError(f"{where}: give columns (the columns to read) or skip_columns "
                              "(the columns not to read), not both: remove one")
    if options.get("decimal", ".") == options.get("delimiter", ","):
        raise FileFormatError(f"{where}: decimal = {options.get('decimal')!r} is also the field "
                              "separator; set delimiter = \";\" (or \"\\t\" for a tab) for a "
                              "file with decimal commas")
    return options

def _csv_option(where: str, key: str, value: Any) -> Any:
    """A CSV reading option of ``[data]``, checked (lists become tuples)."""
    if key in _CSV_TEXT_KEYS:
        text = _string(where, key, value)
        valid = _CSV_TEXT_VALUES.get(key)
        if valid is not None and text not in valid:
            raise FileFormatError(f"{where} {key} must be one of "
                                  f"{', '.join(repr(v) for v in valid)}, got {shown(text)}")
        if key == "delimiter" and (len(text) != 1 or text in _NOT_DELIMITERS):
            raise FileFormatError(
                f"{where} delimiter must be the one character between fields (\",\", \";\" "
                f"or \"\\t\" for a tab), got {shown(text)}; set it to the separator the "
                "file uses, or remove it for a comma")
        return text
    if key == "skip_rows":
        return _integer(where, key, value, 0)
    example = '["time", "u", "y"] or [0, 1, 3]'
    if not isinstance(value, (list, tuple)) or not value or not all(
            isinstance(v, str) and v or isinstance(v, int) and not isinstance(v, bool) and v >= 0
            for v in value):
        raise FileFormatError(
            f"{where} {key} must be a non-empty array of column names (as in the header) or "
            f"0-based column indices (0 is the first column), e.g. {example}; got {_kind(value)}"
        )
    repeated = sorted({repr(v) for v in value if value.count(v) > 1})
    if repeated:
        raise FileFormatError(f"{where} {key} lists {', '.join(repeated)} more than once: "
                              "remove the repeat")
    return tuple(value)

def _number(where: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FileFormatError(f"{where} {key} must be a finite number, got {_kind(value)}")
    try:
        number = float(value)
    except OverflowError:  # an integer past the largest float (10**400)
        number = math.inf
    if not math.isfinite(number):
        raise FileFormatError(f"{where} {key} must be a finite number (within ±1.8e308), got "
                              f"{_kind(value)}")
    return number

def _positive(where: str, key: str, value: Any) -> float:
    number = _number(where, key, value)
    if number <= 0:
        raise FileFormatError(f"{where} {key} must be > 0, got {value!r}")
    return number

def _integer(where: str, key: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise FileFormatError(f"{where} {key} must be an integer >= {minimum}, got {_kind(value)}")
    if value >= 2**63:  # past what numpy indexes and counts with
        raise FileFormatError(f"{where} {key} must be an integer below 2**63, got {_kind(value)}")
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
                limits=_limits(where, entry.get("limits")),
            )
        )
    return tuple(out)

def _file_list(where: str, key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, (list, tuple)):
        if not value:
            raise FileFormatError(f"{where} {key} must name at least one file, got []")
        return tuple(_file_name(where, key, v) for v in value)
    return (_file_name(where, key, value),)

def _file_name(where: str, key: str, value: Any) -> str:
    """A file's path as the experiment file writes it: text the file system can take."""
    text = _string(where, key, value)
    problem = file_name_problem(text)
    if problem is not None:
        raise FileFormatError(f"{where} {key} = {shown(text)} {problem}: write the rig file's "
                              "name")
    return text

def _validation(origin: str, table: Any, fmt: str) -> ValidationSpec:
    _check_keys(origin, "[validation]", table, _VALIDATION_KEYS)
    where = f"{origin}: [validation]"
    if not table:
        return ValidationSpec()
    if "file" not in table:
        raise FileFormatError(f"{where} needs file = \"<validation record>\" (or an array)")
    files = _file_list(where, "file", table["file"])
    for f in files:
        try:
            other = format_of(f, None)
        except OptionError as exc:
            raise OptionError(f"{where}: {exc}") from None
        if other != fmt:
            raise FileFormatError(f"{where} file {f!r} is {other}, but [data] is {fmt}: the "
                                  "validation record must be written like the estimation one")
    initial = table.get("initial", "auto")
    check_option(f"{where} initial", initial, _INITIALS)
    transient = _integer(where, "transient", table.get("transient", 0), 0)
    return ValidationSpec(files, initial, transient)

def _check_like(estimation: Experiment, validation: Experiment) -> None:
    if not math.isclose(estimation.dt, validation.dt, rel_tol=1e-9):
        raise FileFormatError(
            f"the validation record {validation.name!r} has dt = {validation.dt:g} s but the "
            f"estimation data {estimation.dt:g} s: record both at one rate, or resample one"
        )

def _limits(where: str, value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise FileFormatError(f"{where} limits must be [low, high], got {_kind(value)}")
    lo, hi = (_number(where, "limits", v) for v in value)
    if not lo < hi:
        raise FileFormatError(f"{where} limits must be [low, high] with low < high, got {value!r}")
    return lo, hi

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

def _rig(origin: str, table: Any) -> RigSpec:
    _check_keys(origin, "[rig]", table, _RIG_KEYS)
    where = f"{origin}: [rig]"
    order = cutoff = None
    if "anti_alias" in table:
        aa = table["anti_alias"]
        _check_keys(origin, "[rig] anti_alias", aa, _ANTI_ALIAS_KEYS,
                    required=_ANTI_ALIAS_KEYS)
        order = _integer(f"{where} anti_alias", "order", aa["order"], 1)
        if order > 10:
            raise FileFormatError(f"{where} anti_alias order must be an analog Butterworth "
                                  f"order 1..10, got {order}")
        cutoff = _positive(f"{where} anti_alias", "cutoff", aa["cutoff"])
    reference = table.get("reference")
    if reference is not None:
        check_option(f"{where} reference", reference, _RIG_REFERENCES)
    return RigSpec(order, cutoff, reference)

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
        raise FileFormatError(f"{where}: skip_periods needs period; add period = <samples "
                              "per excitation period>, or remove skip_periods")
    return SplitSpec(fraction=fraction, index=index, period=period, skip_periods=skip)

def _free(origin: str, key: str, table: Any, depth: int = 0) -> Mapping[str, Any]:
    where = f"{origin}: [{key}]"
    if not isinstance(table, Mapping):
        raise FileFormatError(f"{where} must be a table, got {_kind(table)}")
    out: dict[str, Any] = {}
    for k, v in table.items():
        if isinstance(v, Mapping):
            if depth >= 1:
                raise FileFormatError(f"{where}: table {shown(k)} is nested more than one level "
                                      "deep; a free-form table holds values and tables of values "
                                      "only: flatten it (key = value, or dotted names)")
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
