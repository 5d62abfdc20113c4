"""The nonlinear EHSA closed loop as a grey-box model of a record.

:class:`NonlinearEhsa` runs :func:`~servoid.plants.ehsa.simulate_ehsa`
(models-spec §1.4, compiled RK4) on a sampled reference and returns the
position at the sample instants, the way the one-step fit's ``Gcl(q, θ)``
does for the reduced model.  Three things sit between the samples and the
simulator:

* **Intersample.**  ``"zoh"``: the reference samples are the staircase
  the actuator saw (a DAC played them); ``"foh"``: they are samples of a
  smooth (band-limited) signal, e.g. a command logged through the rig's
  anti-alias filter, interpolated linearly.  The simulator gets the
  reference on a fine grid (``cells`` per sample), each cell holding the
  *average* of the continuous reference over the cell.
* **Dead time.**  ``T_d`` shifts the continuous reference before the cell
  averages are taken, so the output is continuous in ``T_d`` (the
  simulator's own dead time is rounded to whole RK4 steps, which would
  make the criterion a staircase in ``T_d`` and its derivative zero).
* **Output filter.**  A known continuous filter of the position
  transducer chain (the rig's analog anti-alias filter) can be applied to
  the simulated position on the fine grid before sampling, so that the
  model sees what the ADC saw.

The reduced parameters are coordinates of the physical set
(:func:`physical_parameters`), each realised by one physical parameter
with the others held (models-spec §1.1, [S1] Eq. 6, Merritt)::

    K        = K_s2·C_d·w·√((P_s − P_T)/ρ)/A_p       → area gradient w
    omega_hp = √(4β_e A_p²/(V_t M_t))                → reflected mass M_t
    delta_hp = (K_ce/A_p)√(β_e M_t/V_t)
               + (B_p/(4A_p))√(V_t/(β_e M_t))        → K_ce and B_p, scaled together

so that ``P_s − P_T`` (measured by the rig's pressure transducers) enters
both the flow gain and the flow law's load-pressure droop
``√(P_s − P_T − sgn(x_e)·P_L)``.  Position data see only the sums behind
ω_hp and δ_hp: β_e and M_t (or V_t) cannot be told apart, so M_t is "the
mass that gives this ω_hp at the nominal β_e"; nor can the leakage share
of the damping be told from the viscous one, so both keep their nominal
ratio (in Set B the leakage gives 98 % of δ_hp = 0.249, in Set C the
viscous friction 98 % of 0.228).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float, as_instance, type_error
from ..._errors import DataError, ModelError, check_option
from ..._lazy import signal as sps
from ...models import TransferFunction
from ._params import EhsaParameters
from ._sim import simulate_ehsa

__all__ = [
    "INTERSAMPLES",
    "NONLINEAR_PARAMETERS",
    "UNITS",
    "NonlinearEhsa",
    "physical_parameters",
    "reduced_parameters",
]

Intersample = Literal["zoh", "foh"]
#: Holds the reference can be read with.
INTERSAMPLES: tuple[Intersample, ...] = ("zoh", "foh")

#: Parameters the refinement can fit, in report order.
NONLINEAR_PARAMETERS: tuple[str, ...] = ("K", "omega_hp", "delta_hp", "F_c", "v_s_max",
                                         "x_s_max", "x_f_max", "T_d", "u_0")
#: Their units.
UNITS: Mapping[str, str] = {"K": "1/s", "omega_hp": "rad/s", "delta_hp": "-", "F_c": "N",
                            "v_s_max": "m/s", "x_s_max": "m", "x_f_max": "m", "T_d": "s",
                            "u_0": "m"}
_REDUCED = ("K", "omega_hp", "delta_hp")

# RK4 step: ω_max·dt_int at most 0.1 (phase error ~ (ω dt)⁴/120 = 8e-7 per radian; the fast
# modes are the well-damped valve stages), twice the simulator's default and without its 2 µs
# cap.  On PRBS records of Sets B and C the position moved by 0.007 and 0.17 µm rms (1.3 µm
# peak, where a stick–slip or limit event falls in another step) between ω·dt = 0.025 and
# 0.1: at most 1 % of the noise at 30 dB, for half the run time of 0.05.
_OMEGA_DT = 0.1
# Fine reference grid: at most this many cells in all (memory of the simulator's output).
_MAX_CELLS = 2_000_000


@dataclass(frozen=True, eq=False)
class NonlinearEhsa:
    """The nonlinear EHSA in its loop, driven by a sampled reference.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters, including the dead time ``T_d`` and the
        loop gains ``c = K_TM·K_driver`` and ``F = K_fb``.
    dt : float
        Sample period of the reference and the output [s].
    intersample : {"zoh", "foh"}
        How the reference runs between samples (see the module notes).
    output_filter : TransferFunction or None
        Continuous filter of the position measurement (e.g. the rig's
        anti-alias filter), static gain 1; None for none.
    dt_int : float
        RK4 step [s], ``dt/dt_int`` a whole number.

    Examples
    --------
    >>> from servoid.plants.ehsa import SET_B
    >>> model = NonlinearEhsa.for_parameters(SET_B, 1e-3)
    >>> y = model.simulate(np.full(300, 1e-3))
    >>> bool(abs(y[-1] - 1e-3) < 2.5e-5)
    True
    """

    params: EhsaParameters
    dt: float
    intersample: Intersample = "foh"
    output_filter: TransferFunction | None = None
    dt_int: float = 1e-5

    def __post_init__(self) -> None:
        as_instance("params", self.params, EhsaParameters,
                    "an EhsaParameters (e.g. servoid.plants.ehsa.SET_B)")
        check_option("intersample", self.intersample, INTERSAMPLES)
        object.__setattr__(self, "dt", as_float("dt", self.dt, positive=True, unit="s"))
        object.__setattr__(self, "dt_int", as_float("dt_int", self.dt_int, positive=True,
                                                    unit="s"))
        n = round(self.dt / self.dt_int)
        if n < 1 or abs(n * self.dt_int - self.dt) > 1e-9 * self.dt:
            raise DataError(f"dt/dt_int must be a whole number, got dt = {self.dt:g} s, "
                            f"dt_int = {self.dt_int:g} s")
        check_output_filter(self.output_filter)

    @classmethod
    def for_parameters(
        cls,
        params: EhsaParameters,
        dt: float,
        *,
        intersample: Intersample = "foh",
        output_filter: TransferFunction | None = None,
        omega_max: float | None = None,
    ) -> NonlinearEhsa:
        """Return the model with the default RK4 step for `params`.

        Parameters
        ----------
        params : EhsaParameters
            Physical parameters.
        dt : float
            Sample period [s].
        intersample : {"zoh", "foh"}
            Hold of the reference.
        output_filter : TransferFunction, optional
            Continuous filter of the measured position.
        omega_max : float, optional
            Fastest mode the step must resolve [rad/s]; default that of
            `params` (pass the largest over a parameter search).

        Returns
        -------
        NonlinearEhsa
            With ``dt_int`` the largest ``dt/n`` <= ``0.1/omega_max``.
        """
        w = fastest_mode(params) if omega_max is None else float(omega_max)
        n = max(1, math.ceil(dt * w / _OMEGA_DT * (1.0 - 1e-12)))
        return cls(params, float(dt), intersample, output_filter, float(dt) / n)

    @property
    def reduced(self) -> tuple[float, float, float]:
        """Reduced parameters (K [1/s], ω_hp [rad/s], δ_hp [-])."""
        return reduced_parameters(self.params)

    def with_params(self, params: EhsaParameters) -> NonlinearEhsa:
        """Return the same model with other physical parameters.

        Parameters
        ----------
        params : EhsaParameters
            The new parameters (same RK4 step).

        Returns
        -------
        NonlinearEhsa
            The modified copy.
        """
        return dataclasses.replace(self, params=params)

    def simulate(self, r: ArrayLike, *, y0: float = 0.0) -> NDArray[np.float64]:
        """Simulate the measured position for a reference from rest.

        Parameters
        ----------
        r : array_like, shape (N,)
            Reference samples [m] at period `dt`.
        y0 : float
            Position at rest before the record [m]; the reference before
            the first sample is the one that holds it, ``(F/c)·y0``.

        Returns
        -------
        ndarray, shape (N,)
            Position [m] at the sample instants (after the output filter).

        Raises
        ------
        ModelError
            The simulation left the finite numbers.
        """
        ref = as_array("r", r, ndim=1, min_size=2)
        y0 = as_float("y0", y0, unit="m")
        p = self.params
        n_steps = round(self.dt / self.dt_int)
        cells = _cells_per_sample(n_steps, ref.size)
        h_cell = self.dt / cells
        past = p.K_fb / p.reference_gain * float(y0)
        fine = cell_averages(ref, cells, self.intersample, p.T_d / self.dt, past)
        x0 = np.zeros(8)
        x0[6] = float(y0)
        res = simulate_ehsa(p.with_(T_d=0.0), fine, h_cell, dt_int=self.dt_int, x0=x0,
                            y_r_past=past)
        y = res.y
        if self.output_filter is not None:
            y = _filter(self.output_filter, y, h_cell, float(y0))
        out = np.array(y[::cells], dtype=np.float64)
        if not np.all(np.isfinite(out)):
            raise ModelError("the nonlinear EHSA simulation left the finite numbers")
        return out

    def internals(self, r: ArrayLike, *, y0: float = 0.0) -> dict[str, NDArray[np.float64]]:
        """Return the simulator's internal signals at the sample instants.

        Parameters
        ----------
        r : array_like, shape (N,)
            Reference samples [m].
        y0 : float
            Position at rest before the record [m].

        Returns
        -------
        dict of str to ndarray
            ``y``, ``y_dot``, ``P_L``, ``x_s``, ``x_f`` (before any output
            filter), for physical checks of what the record excites.
        """
        ref = as_array("r", r, ndim=1, min_size=2)
        y0 = as_float("y0", y0, unit="m")
        p = self.params
        n_steps = round(self.dt / self.dt_int)
        cells = _cells_per_sample(n_steps, ref.size)
        past = p.K_fb / p.reference_gain * float(y0)
        fine = cell_averages(ref, cells, self.intersample, p.T_d / self.dt, past)
        x0 = np.zeros(8)
        x0[6] = float(y0)
        res = simulate_ehsa(p.with_(T_d=0.0), fine, self.dt / cells, dt_int=self.dt_int,
                            x0=x0, y_r_past=past)
        return {name: np.array(getattr(res, name), dtype=np.float64)
                for name in ("y", "y_dot", "P_L", "x_s", "x_f")}


def physical_parameters(base: EhsaParameters, values: Mapping[str, float]) -> EhsaParameters:
    """Return `base` with refinable parameters set by name.

    Parameters
    ----------
    base : EhsaParameters
        The parameters not named keep their values; its supply and
        return pressures are the ones the flow gain is evaluated at.
    values : mapping of str to float
        Values of names in :data:`NONLINEAR_PARAMETERS`.  K, omega_hp and delta_hp
        are realised through w, M_t and B_p (module notes), the others
        not named keep those of `base`; F_c moves F_s in proportion.
        delta_hp scales K_ce and B_p by one factor.

    Returns
    -------
    EhsaParameters
        The validated set.

    Raises
    ------
    ModelError
        The values give no valid physical set (e.g. δ_hp <= 0, or
        ``u_0 >= x_s_max``).
    """
    unknown = sorted(set(values) - set(NONLINEAR_PARAMETERS))
    if unknown:
        raise ModelError(f"cannot set {', '.join(unknown)}; refinable: "
                         f"{', '.join(NONLINEAR_PARAMETERS)}")
    k0, w0, d0 = reduced_parameters(base)
    k = float(values.get("K", k0))
    w = float(values.get("omega_hp", w0))
    d = float(values.get("delta_hp", d0))
    p = base
    changes: dict[str, float] = {}
    if "K" in values:
        changes["w"] = k * p.A_p / (p.K_s2 * p.C_d * math.sqrt((p.P_s - p.P_T) / p.rho))
    if "omega_hp" in values or "delta_hp" in values:
        if not (w > 0 and d > 0):
            raise ModelError(f"omega_hp and delta_hp must be > 0, got {w:.6g} rad/s, {d:.6g}")
        m_t = 4.0 * p.beta_e * p.A_p**2 / (p.V_t * w * w)
        leak = (p.K_ce / p.A_p) * math.sqrt(p.beta_e * m_t / p.V_t)
        visc = (p.B_p / (4.0 * p.A_p)) * math.sqrt(p.V_t / (p.beta_e * m_t))
        if not leak + visc > 0:
            raise ModelError("K_ce = B_p = 0: nothing damps the piston, so delta_hp has no "
                             "physical parameter to set; give the nominal set a leakage or a "
                             "viscous friction")
        scale = d / (leak + visc)
        changes.update(M_t=m_t, K_ce=p.K_ce * scale, B_p=p.B_p * scale)
    if "F_c" in values:
        ratio = p.F_s / p.F_c if p.F_c > 0 else 1.0
        changes["F_c"] = float(values["F_c"])
        changes["F_s"] = float(values["F_c"]) * ratio
    for name in ("v_s_max", "x_s_max", "x_f_max", "T_d", "u_0"):
        if name in values:
            changes[name] = float(values[name])
    return p.with_(**changes)


def reduced_parameters(params: EhsaParameters) -> tuple[float, float, float]:
    """Return (K [1/s], ω_hp [rad/s], δ_hp [-]) of a physical set.

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters.

    Returns
    -------
    tuple of float
        ``K = K_s2·K_qs/A_p``, ``ω_hp``, ``δ_hp`` (models-spec §1.1).
    """
    return float(params.K), float(params.omega_hp), float(params.delta_hp)


def fastest_mode(params: EhsaParameters) -> float:
    """Return the fastest linear mode of `params` [rad/s]."""
    return max(params.omega_f, params.omega_sp, params.omega_s1, params.omega_hp,
               params.B_p / params.M_t)


def check_output_filter(g: object) -> None:
    """Raise unless `g` is None or a continuous, stable, unit-gain filter."""
    if g is None:
        return
    if not isinstance(g, TransferFunction):
        raise type_error("output_filter", g, "a continuous TransferFunction or None")
    if g.dt is not None:
        raise ModelError(f"output_filter must be continuous (the analog filter of the "
                         f"transducer chain), got a discrete one with dt = {g.dt} s")
    poles = g.poles()
    if poles.size and not np.all(poles.real < 0):
        raise ModelError("output_filter must be stable (all poles in the left half-plane)")
    gain = g.dc_gain()
    if not math.isclose(gain, 1.0, rel_tol=1e-6):
        raise ModelError(f"output_filter must have static gain 1 (a filter, not a "
                         f"calibration), got {gain:.6g}; calibrate the channel instead")


def cell_averages(
    r: NDArray[np.float64], cells: int, intersample: str, shift: float, past: float,
) -> NDArray[np.float64]:
    """Average the delayed continuous reference over each fine cell.

    The continuous reference is ``r_c(t)`` (samples held or linearly
    interpolated, ``past`` before t = 0, the last sample held after the
    record); cell j of sample k covers ``[(k + j/cells)·dt, … + dt/cells)``
    and gets ``(cells/dt)·∫ r_c(t − shift·dt) dt`` over it.  Computed from
    the antiderivative, so it is exact and continuous in `shift`.

    Parameters
    ----------
    r : ndarray, shape (N,)
        Reference samples.
    cells : int
        Cells per sample period.
    intersample : {"zoh", "foh"}
        Hold between samples.
    shift : float
        Delay in sample periods, >= 0.
    past : float
        Reference before the first sample.

    Returns
    -------
    ndarray, shape (N·cells,)
        Cell averages.
    """
    n = r.size
    base = r - past  # antiderivative of a zero-mean-ish signal: no growing offset
    if intersample == "zoh":
        seg = base  # ∫ over sample k = base[k]
    else:
        nxt = np.append(base[1:], base[-1])
        seg = 0.5 * (base + nxt)
    knots = np.concatenate([[0.0], np.cumsum(seg)])  # R(k), time in samples
    edges = np.arange(n * cells + 1, dtype=np.float64) / cells - shift
    k = np.clip(np.floor(edges).astype(np.int64), 0, n - 1)
    s = edges - k  # position inside sample k (may exceed 1 past the end: held)
    if intersample == "zoh":
        val = knots[k] + s * base[k]
    else:
        nxt = np.append(base[1:], base[-1])
        s1 = np.minimum(s, 1.0)
        val = knots[k] + s1 * base[k] + 0.5 * s1 * s1 * (nxt[k] - base[k])
        val += np.maximum(s - 1.0, 0.0) * base[-1]  # beyond the last sample: held
    val = np.where(edges < 0.0, 0.0, val)  # before the record: r_c − past = 0
    return np.diff(val) * cells + past


# -- private helpers ---------------------------------------------------------


def _cells_per_sample(n_steps: int, n_samples: int) -> int:
    """Largest divisor of the RK4 steps per sample that fits the cell budget."""
    limit = max(1, _MAX_CELLS // max(n_samples, 1))
    best = 1
    for d in range(1, math.isqrt(n_steps) + 1):
        if n_steps % d == 0:
            for c in (d, n_steps // d):
                if best < c <= limit:
                    best = c
    return best


def _filter(g: TransferFunction, y: NDArray[np.float64], h: float,
            y0: float) -> NDArray[np.float64]:
    """Apply a continuous filter to a smooth signal on a grid of step h.

    First-order hold (the position is smooth), started in steady state
    at `y0`; a delay of the filter shifts the result by linear
    interpolation.
    """
    num, den, _ = sps.cont2discrete((g.num, g.den), h, method="foh")
    b = np.ravel(num)
    zi = sps.lfilter_zi(b, den) * y0
    out, _ = sps.lfilter(b, den, y, zi=zi)
    if g.delay > 0.0:
        t = np.arange(y.size) * h - g.delay
        out = np.interp(t, np.arange(y.size) * h, out, left=y0)
    return np.asarray(out, dtype=np.float64)
