"""Operating conditions of an EHSA record from its side channels.

The rig logs the supply and return pressures and the oil temperature
beside the reference and the position (models-spec §1.1: "Measured: y_r,
y, P_s, P_t, oil temperature").  Where servoid's simulator uses them:

* **Supply and return pressure: used.**  The valve flow law of the
  simulator, ``Q_L = C_d·w·x_e·√((P_s − P_T − sgn(x_e)·P_L)/ρ)``
  (models-spec §1.4, Merritt), takes the pressure drop across the
  valve, so the flow gain ``K_qs = C_d·w·√((P_s − P_T)/ρ)`` and the
  load-pressure droop both follow the measured pressures.  The simulator
  holds the supply constant (an ideal supply), so the record's median is
  used (robust to the transducer chain's start-up transient and to pump
  ripple), and a spread of more than :data:`SUPPLY_SPREAD` of the drop
  over the record is warned about.
* **Oil temperature: recorded, not used.**  Bulk modulus, density,
  viscosity and leakage vary with temperature, but the simulator (like
  models-spec §1.4) takes β_e, ρ, B_p and K_ce constant, so the fitted
  parameters are those of the record's mean temperature.  Its median and
  drift are reported, and a drift above :data:`TEMPERATURE_DRIFT` is
  warned about (the parameters then average over it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._checks import type_error
from ..._errors import ChannelError, DataError, ServoidWarning
from ..._warn import warn
from ...data import Experiment

__all__ = ["SUPPLY_SPREAD", "TEMPERATURE_DRIFT", "OperatingPoint", "operating_point"]

#: Largest 5–95 % spread of P_s − P_T over a record, relative to its median,
#: taken as a constant supply: the flow gain ∝ √(P_s − P_T) then moves < 2.5 %.
SUPPLY_SPREAD = 0.05
#: Largest spread of the oil temperature over a record [°C] (5–95 %) taken
#: as one temperature: a mineral hydraulic oil's viscosity changes by about
#: 3 %/°C near 40 °C, β_e by about 0.5 %/°C.
TEMPERATURE_DRIFT = 5.0

# unit → (scale, offset) to Pa and °C
#: A return-pressure median below 0 by less than this fraction of P_s is taken as 0.
_RETURN_OFFSET = 0.01
#: A valve drop below this fraction of the nominal one is taken for a wrong channel (a
#: detrended or uncalibrated transducer), not a rig run at 1/20 of its pressure.
_LOWEST_DROP = 0.05
_PRESSURE_UNITS = {"Pa": (1.0, 0.0), "kPa": (1e3, 0.0), "MPa": (1e6, 0.0), "bar": (1e5, 0.0)}
_TEMPERATURE_UNITS = {"°C": (1.0, 0.0), "degC": (1.0, 0.0), "C": (1.0, 0.0),
                      "K": (1.0, -273.15)}


@dataclass(frozen=True)
class OperatingPoint:
    """Supply, return pressure and oil temperature of a record.

    Parameters
    ----------
    P_s : float
        Supply pressure used by the model [Pa].
    P_T : float
        Return pressure used by the model [Pa].
    supply_source : str
        Where P_s came from: a channel name, ``"given"`` or ``"nominal"``.
    return_source : str
        Where P_T came from, likewise.
    supply_spread : float or None
        5–95 % spread of ``P_s − P_T`` over the records, relative to its
        median (None when not measured).
    oil_temperature : float or None
        Median oil temperature [°C] (None when not logged).
    temperature_spread : float or None
        5–95 % spread of the oil temperature [°C].
    """

    P_s: float
    P_T: float
    supply_source: str
    return_source: str
    supply_spread: float | None = None
    oil_temperature: float | None = None
    temperature_spread: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {"P_s": self.P_s, "P_T": self.P_T, "supply_source": self.supply_source,
                "return_source": self.return_source, "supply_spread": self.supply_spread,
                "oil_temperature_degC": self.oil_temperature,
                "temperature_spread_degC": self.temperature_spread,
                "temperature_used": False}


def operating_point(
    segments: Sequence[Experiment],
    supply_pressure: str | float | None,
    return_pressure: str | float | None,
    oil_temperature: str | None,
    nominal_P_s: float,
    nominal_P_T: float,
) -> OperatingPoint:
    """Read the operating point of the records' side channels.

    Parameters
    ----------
    segments : sequence of Experiment
        The records.
    supply_pressure, return_pressure : str, float or None
        A channel name (Pa, kPa, MPa or bar), a value [Pa], or None for
        the nominal value.
    oil_temperature : str or None
        A channel name (°C or K), or None.
    nominal_P_s, nominal_P_T : float
        Values used for None [Pa].

    Returns
    -------
    OperatingPoint
        The values and where they came from.

    Raises
    ------
    ChannelError
        A named channel is missing from a record.
    DataError
        A channel in another unit, or pressures with P_s <= P_T.

    Warns
    -----
    ServoidWarning
        The supply or the temperature varies over the records more than
        the model's constant values allow.
    """
    p_s, src_s, series_s = _pressure(segments, supply_pressure, "supply_pressure", nominal_P_s)
    p_t, src_t, series_t = _pressure(segments, return_pressure, "return_pressure", nominal_P_T)
    if p_t < 0.0 and -p_t <= _RETURN_OFFSET * max(p_s, 0.0):
        # gauge transducers read a return line at ~0 with noise and offset: a median a
        # little below 0 is 0 (the simulator needs P_T >= 0)
        p_t = 0.0
    nominal_drop = nominal_P_s - nominal_P_T
    if p_t < 0.0 or not p_s - p_t > _LOWEST_DROP * nominal_drop:
        raise DataError(
            f"the supply pressure ({src_s}: {p_s:.6g} Pa) must exceed the return pressure "
            f"({src_t}: {p_t:.6g} Pa), both >= 0, by more than {100 * _LOWEST_DROP:g} % of the "
            f"nominal drop {nominal_drop:.6g} Pa; a detrended or uncalibrated pressure "
            "channel reads about 0 — map it with role 'side' and its calibration to Pa")
    spread = None
    if series_s is not None:
        drop = series_s - (series_t if series_t is not None else p_t)
        lo, hi = np.percentile(drop, [5.0, 95.0])
        spread = float((hi - lo) / (p_s - p_t))
        if spread > SUPPLY_SPREAD:
            warn(
                f"the valve pressure drop P_s − P_T varies by {100 * spread:.3g} % over the "
                f"record (5–95 %); the simulator holds the supply constant at the median "
                f"{(p_s - p_t) / 1e6:.4g} MPa, so the flow gain (∝ √(P_s − P_T)) is an average",
                ServoidWarning)
    temp = spread_t = None
    if oil_temperature is not None and not isinstance(oil_temperature, str):
        raise type_error("oil_temperature", oil_temperature, "a channel name or None")
    if oil_temperature is not None:
        series = _series(segments, oil_temperature, "oil_temperature", _TEMPERATURE_UNITS,
                         "°C or K")
        temp = float(np.median(series))
        lo, hi = np.percentile(series, [5.0, 95.0])
        spread_t = float(hi - lo)
        if spread_t > TEMPERATURE_DRIFT:
            warn(
                f"the oil temperature varies by {spread_t:.3g} °C over the record (5–95 %); the "
                "simulator takes β_e, ρ, B_p and K_ce constant, so the refined parameters "
                f"average over it (median {temp:.4g} °C)", ServoidWarning)
    return OperatingPoint(p_s, p_t, src_s, src_t, spread, temp, spread_t)


# -- private helpers ---------------------------------------------------------


def _pressure(segments: Sequence[Experiment], spec: str | float | None, what: str,
              nominal: float) -> tuple[float, str, np.ndarray | None]:
    if spec is None:
        return float(nominal), "nominal", None
    if isinstance(spec, str):
        series = _series(segments, spec, what, _PRESSURE_UNITS, "Pa, kPa, MPa or bar")
        return float(np.median(series)), spec, series
    if isinstance(spec, bool) or not isinstance(spec, (int, float, np.integer, np.floating)):
        raise type_error(what, spec, "a channel name, a pressure [Pa] or None")
    value = float(spec)
    if not (math.isfinite(value) and value >= 0.0):
        raise DataError(f"{what} must be a finite pressure >= 0 Pa, got {value}")
    return value, "given", None


def _series(segments: Sequence[Experiment], name: str, what: str,
            units: Mapping[str, tuple[float, float]], listed: str) -> np.ndarray:
    parts = []
    for seg in segments:
        if name not in seg.names:
            raise ChannelError(
                f"{what}: the record {seg.name or '(unnamed)'} has no channel {name!r} (it has "
                f"{', '.join(seg.names)}); map the side channel in the experiment file, pass "
                f"{what}=<channel name>, a value, or None to use the nominal value")
        unit = seg.unit(name)
        if unit not in units:
            raise DataError(f"{what}: channel {name!r} is in {unit or 'no unit'!r}; calibrate "
                            f"it to {listed}")
        scale, offset = units[unit]
        parts.append(seg[name] * scale + offset)
    return np.concatenate(parts)
