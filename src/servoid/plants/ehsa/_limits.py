"""A test the actuator can run: the excitation within the EHSA's limits.

An identification test of the electro-hydraulic actuator is a position
command played into its loop.  What it asks of the hardware follows from
the loop's linear model (the full-order loop of models-spec §1.1 with the
exact piston linearisation), driven by the command as the DAQ plays it (a
staircase held over each sample) and read between samples:

=================  =========================================  ===========================
quantity           from the command r through                  limit
=================  =========================================  ===========================
load pressure      ``(M_t s² + B_p s + K_l)/A_p · H``          ``fraction·(P_s − P_T)``
spool opening      ``G_f·G_s2 · c/(1 + F·G)``                  ``x_s,max``
spool rate         ``s · G_f·G_s2 · c/(1 + F·G)``               ``v_s,max``
flapper travel     ``G_f · c/(1 + F·G)``                        ``x_f,max``
piston velocity    ``s · H``                                    ``v_max = K_qs·x_s,max/A_p``
stroke             ``H`` (and the offset's ``c/F·offset``)      the half-stroke
=================  =========================================  ===========================

with ``H = c·G/(1 + F·G)`` the closed loop.  The load pressure is the one
the usual rule ``a ≲ v_max/(F·K)`` (models-spec §3.1) misses: a PRBS step
accelerates the load, and for the 1500 kg of Set B a ±1 mm PRBS needs
about 35 MPa from a 21 MPa supply.

**The stated fraction of supply.**  :data:`PRESSURE_FRACTION` = 1/3: up to
``|P_L| = P_s/3`` the valve's flow gain ``√(1 ∓ P_L/P_s)`` stays within
−18 %…+15 % of its linearisation at P_L = 0, the small-signal range the
reduced model stands for; beyond ``2·P_s/3`` (Merritt's power point) the
valve cannot deliver the flow the linear model assumes.  The flow law's
effect on the estimates *within* this range is checked on the data
(:func:`servoid.plants.ehsa.check_flow_law`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float, as_instance
from ..._errors import DataError, OptionError
from ...bench import discretise, realise
from ...models import TransferFunction
from ...signals import AmplitudeRule, Excitation, Limit, largest_amplitude
from ._linear import full_order_plant
from ._params import EhsaParameters

__all__ = ["PRESSURE_FRACTION", "PlannedTest", "excitation_limits", "plan_test", "within_limits"]

#: Largest load pressure a test may ask for, as a fraction of the supply (module notes).
PRESSURE_FRACTION = 1.0 / 3.0
#: Points per sample at which the quantities are read between samples (peaks of a PRBS
#: response fall between samples; 8 points put the error of a peak of a response with
#: ω·dt <= 0.2 below (0.2/8)²/2 = 0.03 %).
_READ = 8


@dataclass(frozen=True)
class PlannedTest:
    """What a planned test asks of the actuator, and what it may ask.

    Parameters
    ----------
    amplitude : float
        The planned excitation's amplitude [m of commanded position].
    rule : AmplitudeRule
        The limits, each with its peak per unit amplitude, and the largest
        amplitude they allow (``rule.amplitude``).
    pressure_fraction : float
        The fraction of the supply the load pressure may reach.
    supply : float
        The pressure drop ``P_s − P_T`` across the valve [Pa].
    """

    amplitude: float
    rule: AmplitudeRule
    pressure_fraction: float
    supply: float

    @property
    def largest_amplitude(self) -> float:
        """Largest amplitude within every limit [m]."""
        return self.rule.amplitude

    @property
    def suggested_amplitude(self) -> float:
        """The largest amplitude rounded down to two significant digits [m].

        The default test of the bench and the demo: within every limit,
        and a number a test plan can state.
        """
        a = self.rule.amplitude
        if not math.isfinite(a):
            return self.amplitude
        scale = 10.0 ** (math.floor(math.log10(a)) - 1)
        return math.floor(a / scale * (1.0 + 1e-12)) * scale

    @property
    def feasible(self) -> bool:
        """True when the planned amplitude keeps every quantity within its limit."""
        return not self.rule.exceeded(self.amplitude)

    @property
    def load_pressure(self) -> float:
        """Peak load pressure of the planned test [Pa]."""
        return self._limit("load pressure").peak(self.amplitude)

    def table(self) -> list[dict[str, Any]]:
        """Each quantity's peak, limit and ratio at the planned amplitude."""
        return self.rule.table(self.amplitude)

    def note(self) -> str:
        """Return where the planned test saturates, or "" when it does not."""
        over = self.rule.exceeded(self.amplitude)
        if not over:
            return ""
        parts = [f"{lim.name} {_quantity(lim.peak(self.amplitude), lim.unit)} "
                 f"({lim.peak(self.amplitude) / lim.limit:.3g}× its limit "
                 f"{_quantity(lim.limit, lim.unit)}{', ' + lim.note if lim.note else ''})"
                 for lim in over]
        return (
            f"the planned test (amplitude ±{self.amplitude * 1e3:.4g} mm) asks more than the "
            f"actuator can do: {'; '.join(parts)}. A real actuator saturates there and the "
            "linear model no longer describes it; the largest amplitude within every limit is "
            f"±{self.largest_amplitude * 1e3:.3g} mm (set by the {self.rule.binding})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "amplitude": self.amplitude,
            "largest_amplitude": self.largest_amplitude,
            "suggested_amplitude": self.suggested_amplitude,
            "binding": self.rule.binding,
            "feasible": self.feasible,
            "pressure_fraction": self.pressure_fraction,
            "supply": self.supply,
            "limits": self.table(),
        }

    def _limit(self, name: str) -> Limit:
        return next(lim for lim in self.rule.limits if lim.name == name)


def excitation_limits(
    params: EhsaParameters,
    excitation: Excitation,
    *,
    pressure_fraction: float = PRESSURE_FRACTION,
) -> PlannedTest:
    """Return what a test asks of the actuator and what it may ask.

    The quantities of the module table are simulated on the excitation at
    unit amplitude (the command held over each sample, read at eight
    points per sample) with the full-order linear loop; each limit then
    allows an amplitude, and the smallest is the rule's.

    Parameters
    ----------
    params : EhsaParameters
        The actuator (its loop gains, valve, piston and load).
    excitation : Excitation
        The planned position command [m], e.g. a PRBS.
    pressure_fraction : float
        Largest load pressure as a fraction of ``P_s − P_T``, in (0, 1];
        default :data:`PRESSURE_FRACTION`.

    Returns
    -------
    PlannedTest
        Peaks and limits at the planned amplitude, the largest amplitude
        within every limit and the one that binds.

    Raises
    ------
    DataError
        An excitation of amplitude 0, a fraction outside (0, 1], or an
        offset beyond the stroke.

    Examples
    --------
    >>> from servoid.signals import prbs
    >>> from servoid.plants.ehsa import SET_B
    >>> plan = excitation_limits(SET_B, prbs(11, clock=10, amplitude=1e-3, dt=1e-3))
    >>> plan.feasible, round(plan.load_pressure / 1e6), plan.rule.binding
    (False, 35, 'load pressure')
    >>> round(plan.suggested_amplitude * 1e3, 3)
    0.19
    """
    p = as_instance("params", params, EhsaParameters, "an EhsaParameters (e.g. SET_B)")
    ex = as_instance("excitation", excitation, Excitation, "a servoid.signals.Excitation")
    fraction = as_float("pressure_fraction", pressure_fraction, positive=True)
    if fraction > 1.0:
        raise DataError(f"pressure_fraction must lie in (0, 1], a fraction of the supply "
                        f"P_s − P_T, got {fraction:g}")
    if ex.amplitude == 0.0:
        raise DataError("the excitation has amplitude 0: it asks nothing of the actuator and "
                        "identifies nothing")
    unit_values = (np.asarray(ex.values) - ex.offset) / ex.amplitude
    peaks = _peaks(p, unit_values, ex.dt)
    supply = p.P_s - p.P_T
    dc = p.dc_gain
    limits = [
        Limit("load pressure", peaks["load pressure"], fraction * supply, "Pa",
              note=f"{_fraction(fraction)} of the supply {supply / 1e6:.3g} MPa"),
        Limit("spool opening", peaks["spool opening"], p.x_s_max, "m", note="spool travel"),
        Limit("spool rate", peaks["spool rate"], p.v_s_max, "m/s", note="spool rate limit"),
        Limit("flapper travel", peaks["flapper travel"], p.x_f_max, "m",
              note="flapper to nozzle"),
        Limit("piston velocity", peaks["piston velocity"], p.v_max, "m/s",
              note="no-load speed at full spool"),
        Limit("stroke", peaks["stroke"], p.stroke, "m", static=abs(dc * ex.offset),
              note="end stops"),
    ]
    return PlannedTest(ex.amplitude, largest_amplitude(limits), fraction, supply)


def within_limits(
    params: EhsaParameters,
    excitation: Excitation,
    *,
    pressure_fraction: float = PRESSURE_FRACTION,
) -> Excitation:
    """Return the excitation scaled to a test the actuator can run.

    The default test of the bench and the demo: a design whose planned
    amplitude asks more than :func:`excitation_limits` allows is scaled
    about its offset to :attr:`PlannedTest.suggested_amplitude`; a
    feasible one is returned as it is.

    Parameters
    ----------
    params : EhsaParameters
        The actuator.
    excitation : Excitation
        The planned position command [m].
    pressure_fraction : float
        Largest load pressure as a fraction of ``P_s − P_T``.

    Returns
    -------
    Excitation
        A test within every limit.

    Examples
    --------
    >>> from servoid.signals import prbs
    >>> from servoid.plants.ehsa import SET_B
    >>> within_limits(SET_B, prbs(11, clock=10, amplitude=1e-3, dt=1e-3)).amplitude * 1e3
    0.19
    """
    plan = excitation_limits(params, excitation, pressure_fraction=pressure_fraction)
    if plan.feasible:
        return excitation
    return excitation.with_amplitude(plan.suggested_amplitude)


def plan_test(set_name: str, excitation: Excitation, unit: str = "m") -> PlannedTest:
    """Check a designed command against a named parameter set's limits.

    The plant's ``limits`` part, for ``servoid excite --plant ehsa``.

    Parameters
    ----------
    set_name : str
        A parameter set of :data:`~._params.PARAMETER_SETS` (``"B"``, ``"C"``).
    excitation : Excitation
        The designed position command.
    unit : str
        Its unit: the command must be a position in m.

    Returns
    -------
    PlannedTest
        As :func:`excitation_limits` gives it.

    Raises
    ------
    OptionError
        An unknown set, or a command not in m.
    """
    from ._params import PARAMETER_SETS

    if set_name not in PARAMETER_SETS:
        raise OptionError(f"--set {set_name!r}: the EHSA's parameter sets are "
                          f"{', '.join(sorted(PARAMETER_SETS))}")
    if unit != "m":
        raise OptionError(f"--plant ehsa checks a position command in m, got --unit {unit!r}: "
                          "pass --unit m and the amplitude and offset in metres")
    return excitation_limits(PARAMETER_SETS[set_name], excitation)


def _peaks(p: EhsaParameters, r: NDArray[np.float64], dt: float) -> dict[str, float]:
    """Peak |quantity| per unit command for each row of the module table."""
    g = full_order_plant(p, exact=True)
    c, f = p.reference_gain, p.K_fb
    num_g, den_g = np.asarray(g.num, float), np.asarray(g.den, float)
    loop = np.polyadd(den_g, f * num_g)  # H = c·num_g/loop
    held = np.repeat(r, _READ)
    step = dt / _READ

    def run(num: NDArray[np.float64], den: NDArray[np.float64], x: NDArray[np.float64],
            hold: str) -> NDArray[np.float64]:
        model = discretise(realise(TransferFunction(num, den)), step, hold)  # type: ignore[arg-type]
        return np.asarray(model.simulate(x), dtype=float)

    y = run(c * num_g, loop, held, "zoh")
    u = c * held - f * y  # the flapper-equivalent error, a jump where the command steps
    flapper = np.array([1.0 / p.omega_f**2, 2.0 * p.delta_f / p.omega_f, 1.0])
    stage = np.polymul([1.0 / p.omega_s1, 1.0],
                       [1.0 / p.omega_sp**2, 2.0 * p.delta_sp / p.omega_sp, 1.0])
    x_f = run(np.ones(1), flapper, u, "foh")
    piston = [p.M_t / p.A_p, p.B_p / p.A_p, p.K_l / p.A_p]
    return {
        "load pressure": _peak(run(np.polymul(c * num_g, piston), loop, held, "zoh")),
        "spool opening": _peak(run(np.array([p.K_s2]), stage, x_f, "foh")),
        "spool rate": _peak(run(np.array([p.K_s2, 0.0]), stage, x_f, "foh")),
        "flapper travel": _peak(x_f),
        "piston velocity": _peak(run(np.polymul(c * num_g, [1.0, 0.0]), loop, held, "zoh")),
        "stroke": _peak(y),
    }


def _peak(x: NDArray[np.float64]) -> float:
    return float(np.max(np.abs(x)))


def _fraction(x: float) -> str:
    for k in (2, 3, 4, 5):
        for j in range(1, k):
            if math.isclose(x, j / k, rel_tol=1e-9):
                return f"{j}/{k}"
    return f"{x:.3g}"


def _quantity(value: float, unit: str) -> str:
    if unit == "Pa":
        return f"{value / 1e6:.3g} MPa"
    if unit == "m":
        return f"{value * 1e3:.3g} mm"
    if unit == "m/s":
        return f"{value * 1e3:.3g} mm/s"
    return f"{value:.3g} {unit}"
