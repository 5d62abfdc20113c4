"""Physical parameters of the electro-hydraulic servo actuator (EHSA).

The actuator of models-spec §1 ([S1], a launcher's thrust-vector-control
EHSA with mechanical position feedback): driver → torque motor → flapper
→ flapper-nozzle stage → spool → four-way valve → symmetric piston, with a
feedback spring from the piston back to the flapper.  Every value carries a
source tag as in the spec:

* **[P]** printed in [S1] and legible;
* **[A]** assumption (Merritt, *Hydraulic Control Systems*, or common
  practice);
* **[D]** derived from other parameters (computed here, never typed in).

Two named sets: :data:`SET_B` (loaded, 1500 kg reflected mass) and
:data:`SET_C` (unloaded bench, 0.5 kg piston).  Vary them with
:meth:`EhsaParameters.with_` (or :func:`dataclasses.replace`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..._errors import ModelError
from .._common import Bounds, check_fields, replace_fields

__all__ = ["PARAMETER_SETS", "SET_B", "SET_C", "EhsaParameters"]

# Printed driver gain [S1]: 0.050 A for 0.023 m of command.
_K_DRIVER = 0.050 / 0.023
_K_FB = 0.010

# name → (lower bound, strict?) for validation; None = any finite value.
_BOUNDS: Bounds = {
    "P_s": (0.0, True),
    "P_T": (0.0, False),
    "beta_e": (0.0, True),
    "rho": (0.0, True),
    "C_d": (0.0, True),
    "w": (0.0, True),
    "A_p": (0.0, True),
    "stroke": (0.0, True),
    "V_t": (0.0, True),
    "K_ce": (0.0, False),
    "B_p": (0.0, False),
    "M_t": (0.0, True),
    "K_driver": (0.0, True),
    "K_fb": (0.0, True),
    "K_TM": (0.0, True),
    "omega_f": (0.0, True),
    "delta_f": (0.0, True),
    "K_s2": (0.0, True),
    "omega_s1": (0.0, True),
    "omega_sp": (0.0, True),
    "delta_sp": (0.0, True),
    "x_f_max": (0.0, True),
    "x_s_max": (0.0, True),
    "v_s_max": (0.0, True),
    "T_d": (0.0, False),
    "u_0": (0.0, False),
    "F_c": (0.0, False),
    "F_s": (0.0, False),
    "eps_v": (0.0, True),
    "K_l": (0.0, False),
    "F_ext": None,
}


@dataclass(frozen=True)
class EhsaParameters:
    """Physical parameters of the EHSA (models-spec §1.3, §1.4).

    Defaults are those of Set B (:data:`SET_B`).  ``K_TM`` is a parameter
    of its own (a torque motor can be miscalibrated); its default is the
    unit-tracking value ``K_fb/K_driver``.  Changing ``K_fb`` or
    ``K_driver`` with :meth:`with_` does not change ``K_TM``; the static
    gain :attr:`dc_gain` then moves away from 1.

    Parameters
    ----------
    P_s : float
        Supply pressure [Pa]. [A] 21 MPa.
    P_T : float
        Return (tank) pressure [Pa], < P_s. [A] 0.  The flow law and
        :attr:`K_qs` use the pressure drop ``P_s − P_T``, which is the
        spec's ``P_s`` for P_T = 0.
    beta_e : float
        Effective bulk modulus of the oil [Pa]. [A] 700 MPa.
    rho : float
        Oil density [kg/m³]. [A] 850 (MIL-H-5606).
    C_d : float
        Discharge coefficient of the spool ports [-]. [A] 0.61.
    w : float
        Area gradient of the spool ports [m]. [A] 3.0 mm.
    A_p : float
        Piston area [m²]. [A] 1.0e-3.
    stroke : float
        Mechanical half-stroke [m]: end stops at ±stroke. [A] 25 mm
        (the command range is ±23 mm [P]).
    V_t : float
        Total trapped oil volume of both chambers [m³]. [A] 7.0e-5.
    K_ce : float
        Total flow-pressure coefficient (valve + leakage)
        [m³/(s·Pa)]. [A] 2e-12.
    B_p : float
        Viscous damping of piston and load [N·s/m]. [A] 2000.
    M_t : float
        Total moving mass reflected to the piston [kg]. [A] 1500 (Set B),
        [P] 0.5 (Set C).
    K_driver : float
        Driver gain from command to coil current [A/m]. [P] 0.050 A /
        0.023 m = 2.1739.
    K_fb : float
        Feedback-spring gain in equivalent flapper displacement
        [m/m]. [A] 0.010.
    K_TM : float
        Torque-motor gain in equivalent flapper displacement [m/A].
        [D] K_fb/K_driver = 4.6e-3.
    omega_f : float
        Flapper natural frequency [rad/s]. [A] 2π·600.
    delta_f : float
        Flapper damping ratio [-]. [A] 0.5.
    K_s2 : float
        Static gain of the spool stage, spool per flapper displacement
        [m/m]. [A] 12.
    omega_s1 : float
        Spool-stage corner ``K_cf·K_sp/A_s²`` [rad/s]. [A] 1000.
    omega_sp : float
        Spool natural frequency [rad/s]. [A] 2π·800.
    delta_sp : float
        Spool damping ratio [-]. [A] 0.6.
    x_f_max : float
        Flapper travel to the nozzles [m]. [A] 40 µm.
    x_s_max : float
        Spool travel [m]. [A] 0.4 mm.
    v_s_max : float
        Spool rate limit [m/s]. [A] 0.1.
    T_d : float
        Dead time on the command [s] (simulator). [A] 1 ms.
    u_0 : float
        Spool overlap, the dead zone of the valve [m], < x_s_max
        (simulator). [A] 0 (option: 2 % of x_s_max).
    F_c : float
        Coulomb friction [N] (simulator). [A] 300.
    F_s : float
        Static (breakaway) friction [N], >= F_c (simulator). [A] 400.
    eps_v : float
        Velocity band of the Karnopp stick zone [m/s] (simulator).
        [A] 1e-5.
    K_l : float
        Load spring, e.g. a nozzle flex joint [N/m] (simulator). [A] 0.
    F_ext : float
        Constant external force opposing positive motion [N]
        (simulator). [A] 0.

    Examples
    --------
    >>> round(SET_B.omega_hp, 1), round(SET_B.delta_hp, 3)
    (163.3, 0.249)
    >>> SET_B.with_(M_t=0.5) == SET_C
    True
    """

    P_s: float = 21e6
    P_T: float = 0.0
    beta_e: float = 700e6
    rho: float = 850.0
    C_d: float = 0.61
    w: float = 3.0e-3
    A_p: float = 1.0e-3
    stroke: float = 0.025
    V_t: float = 7.0e-5
    K_ce: float = 2e-12
    B_p: float = 2000.0
    M_t: float = 1500.0
    K_driver: float = _K_DRIVER
    K_fb: float = _K_FB
    K_TM: float = _K_FB / _K_DRIVER
    omega_f: float = 2.0 * math.pi * 600.0
    delta_f: float = 0.5
    K_s2: float = 12.0
    omega_s1: float = 1000.0
    omega_sp: float = 2.0 * math.pi * 800.0
    delta_sp: float = 0.6
    x_f_max: float = 40e-6
    x_s_max: float = 0.4e-3
    v_s_max: float = 0.1
    T_d: float = 1e-3
    u_0: float = 0.0
    F_c: float = 300.0
    F_s: float = 400.0
    eps_v: float = 1e-5
    K_l: float = 0.0
    F_ext: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self, _BOUNDS)
        if self.P_T >= self.P_s:
            raise ModelError(
                f"EhsaParameters.P_T must be < P_s = {self.P_s:g} Pa, got {self.P_T:g} Pa"
            )
        if self.F_s < self.F_c:
            raise ModelError(
                f"EhsaParameters.F_s (static friction) must be >= F_c = {self.F_c:g} N, "
                f"got {self.F_s:g} N"
            )
        if self.u_0 >= self.x_s_max:
            raise ModelError(
                f"EhsaParameters.u_0 (overlap) must be < x_s_max = {self.x_s_max:g} m, "
                f"got {self.u_0:g} m"
            )

    def with_(self, **changes: Any) -> EhsaParameters:
        """Return a copy with some parameters changed.

        Parameters
        ----------
        **changes : float
            New values by field name, e.g. ``M_t=0.5``.

        Returns
        -------
        EhsaParameters
            The modified, validated copy.
        """
        return replace_fields(self, changes)

    # -- derived quantities [D] -------------------------------------------
    @property
    def K_qs(self) -> float:
        """Valve flow gain ``C_d·w·√((P_s − P_T)/ρ)`` [m²/s]."""
        return self.C_d * self.w * math.sqrt((self.P_s - self.P_T) / self.rho)

    @property
    def omega_hp(self) -> float:
        """Hydraulic natural frequency ``√(4β_e A_p²/(V_t M_t))`` [rad/s]."""
        return math.sqrt(4.0 * self.beta_e * self.A_p**2 / (self.V_t * self.M_t))

    @property
    def delta_hp(self) -> float:
        """Hydraulic damping ratio (Merritt, mass load) [-]."""
        leak = (self.K_ce / self.A_p) * math.sqrt(self.beta_e * self.M_t / self.V_t)
        visc = (self.B_p / (4.0 * self.A_p)) * math.sqrt(self.V_t / (self.beta_e * self.M_t))
        return leak + visc

    @property
    def K(self) -> float:
        """Velocity gain of the reduced plant ``K_s2·K_qs/A_p`` [1/s]."""
        return self.K_s2 * self.K_qs / self.A_p

    @property
    def loop_gain(self) -> float:
        """Closed-loop velocity constant ``F·K = K_fb·K`` [1/s]."""
        return self.K_fb * self.K

    @property
    def reference_gain(self) -> float:
        """Reference gain ``c = K_TM·K_driver`` [m/m]."""
        return self.K_TM * self.K_driver

    @property
    def dc_gain(self) -> float:
        """Static closed-loop gain ``c/F`` [m/m]."""
        return self.reference_gain / self.K_fb

    @property
    def v_max(self) -> float:
        """No-load piston speed at full spool ``K_qs·x_s,max/A_p`` [m/s]."""
        return self.K_qs * self.x_s_max / self.A_p

    @property
    def routh_limit(self) -> float:
        """Largest stable reduced loop gain ``2·δ_hp·ω_hp`` [1/s]."""
        return 2.0 * self.delta_hp * self.omega_hp

    @property
    def stall_force(self) -> float:
        """Stall force ``A_p·(P_s − P_T)`` [N]."""
        return self.A_p * (self.P_s - self.P_T)


#: Set B: loaded actuator, 1500 kg reflected mass (models-spec §1.3).
SET_B = EhsaParameters()

#: Set C: unloaded bench, 0.5 kg piston [P] (models-spec §1.3).
SET_C = SET_B.with_(M_t=0.5)

#: The documented sets by name (the source study's Set B, 1500 kg, and Set C, unloaded).
PARAMETER_SETS = {"B": SET_B, "C": SET_C}
