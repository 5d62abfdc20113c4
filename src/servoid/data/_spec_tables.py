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

from .._errors import FileFormatError, OptionError, ServoidError, check_option
from ._experiment import ROLES, Experiment, Role
from ._io import format_of

DetrendSpec = Literal["none", "mean", "linear"]
_DETRENDS: tuple[DetrendSpec, ...] = ("none", "mean", "linear")
_TOP_KEYS = ("data", "channels", "preprocess", "split", "validation", "rig", "loop",
             "identify", "report")
_DATA_KEYS = ("file", "format", "group", "time", "dt", "max_bytes", "jitter", "delimiter",
              "decimal", "time_unit", "columns", "skip_columns", "skip_rows")
_CSV_KEYS = ("delimiter", "decimal", "time_unit", "columns", "skip_columns", "skip_rows")
_CSV_TEXT_KEYS = ("delimiter", "decimal", "time_unit")
_CHANNEL_KEYS = ("source", "role", "gain", "offset", "unit", "limits")
_VALIDATION_KEYS = ("file", "initial", "transient")
_INITIALS = ("auto", "estimate", "zero", "measured")
_PREPROCESS_KEYS = ("lowpass", "decimate", "detrend")
_RIG_KEYS = ("anti_alias", "reference")
_ANTI_ALIAS_KEYS = ("order", "cutoff")
RigReference = Literal["command", "readback"]
_RIG_REFERENCES: tuple[RigReference, ...] = ("command", "readback")
_SPLIT_KEYS = ("fraction", "index", "period", "skip_periods")
_FREE_KEYS = ("loop", "identify", "report")


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


def _csv_option(where: str, key: str, value: Any) -> Any:
    """A CSV reading option of ``[data]``, checked (lists become tuples)."""
    if key in _CSV_TEXT_KEYS:
        return _string(where, key, value)
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
                limits=_limits(where, entry.get("limits")),
            )
        )
    return tuple(out)


def _file_list(where: str, key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, (list, tuple)):
        if not value:
            raise FileFormatError(f"{where} {key} must name at least one file, got []")
        return tuple(_string(where, key, v) for v in value)
    return (_string(where, key, value),)


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
