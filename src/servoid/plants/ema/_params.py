"""Physical parameters of the electromechanical servo actuator (EMA).

The actuator: a permanent-magnet DC (or brushless DC, in its DC
equivalent) motor drives a gearbox of ratio ``N`` and a ball screw of lead
``lead``; the nut moves the load through the screw's axial compliance
``k_s`` (nut, shaft, bearings and attachment in series) with optional
backlash.  Both sides have viscous and Coulomb friction; the load may see
an external force.  In SI units the torque constant equals the back-EMF
constant, ``K_t = K_e = K_m``, so the motor has one constant.

The nominal set :data:`TVC_EMA` describes a representative
thrust-vector-control EMA of about 30 kN peak force.  No public data sheet
of one such actuator gives every value, so the set is *chosen* for a
consistent design, and each value below says why; the only value taken
from a document is the supply voltage (MIL-STD-704F, the 270 V DC bus of
aircraft power).  The design it describes:

* peak force ``K_m·i_max·2πN/lead`` = 0.2·40·3770 ≈ 30 kN at the 40 A
  current limit of :data:`TVC_CONTROLLER`;
* no-load speed about ``u_max/(K_m·2πN/lead)`` ≈ 0.36 m/s at 270 V;
* reflected motor mass ``J_m·(2πN/lead)²`` ≈ 5700 kg, seven times the
  800 kg load: like most EMAs, it is dominated by the motor's inertia;
* a screw–load mode at about 74 Hz (anti-resonance 69 Hz), above the
  position loop (about 6 Hz) and the speed loop (about 30 Hz), as a TVC
  actuator must be.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from ..._errors import OptionTypeError
from ._checks import Bounds, check_fields

__all__ = ["PARAMETER_SETS", "TVC_EMA", "UNITS", "EmaParameters"]

#: Unit of each parameter.
UNITS: Mapping[str, str] = MappingProxyType({
    "K_m": "N·m/A", "R": "Ω", "L": "H", "J_m": "kg·m²", "b_m": "N·m·s/rad", "T_cm": "N·m",
    "N": "-", "lead": "m", "k_s": "N/m", "c_s": "N·s/m", "backlash": "m", "m_L": "kg",
    "b_L": "N·s/m", "F_cL": "N", "stroke": "m",
})

_POSITIVE = ("K_m", "R", "L", "J_m", "N", "lead", "k_s", "m_L", "stroke")
_NONNEG = ("b_m", "T_cm", "c_s", "backlash", "b_L", "F_cL")
_BOUNDS: Bounds = MappingProxyType({**{n: (0.0, True, False) for n in _POSITIVE},
                                    **{n: (0.0, False, False) for n in _NONNEG}})


@dataclass(frozen=True)
class EmaParameters:
    """Physical parameters of an EMA; defaults are :data:`TVC_EMA`.

    Parameters
    ----------
    K_m : float
        Motor constant, torque per current = back-EMF per speed
        [N·m/A = V·s/rad].  Chosen: 0.2, a 3–5 kW servomotor wound for a
        270 V bus (back-EMF 150 V at 750 rad/s, the 0.2 m/s slew rate).
    R : float
        Winding resistance (DC equivalent) [Ω].  Chosen: 0.4, so that
        ``R·i_max`` = 16 V, 6 % of the bus, and the copper loss at 20 A is
        160 W.
    L : float
        Winding inductance [H].  Chosen: 1.5 mH, an electrical time
        constant ``L/R`` of 3.75 ms, typical of servomotors of this size.
    J_m : float
        Inertia at the motor shaft: rotor, gear and screw [kg·m²].
        Chosen: 4e-4, a rotor of about 3e-4 plus the screw reflected
        through the gear.
    b_m : float
        Viscous friction at the motor shaft [N·m·s/rad].  Chosen: 2e-4,
        0.15 N·m at 750 rad/s (bearings, gear churning).
    T_cm : float
        Coulomb friction at the motor shaft [N·m].  Chosen: 0.08, 1 % of
        the peak torque (bearings, gear mesh, screw).
    N : float
        Gear ratio, motor turns per screw turn [-].  Chosen: 3.
    lead : float
        Screw lead, nut travel per screw turn [m].  Chosen: 5 mm.
    k_s : float
        Axial stiffness between nut and load: screw, nut, bearings and
        attachment in series [N/m].  Chosen: 1.5e8 (150 N/µm), which puts
        the screw–load mode at 74 Hz.
    c_s : float
        Damping of that compliance [N·s/m].  Chosen: 2e4, about 3 % of
        critical damping of the mode (steel structure).
    backlash : float
        Total axial play of the screw and joints [m]: the spring carries
        no force within ±backlash/2.  Chosen: 0 (a preloaded nut); the
        bench and the simulator take any value.
    m_L : float
        Load mass [kg]: a nozzle's inertia reflected to the actuator's
        line.  Chosen: 800 (e.g. 200 kg·m² at a 0.5 m lever arm).
    b_L : float
        Viscous friction on the load side [N·s/m].  Chosen: 2000, 400 N at
        0.2 m/s (rod seal, joints).
    F_cL : float
        Coulomb friction on the load side [N].  Chosen: 150 (rod seal and
        spherical joints).
    stroke : float
        Half-stroke [m]: the bench keeps references within ±stroke.
        Chosen: 40 mm.

    Examples
    --------
    >>> round(TVC_EMA.transmission, 1), round(TVC_EMA.reflected_mass)
    (3769.9, 5685)
    >>> round(TVC_EMA.resonance_hz, 1), round(TVC_EMA.antiresonance_hz, 1)
    (73.6, 68.9)
    """

    K_m: float = 0.2
    R: float = 0.4
    L: float = 1.5e-3
    J_m: float = 4.0e-4
    b_m: float = 2.0e-4
    T_cm: float = 0.08
    N: float = 3.0
    lead: float = 5.0e-3
    k_s: float = 1.5e8
    c_s: float = 2.0e4
    backlash: float = 0.0
    m_L: float = 800.0
    b_L: float = 2000.0
    F_cL: float = 150.0
    stroke: float = 0.04

    def __post_init__(self) -> None:
        check_fields(self, _BOUNDS)

    def with_(self, **changes: Any) -> EmaParameters:
        """Return a validated copy with some parameters changed.

        Parameters
        ----------
        **changes : float
            New values by name, e.g. ``k_s=5e7``.

        Returns
        -------
        EmaParameters
            The copy.
        """
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise OptionTypeError(f"EmaParameters has no parameter(s) {', '.join(unknown)}; it "
                                  f"has {', '.join(sorted(names))}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, float]:
        """Every parameter as plain data [SI]."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}

    # -- derived quantities ------------------------------------------------------------------
    @property
    def transmission(self) -> float:
        """Motor angle per nut travel ``2πN/lead`` [rad/m]."""
        return 2.0 * math.pi * self.N / self.lead

    @property
    def reflected_mass(self) -> float:
        """Motor-side inertia seen at the nut ``J_m·(2πN/lead)²`` [kg]."""
        return self.J_m * self.transmission**2

    @property
    def resonance_hz(self) -> float:
        """Screw–load mode with the motor free ``√(k_s(1/m_L + 1/M_m))/2π`` [Hz]."""
        return math.sqrt(self.k_s * (1.0 / self.m_L + 1.0 / self.reflected_mass)) / (2 * math.pi)

    @property
    def antiresonance_hz(self) -> float:
        """Load on the screw with the motor held ``√(k_s/m_L)/2π`` [Hz]."""
        return math.sqrt(self.k_s / self.m_L) / (2.0 * math.pi)

    def force(self, current: float) -> float:
        """Static screw force at a motor current, friction aside [N].

        Parameters
        ----------
        current : float
            Motor current [A].
        """
        return self.K_m * float(current) * self.transmission


#: A representative thrust-vector-control EMA (values and reasons: :class:`EmaParameters`).
TVC_EMA = EmaParameters()

#: The named parameter sets, for the plant record and the bench.
PARAMETER_SETS: Mapping[str, EmaParameters] = MappingProxyType({"tvc": TVC_EMA})
