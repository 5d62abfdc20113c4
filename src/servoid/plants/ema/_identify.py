"""Physical identification of an EMA from a closed-loop record: :func:`fit_ema`.

Three linear equations in the measured signals, each filtered by the same
state-variable filter ``F(s) = ω_f^n/(s + ω_f)^n`` (filtered derivatives
``s^k F``, :func:`servoid.estimate.state_variable_filter`) after the
drive's digital channels got the rig's anti-alias filter (:mod:`._filters`).
With ``n_t = 2πN/lead``, the nut position ``x_m = θ/n_t`` (encoder), the
load position ``x_L`` (LVDT) and the screw's deflection ``δ = x_m − x_L``:

**Electrical** (needs the voltage command)::

    u = R·i + L·di/dt + K_m·ω                         → R, L, K_m

**Force balance of the drive train** (motor and load summed, so the screw
force cancels; ``ẍ_L = ẍ_m − δ̈``)::

    K_m·n_t·i = M·ẍ_m − m_L·δ̈ + B·ẋ_m − b_L·δ̇ + C·sgn(ẋ_m) + F_0

with ``M = J_m·n_t² + m_L`` the whole inertia at the nut, ``B`` and ``C``
the viscous and Coulomb friction of both sides at the nut and ``F_0`` a
constant load (gravity, a preload).  The left side is the measured current
(its noise is output noise); ``δ̈`` and ``δ̇`` carry the LVDT's noise, so
this equation is solved by instrumental variables with instruments from
the encoder alone (``s⁴F x_m`` for ``δ̈``, ``s³F x_m`` for ``δ̇``), which
the LVDT's noise does not reach.

**Deflection of the screw** (the load's equation divided by ``k_s``)::

    δ = (m_L/k_s)·ẍ_L + (b_L/k_s)·ẋ_L + (F_cL/k_s)·sgn(ẋ_L) + F_0/k_s − (c_s/k_s)·δ̇

The deflection is a load cell of unknown gain ``1/k_s``: it gives the
load-side forces as ratios to ``k_s``.  The scale — the split of ``M``
into motor and load, hence ``k_s`` — comes from the ``m_L·δ̈`` term of the
force balance, i.e. from motion fast enough to deflect the screw
dynamically; a known load mass (``load_mass``) gives it instead.  Then
``k_s = m_L/(m_L/k_s)``, ``b_L``, ``F_cL``, ``c_s`` follow, and the motor
side is what is left of the totals.

Coulomb friction needs the sign of each velocity.  Rows whose filter memory
holds a velocity reversal or slow motion (``|v| < min_speed``, where the
friction is static and ``sgn`` is wrong) are left out, so the sign
columns are constant over every row used and their timing does not
matter; a trajectory with long one-way segments keeps most rows.

The LVDT's noise reaches the motor through the position loop (with load
feedback), so the encoder's instruments are not quite independent of it:
the bias this leaves on ``m_L`` grows with the noise (on the bench, 0.9,
2 and 3 standard deviations at 2.5, 10 and 20 times the nominal noise,
where the deflection equation fits 90, 62 and 38 %).  Instruments from the
reference avoid it but widen the intervals six-fold; instead, when the
deflection equation fits less than ``min_deflection_fit`` (85 %), what rests
on the deflection is reported not identifiable.

Covariance: the joint sandwich of the three equations (:mod:`._regress`,
Newey–West over the filter's memory), with the motor constant's own
uncertainty carried into the force balance; the physical parameters get
theirs by the delta method.  A parameter whose relative standard
deviation exceeds ``max_relative_std`` is reported as *not identifiable
from this record*, with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_float, as_instance, as_int, as_str
from ..._errors import ChannelError, DataError, IdentifiabilityError
from ..._lazy import signal as sps
from ._filters import anti_alias_replica
from ._params import TVC_EMA, EmaParameters
from ._regress import Regression, joint_covariance, solve

__all__ = ["PHYSICAL", "EmaIdentification", "fit_ema"]

#: The physical parameters fit_ema reports: name → (unit, what).
PHYSICAL: Mapping[str, tuple[str, str]] = {
    "K_m": ("N·m/A", "motor constant (torque per current = back-EMF per speed)"),
    "R": ("Ω", "winding resistance"),
    "L": ("H", "winding inductance"),
    "J_total": ("kg·m²", "all inertia at the motor shaft, J_m + m_L/n_t²"),
    "J_m": ("kg·m²", "motor-side inertia (rotor, gear, screw)"),
    "m_L": ("kg", "load mass"),
    "k_s": ("N/m", "axial stiffness of screw, nut, bearings and attachment"),
    "c_s": ("N·s/m", "damping of that compliance"),
    "b_total": ("N·m·s/rad", "viscous friction of both sides at the motor shaft"),
    "b_m": ("N·m·s/rad", "motor-side viscous friction"),
    "b_L": ("N·s/m", "load-side viscous friction"),
    "T_c_total": ("N·m", "Coulomb friction of both sides at the motor shaft"),
    "T_cm": ("N·m", "motor-side Coulomb friction"),
    "F_cL": ("N", "load-side Coulomb friction"),
    "F_0": ("N", "constant load on the actuator (positive against positive motion)"),
}
_ELECTRICAL = ("K_m", "R", "L")
#: Parameters that are offsets, not physical magnitudes: no identifiability verdict.
_OFFSETS = ("F_0",)


@dataclass(frozen=True, eq=False)
class EmaIdentification:
    """An EMA's physical parameters from one record, with covariance.

    Attributes
    ----------
    names : tuple of str
        The parameters (see :data:`PHYSICAL`), in order.
    values : ndarray
        Their estimates [SI].
    covariance : ndarray
        Their covariance.
    identifiable : mapping of str to bool
        False where the record does not determine the parameter (relative
        standard deviation above ``max_relative_std``).
    given : tuple of str
        Parameters taken as known (``motor_constant``, ``load_mass``).
    equations : mapping of str to mapping
        Per equation: its parameters, their values and standard
        deviations, its fit [%] and condition number.
    gear_ratio, lead : float
        The transmission used [-], [m].
    n_rows : int
        Regression rows (per equation).
    kept : float
        Fraction of the record's samples whose rows were usable (not near
        a reversal or slow motion).
    settings : mapping
        The options used.
    notes : tuple of str
        What the reader should know (verdicts, reasons).
    series : mapping
        Per equation: (row times [s], filtered left-hand side, fitted
        right-hand side), for the report's figure.
    """

    names: tuple[str, ...]
    values: NDArray[np.float64]
    covariance: NDArray[np.float64]
    identifiable: Mapping[str, bool]
    given: tuple[str, ...]
    equations: Mapping[str, Mapping[str, Any]]
    gear_ratio: float
    lead: float
    n_rows: int
    kept: float
    settings: Mapping[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    series: Mapping[str, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]] = \
        field(default_factory=dict, repr=False)

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviations."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def __getitem__(self, name: str) -> float:
        try:
            return float(self.values[self.names.index(name)])
        except ValueError:
            raise ChannelError(f"no parameter {name!r}; parameters are "
                               f"{', '.join(self.names)}") from None

    def rows(self, level: float = 0.95) -> list[dict[str, Any]]:
        """Per parameter: value, std, interval (None when not identifiable), unit, verdict."""
        from ..._lazy import stats

        q = float(stats.norm.ppf(0.5 + level / 2))
        out = []
        for name, value, std in zip(self.names, self.values, self.std, strict=True):
            ok = self.identifiable[name]
            out.append({
                "name": name, "value": float(value), "std": float(std),
                "ci_low": float(value - q * std) if ok else None,
                "ci_high": float(value + q * std) if ok else None,
                "unit": PHYSICAL[name][0], "identifiable": ok, "given": name in self.given,
            })
        return out

    def parameters(self, base: EmaParameters = TVC_EMA) -> EmaParameters:
        """The identified actuator as :class:`EmaParameters` (for simulation).

        Parameters the record did not determine, or whose estimate is not
        physical (a negative friction), are taken from ``base``; backlash
        and stroke always are.
        """
        vals = dict(zip(self.names, self.values, strict=True))
        changes: dict[str, float] = {"N": self.gear_ratio, "lead": self.lead}
        for name in ("K_m", "R", "L", "J_m", "b_m", "T_cm", "k_s", "c_s", "m_L", "b_L", "F_cL"):
            value = vals.get(name)
            if value is not None and math.isfinite(value) and value > 0 and (
                    self.identifiable.get(name, False) or name in self.given):
                changes[name] = float(value)
        return base.with_(**changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``results.json``."""
        return {"parameters": self.rows(), "given": list(self.given),
                "equations": {k: dict(v) for k, v in self.equations.items()},
                "gear_ratio": self.gear_ratio, "lead": self.lead, "n_rows": self.n_rows,
                "kept_fraction": self.kept, "settings": dict(self.settings),
                "notes": list(self.notes)}

    def __str__(self) -> str:
        lines = [(f"EMA identification: {self.n_rows} rows per equation, "
                  f"{100 * self.kept:.0f} % of the record usable")]
        for row in self.rows():
            if row["given"]:
                text = "given"
            elif row["identifiable"]:
                text = f"[{row['ci_low']:.6g}, {row['ci_high']:.6g}]"
            else:
                text = "not identifiable from this record"
            lines.append(f"  {row['name']:<10} {row['value']:>12.6g} ± {row['std']:<9.3g} "
                         f"{row['unit']:<10} {text}")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def fit_ema(
    data: Any,
    *,
    gear_ratio: float,
    lead: float,
    current: str = "i_motor",
    voltage: str | None = "u_cmd",
    angle: str = "theta_m",
    position: str = "x_load",
    anti_alias: tuple[int, float] | None = None,
    motor_constant: float | None = None,
    motor_constant_std: float = 0.0,
    load_mass: float | None = None,
    bandwidth: float = 30.0,
    bandwidth_electrical: float = 150.0,
    order: int = 4,
    row_step: int | None = None,
    min_speed: float | None = None,
    max_relative_std: float = 0.25,
    min_deflection_fit: float = 85.0,
) -> EmaIdentification:
    """Identify an EMA's physical parameters from closed-loop data.

    See the module notes for the equations, the rows used and the
    covariance.

    Parameters
    ----------
    data : Experiment
        The record, calibrated: motor current [A], voltage command [V]
        (optional), encoder angle [rad] and load position [m], sampled
        together (the drive's rate).
    gear_ratio : float
        Motor turns per screw turn [-] (the drawing's value).
    lead : float
        Screw lead [m].
    current, voltage, angle, position : str
        The channels; ``voltage=None`` when the record has none (then
        ``motor_constant`` is needed).
    anti_alias : (int, float), optional
        The rig's analog anti-alias filter on the current and the LVDT:
        Butterworth order and cutoff [Hz]; the voltage and the angle get
        its replica.  None: no such filter (or the same on every channel).
    motor_constant : float, optional
        Known K_m [N·m/A]; default: identified from the electrical
        equation.
    motor_constant_std : float
        Its standard deviation [N·m/A], carried into the mechanics.
    load_mass : float, optional
        Known load mass [kg]; default: identified from the screw's
        dynamic deflection.
    bandwidth : float
        State-variable filter bandwidth of the mechanical equations [Hz]:
        below the screw's anti-resonance, where the LVDT's noise is low.
    bandwidth_electrical : float
        Bandwidth of the electrical equation's filter [Hz].
    order : int
        Filter order (>= 4: the force balance's instruments use s⁴F).
    row_step : int, optional
        Use every ``row_step``-th sample as a row; default about eight
        rows per period of ``bandwidth_electrical``.
    min_speed : float, optional
        Nut speed below which motion counts as slow [m/s]; default 5 % of
        the record's rms speed.
    max_relative_std : float
        Largest relative standard deviation of an identified parameter.
    min_deflection_fit : float
        Least fit [%] of the deflection equation for the parameters that
        rest on the measured deflection (the load side, the split, k_s):
        below it the deflection is too close to the LVDT's noise, whose
        echo through the position loop biases them (module notes).

    Returns
    -------
    EmaIdentification
        Parameters, covariance, verdicts and the equations' details.

    Raises
    ------
    ChannelError
        A channel is missing.
    DataError
        Bad options, or a record too short for the filters.
    IdentifiabilityError
        Too few usable rows (the record reverses too often or hardly
        moves), or regressors the record does not separate.
    """
    from ...data import Experiment
    from ...estimate import state_variable_filter

    exp = as_instance("data", data, Experiment, "a servoid Experiment")
    n_ratio = as_float("gear_ratio", gear_ratio, positive=True)
    lead_m = as_float("lead", lead, positive=True, unit="m")
    if voltage is None and motor_constant is None:
        raise DataError("without a voltage channel the motor constant cannot be identified: "
                        "give motor_constant (its data-sheet value) or the voltage channel")
    k_given = None if motor_constant is None else as_float("motor_constant", motor_constant,
                                                           positive=True, unit="N·m/A")
    k_given_std = as_float("motor_constant_std", motor_constant_std, nonneg=True)
    m_given = None if load_mass is None else as_float("load_mass", load_mass, positive=True,
                                                      unit="kg")
    bw = as_float("bandwidth", bandwidth, positive=True, unit="Hz")
    bw_e = as_float("bandwidth_electrical", bandwidth_electrical, positive=True, unit="Hz")
    order = as_int("order", order, minimum=4, maximum=8)
    mrs = as_float("max_relative_std", max_relative_std, positive=True)
    min_fit = as_float("min_deflection_fit", min_deflection_fit, unit="%")
    dt = exp.dt
    nyq = 0.5 / dt
    for name, value in (("bandwidth", bw), ("bandwidth_electrical", bw_e)):
        if value >= 0.25 * nyq:
            raise DataError(f"{name} = {value:g} Hz must lie below a quarter of the Nyquist "
                            f"frequency ({0.25 * nyq:g} Hz at dt = {dt:g} s)")
    if anti_alias is not None:
        aa_order = as_int("anti_alias order", anti_alias[0], minimum=1, maximum=12)
        aa_cut = as_float("anti_alias cutoff", anti_alias[1], positive=True, unit="Hz")
    signals = {}
    for role, name in (("current", current), ("angle", angle), ("position", position),
                       ("voltage", voltage)):
        if name is None:
            continue
        as_str(role, name)
        signals[role] = np.asarray(exp[name], dtype=float)
    n = exp.n_samples
    nt = 2.0 * math.pi * n_ratio / lead_m
    th = signals["angle"]
    u = signals.get("voltage")
    if anti_alias is not None:
        th_f = anti_alias_replica(th, dt, aa_order, aa_cut, "cubic")
        u_f = None if u is None else anti_alias_replica(u, dt, aa_order, aa_cut, "zoh")
        u_hold = "cubic"
    else:
        th_f, u_f, u_hold = th, u, "zoh"
    i_m, x_l = signals["current"], signals["position"]

    # velocities for the signs and the row mask: zero-phase (Savitzky–Golay) derivatives
    win = max(7, 2 * round(1e-3 / dt) + 1)
    if n < 4 * win:
        raise DataError(f"the record has {n} samples; the identification needs at least "
                        f"{4 * win} (a few ms), and in practice seconds")
    v_m = sps.savgol_filter(th, win, 3, deriv=1, delta=dt) / nt
    v_min = 0.05 * float(np.sqrt(np.mean(v_m**2))) if min_speed is None else as_float(
        "min_speed", min_speed, positive=True, unit="m/s")
    w_f, w_e = 2 * math.pi * bw, 2 * math.pi * bw_e

    def svf(x: NDArray[np.float64], w: float, k: int, hold: str = "cubic") -> NDArray[np.float64]:
        return state_variable_filter(x, dt, w, k, hold=hold, initial="steady").values

    try:
        f_i, f_th, f_x = svf(i_m, w_f, order), svf(th_f, w_f, order), svf(x_l, w_f, order)
        # the load's velocity: the nut's less the screw's deflection rate, which is small and
        # taken from the filtered signals (its lag matters little; the LVDT's noise would)
        v_l = v_m - (f_th[:, 1] / nt - f_x[:, 1])
        s_m, s_l = np.sign(v_m), np.sign(v_l)
        slow = (np.abs(v_m) < v_min) | (np.abs(v_l) < v_min)
        f_sm, f_sl = svf(s_m, w_f, order, "zoh"), svf(s_l, w_f, order, "zoh")
        e_i = e_u = e_th = None
        if u_f is not None:
            e_u, e_i, e_th = svf(u_f, w_e, 2, u_hold), svf(i_m, w_e, 2), svf(th_f, w_e, 2)
    except DataError as exc:
        raise DataError(f"the record is too short for the filters ({exc})") from None
    memory = math.ceil((order + 5) / w_f / dt)
    first = math.ceil((order + 8) / w_f / dt)
    if first >= n:
        raise DataError(f"the record ({n * dt:.3g} s) is shorter than the filter's start-up "
                        f"({first * dt:.3g} s); raise bandwidth or record longer")
    # a row is usable when no slow sample lies within its filter memory or just after it
    # (the Savitzky–Golay window looks ahead)
    bad = np.convolve(slow.astype(float), np.ones(memory + win), "full")[win // 2: win // 2 + n]
    keep = bad == 0
    keep[:first] = False
    step = row_step if row_step is not None else max(1, int(1.0 / (8.0 * bw_e * dt)))
    step = as_int("row_step", step, minimum=1)
    rows = np.flatnonzero(keep)[::step]
    n_params = 16
    if rows.size < 10 * n_params:
        raise IdentifiabilityError(
            f"only {rows.size} usable rows ({100 * keep.mean():.1f} % of the record): the "
            "actuator reverses or moves slowly too often for the friction model (sgn v); "
            "record a trajectory with long one-way segments (e.g. a slow sweep over the "
            "stroke with the excitation on top), or lower min_speed")
    xm = [f_th[rows, k] / nt for k in range(order + 1)]
    xl = [f_x[rows, k] for k in range(order + 1)]
    dl = [a - b for a, b in zip(xm, xl, strict=True)]
    ones = np.ones(rows.size)
    sm, sl = f_sm[rows, 0], f_sl[rows, 0]

    regs: list[Regression] = []
    if e_u is not None:
        assert e_i is not None and e_th is not None
        regs.append(solve("electrical equation", ("R", "L", "K_m"),
                          np.column_stack([e_i[rows, 0], e_i[rows, 1], e_th[rows, 1]]),
                          e_u[rows, 0]))
    k_m = float(regs[0].theta[2]) if k_given is None else k_given
    y_force = nt * f_i[rows, 0]  # × K_m: the force at the nut
    names_a = ["M", "m_L", "B", "b_L(a)", "C", "F_0"]
    phi_a = np.column_stack([xm[2], -dl[2], xm[1], -dl[1], sm, ones])
    z_a = np.column_stack([xm[2], xm[4], xm[1], xm[3], sm, ones])
    if m_given is not None:  # the load's inertia force moves to the left-hand side
        phi_a, z_a = np.delete(phi_a, 1, axis=1), np.delete(z_a, 1, axis=1)
        names_a.remove("m_L")
        y_a = k_m * y_force - m_given * (-dl[2])
    else:
        y_a = k_m * y_force
    reg_a = solve("force balance", names_a, phi_a, y_a, z_a)
    reg_b = solve("deflection equation", ("m_L/k_s", "b_L/k_s", "F_cL/k_s", "F_0/k_s", "c_s/k_s"),
                  np.column_stack([xl[2], xl[1], sl, ones, -dl[1]]), dl[0],
                  np.column_stack([xm[2], xm[1], sl, ones, xm[3]]))
    regs += [reg_a, reg_b]
    lags = math.ceil((order + 2) / (w_f * dt * step))  # the filter's memory in rows
    cov_raw = joint_covariance(regs, lags)
    theta = np.concatenate([r.theta for r in regs])
    # the force balance used K̂_m: its error moves θ_a by g·(K̂_m − K_m)
    a_at = 3 if e_u is not None else 0
    g = np.linalg.solve(reg_a.z.T @ reg_a.phi, reg_a.z.T @ y_force)
    trans = np.eye(theta.size)
    if e_u is not None and k_given is None:
        trans[a_at:a_at + reg_a.theta.size, 2] += g
        cov = trans @ cov_raw @ trans.T
    else:
        cov = cov_raw.copy()
        block = slice(a_at, a_at + reg_a.theta.size)
        cov[block, block] += np.outer(g, g) * k_given_std**2
    b_at = a_at + reg_a.theta.size

    def physical(t: NDArray[np.float64]) -> dict[str, float]:
        out: dict[str, float] = {}
        if e_u is not None:
            out["R"], out["L"] = t[0], t[1]
        out["K_m"] = t[2] if (e_u is not None and k_given is None) else float(k_given or 0.0)
        a = dict(zip(names_a, t[a_at:b_at], strict=True))
        rb = t[b_at:b_at + 5]
        m_l = m_given if m_given is not None else a["m_L"]
        k_s = m_l / rb[0]
        b_l, f_cl = k_s * rb[1], k_s * rb[2]
        out.update({
            "J_total": a["M"] / nt**2, "J_m": (a["M"] - m_l) / nt**2, "m_L": m_l, "k_s": k_s,
            "c_s": k_s * rb[4], "b_total": a["B"] / nt**2, "b_m": (a["B"] - b_l) / nt**2,
            "b_L": b_l, "T_c_total": a["C"] / nt, "T_cm": (a["C"] - f_cl) / nt, "F_cL": f_cl,
            "F_0": a["F_0"]})
        return out

    base = physical(theta)
    names = tuple(p for p in PHYSICAL if p in base)
    values = np.array([base[p] for p in names])
    jac = np.empty((len(names), theta.size))
    for j in range(theta.size):
        h = 1e-6 * max(abs(theta[j]), math.sqrt(cov[j, j]), 1e-300)
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        pu, pd = physical(up), physical(down)
        jac[:, j] = [(pu[p] - pd[p]) / (2 * h) for p in names]
    cov_phys = jac @ cov @ jac.T
    cov_phys = 0.5 * (cov_phys + cov_phys.T)
    std = np.sqrt(np.clip(np.diag(cov_phys), 0.0, None))
    given = tuple(p for p, v in (("K_m", k_given), ("m_L", m_given)) if v is not None)
    verdict = {}
    notes: list[str] = []
    deflection_fit = reg_b.fit_percent
    lost = deflection_fit < min_fit
    on_deflection = {"k_s", "c_s", "b_L", "b_m", "F_cL", "T_cm"}
    if m_given is None:
        on_deflection |= {"m_L", "J_m"}
    for p, v, s in zip(names, values, std, strict=True):
        if p in given or p in _OFFSETS:
            verdict[p] = True
            continue
        rel = s / abs(v) if v != 0 else math.inf
        verdict[p] = bool(rel <= mrs and v > 0) and not (lost and p in on_deflection)
    if lost:
        notes.append(
            f"the screw's deflection is hardly above the LVDT's noise: the deflection equation "
            f"fits {deflection_fit:.1f} %, below min_deflection_fit = {min_fit:g} %. The noise "
            "reaches the motor through the position loop and biases what rests on the "
            f"deflection ({', '.join(p for p in names if p in on_deflection)}): not "
            "identifiable from this record; the totals and the electrical parameters stand")
    if given and "K_m" in given and k_given_std == 0:
        notes.append("K_m is the given motor constant (no uncertainty given for it): the "
                     "mechanical intervals leave its error out")
    if lost:
        pass
    elif not verdict.get("k_s", True) and "m_L" not in given:
        notes.append(
            "k_s and the motor/load split of the inertia are not identifiable from this "
            "record: the screw's dynamic deflection (the m_L·δ̈ term) is lost in the LVDT's "
            "noise. The load-side ratios m_L/k_s, b_L/k_s, F_cL/k_s are still measured; give "
            "the load mass (load_mass) or excite closer to the screw's resonance")
    elif not verdict.get("k_s", True):
        notes.append("k_s is not identifiable from this record: its deflection (δ = m_L·ẍ/k_s) "
                     "is lost in the LVDT's noise — the screw looks rigid at these "
                     "frequencies; use a finer LVDT or faster motion")
    weak = [p for p in names if not verdict[p] and p != "k_s"
            and not (lost and p in on_deflection)]
    if weak:
        notes.append(f"not identifiable from this record (relative std above "
                     f"{max_relative_std:g}): {', '.join(weak)}")
    equations = {}
    for r, (lo, hi) in zip(regs, _blocks(regs), strict=True):
        equations[r.name] = {
            "parameters": list(r.names), "values": [float(v) for v in r.theta],
            "std": [float(np.sqrt(max(cov[k, k], 0.0))) for k in range(lo, hi)],
            "fit_percent": r.fit_percent, "condition": r.condition,
            "method": "least squares" if r.z is r.phi else "instrumental variables"}
    settings = {"bandwidth": bw, "bandwidth_electrical": bw_e, "order": order, "row_step": step,
                "min_speed": v_min, "hac_lags": lags, "max_relative_std": mrs,
                "min_deflection_fit": min_fit,
                "anti_alias": None if anti_alias is None else [aa_order, aa_cut],
                "motor_constant": k_given, "load_mass": m_given}
    times = exp.t0 + rows * dt
    series = {r.name: (times, r.y, r.y - r.residuals) for r in regs}
    return EmaIdentification(
        names=names, values=values, covariance=cov_phys, identifiable=verdict, given=given,
        equations=equations, gear_ratio=n_ratio, lead=lead_m, n_rows=int(rows.size),
        kept=float(keep.mean()), settings=settings, notes=tuple(notes), series=series)


def _blocks(regs: Sequence[Regression]) -> list[tuple[int, int]]:
    out, at = [], 0
    for r in regs:
        out.append((at, at + r.theta.size))
        at += r.theta.size
    return out
