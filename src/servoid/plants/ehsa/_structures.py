"""Plant structures the one-step closed-loop fit can take.

A structure is a continuous plant G0(s, θ) with named, unit-carrying
parameters, the transforms the optimiser works in, and a start built from
the reduced EHSA parameters (K, ω_hp, δ_hp).  The reduced model of the
source study is one structure; richer ones are alternatives a structure
test (:func:`~servoid.plants.ehsa.compare_structures`) compares with it::

    "reduced"      K/(s(s²/ω² + 2δs/ω + 1))                      θ = (K, ω_hp, δ_hp)
    "reduced+lag"  reduced · 1/(τ_v·s + 1)                        θ = (K, ω_hp, δ_hp, τ_v)
    "full-order"   reduced · V(s·τ_v/τ_nom)  (spec §1.1, Eq. 5)   θ = (K, ω_hp, δ_hp, τ_v)

Both richer structures *nest* the reduced one: at ``τ_v = 0`` their plant
is the reduced plant exactly, so a likelihood-ratio test of the reduced
model against them is a test of one restriction, ``τ_v = 0``.

Why the valve is parameterised by a time τ_v [s] and not by a bandwidth
ω_v = 1/τ_v [rad/s]: the question the test asks is whether τ_v = 0, and
in τ_v that point is an ordinary value with a non-zero output gradient
``∂ŷ/∂τ_v = −s·G0·…`` (the lag's first-order effect is a phase ω·τ_v,
linear in τ_v), so the Jacobian keeps full rank there and the criterion
is close to quadratic in τ_v.  In ω_v (or log ω_v) the reduced model sits
at ω_v = ∞, where ``∂ŷ/∂ω_v → 0``: the Jacobian loses rank as the lag
shrinks (its column scales by τ_v), the covariance blows up and the
likelihood-ratio theory does not apply.  For Set B at 1 kHz (PRBS n = 9)
the condition number of the Jacobian in (log K, log ω_hp, δ_hp, τ_v) is
230 at any τ_v; in log ω_v it is 49 at τ_v = 1.5 ms but 6·10³ at 10 µs
and 6·10⁴ at 1 µs.  τ_v correlates with ω_hp (ρ ≈ 0.9: both shift the
phase below the resonance) but stays separable through the resonance's
shape.
The lag cannot be negative (a plant pole at +1/|τ_v|, which no gain
stabilises), so τ_v >= 0 is a bound and the reduced model lies on it:
the test is one-sided (Chernoff 1954; Self & Liang 1987).

Exact samplers of the loop need a plant that is not too stiff; a lag
pole at 1/τ_v → ∞ is.  So below ``τ_v = 10⁻⁴/ω_hp`` (a pole at 10⁴·ω_hp)
the lag becomes a lead–lag with a fixed pole and the same mean delay, which
agrees with the lag to (ω·τ_v)² and is exactly 1 at τ_v = 0; likewise the
full-order valve becomes its first-order lag below 10⁻³ of its nominal
time scale.

τ_v means the same thing in both structures: the valve's mean delay,
``−d∠V(jω)/dω`` at ω = 0, the part of its dynamics that shows in the
actuator's band.  A first-order lag has mean delay τ; the eighth-order
valve of spec §1.1 has ``τ_nom = 2δ_f/ω_f + 1/ω_s1 + 2δ_sp/ω_sp``
(1.50 ms for Set B).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_instance
from ..._errors import ModelError
from ...models import TransferFunction
from ._loop import PARAMETER_NAMES, PARAMETER_UNITS, plant_of_theta
from ._params import SET_B, EhsaParameters

__all__ = ["STRUCTURES", "PlantStructure", "full_order_structure", "skew_structure"]

Transform = Literal["none", "log"]

_INF = math.inf
#: Valve time scale κ = τ_v/τ_nom below which the full-order valve is its first-order lag.
_KAPPA_FLOOR = 1e-3
#: τ_v·ω_hp below which the first-order lag is a lead–lag with its pole at 10⁴·ω_hp.
_LAG_FLOOR = 1e-4


@dataclass(frozen=True, eq=False)
class PlantStructure:
    """A parameterised continuous plant for the one-step fit.

    Attributes
    ----------
    name : str
        Its label (``"reduced"``, ``"reduced+lag"``, ``"full-order"``).
    names, units : tuple of str
        Parameter names and units, in the order of θ.
    transforms : tuple of {"none", "log"}
        Coordinates the optimiser uses (``"log"`` keeps a parameter
        positive and makes its steps relative).
    plant : callable
        ``plant(theta) -> TransferFunction``, continuous.
    start : callable
        ``start(reduced) -> theta0`` from reduced parameters (K, ω_hp, δ_hp).
    reduced : callable
        ``reduced(theta) -> (K, ω_hp, δ_hp)``: the reduced parameters this
        θ corresponds to, for reporting one set of physical numbers.
    lower, upper : tuple of float
        Bounds on θ in physical units (``-inf``/``inf``: none); empty for
        an unbounded structure.  A log-transformed parameter is positive
        by its transform and has bound 0 here.
    nests : str or None
        Name of the smaller structure this one contains: with its trailing
        parameters at `null`, ``plant(θ)`` is ``nests``'s plant at the
        leading parameters.
    null : tuple of float
        Values of the trailing parameters that give the smaller structure.
    fixed : mapping of str to float
        Physical constants the structure holds fixed, for the record.
    description : str
        One line for reports.
    """

    name: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    transforms: tuple[Transform, ...]
    plant: Callable[[NDArray[np.float64]], TransferFunction]
    start: Callable[[Sequence[float]], NDArray[np.float64]]
    reduced: Callable[[NDArray[np.float64]], tuple[float, float, float]]
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()
    nests: str | None = None
    null: tuple[float, ...] = ()
    fixed: Mapping[str, float] = field(default_factory=dict)
    description: str = ""

    @property
    def n_parameters(self) -> int:
        """Number of parameters."""
        return len(self.names)

    @property
    def bounds(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """``(lower, upper)`` for the optimiser, or None when unbounded."""
        if not self.lower and not self.upper:
            return None
        n = self.n_parameters
        lower = self.lower or (-_INF,) * n
        upper = self.upper or (_INF,) * n
        return tuple(lower), tuple(upper)

    @property
    def extra_names(self) -> tuple[str, ...]:
        """Names of the parameters the restriction to `nests` fixes."""
        return self.names[self.n_parameters - len(self.null):] if self.null else ()

    def is_on_bound(self) -> tuple[bool, ...]:
        """Return whether each null value lies on a bound (one-sided)."""
        bounds = self.bounds
        k = len(self.null)
        if bounds is None:
            return (False,) * k
        lower, upper = (b[self.n_parameters - k:] for b in bounds)
        return tuple(v in (lo, hi) for v, lo, hi in zip(self.null, lower, upper, strict=True))


def full_order_structure(params: EhsaParameters = SET_B) -> PlantStructure:
    """Return the full-order structure for a nominal valve.

    The eighth-order plant of spec §1.1, Eq. 5, ``G_f·G_s2·G_h``: the piston
    ``G_h`` keeps its three reduced parameters free; the valve (flapper
    ``G_f``, first-order spool stage ``ω_s1``, spool mechanics ``ω_sp``)
    keeps its *shape* fixed at `params` (δ_f, δ_sp and the ratios
    ω_f : ω_s1 : ω_sp) and one free time scale, its mean delay τ_v::

        G0(s) = K/(s(s²/ω_hp² + 2δ_hp s/ω_hp + 1)) · V(κ·s),   κ = τ_v/τ_nom
        V(s)  = 1/[(s²/ω_f² + 2δ_f s/ω_f + 1)(s/ω_s1 + 1)(s²/ω_sp² + 2δ_sp s/ω_sp + 1)]

    with ``τ_nom = 2δ_f/ω_f + 1/ω_s1 + 2δ_sp/ω_sp``.  At ``τ_v = τ_nom``
    it is the nominal eighth-order plant; at ``τ_v = 0`` the reduced one.
    Below ``τ_v = 10⁻³·τ_nom`` the valve is its first-order lag of the same
    mean delay (the same to (ω·τ_v)², and sampled without overflow).
    Why only one valve parameter: at f_s = 1 kHz (Nyquist 3142 rad/s) the
    flapper (3770 rad/s) and spool (5027 rad/s) modes lie above the band
    and the spool stage (1000 rad/s) far above the actuator's (46 rad/s);
    closed-loop r → y data see the valve only through its phase lag,
    which is τ_v to first order.  Freeing ω_f, δ_f, ω_sp, δ_sp as well
    would make the Jacobian rank deficient.

    Parameters
    ----------
    params : EhsaParameters
        The nominal set whose valve shape is held: the user's design
        values, or the bench's truth.

    Returns
    -------
    PlantStructure
        Named ``"full-order"``, θ = (K [1/s], ω_hp [rad/s], δ_hp [-],
        τ_v [s]); it nests ``"reduced"`` at τ_v = 0.

    Examples
    --------
    >>> s = full_order_structure()
    >>> round(s.fixed["tau_nom"] * 1e3, 3)
    1.504
    """
    p = as_instance("params", params, EhsaParameters,
                    "an EhsaParameters (e.g. servoid.plants.ehsa.SET_B)")
    valve = np.polymul(
        np.polymul([1.0 / p.omega_f**2, 2.0 * p.delta_f / p.omega_f, 1.0], [1.0 / p.omega_s1, 1.0]),
        [1.0 / p.omega_sp**2, 2.0 * p.delta_sp / p.omega_sp, 1.0],
    )
    tau_nom = 2.0 * p.delta_f / p.omega_f + 1.0 / p.omega_s1 + 2.0 * p.delta_sp / p.omega_sp
    powers = np.arange(valve.size - 1, -1, -1)

    def plant(theta: NDArray[np.float64]) -> TransferFunction:
        k, w, d, tau = (float(x) for x in theta)
        if abs(tau) < _KAPPA_FLOOR * tau_nom:
            # Five valve poles beyond 1000× their nominal frequencies (> 3.8e6 rad/s for Set B)
            # make the polynomial too stiff to sample exactly (its leading coefficient ∝ κ⁵);
            # there V(κs) is its first-order lag of the same mean delay to (ωτ_v)² — 2e-5 at
            # 1 kHz's Nyquist frequency, 2e-8 at 100 rad/s — and τ_v = 0 stays the reduced plant.
            return _lag_plant(theta)
        scaled = valve * (tau / tau_nom) ** powers  # V(κs): s^j coefficient times κ^j
        return TransferFunction([k * w * w], np.polymul(scaled, _hydraulic_den(w, d)))

    fixed = {"omega_f": p.omega_f, "delta_f": p.delta_f, "omega_s1": p.omega_s1,
             "omega_sp": p.omega_sp, "delta_sp": p.delta_sp, "tau_nom": tau_nom}
    return PlantStructure(
        name="full-order",
        names=(*PARAMETER_NAMES, "tau_v"),
        units=(*PARAMETER_UNITS, "s"),
        transforms=("log", "log", "none", "none"),
        plant=plant,
        start=_lag_start,
        reduced=_reduced_of,
        lower=(0.0, 0.0, -_INF, 0.0),
        upper=(_INF, _INF, _INF, _INF),
        nests="reduced",
        null=(0.0,),
        fixed=MappingProxyType(fixed),
        description=(
            "eighth-order plant (spec Eq. 5): piston K, omega_hp, delta_hp free; valve shape "
            f"fixed (omega_f {p.omega_f:.4g}, delta_f {p.delta_f:.3g}, omega_s1 "
            f"{p.omega_s1:.4g}, omega_sp {p.omega_sp:.4g} rad/s, delta_sp {p.delta_sp:.3g}), "
            f"its mean delay tau_v free (nominal {tau_nom * 1e3:.3g} ms)"
        ),
    )


def skew_structure(feedback: float) -> PlantStructure:
    """Return the reduced loop with a measurement delay between its channels.

    A multiplexed ADC reads the position a few µs after the reference (or
    before it): the record is ``y(t − τ_d)`` against ``r(t)``, a delay
    *outside* the loop, which the reduced model absorbs into ω_hp (12.5 µs
    put Set B's ω_hp interval off in 40 % of the records).  The one-step
    fit closes a plant inside the known loop, so the delay is written as
    the plant ``G_d`` whose loop is the reduced loop times the delay
    ``D(s)``::

        c·G_d/(1 + F·G_d) = D·c·G/(1 + F·G)   ⇔   G_d = G·D/(1 + F·G·(1 − D))

    with ``D(s) = (1 + (τ_f − τ_d)·s)/(1 + τ_f·s)``, whose mean delay is
    τ_d: with ``τ_f = |τ_d|/2`` it is the (1, 1) Padé approximant of a
    delay (an all-pass, right to ``(ω·τ_d)³/12``: 1 ms of dead time in the
    reference path is modelled too), and below ``τ_f = 10⁻⁴/ω_hp`` that
    floor keeps the pole within what the exact samplers take (as the lag
    structures do; the form then differs from the delay by
    ``(ω·τ_d)²/2``, 7.7·10⁻⁴ at 1 kHz's Nyquist frequency for 12.5 µs).
    ``1 − D = τ_d·s/(1 + τ_f·s)``, so::

        G_d = K·ω²·(1 + (τ_f − τ_d)s) / [s(s² + 2δωs + ω²)(1 + τ_f s) + F·K·ω²·τ_d·s]

    keeps the integrator, and at ``τ_d = 0`` is the reduced plant.  τ_d
    may have either sign (the position read early is ``τ_d < 0``), so the
    test of ``τ_d = 0`` is two-sided.

    Parameters
    ----------
    feedback : float
        The loop's static feedback F (the delay lies outside the loop, so
        its plant form depends on F).

    Returns
    -------
    PlantStructure
        Named ``"reduced+skew"``, θ = (K [1/s], ω_hp [rad/s], δ_hp [-],
        tau_d [s]); it nests ``"reduced"`` at τ_d = 0.

    Examples
    --------
    >>> s = skew_structure(0.01)
    >>> g = s.plant(np.array([3451.7, 163.3, 0.249, 0.0]))
    >>> [round(float(x), 6) for x in np.roots(g.den)][-1]
    0.0
    """
    f = float(feedback)
    if not math.isfinite(f) or f <= 0.0:
        raise ModelError(f"the skew structure needs the loop's static feedback F > 0, got {f}")

    def plant(theta: NDArray[np.float64]) -> TransferFunction:
        k, w, d, tau = (float(x) for x in theta)
        if tau == 0.0:
            return plant_of_theta((k, w, d))
        floor = max(abs(tau) / 2.0, _LAG_FLOOR / w)
        num = np.array([k * w * w * (floor - tau), k * w * w])
        den = np.polymul(_hydraulic_den(w, d), [floor, 1.0])
        den[-2] += f * k * w * w * tau  # the s¹ coefficient
        return TransferFunction(num, den)

    return PlantStructure(
        name="reduced+skew",
        names=(*PARAMETER_NAMES, "tau_d"),
        units=(*PARAMETER_UNITS, "s"),
        transforms=("log", "log", "none", "none"),
        plant=plant,
        start=_skew_start,
        reduced=_reduced_of,
        nests="reduced",
        null=(0.0,),
        fixed=MappingProxyType({"F": f}),
        description=("reduced loop with a measurement delay tau_d of the position against the "
                     "reference (channel skew), either sign"),
    )


# -- the structures ----------------------------------------------------------------------------


def _hydraulic_den(w: float, d: float) -> NDArray[np.float64]:
    return np.array([1.0, 2.0 * d * w, w * w, 0.0])


def _reduced_start(reduced: Sequence[float]) -> NDArray[np.float64]:
    return np.asarray(reduced, dtype=float)


def _lag_start(reduced: Sequence[float]) -> NDArray[np.float64]:
    # A valve ten times faster than the hydraulics: the reduced model only makes sense when
    # the valve is fast, and the start must lie off the bound τ_v = 0 for the first step to
    # see the lag.  The optimiser moves τ_v from 0.6 ms (Set B) to the 1.5 ms of the
    # full-order bench and to ~0 on reduced data within a few iterations.
    k, w, d = (float(x) for x in reduced)
    return np.array([k, w, d, 0.1 / w])


def _skew_start(reduced: Sequence[float]) -> NDArray[np.float64]:
    k, w, d = (float(x) for x in reduced)
    return np.array([k, w, d, 0.0])


def _reduced_of(theta: NDArray[np.float64]) -> tuple[float, float, float]:
    k, w, d = (float(x) for x in theta[:3])
    return k, w, d


def _lag_plant(theta: NDArray[np.float64]) -> TransferFunction:
    k, w, d, tau = (float(x) for x in theta)
    if tau == 0.0:
        return plant_of_theta((k, w, d))
    floor = _LAG_FLOOR / w
    if tau >= floor:
        return TransferFunction([k * w * w], np.polymul([tau, 1.0], _hydraulic_den(w, d)))
    # A lag pole beyond 10⁴·ω_hp is too stiff to sample exactly: the sampled models lose six
    # digits at τ_v = 1e-12 s and finite-difference Jacobians near the bound τ_v = 0 turn to
    # noise. Below the floor τ_f the lag is the lead–lag (1 + (τ_f − τ_v)s)/(1 + τ_f·s): the
    # same mean delay τ_v, equal to it at τ_f, 1 at τ_v = 0, and within (ω·τ_f)² <= 1e-8·
    # (ω/ω_hp)² of the lag in between.
    return TransferFunction(np.polymul([floor - tau, 1.0], [k * w * w]),
                            np.polymul([floor, 1.0], _hydraulic_den(w, d)))


REDUCED = PlantStructure(
    name="reduced",
    names=PARAMETER_NAMES,
    units=PARAMETER_UNITS,
    transforms=("log", "log", "none"),
    plant=plant_of_theta,
    start=_reduced_start,
    reduced=_reduced_of,
    description="reduced plant K/(s(s^2/omega_hp^2 + 2 delta_hp s/omega_hp + 1)) (spec Eq. 6)",
)

REDUCED_LAG = PlantStructure(
    name="reduced+lag",
    names=(*PARAMETER_NAMES, "tau_v"),
    units=(*PARAMETER_UNITS, "s"),
    transforms=("log", "log", "none", "none"),
    plant=_lag_plant,
    start=_lag_start,
    reduced=_reduced_of,
    lower=(0.0, 0.0, -_INF, 0.0),
    upper=(_INF, _INF, _INF, _INF),
    nests="reduced",
    null=(0.0,),
    description="reduced plant times a first-order valve/servo lag 1/(tau_v s + 1)",
)

FULL_ORDER = full_order_structure(SET_B)

#: Registered structures by name ("full-order" holds the valve shape of Set B; build another
#: with :func:`full_order_structure`).
STRUCTURES: Mapping[str, PlantStructure] = MappingProxyType(
    {s.name: s for s in (REDUCED, REDUCED_LAG, FULL_ORDER)}
)
