"""Linear EHSA models: reduced third order and full eighth order.

Reduced ([S1] Eq. 6, 11)::

    G_simple = K / [s(s²/ω_hp² + 2δ_hp s/ω_hp + 1)],   K = K_s2·K_qs/A_p
    G_at     = c·G_simple/(1 + F·G_simple) = cK/(s³/ω² + 2δs²/ω + s + FK)

Routh: the loop is stable iff ``0 < F·K < 2·δ_hp·ω_hp``.

Full order ([S1] Eq. 4, 1a, 1b, 5): ``G_plant = G_f·G_s2·G_h`` from the
flapper error ``K_TM·i_c − K_fb·y`` to ``y``, with::

    G_f  = 1/(s²/ω_f² + 2δ_f s/ω_f + 1)
    G_s2 = K_s2·ω_s1/[(s + ω_s1)(s²/ω_sp² + 2δ_sp s/ω_sp + 1)]
    G_h  = (K_qs/A_p)/[s(s²/ω_hp² + 2δ_hp s/ω_hp + 1)]

and the closed loop ``G_at,full = K_TM·K_driver·G_plant/(1 + K_fb·G_plant)``.
``G_h`` is Merritt's mass-load form, which drops ``K_ce·B_p/A_p²`` (0.4 %
for the nominal sets) against 1 and assumes no load spring.  With
``exact=True`` the piston factor is the exact linearisation of the
simulator's equations instead::

    G_h = K_qs·A_p / [(V_t s/(4β_e) + K_ce)(M_t s² + B_p s + K_l) + A_p² s]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._errors import ModelError, OptionTypeError, check_option
from ..._lazy import optimize
from ...models import TransferFunction
from .._common import check_finite, check_instance
from ._params import EhsaParameters

__all__ = [
    "ReducedEhsa",
    "StabilityMargins",
    "closed_loop_bandwidth",
    "full_order_closed_loop",
    "full_order_plant",
    "loop_margins",
]

Order = Literal["reduced", "full"]
_ORDERS = ("reduced", "full")


@dataclass(frozen=True)
class ReducedEhsa:
    """Reduced third-order EHSA plant ``K/(s(s²/ω² + 2δs/ω + 1))``.

    Parameters
    ----------
    K : float
        Velocity gain [1/s], > 0.
    omega_hp : float
        Hydraulic natural frequency [rad/s], > 0.
    delta_hp : float
        Hydraulic damping ratio [-], > 0 (may exceed 1: two real poles).

    Examples
    --------
    >>> g = ReducedEhsa(K=100.0, omega_hp=200.0, delta_hp=0.3)
    >>> g.is_stable(1.0), g.is_stable(2.0)
    (True, False)
    """

    K: float
    omega_hp: float
    delta_hp: float

    def __post_init__(self) -> None:
        for name, unit in (("K", "1/s"), ("omega_hp", "rad/s"), ("delta_hp", "-")):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise OptionTypeError(f"ReducedEhsa.{name} must be a real number, got {value!r}")
            if not (math.isfinite(value) and value > 0.0):
                raise ModelError(f"ReducedEhsa.{name} must be finite and > 0 [{unit}], "
                                 f"got {value}")
            object.__setattr__(self, name, float(value))

    @classmethod
    def from_parameters(cls, params: EhsaParameters) -> ReducedEhsa:
        """Build the reduced plant from physical parameters.

        Parameters
        ----------
        params : EhsaParameters
            Physical parameters.

        Returns
        -------
        ReducedEhsa
            ``K = K_s2·K_qs/A_p``, ``ω_hp``, ``δ_hp`` of `params`.
        """
        if not isinstance(params, EhsaParameters):
            raise OptionTypeError(f"params must be EhsaParameters, got {type(params).__name__}")
        return cls(params.K, params.omega_hp, params.delta_hp)

    @classmethod
    def from_real_poles(cls, gain: float, a: float, b: float) -> ReducedEhsa:
        """Build the plant from the factored form ``gain/(s(s+a)(s+b))``.

        Parameters
        ----------
        gain : float
            Numerator constant [1/s³].
        a, b : float
            The two non-zero poles are −a and −b [rad/s], a, b > 0.

        Returns
        -------
        ReducedEhsa
            ``K = gain/(ab)``, ``ω_hp = √(ab)``, ``δ_hp = (a + b)/(2ω_hp)``.
        """
        if not (a > 0.0 and b > 0.0 and gain > 0.0):
            raise ModelError(f"gain, a and b must be > 0, got {gain}, {a}, {b}")
        omega = math.sqrt(a * b)
        return cls(gain / (a * b), omega, (a + b) / (2.0 * omega))

    @property
    def routh_limit(self) -> float:
        """Largest stable loop gain ``F·K = 2·δ_hp·ω_hp`` [1/s]."""
        return 2.0 * self.delta_hp * self.omega_hp

    def plant(self) -> TransferFunction:
        """Return the continuous plant ``K/(s(s²/ω² + 2δs/ω + 1))``.

        Returns
        -------
        TransferFunction
            Continuous (``dt=None``), from valve command to position.
        """
        w, d = self.omega_hp, self.delta_hp
        return _tf([self.K], [1.0 / w**2, 2.0 * d / w, 1.0, 0.0])

    def closed_loop(self, c: float, F: float) -> TransferFunction:
        """Return ``cK/(s³/ω² + 2δs²/ω + s + FK)`` ([S1] Eq. 11).

        Parameters
        ----------
        c : float
            Reference gain [-].
        F : float
            Static feedback gain [-].

        Returns
        -------
        TransferFunction
            Continuous closed loop from reference to position.
        """
        c, F = _gain("c", c), _gain("F", F)
        w, d = self.omega_hp, self.delta_hp
        return _tf([c * self.K], [1.0 / w**2, 2.0 * d / w, 1.0, F * self.K])

    def is_stable(self, F: float) -> bool:
        """Return True if the loop closed with gain F is stable (Routh).

        Parameters
        ----------
        F : float
            Static feedback gain [-].

        Returns
        -------
        bool
            ``0 < F·K < 2·δ_hp·ω_hp``.
        """
        fk = _gain("F", F) * self.K
        return bool(0.0 < fk < self.routh_limit)


@dataclass(frozen=True)
class StabilityMargins:
    """Gain and phase margins of a loop transfer function.

    Parameters
    ----------
    gain_margin_db : float
        ``−20·log10|L(jω_pc)|`` [dB] at the lowest phase crossover; inf
        if the phase never reaches −180°.
    phase_margin_deg : float
        ``180° + ∠L(jω_gc)`` [deg] at the gain crossover; inf if
        ``|L| = 1`` nowhere.
    phase_crossover : float
        ω_pc [rad/s], nan if none.
    gain_crossover : float
        ω_gc [rad/s], nan if none.
    """

    gain_margin_db: float
    phase_margin_deg: float
    phase_crossover: float
    gain_crossover: float


def full_order_plant(params: EhsaParameters, *, exact: bool = False) -> TransferFunction:
    """Return the eighth-order plant ``G_f·G_s2·G_h`` ([S1] Eq. 5).

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters.
    exact : bool
        False: Merritt's mass-load piston of the spec.  True: the exact
        linearisation of the simulator's piston (keeps ``K_ce·B_p`` and
        ``K_l``), which ``simulate_ehsa(linear=True)`` reproduces.

    Returns
    -------
    TransferFunction
        Continuous, from flapper error ``K_TM·i_c − K_fb·y`` [m] to y [m].
    """
    p = _params(params)
    g_f = _second_order(p.omega_f, p.delta_f)
    g_s2 = _tf([p.K_s2 * p.omega_s1], [1.0, p.omega_s1]) * _second_order(
        p.omega_sp, p.delta_sp
    )
    if exact:
        den = np.polyadd(
            np.polymul([p.V_t / (4.0 * p.beta_e), p.K_ce], [p.M_t, p.B_p, p.K_l]),
            [p.A_p**2, 0.0],
        )
        g_h = _tf([p.K_qs * p.A_p], den)
    else:
        w, d = p.omega_hp, p.delta_hp
        g_h = _tf([p.K_qs / p.A_p], [1.0 / w**2, 2.0 * d / w, 1.0, 0.0])
    return g_f * g_s2 * g_h


def full_order_closed_loop(params: EhsaParameters, *, exact: bool = False) -> TransferFunction:
    """Return ``K_TM·K_driver·G_plant/(1 + K_fb·G_plant)``.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters.
    exact : bool
        Piston form, as in :func:`full_order_plant`.

    Returns
    -------
    TransferFunction
        Continuous closed loop from y_r [m] to y [m].
    """
    p = _params(params)
    return full_order_plant(p, exact=exact).feedback(p.K_fb) * p.reference_gain


def loop_margins(params: EhsaParameters, order: Order = "reduced") -> StabilityMargins:
    """Return the gain and phase margins of the EHSA loop.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters.
    order : {"reduced", "full"}
        Loop ``F·G_simple`` (third order) or ``K_fb·G_plant`` (eighth).

    Returns
    -------
    StabilityMargins
        Margins and crossover frequencies.
    """
    check_option("order", order, _ORDERS)
    p = _params(params)
    if order == "reduced":
        loop = ReducedEhsa.from_parameters(p).plant() * p.K_fb
    else:
        loop = full_order_plant(p) * p.K_fb
    return _margins(loop)


def closed_loop_bandwidth(params: EhsaParameters, order: Order = "reduced") -> float:
    """Return the −3 dB bandwidth of the closed loop [Hz].

    The frequency where ``|G_at(jω)/G_at(0)|`` first falls to 1/√2.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters.
    order : {"reduced", "full"}
        Reduced ([S1] Eq. 11) or full-order closed loop.

    Returns
    -------
    float
        Bandwidth [Hz].
    """
    check_option("order", order, _ORDERS)
    p = _params(params)
    if order == "reduced":
        cl = ReducedEhsa.from_parameters(p).closed_loop(p.reference_gain, p.K_fb)
    else:
        cl = full_order_closed_loop(p)
    return _bandwidth(cl) / (2.0 * math.pi)


# -- private helpers ---------------------------------------------------------


def _params(params: object) -> EhsaParameters:
    return check_instance("params", params, EhsaParameters)


def _gain(name: str, value: object) -> float:
    return check_finite(name, value, ModelError)


def _tf(num: ArrayLike, den: ArrayLike) -> TransferFunction:
    """Continuous transfer function from coefficient lists."""
    return TransferFunction(np.asarray(num, dtype=np.float64), np.asarray(den, dtype=np.float64))


def _second_order(omega: float, delta: float) -> TransferFunction:
    return _tf([1.0], [1.0 / omega**2, 2.0 * delta / omega, 1.0])


def _grid(g: TransferFunction) -> NDArray[np.float64]:
    """Log grid spanning three decades beyond the poles and zeros."""
    roots = np.abs(np.concatenate([g.poles(), g.zeros()]))
    roots = roots[roots > 1e-9]
    lo = 1e-3 * (roots.min() if roots.size else 1.0)
    hi = 1e3 * (roots.max() if roots.size else 1.0)
    return np.logspace(np.log10(lo), np.log10(hi), 400 * int(np.ceil(np.log10(hi / lo))))


def _margins(loop: TransferFunction) -> StabilityMargins:
    w = _grid(loop)
    resp = loop.freqresp(w)
    phase = np.unwrap(np.angle(resp))
    # phase crossover: the unwrapped phase passes −180° (mod 360°)
    k = np.floor((phase + np.pi) / (2.0 * np.pi))
    cross = np.flatnonzero(np.diff(k) != 0)
    gm, w_pc = math.inf, math.nan
    if cross.size:
        i = int(cross[0])

        def im(x: float) -> float:
            return float(loop.freqresp(x).imag)

        w_pc = optimize.brentq(im, w[i], w[i + 1], xtol=1e-12 * w[i])
        gm = -20.0 * math.log10(abs(loop.freqresp(w_pc)))
    mag = np.log(np.abs(resp))
    sign = np.flatnonzero(np.diff(np.sign(mag)) != 0)
    pm, w_gc = math.inf, math.nan
    if sign.size:
        i = int(sign[0])

        def logmag(x: float) -> float:
            return float(np.log(np.abs(loop.freqresp(x))))

        w_gc = optimize.brentq(logmag, w[i], w[i + 1], xtol=1e-12 * w[i])
        ang = float(np.angle(loop.freqresp(w_gc)))
        # choose the branch of the unwrapped grid phase next to the crossover
        ang += 2.0 * math.pi * round((phase[i] - ang) / (2.0 * math.pi))
        pm = math.degrees(ang + math.pi)
    return StabilityMargins(gm, pm, float(w_pc), float(w_gc))


def _bandwidth(cl: TransferFunction) -> float:
    dc = cl.dc_gain()
    if not (math.isfinite(dc) and dc != 0.0):
        raise ModelError(f"the closed loop needs a finite non-zero DC gain, got {dc}")
    w = _grid(cl)
    rel = np.abs(cl.freqresp(w)) / abs(dc) - 1.0 / math.sqrt(2.0)
    below = np.flatnonzero(rel < 0.0)
    if below.size == 0 or below[0] == 0:
        raise ModelError("the closed loop has no −3 dB point on the analysed grid")
    i = int(below[0]) - 1

    def f(x: float) -> float:
        return float(abs(cl.freqresp(x)) / abs(dc) - 1.0 / math.sqrt(2.0))

    return float(optimize.brentq(f, w[i], w[i + 1], xtol=1e-12 * w[i]))
