"""Steps S0 (ẋ_krit), S4 (d_k, c_k) and S5 (F_haft): piston friction.

The piston equation of [S2] (models-spec §2) with the applied force
``F_p = p_I A_I − p_II A_II − p_amb(A_I − A_II) − m_k g + F_ext``::

    (4.1) |ẋ_k| ≥ ẋ_krit:      m_k ẍ_k = F_p − sgn(ẋ_k)(d_k + c_k|ẋ_k|)
    (4.2) ε < |ẋ_k| < ẋ_krit:  m_k ẍ_k = F_p − sgn(ẋ_k)·F_haft

(optionally the blended (4.2) of :func:`~servoid.plants.three_regime_friction`,
where F_haft fades linearly into d_k + c_k·ẋ_krit, so c_k and d_k enter).

* **S0 ẋ_krit** — the friction–velocity map F_fr = F_p − m_k ẍ_k against
  |ẋ_k|.  For each threshold the map is fitted by a constant below it
  and d + c|ẋ| above it; the threshold with the smallest residual sum
  is found *exactly* among all gaps between sorted sample speeds (cumulative
  sums, O(N log N)), the documented alternative to a grid.  The residual
  sum is a step function of the threshold, so there is no curvature for
  a variance: the std is a moving-block bootstrap (the map's samples in
  time order, resampled in 20 ms blocks, the search repeated).  The
  optimal gap's width/√12, a resolution, is 10× smaller and kept only as
  ``options["resolution_std"]``.
* **S4** — (4.1) over the samples with |ẋ_k| ≥ ẋ_krit:
  ``y = m_k ẍ_k − F_p``, ``φ = [−sgn ẋ_k, −ẋ_k]`` → (d_k, c_k), by
  instrumental variables (default; ``estimator="ls"`` for LS).  The
  measured ẋ_k in φ is noisy, which attenuates c_k under LS (−2.5σ, d_k
  +2.3σ at 25 dB on the virtual rig).  A row's instruments are φ 2 ms
  before and after it, averaged, and its regime is read from those two
  samples (both sliding, same sign), not from its own noisy speed: a row
  chosen by its own |ẋ_k| ≥ ẋ_krit carries noise of one sign near the
  threshold.
* **S5** — LS on (4.2) over ε < |ẋ_k| < ẋ_krit with c_k, d_k inserted.

Derivatives.  ``"measured"`` takes ẋ_k, ẍ_k from the ``v_k``, ``a_k``
channels, sample by sample; a sample counts as moving above max(ε, 4σ_v), σ_v the
velocity noise from second differences, so a stuck piston's noisy velocity does
not enter (4.2), and only samples at least ``guard`` (0.5 ms) away from a change
of regime are used: the sensors and the rig's anti-alias filter smear the
friction jump at a change (85 → 67 N at ẋ_krit) over a few samples, which
biased c_k by −2 % on the virtual rig; 0.5 ms covers a 2 kHz anti-alias
filter.  ``"svf"`` filters x_k and every term of the
equation by one zero-phase state-variable filter G = F(−s)F(s) (no lag),
so ``m_k s²G x_k − G F_p = −G[friction]`` holds exactly; the regime of
each sample comes from the filtered velocity sG x_k, and only samples
whose whole filter window (±6/ω_f, ω_f = 2π·400 rad/s by default) lies in the regimes of the regression
are used, where ``G[sgn ẋ·σ]`` is the friction regressor.  The price is
fewer usable samples and a regime classification from a smoothed
velocity; the gain is that no differentiated noise enters.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_array, as_bool, as_float, as_float_list, as_int, type_error
from ..._errors import DataError, IdentifiabilityError, check_option
from ...data import Experiment
from ...estimate import Estimate, lstsq
from ._step_thermo import zero_phase_derivatives
from ._steps import (
    Derivatives,
    KnownConstants,
    StepResult,
    channel,
    check_derivatives,
    check_known,
    check_positive,
    check_record,
    hac_covariance,
    ls_estimate,
    newey_west_lags,
    pressures,
    propagate,
    window_all,
)

__all__ = [
    "identify_critical_velocity",
    "identify_low_speed_friction",
    "identify_sliding_friction",
]

_EQ_S0 = ("friction–velocity map F_fr = F_p − m_k ẍ_k against |ẋ_k|: constant below the "
          "threshold, d + c|ẋ_k| above; exact search of the threshold over all gaps between "
          "sorted sample speeds (least residual sum)")
_EQ_S4 = ("(4.1) m_k ẍ_k = F_p − sgn(ẋ_k)(d_k + c_k|ẋ_k|) on |ẋ_k| ≥ ẋ_krit: IV regression "
          "of y = m_k ẍ_k − F_p on φ = [−sgn ẋ_k, −ẋ_k] (instruments: φ ±2 ms away) → d_k, c_k")
_EQ_S5 = ("(4.2) m_k ẍ_k = F_p − sgn(ẋ_k)·F_haft on ε < |ẋ_k| < ẋ_krit with c_k, d_k "
          "inserted: LS of y = m_k ẍ_k − F_p on φ = −sgn ẋ_k → F_haft")


@dataclass(frozen=True)
class _Signals:
    """Velocity, the equation's left side y = m ẍ − F_p, and its filter."""

    v: NDArray[np.float64]
    y: NDArray[np.float64]
    valid: NDArray[np.bool_]
    half_window: int  # 0 for measured derivatives
    dt: float
    omega_f: float
    floor: float  # lowest speed counted as moving: ε, or 4σ of the velocity noise
    guard: int  # measured derivatives: samples kept clear of a regime change on each side

    def filt(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Apply the equation's filter to a regressor signal."""
        if self.half_window == 0:
            return s
        return zero_phase_derivatives(s, self.dt, self.omega_f)[0]

    def whole_window(self, mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Samples whose filter window (or guard band) lies entirely in ``mask``."""
        h = self.half_window if self.half_window else self.guard
        if h == 0:
            return mask & self.valid
        full = window_all(mask, 2 * h + 1)  # True at i when mask[i−2h..i] all hold
        out = np.zeros_like(mask)
        out[:-h] = full[h:]
        return out & self.valid


def identify_critical_velocity(
    record: Experiment,
    known: KnownConstants,
    *,
    derivatives: Derivatives = "measured",
    bounds: tuple[float, float] = (0.01, 0.5),
    omega_f: float = 2 * math.pi * 400.0,
    guard: float = 5e-4,
    min_samples: int = 20,
    n_boot: int = 100,
    block: float = 0.02,
    rng: np.random.Generator | int | None = None,
    name: str = "friction",
) -> StepResult:
    """Find the friction threshold ẋ_krit from the F_fr–ẋ_k map (S0).

    Parameters
    ----------
    record : Experiment
        Friction test with ``x_k`` [m], ``p_I``, ``p_II`` [Pa], optional
        ``f_ext`` [N], and ``v_k`` [m/s], ``a_k`` [m/s²] for
        ``derivatives="measured"``.
    known : KnownConstants
        Areas, m_k, p_amb, g and the stick band ε.
    derivatives : {"measured", "svf"}
        Recorded velocity/acceleration, or the zero-phase SVF of x_k.
    bounds : (float, float)
        Search interval of the threshold [m/s].
    omega_f : float
        Zero-phase filter bandwidth for ``"svf"`` [rad/s].
    guard : float
        With measured derivatives: samples closer than this to a change of
        regime are left out [s] (module notes).
    min_samples : int
        Fewest samples on each side of the threshold.
    n_boot : int
        Bootstrap resamples for the std (module notes).
    block : float
        Length of the bootstrap's blocks [s]; longer than the noise's
        correlation (the anti-alias filter's few samples).
    rng : numpy.random.Generator or int, optional
        Source of the bootstrap's draws, or a seed; None: seed 0, so a
        result is reproducible.
    name : str
        Record name for the result.

    Returns
    -------
    StepResult
        ``v_krit`` [m/s] with its bootstrap std (module notes).

    Raises
    ------
    IdentifiabilityError
        Too few samples on one side of every candidate threshold.
    """
    known = check_known(known)
    lo, hi = as_float_list("bounds", bounds, length=2)
    if not 0.0 <= lo < hi:
        raise DataError(f"bounds must be (low, high) with 0 <= low < high [m/s], got "
                        f"({lo:g}, {hi:g})")
    min_samples = as_int("min_samples", min_samples, minimum=1)
    n_boot = as_int("n_boot", n_boot, minimum=2)
    block = check_positive("block", block, "s")
    if not (rng is None or isinstance(rng, (np.random.Generator, int, np.integer))) or (
            isinstance(rng, bool)):
        raise type_error("rng", rng, "a numpy.random.Generator, an integer seed or None")
    if isinstance(rng, (int, np.integer)) and rng < 0:
        raise DataError(f"rng as a seed must be >= 0, got {rng}")
    sig = _signals(record, known, derivatives, omega_f, guard, "S0 (ẋ_krit)")
    # with filtered derivatives a window touching a stuck sample smears the static force
    # into the map: keep whole windows of motion only
    use = sig.whole_window(np.abs(sig.v) > sig.floor)
    speed = np.abs(sig.v[use])
    force = -sig.y[use] * np.sign(sig.v[use])  # friction along the motion
    best = _best_split(speed, force, lo, hi, min_samples)
    if best is None:
        s = np.sort(speed)
        raise IdentifiabilityError(
            f"S0 (ẋ_krit): no threshold in [{lo:g}, {hi:g}] m/s has {min_samples} moving samples "
            f"on both sides (speeds span {s.min() if s.size else 0:.3g}–"
            f"{s.max() if s.size else 0:.3g} m/s); the friction test must pass through low and "
            "high speeds"
        )
    value, gap, rss_best, s, f = best
    # the RSS is a step function of the threshold (no curvature for a variance): moving-block
    # bootstrap over the map's samples in time order, blocks longer than the noise's colour
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(
        0 if rng is None else int(rng))
    width = max(1, min(speed.size, round(block / record.dt)))
    boot = []
    for _ in range(n_boot):
        starts = gen.integers(0, speed.size - width + 1, math.ceil(speed.size / width))
        idx = (starts[:, None] + np.arange(width)).ravel()[:speed.size]
        again = _best_split(speed[idx], force[idx], lo, hi, min_samples)
        if again is not None:
            boot.append(again[0])
    if len(boot) < 2:
        raise IdentifiabilityError("S0 (ẋ_krit): the bootstrap resamples find no threshold; "
                                   "the map is too sparse near ẋ_krit")
    var = float(np.var(boot, ddof=1))
    est = Estimate(
        model=None, parameters=np.array([value]), names=("v_krit",),
        covariance=np.array([[var]]), noise_variance=rss_best / max(s.size - 4, 1),
        n_samples=int(s.size), method="threshold_search", units=("m/s",),
        options={"gap": gap, "bounds": [lo, hi], "n_boot": n_boot, "block": width,
                 "resolution_std": (gap[1] - gap[0]) / math.sqrt(12.0),
                 "std": f"moving-block bootstrap ({n_boot} resamples, blocks of {width} "
                        "samples) of the threshold search"},
    )
    stride = max(1, s.size // 2000)
    mask = np.zeros(record.n_samples, dtype=bool)
    mask[np.flatnonzero(use)] = True
    return StepResult(
        step="S0 ẋ_krit", title="friction threshold ẋ_krit", equation=_EQ_S0, record=name,
        estimate=est, mask=mask, method="threshold_search",
        extra={"map_speed": s[::stride], "map_force": f[::stride],
               "derivatives": derivatives},
    )


def identify_sliding_friction(
    record: Experiment,
    known: KnownConstants,
    *,
    v_krit: float,
    v_krit_std: float = 0.0,
    derivatives: Derivatives = "measured",
    omega_f: float = 2 * math.pi * 400.0,
    guard: float = 5e-4,
    name: str = "friction",
    estimator: str = "iv",
    iv_delay: float = 2e-3,
) -> StepResult:
    """Identify Coulomb d_k and viscous c_k friction (step S4).

    Parameters
    ----------
    record : Experiment
        Friction test (see :func:`identify_critical_velocity`).
    known : KnownConstants
        Areas, m_k, p_amb, g.
    v_krit : float
        Threshold ẋ_krit from S0 [m/s].
    v_krit_std : float
        Its std, propagated into the covariance (delta method, secant
        over ±σ: the rows change with the threshold).
    derivatives : {"measured", "svf"}
        Recorded ẋ_k, ẍ_k, or the zero-phase SVF of x_k (module notes).
    omega_f : float
        Zero-phase filter bandwidth for ``"svf"`` [rad/s].
    guard : float
        With measured derivatives: samples closer than this to a change of
        regime are left out [s] (module notes).
    name : str
        Record name for the result.
    estimator : {"iv", "ls"}
        "iv" (default): instrumental variables, the regressors `iv_delay`
        before and after each row (averaged) as instruments: the measured
        velocity's noise in the regressor ẋ_k attenuates c_k and raises
        d_k under LS (−2σ, +2σ at 30 dB on the virtual rig); "ls": least
        squares.
    iv_delay : float
        Delay of the instruments [s], beyond the velocity noise's
        correlation (and, with "svf", twice the filter's half window, which
        is used if longer); default 2 ms.

    Returns
    -------
    StepResult
        ``d_k`` [N] and ``c_k`` [N·s/m]; covariance LS (or IV) robust to
        coloured residuals (Newey–West) plus the propagated v_krit std.
    """
    known = check_known(known)
    v_krit = check_positive("v_krit", v_krit, "m/s")
    v_krit_std = _check_std("v_krit_std", v_krit_std)
    check_option("estimator", estimator, ("iv", "ls"))
    sig = _signals(record, known, derivatives, omega_f, guard, "S4 (sliding friction)")
    delay = max(round(check_positive("iv_delay", iv_delay, "s") / sig.dt),
                2 * sig.half_window + 1)
    use_iv = estimator == "iv"

    def fit(threshold: float) -> tuple[Any, NDArray[np.bool_], NDArray[np.float64],
                                       NDArray[np.float64] | None]:
        sliding = np.abs(sig.v) >= threshold
        if use_iv:
            # a row's regime is read from the instruments' samples (sliding, same sign, at
            # t ± delay), not from its own noisy velocity: a row chosen by |ẋ(t)| >= ẋ_krit
            # carries noise of one sign near the threshold, which biases even the IV
            sgn = np.sign(sig.v)
            both = np.zeros_like(sliding)
            both[delay:-delay] = (sliding[:-2 * delay] & sliding[2 * delay:]
                                  & (sgn[:-2 * delay] == sgn[2 * delay:]))
            rows = sig.whole_window(both)
            rows[:delay] = False
            rows[rows.size - delay:] = False
            full = np.column_stack([-sig.filt(sgn), -sig.filt(sig.v)])
        else:
            rows = sig.whole_window(sliding)
            full = np.column_stack([-sig.filt(np.sign(sig.v) * sliding),
                                    -sig.filt(sig.v * sliding)])
        phi = full[rows]
        _enough(rows, "S4 (sliding friction)", f"|ẋ_k| >= ẋ_krit = {threshold:g} m/s")
        res = lstsq(phi, sig.y[rows], ("d_k", "c_k"))
        ls_theta[:] = [float(v) for v in res.theta]
        if not use_iv:
            return res, rows, phi, None
        idx = np.flatnonzero(rows)
        z = 0.5 * (full[idx - delay] + full[idx + delay])
        theta = np.linalg.solve(z.T @ phi, z.T @ sig.y[rows])
        rss = float(np.sum((sig.y[rows] - phi @ theta) ** 2))
        return dataclasses.replace(res, theta=theta, rss=rss), rows, phi, z

    ls_theta: list[float] = []
    res, rows, phi, z = fit(v_krit)
    ls_values = dict(zip(("d_k", "c_k"), ls_theta, strict=True))
    # residuals coloured by the anti-alias filter (and the SVF): Newey–West
    lags = max(sig.half_window, newey_west_lags(res.n_rows))
    resid = sig.y[rows] - phi @ res.theta
    cov = hac_covariance([(phi, resid, np.flatnonzero(rows)) if z is None else
                          (phi, resid, np.flatnonzero(rows), z)], lags)
    # ẋ_krit (S0) selects the rows: secant over ±σ (the fit is a step function of it)
    h = min(v_krit_std, 0.5 * v_krit)
    cov, grads = propagate(cov, lambda _, d: fit(v_krit + d)[0].theta, [(v_krit_std, h)])
    est = dataclasses.replace(
        ls_estimate(res, ("d_k", "c_k"), ("N", "N·s/m"), "ls",
                    {"v_krit": v_krit, "v_krit_std": v_krit_std, "derivatives": derivatives,
                     "hac_lags": lags, "white_std": [float(v) for v in res.std],
                     "d_dv_krit": grads[0].tolist(), "estimator": estimator,
                     "ls_values": ls_values,
                     "iv_delay_samples": delay if use_iv else 0,
                     "covariance": f"{'IV' if use_iv else 'LS'}, Newey–West; v_krit std "
                                   "propagated (delta method)"}),
        covariance=cov)
    return StepResult(
        step="S4", title="sliding friction d_k, c_k", equation=_EQ_S4, record=name,
        estimate=est, mask=rows, method="iv" if use_iv else "ls",
        extra={"derivatives": derivatives},
    )


def identify_low_speed_friction(
    record: Experiment,
    known: KnownConstants,
    *,
    v_krit: float,
    d_k: float,
    c_k: float,
    v_krit_std: float = 0.0,
    sliding_covariance: NDArray[np.float64] | None = None,
    derivatives: Derivatives = "measured",
    blend: bool = False,
    omega_f: float = 2 * math.pi * 400.0,
    guard: float = 5e-4,
    name: str = "friction",
) -> StepResult:
    """Identify the static friction F_haft (step S5).

    Parameters
    ----------
    record : Experiment
        Friction test (rectangular input) as for S0.
    known : KnownConstants
        Areas, m_k, p_amb, g and the stick band ε.
    v_krit : float
        Threshold ẋ_krit from S0 [m/s].
    d_k : float
        Coulomb friction from S4 [N].
    c_k : float
        Viscous friction from S4 [N·s/m].
    v_krit_std : float
        Std of ẋ_krit, propagated (delta method, secant over ±σ).
    sliding_covariance : ndarray, shape (2, 2), optional
        Covariance of (d_k, c_k) from S4, propagated likewise.
    derivatives : {"measured", "svf"}
        Recorded ẋ_k, ẍ_k, or the zero-phase SVF of x_k.
    blend : bool
        The blended (4.2): friction fades linearly from F_haft at ε to
        d_k + c_k ẋ_krit at ẋ_krit (then c_k and d_k enter the regression).
    omega_f : float
        Zero-phase filter bandwidth for ``"svf"`` [rad/s].
    guard : float
        With measured derivatives: samples closer than this to a change of
        regime are left out [s] (module notes).
    name : str
        Record name for the result.

    Returns
    -------
    StepResult
        ``F_haft`` [N]; covariance LS robust to coloured residuals
        (Newey–West) plus the propagated inserted values.
    """
    known = check_known(known)
    v_krit = check_positive("v_krit", v_krit, "m/s")
    v_krit_std = _check_std("v_krit_std", v_krit_std)
    d_k = as_float("d_k", d_k, unit="N")
    c_k = as_float("c_k", c_k, unit="N·s/m")
    blend = as_bool("blend", blend)
    dc_cov = np.zeros((2, 2)) if sliding_covariance is None else as_array(
        "sliding_covariance", sliding_covariance, finite=False)
    if dc_cov.shape != (2, 2) or not np.all(np.isfinite(dc_cov)):
        raise DataError(f"sliding_covariance must be a finite 2×2 covariance of (d_k, c_k), "
                        f"got shape {dc_cov.shape}")
    sig = _signals(record, known, derivatives, omega_f, guard, "S5 (low-speed friction)")
    eps = sig.floor
    if v_krit <= eps:
        raise DataError(f"v_krit must be > the moving-speed floor {eps:g} m/s (ε or 4σ of the "
                        f"velocity noise), got {v_krit:g} m/s")
    speed = np.abs(sig.v)
    sgn = np.sign(sig.v)

    def fit(vk: float, dk: float, ck: float) -> tuple[Any, NDArray[np.bool_],
                                                      NDArray[np.float64], NDArray[np.float64]]:
        sliding = speed >= vk
        low = (speed > eps) & ~sliding
        w = np.clip((speed - eps) / (vk - eps), 0.0, 1.0) if blend else np.zeros_like(speed)
        known_part = sgn * sliding * (dk + ck * speed) + sgn * low * w * (dk + ck * vk)
        y = sig.y + sig.filt(known_part)
        reg = -sig.filt(sgn * low * (1.0 - w))
        if sig.half_window == 0:
            rows = sig.whole_window(low)
        else:
            rows = sig.whole_window(speed > eps) & (np.abs(reg) > 0.2)
        _enough(rows, "S5 (low-speed friction)",
                f"ε = {eps:g} < |ẋ_k| < ẋ_krit = {vk:g} m/s")
        return lstsq(reg[rows, None], y[rows], ("F_haft",)), rows, reg[rows, None], y[rows]

    res, rows, phi, y_rows = fit(v_krit, d_k, c_k)
    lags = max(sig.half_window, newey_west_lags(res.n_rows))
    cov = hac_covariance([(phi, y_rows - phi @ res.theta, np.flatnonzero(rows))], lags)
    # inserted ẋ_krit (secant over ±σ: it selects the rows) and (d_k, c_k) with their
    # joint covariance from S4 (delta method)
    base = np.array([v_krit, d_k, c_k])
    steps = [min(v_krit_std, 0.5 * (v_krit - eps)), *np.sqrt(np.diag(dc_cov))]
    grads = np.zeros(3)
    for j, h in enumerate(steps):
        if h > 0.0:
            up, down = base.copy(), base.copy()
            up[j] += h
            down[j] -= h
            grads[j] = (fit(*up)[0].theta[0] - fit(*down)[0].theta[0]) / (2.0 * h)
    inserted = np.zeros((3, 3))
    inserted[0, 0] = v_krit_std**2
    inserted[1:, 1:] = dc_cov
    cov = cov + float(grads @ inserted @ grads)
    est = dataclasses.replace(
        ls_estimate(res, ("F_haft",), ("N",), "ls",
                    {"v_krit": v_krit, "d_k": d_k, "c_k": c_k, "blend": bool(blend),
                     "derivatives": derivatives, "hac_lags": lags,
                     "white_std": [float(v) for v in res.std],
                     "d_dinserted": dict(zip(("v_krit", "d_k", "c_k"), grads.tolist(),
                                             strict=True)),
                     "covariance": "LS, Newey–West; v_krit, d_k, c_k propagated (delta "
                                   "method)"}),
        covariance=np.atleast_2d(cov))
    return StepResult(
        step="S5", title="static friction F_haft", equation=_EQ_S5, record=name,
        estimate=est, mask=rows, method="ls", extra={"derivatives": derivatives,
                                                     "blend": bool(blend)},
    )


# -- helpers --------------------------------------------------------------------------------


def _signals(
    record: Experiment, known: KnownConstants, derivatives: str, omega_f: float,
    guard: float, step: str,
) -> _Signals:
    check_derivatives(derivatives)
    check_record(record, step)
    known = check_known(known)
    guard = as_float("guard", guard, nonneg=True, unit="s")
    n_guard = math.ceil(guard / record.dt - 1e-9)
    p_1, p_2 = pressures(record, step)
    f_ext = np.asarray(record["f_ext"], dtype=float) if "f_ext" in record.names else 0.0
    f_p = (p_1 * known.A_I - p_2 * known.A_II - known.p_amb * (known.A_I - known.A_II)
           - known.m_k * known.g + f_ext)
    valid = np.ones(record.n_samples, dtype=bool)
    if derivatives == "measured":
        v = channel(record, "v_k", step)
        a = channel(record, "a_k", step)
        # a stuck piston's noisy velocity must not count as motion: floor at 4σ of its noise
        floor = max(known.eps_v, 4.0 * _noise_level(v))
        return _Signals(v, known.m_k * a - f_p, valid, 0, record.dt, omega_f, floor, n_guard)
    omega_f = check_positive("omega_f", omega_f, "rad/s")
    x_k = channel(record, "x_k", step)
    _, v, a, margin = zero_phase_derivatives(x_k, record.dt, omega_f)
    g_fp = zero_phase_derivatives(np.asarray(f_p, dtype=float), record.dt, omega_f)[0]
    valid[:margin] = False
    valid[record.n_samples - margin:] = False
    half = math.ceil(6.0 / omega_f / record.dt)
    return _Signals(v, known.m_k * a - g_fp, valid, max(half, 1), record.dt, omega_f,
                    known.eps_v, 0)


def _noise_level(v: NDArray[np.float64]) -> float:
    """Std of the noise on a smooth signal from its second differences (robust).

    White noise gives var(x[k+L] − 2x[k] + x[k−L]) = 6σ² at every lag L.  A
    rig's anti-alias filter colours the noise (at 0.2·f_acq it stays correlated
    over two to three samples), and the lag-1 difference then sees only a third
    of σ (checked on the virtual rig), which let a stuck piston's noisy velocity
    pass the 4σ floor.  From lag 3 on the noise is decorrelated while a smooth
    signal's curvature, growing as L², stays small and sparse; the median over
    lags 1..8 of the MAD estimates is robust to both.
    """
    est = []
    for lag in range(1, 9):
        if v.size <= 2 * lag + 2:
            break
        d2 = v[2 * lag:] - 2.0 * v[lag:-lag] + v[:-2 * lag]
        est.append(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))
    return float(np.median(est)) if est else 0.0


def _best_split(
    speed: NDArray[np.float64], force: NDArray[np.float64], lo: float, hi: float,
    min_samples: int,
) -> tuple[float, list[float], float, NDArray[np.float64], NDArray[np.float64]] | None:
    """Threshold of least RSS: (value, gap, rss, sorted speeds, forces), None if none."""
    order = np.argsort(speed, kind="stable")
    s, f = speed[order], force[order]
    if s.size < 2:
        return None
    rss = _split_rss(s, f)
    k = np.arange(1, s.size)  # split between s[k−1] and s[k]: k samples below
    thr = 0.5 * (s[k - 1] + s[k])
    ok = (thr >= lo) & (thr <= hi) & (k >= min_samples) & (s.size - k >= min_samples) & (
        s[k] > s[k - 1])
    if not ok.any():
        return None
    best = int(np.flatnonzero(ok)[np.argmin(rss[ok])])
    gap = [float(s[k[best] - 1]), float(s[k[best]])]
    return float(thr[best]), gap, float(rss[best]), s, f


def _split_rss(s: NDArray[np.float64], f: NDArray[np.float64]) -> NDArray[np.float64]:
    """RSS of (constant below | line above) for every split k = 1..n−1."""
    s = s - s.mean()
    f = f - f.mean()
    n = s.size

    def cums(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([[0.0], np.cumsum(x)])

    c1, cs, css, cf, cff, csf = (cums(x) for x in (np.ones(n), s, s * s, f, f * f, s * f))
    k = np.arange(1, n)
    n_lo = c1[k]
    rss_lo = cff[k] - cf[k] ** 2 / n_lo
    n_hi = n - n_lo
    s1, s2 = cs[n] - cs[k], css[n] - css[k]
    f1, f2, sf = cf[n] - cf[k], cff[n] - cff[k], csf[n] - csf[k]
    det = n_hi * s2 - s1**2
    with np.errstate(divide="ignore", invalid="ignore"):
        explained = (s2 * f1**2 - 2 * s1 * f1 * sf + n_hi * sf**2) / det
        rss_hi = np.where(det > 1e-12 * np.maximum(n_hi * s2, 1e-300), f2 - explained,
                          f2 - f1**2 / n_hi)
    return np.asarray(rss_lo + rss_hi)


def _check_std(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise type_error(name, value, "a real number")
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise DataError(f"{name} must be finite and >= 0, got {v:g}")
    return v


def _enough(rows: NDArray[np.bool_], step: str, what: str) -> None:
    if int(rows.sum()) < 10:
        raise IdentifiabilityError(
            f"{step}: only {int(rows.sum())} samples with {what}; the test must drive the "
            "piston through that speed range"
        )
