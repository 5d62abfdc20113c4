"""The amplitude rule: the largest excitation a system's limits allow.

A test must stay inside what the system under test can do: a pressure
below its supply, a valve opening below its travel, a velocity, a stroke.
For a system that is linear about its operating point, every such quantity
peaks at ``offset_part + amplitude·peak_per_amplitude``, so one simulation
of the design at unit amplitude gives the largest amplitude each limit
allows, and the rule is their minimum.  :class:`Limit` records one
quantity; :func:`largest_amplitude` applies the rule and says which limit
binds and which are exceeded at a planned amplitude.  The system's own
model supplies the peaks (e.g. :func:`servoid.plants.ehsa.excitation_limits`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from .._checks import type_error
from .._errors import DataError
from ._checks import as_float

__all__ = ["AmplitudeRule", "Limit", "largest_amplitude"]


@dataclass(frozen=True)
class Limit:
    """One limited quantity of a test, peak per unit amplitude.

    Parameters
    ----------
    name : str
        The quantity in words, e.g. ``"load pressure"``.
    peak_per_amplitude : float
        Peak of ``|quantity − its operating value|`` for an excitation of
        amplitude 1 [unit per signal unit], >= 0.
    limit : float
        Largest allowed ``|quantity|`` [unit], > 0.
    unit : str
        Unit of the quantity and of `limit`.
    static : float
        The quantity's magnitude at the operating point (the offset's part,
        which does not scale with the amplitude) [unit], >= 0.
    note : str
        Where the limit comes from, for messages.
    """

    name: str
    peak_per_amplitude: float
    limit: float
    unit: str = ""
    static: float = 0.0
    note: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise type_error("name", self.name, "a non-empty string")
        object.__setattr__(self, "peak_per_amplitude",
                           as_float("peak_per_amplitude", self.peak_per_amplitude, nonneg=True))
        object.__setattr__(self, "limit", as_float("limit", self.limit, positive=True))
        object.__setattr__(self, "static", as_float("static", self.static, nonneg=True))

    def peak(self, amplitude: float) -> float:
        """Return the quantity's peak at `amplitude` [unit].

        Parameters
        ----------
        amplitude : float
            Excitation amplitude [signal unit], >= 0.
        """
        return self.static + amplitude * self.peak_per_amplitude

    def allows(self) -> float:
        """Return the largest amplitude this limit allows (inf: any, 0: none)."""
        room = self.limit - self.static
        if room <= 0.0:
            return 0.0
        if self.peak_per_amplitude == 0.0:
            return math.inf
        return room / self.peak_per_amplitude


@dataclass(frozen=True)
class AmplitudeRule:
    """The largest amplitude a set of limits allows, and which binds.

    Parameters
    ----------
    amplitude : float
        Largest amplitude with every quantity within its limit [signal unit].
    binding : str
        The limit that sets it.
    limits : tuple of Limit
        Every limit considered.
    """

    amplitude: float
    binding: str
    limits: tuple[Limit, ...]

    def exceeded(self, amplitude: float) -> tuple[Limit, ...]:
        """Return the limits a test of `amplitude` exceeds.

        Parameters
        ----------
        amplitude : float
            Planned amplitude [signal unit].
        """
        return tuple(lim for lim in self.limits if lim.peak(amplitude) > lim.limit)

    def table(self, amplitude: float) -> list[dict[str, Any]]:
        """Return each quantity's peak, limit and their ratio at `amplitude`.

        Parameters
        ----------
        amplitude : float
            Planned amplitude [signal unit].
        """
        return [{"quantity": lim.name, "peak": lim.peak(amplitude), "limit": lim.limit,
                 "ratio": lim.peak(amplitude) / lim.limit, "unit": lim.unit, "note": lim.note}
                for lim in self.limits]


def largest_amplitude(limits: Sequence[Limit], *, margin: float = 1.0) -> AmplitudeRule:
    """Return the largest amplitude within every limit.

    Parameters
    ----------
    limits : sequence of Limit
        The test's limited quantities (at least one).
    margin : float
        Fraction of each limit to use, in (0, 1].

    Returns
    -------
    AmplitudeRule
        The amplitude, the binding limit and the limits.

    Raises
    ------
    DataError
        No limit given, or a limit already exceeded at the operating point.

    Examples
    --------
    >>> rule = largest_amplitude([Limit("pressure", 3e10, 7e6, "Pa"),
    ...                           Limit("stroke", 1.0, 0.023, "m")])
    >>> round(rule.amplitude * 1e3, 3), rule.binding
    (0.233, 'pressure')
    """
    if isinstance(limits, Limit) or not isinstance(limits, Sequence) or isinstance(limits, str):
        raise DataError("limits must be a list of one or more servoid.signals.Limit records, "
                        f"got {type(limits).__name__}")
    limits = tuple(limits)
    if not limits or not all(isinstance(lim, Limit) for lim in limits):
        raise DataError("limits must be one or more servoid.signals.Limit records")
    margin = as_float("margin", margin, positive=True)
    if margin > 1.0:
        raise DataError(f"margin must lie in (0, 1], the fraction of each limit used, got "
                        f"{margin:g}")
    scaled = tuple(Limit(lim.name, lim.peak_per_amplitude, lim.limit * margin, lim.unit,
                         lim.static, lim.note) for lim in limits)
    allowed = [(lim.allows(), lim.name) for lim in scaled]
    amplitude, binding = min(allowed, key=lambda item: item[0])
    if amplitude == 0.0:
        lim = next(x for x in scaled if x.name == binding)
        raise DataError(
            f"the operating point alone puts the {binding} at {lim.static:.4g} {lim.unit}, at or "
            f"beyond its limit {lim.limit:.4g} {lim.unit}: move the operating point (offset)"
        )
    return AmplitudeRule(amplitude, binding, scaled)
