"""The :class:`Excitation`: a designed test signal with its design record."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, check_option
from ..data import Experiment
from ._checks import as_dt, as_float, as_int, as_signal, nyquist

__all__ = ["Excitation", "ExcitationRole"]

ExcitationRole = Literal["r", "u", "side"]
_EXCITATION_ROLES: tuple[ExcitationRole, ...] = ("r", "u", "side")


@dataclass(frozen=True, eq=False)
class Excitation:
    """A designed excitation signal and the parameters behind it.

    Built by the designers (:func:`prbs`, :func:`multisine`, ...); the
    constructor only checks consistency. ``values`` is a read-only copy.

    Parameters
    ----------
    values : ndarray of float, shape (N,)
        The samples, N >= 2 [signal unit].
    dt : float
        Sample period [s], > 0.
    kind : str
        Designer name: ``"prbs"``, ``"random_binary"``, ``"multisine"``,
        ``"chirp"`` or ``"steps"``.
    period : int or None
        Samples per period for a periodic signal (it divides N), or None.
    band : tuple of float
        ``(f_lo, f_hi)`` [Hz], the band the design excites; see each designer.
    amplitude : float
        Peak deviation from ``offset`` [signal unit], >= 0. For a chirp it
        is the sine's amplitude, which the samples may slightly miss.
    offset : float
        Level the signal moves about (operating point) [signal unit].
    clock : int or None
        Samples per bit for binary signals, else None.
    description : mapping
        The design parameters, for reports and reproduction.
    """

    values: NDArray[np.float64]
    dt: float
    kind: str
    period: int | None
    band: tuple[float, float]
    amplitude: float
    offset: float = 0.0
    clock: int | None = None
    description: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        values = np.array(as_signal("values", self.values), dtype=np.float64, copy=True)
        values.setflags(write=False)
        object.__setattr__(self, "values", values)
        dt = as_dt(self.dt)
        object.__setattr__(self, "dt", dt)
        if not isinstance(self.kind, str) or not self.kind:
            raise DataError(f"kind must be a non-empty string, got {self.kind!r}")
        if self.period is not None:
            period = as_int("period", self.period, what=" (samples per period)")
            if values.size % period:
                raise DataError(
                    f"period = {period} samples must divide the length {values.size}; "
                    "an Excitation holds whole periods"
                )
            object.__setattr__(self, "period", period)
        if self.clock is not None:
            clock = as_int("clock", self.clock, what=" (samples per bit)")
            object.__setattr__(self, "clock", clock)
        lo, hi = (as_float("band", f, nonneg=True, unit=" [Hz]") for f in self.band)
        if lo > hi or hi > nyquist(dt) * (1 + 1e-12):
            raise DataError(
                f"band must satisfy 0 <= f_lo <= f_hi <= {nyquist(dt):g} Hz (Nyquist), "
                f"got ({lo:g}, {hi:g})"
            )
        object.__setattr__(self, "band", (lo, hi))
        object.__setattr__(self, "amplitude", as_float("amplitude", self.amplitude, nonneg=True))
        object.__setattr__(self, "offset", as_float("offset", self.offset))
        object.__setattr__(self, "description", MappingProxyType(dict(self.description)))

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.values.size)

    def __len__(self) -> int:
        return self.n_samples

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times k·dt [s], starting at 0."""
        return np.arange(self.n_samples, dtype=np.float64) * self.dt

    @property
    def duration(self) -> float:
        """Signal length N·dt [s]."""
        return self.n_samples * self.dt

    def with_amplitude(self, amplitude: float) -> Excitation:
        """Return the design scaled about its offset to a new amplitude.

        Parameters
        ----------
        amplitude : float
            New peak deviation from ``offset`` [signal unit], > 0.

        Returns
        -------
        Excitation
            The same design (band, period, clock, phases) at `amplitude`;
            ``description["amplitude"]`` follows.

        Examples
        --------
        >>> from servoid.signals import prbs
        >>> prbs(5, amplitude=2.0, dt=1e-3).with_amplitude(0.5).values.max()
        np.float64(0.5)
        """
        amplitude = as_float("amplitude", amplitude, positive=True)
        if self.amplitude == 0.0:
            raise DataError("an excitation of amplitude 0 has no shape to scale; design it "
                            "again with the amplitude wanted")
        values = self.offset + (self.values - self.offset) * (amplitude / self.amplitude)
        description = dict(self.description)
        if "amplitude" in description:
            description["amplitude"] = amplitude
        return replace(self, values=values, amplitude=amplitude, description=description)

    def to_experiment(
        self, name: str = "r", role: ExcitationRole = "r", unit: str = ""
    ) -> Experiment:
        """Return the signal as a one-channel :class:`Experiment`.

        Parameters
        ----------
        name : str
            Channel name.
        role : {"r", "u", "side"}
            Channel role: reference, plant input or side channel.
        unit : str
            Channel unit, e.g. ``"m"`` or ``"V"``.

        Returns
        -------
        Experiment
            One channel; ``notes["excitation"]`` holds the design record.

        Examples
        --------
        >>> from servoid.signals import prbs
        >>> prbs(5, dt=1e-3).to_experiment("x_ref", unit="m")
        <Experiment: 31 samples, dt=0.001 s, channels: x_ref (r)>
        """
        check_option("role", role, _EXCITATION_ROLES)
        units = {name: unit}
        if role == "side":
            exp = Experiment.from_arrays(self.dt, side={name: self.values}, units=units)
        elif role == "u":
            exp = Experiment.from_arrays(self.dt, u=self.values, names={"u": name}, units=units)
        else:
            exp = Experiment.from_arrays(self.dt, r=self.values, names={"r": name}, units=units)
        record = {
            "kind": self.kind,
            "period": self.period,
            "band": self.band,
            "amplitude": self.amplitude,
            "offset": self.offset,
            "clock": self.clock,
            "description": dict(self.description),
        }
        return replace(exp, notes={**exp.notes, "excitation": record})

    def __repr__(self) -> str:
        per = f", period={self.period}" if self.period is not None else ""
        return (
            f"<Excitation {self.kind}: {self.n_samples} samples, dt={self.dt:g} s{per}, "
            f"band=({self.band[0]:.4g}, {self.band[1]:.4g}) Hz, amplitude={self.amplitude:g}>"
        )
