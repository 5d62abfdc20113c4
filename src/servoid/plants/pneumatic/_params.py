"""Physical parameters of the servopneumatic actuator ([S2]).

The actuator of models-spec §2 (Hahn & Piepenbrink, IFAC SYSID 1994): a
four-edge servovalve (2nd-order spool dynamics, zero overlap) feeding a
vertical differential cylinder, rod up, chamber I (full bore) under the
piston, x_k positive upwards; x_v > 0 connects chamber I to supply and
chamber II to exhaust.  Source tags as in the spec:

* **[P]** printed in [S2] and legible;
* **[P*]** decoded from garbled text (Table 2 of [S2]);
* **[A]** assumption (the paper does not give it);
* **[D]** derived from other parameters (computed here, never typed in).

The named set :data:`PNEUMATIC_NOMINAL` is Table 2 with the spec's
assumed constants.  Vary it with :meth:`PneumaticParameters.with_`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..._errors import ModelError
from .._common import Bounds, check_fields, replace_fields

__all__ = ["PARAMETER_SETS", "PNEUMATIC_NOMINAL", "PneumaticParameters"]

# name → (lower bound, strict?) for validation; None = any finite value.
_BOUNDS: Bounds = {
    "k_v": (0.0, True),
    "xi_v": (0.0, False),
    "omega_v": (0.0, True),
    "ad_1": (0.0, True),
    "ad_2": (0.0, True),
    "ad_3": (0.0, True),
    "ad_4": (0.0, True),
    "R": (0.0, True),
    "kappa": (1.0, True),
    "F_haft": (0.0, False),
    "v_krit": (0.0, True),
    "c_k": (0.0, False),
    "d_k": (0.0, False),
    "p_krit": (0.0, False),
    "p_S": (0.0, True),
    "p_R": (0.0, True),
    "p_amb": (0.0, False),
    "T_S": (0.0, True),
    "bore": (0.0, True),
    "rod": (0.0, False),
    "V_dead_I": (0.0, True),
    "V_dead_II": (0.0, True),
    "stroke": (0.0, True),
    "m_k": (0.0, True),
    "g": None,
    "u_max": (0.0, True),
    "eps_v": (0.0, True),
}


@dataclass(frozen=True)
class PneumaticParameters:
    """Physical parameters of the servopneumatic actuator (spec §2).

    Defaults are the nominal set :data:`PNEUMATIC_NOMINAL`.  The orifice
    area of edge i at spool opening x_v is ``π·(a_i d_i)·|x_v|``; edges:
    1 chamber I → exhaust, 2 supply → I, 3 supply → II, 4 II → exhaust.

    Parameters
    ----------
    k_v : float
        Valve gain, spool travel per amplifier volt [m/V]. [P] 1e-4 (unit
        inferred: 10 V → 1 mm).
    xi_v : float
        Spool damping ratio [-]. [P] 0.35.
    omega_v : float
        Spool natural frequency [rad/s]. [P] 1000 (159 Hz).
    ad_1 : float
        Flow coefficient × edge diameter a₁d₁, edge I → exhaust [m].
        [P*] 6 mm.
    ad_2 : float
        a₂d₂, edge supply → I [m]. [P*] 6 mm.
    ad_3 : float
        a₃d₃, edge supply → II [m]. [P*] 6 mm.
    ad_4 : float
        a₄d₄, edge II → exhaust [m]. [P*] 6 mm.
    R : float
        Gas constant [J/(kg·K)]. [P] 290 (air: 287).
    kappa : float
        Isentropic exponent κ [-], > 1. [P] 1.4.
    F_haft : float
        Static (sticking) friction [N]. [P*] 85.
    v_krit : float
        Speed ẋ_krit above which the sliding friction law holds [m/s],
        > eps_v. [P*] 0.1 (unit garbled).
    c_k : float
        Viscous friction [N·s/m]. [P*] 120.
    d_k : float
        Coulomb friction [N]. [P*] 55.
    p_krit : float
        Critical pressure ratio b of the ellipse flow function [-],
        0 <= b < 1. [P*] 0.25 (low–medium confidence; fallback 0.528).
    p_S : float
        Supply pressure [Pa] (absolute). [A] 6 bar.
    p_R : float
        Exhaust pressure [Pa] (absolute), < p_S. [A] 1.013 bar.
    p_amb : float
        Ambient pressure acting on the rod cross-section A_I − A_II [Pa]
        (absolute). [A] 1.013 bar.
    T_S : float
        Supply temperature [K], also the chamber temperature of the
        model. [A] 293.15.
    bore : float
        Piston diameter [m]. [A] 50 mm.
    rod : float
        Rod diameter [m], < bore. [A] 20 mm.
    V_dead_I : float
        Dead volume of chamber I at its end of stroke [m³]. [A] 20 cm³.
    V_dead_II : float
        Dead volume of chamber II [m³]. [A] 20 cm³.
    stroke : float
        Full stroke [m]; end stops at ±stroke/2. [A] 200 mm.
    m_k : float
        Moving mass (piston and rod) [kg]. [A] 3.
    g : float
        Gravitational acceleration [m/s²] (0 for a horizontal
        cylinder). [A] 9.81.
    u_max : float
        Saturation of the valve amplifier input [V]. [A] 10.
    eps_v : float
        Half-width of the stick band of the friction law [m/s].
        [A] 1e-4.

    Examples
    --------
    >>> p = PNEUMATIC_NOMINAL
    >>> round(p.A_I * 1e3, 3), round(p.A_II * 1e3, 3), round(p.psi_max, 4)
    (1.963, 1.649, 0.4842)
    >>> round(p.natural_frequency(3.5e5) / (2 * 3.14159265), 1)  # [Hz]
    11.6
    """

    k_v: float = 1e-4
    xi_v: float = 0.35
    omega_v: float = 1000.0
    ad_1: float = 6e-3
    ad_2: float = 6e-3
    ad_3: float = 6e-3
    ad_4: float = 6e-3
    R: float = 290.0
    kappa: float = 1.4
    F_haft: float = 85.0
    v_krit: float = 0.1
    c_k: float = 120.0
    d_k: float = 55.0
    p_krit: float = 0.25
    p_S: float = 6.0e5
    p_R: float = 1.013e5
    p_amb: float = 1.013e5
    T_S: float = 293.15
    bore: float = 0.050
    rod: float = 0.020
    V_dead_I: float = 20e-6
    V_dead_II: float = 20e-6
    stroke: float = 0.200
    m_k: float = 3.0
    g: float = 9.81
    u_max: float = 10.0
    eps_v: float = 1e-4

    def __post_init__(self) -> None:
        check_fields(self, _BOUNDS)
        if self.p_krit >= 1.0:
            raise ModelError(f"PneumaticParameters.p_krit must be < 1, got {self.p_krit:g}")
        if self.p_R >= self.p_S:
            raise ModelError(
                f"PneumaticParameters.p_R must be < p_S = {self.p_S:g} Pa, got {self.p_R:g} Pa"
            )
        if self.rod >= self.bore:
            raise ModelError(
                f"PneumaticParameters.rod must be < bore = {self.bore:g} m, got {self.rod:g} m"
            )
        if self.v_krit <= self.eps_v:
            raise ModelError(
                f"PneumaticParameters.v_krit must be > eps_v = {self.eps_v:g} m/s, "
                f"got {self.v_krit:g} m/s"
            )

    def with_(self, **changes: Any) -> PneumaticParameters:
        """Return a copy with some parameters changed.

        Parameters
        ----------
        **changes : float
            New values by field name, e.g. ``p_krit=0.528``.

        Returns
        -------
        PneumaticParameters
            The modified, validated copy.
        """
        return replace_fields(self, changes)

    # -- derived quantities [D] -------------------------------------------
    @property
    def A_I(self) -> float:
        """Piston area of chamber I ``π·bore²/4`` [m²]."""
        return math.pi * self.bore**2 / 4.0

    @property
    def A_II(self) -> float:
        """Annulus area of chamber II ``π(bore² − rod²)/4`` [m²]."""
        return math.pi * (self.bore**2 - self.rod**2) / 4.0

    @property
    def V_0I(self) -> float:
        """Volume of chamber I at x_k = 0, V_dead,I + A_I·stroke/2 [m³]."""
        return self.V_dead_I + self.A_I * self.stroke / 2.0

    @property
    def V_0II(self) -> float:
        """Volume of chamber II at x_k = 0 [m³]."""
        return self.V_dead_II + self.A_II * self.stroke / 2.0

    @property
    def psi_max(self) -> float:
        """Choked flow function ``(2/(κ+1))^{1/(κ−1)}√(κ/(κ+1))`` [-]."""
        k = self.kappa
        return (2.0 / (k + 1.0)) ** (1.0 / (k - 1.0)) * math.sqrt(k / (k + 1.0))

    @property
    def pi_crit(self) -> float:
        """Saint-Venant critical ratio ``(2/(κ+1))^{κ/(κ−1)}`` [-]."""
        k = self.kappa
        return (2.0 / (k + 1.0)) ** (k / (k - 1.0))

    @property
    def static_force(self) -> float:
        """Force to hold the piston ``p_amb(A_I − A_II) + m_k g`` [N]."""
        return self.p_amb * (self.A_I - self.A_II) + self.m_k * self.g

    def orifice_area(self, edge: int, x_v: float) -> float:
        """Return the opening ``π·(a_i d_i)·|x_v|`` of one edge [m²].

        Parameters
        ----------
        edge : int
            Edge number 1–4 (1 I → exhaust, 2 supply → I, 3 supply → II,
            4 II → exhaust).
        x_v : float
            Spool position [m].

        Returns
        -------
        float
            Effective orifice area [m²] (the sign of x_v decides which
            edges are open; this is the area if the edge is open).
        """
        if edge not in (1, 2, 3, 4):
            raise ModelError(f"edge must be 1, 2, 3 or 4, got {edge!r}")
        ad = (self.ad_1, self.ad_2, self.ad_3, self.ad_4)[edge - 1]
        return math.pi * ad * abs(x_v)

    def choked_mass_flow(self, x_v: float, edge: int = 2) -> float:
        """Return the choked supply mass flow at opening x_v [kg/s].

        Parameters
        ----------
        x_v : float
            Spool position [m].
        edge : int
            Edge number 1–4 (default 2, supply → I).

        Returns
        -------
        float
            ``π(a_i d_i)|x_v|·ψ_max·p_S·√(2/(R·T_S))`` [kg/s].
        """
        c = math.sqrt(2.0 / (self.R * self.T_S))
        return self.orifice_area(edge, x_v) * self.psi_max * self.p_S * c

    def stiffness(self, p_I: float, p_II: float | None = None, x_k: float = 0.0) -> float:
        """Return the pneumatic spring stiffness at a pressure [N/m].

        Parameters
        ----------
        p_I : float
            Pressure in chamber I [Pa] (absolute).
        p_II : float, optional
            Pressure in chamber II [Pa]; default `p_I`.
        x_k : float
            Piston position [m], inside ±stroke/2.

        Returns
        -------
        float
            ``κ(p_I A_I²/V_I + p_II A_II²/V_II)`` [N/m], the isentropic
            stiffness of the two closed chambers.
        """
        p2 = p_I if p_II is None else p_II
        if p_I <= 0.0 or p2 <= 0.0:
            raise ModelError(f"pressures must be > 0 Pa, got p_I = {p_I:g}, p_II = {p2:g}")
        if abs(x_k) > self.stroke / 2.0:
            raise ModelError(f"x_k must be within ±{self.stroke / 2:g} m, got {x_k:g}")
        v1 = self.V_0I + self.A_I * x_k
        v2 = self.V_0II - self.A_II * x_k
        return self.kappa * (p_I * self.A_I**2 / v1 + p2 * self.A_II**2 / v2)

    def natural_frequency(
        self, p_I: float, p_II: float | None = None, x_k: float = 0.0,
    ) -> float:
        """Return the pneumatic natural frequency ``√(k/m_k)`` [rad/s].

        Parameters
        ----------
        p_I : float
            Pressure in chamber I [Pa] (absolute).
        p_II : float, optional
            Pressure in chamber II [Pa]; default `p_I`.
        x_k : float
            Piston position [m].

        Returns
        -------
        float
            Undamped natural frequency [rad/s] of the piston mass on the
            pneumatic spring of :meth:`stiffness`.
        """
        return math.sqrt(self.stiffness(p_I, p_II, x_k) / self.m_k)


#: Nominal set: [S2] Table 2 and the spec's assumed constants (spec §2).
PNEUMATIC_NOMINAL = PneumaticParameters()

#: The documented sets by name.
PARAMETER_SETS = {"nominal": PNEUMATIC_NOMINAL}
