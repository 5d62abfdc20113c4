"""The best linear approximation from M multisine realisations × P periods.

A nonlinear system driven by a random-phase multisine answers on the
excited lines as ``Y = G_BLA·U + Y_S + V``: the best linear approximation
(BLA), the stochastic nonlinear distortion Y_S (zero mean, uncorrelated
with U, different in every realisation, the same in every period of one
realisation) and the noise V (different in every period) — Schoukens,
Pintelon, Dobrowiecki & Rolain, *Automatica* 41, 2005; Pintelon &
Schoukens, *System Identification: A Frequency Domain Approach*, 2nd ed.,
2012, the "robust" method.  Hence, per line:

1. Per realisation m, the spectra averaged over the P periods, Û^[m] and
   Ŷ^[m], with the variances of those averages from the scatter over the
   periods, ``σ̂²_Ŷ = Σ_p |Y^[m,p] − Ŷ^[m]|²/(P(P − 1))`` (and σ̂²_Û, the
   covariance σ̂_ŶÛ).
2. ``Ĝ^[m] = Ŷ^[m]/Û^[m]``, with the noise variance
   ``σ̂²_n^[m] = (σ̂²_Ŷ + |Ĝ^[m]|²·σ̂²_Û − 2·Re(conj(Ĝ^[m])·σ̂_ŶÛ))/|Û^[m]|²``.
3. ``Ĝ_BLA = mean_m Ĝ^[m]``; its total variance from the scatter over
   the realisations, ``σ̂²_BLA = Σ_m |Ĝ^[m] − Ĝ_BLA|²/(M(M − 1))``
   (M − 1 degrees of freedom); its noise variance
   ``σ̂²_BLA,n = Σ_m σ̂²_n^[m]/M²`` (M(P − 1) degrees of freedom); the
   difference is the variance due to the stochastic nonlinear
   distortion, ``σ̂²_BLA,S = σ̂²_BLA − σ̂²_BLA,n``.  One realisation of Y_S
   has M times that variance.

With one realisation this is the periodic FRF with its noise variance.
The lines the design leaves empty carry no linear response: there the
output averaged over periods is nonlinear distortion plus noise of
variance σ̂²_Ŷ.  For an odd design, odd distortion lands on the odd and
even distortion on the even detection lines.

In closed loop the input holds the noise fed back, so Ŷ/Û per
realisation is not consistent at low signal-to-noise ratio; the
reference R is noise-free and periodic, and the plant is the ratio of
the averaged FRFs from it, ``Ĝ = mean_m(Ŷ/R) / mean_m(Û/R)`` (S_yr/S_ur).
Its variance follows from the linearised error
``d^[m] = (Ĝ_yr^[m] − Ĝ·Ĝ_ur^[m])/Ĝ_ur``, whose mean is zero, over the
realisations (total) and from the period scatter of Y and U with their
correlation (noise).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import DataError, OptionTypeError, ServoidWarning
from .._lazy import stats
from .._warn import warn
from ..data import Experiment
from ..estimate import frf_channels as _io_channels
from ..signals import MultisinePlan
from ._measured import DistortionLevels, FrfMeasurement

__all__ = ["estimate_bla"]

# relative tolerance of the record's sample period against a whole multiple of the plan's
_RATE_TOL = 1e-9


def estimate_bla(
    data: Experiment,
    plan: MultisinePlan,
    *,
    input: str = "u",
    output: str | None = None,
    reference: str | None = None,
    start: int = 0,
    f_min: float | None = None,
    f_max: float | None = None,
) -> FrfMeasurement:
    """Best linear approximation with noise and nonlinear variances.

    Parameters
    ----------
    data : Experiment
        The record of the planned test (every realisation, transient
        periods included), at the plan's sample period or an integer
        multiple of it that divides the period.
    plan : MultisinePlan
        The test's plan (:func:`servoid.signals.plan_multisine`, or
        :func:`servoid.signals.read_plan` of the file beside the DAQ file).
    input : str
        Input channel (name or role).
    output : str, optional
        Output channel; default the only ``y`` channel.
    reference : str, optional
        The reference channel of a closed-loop test: the plant is then
        ``mean(Y/R)/mean(U/R)`` (module notes).
    start : int
        Sample of the record where the test's first period begins, >= 0.
    f_min, f_max : float, optional
        Band of excited lines to keep [Hz].

    Returns
    -------
    FrfMeasurement
        The excited lines: ``variance`` total (noise plus stochastic
        nonlinear), ``noise_variance``, ``nonlinear_variance`` (M >= 2
        and P >= 2), ``dof`` M − 1 (P − 1 for one realisation);
        ``distortion`` from the detection lines.

    Raises
    ------
    DataError
        A record too short for one realisation, a sample period that
        does not fit the plan, one realisation of one period (no
        variance).

    Warns
    -----
    ServoidWarning
        The record holds fewer realisations than planned (the complete
        ones are used).

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.data import Experiment
    >>> from servoid.frequency import estimate_bla
    >>> from servoid.signals import plan_multisine, random_multisine
    >>> plan = plan_multisine(0.01, 0.1, 20.0, period=500, lines="odd", realisations=2,
    ...                       periods=2, transient_periods=0)
    >>> u = random_multisine(plan, rng=0).values
    >>> y = 2.0 * u + 0.1 * u**2  # a static curve: BLA 2, even distortion
    >>> frm = estimate_bla(Experiment.from_arrays(0.01, u=u, y=y), plan)
    >>> bool(np.allclose(frm.response, 2.0)), frm.distortion.even_db > -40
    (True, True)
    """
    if not isinstance(data, Experiment):
        raise OptionTypeError(f"data must be an Experiment, got {type(data).__name__}")
    if not isinstance(plan, MultisinePlan):
        raise OptionTypeError(f"plan must be a MultisinePlan, got {type(plan).__name__}")
    first = as_int("start", start, minimum=0)
    u_ch, y_ch, r_ch = _io_channels(data, input, output, reference)
    period = _record_period(plan, data.dt)
    p, p_tr = plan.periods, plan.transient_periods
    span = (p_tr + p) * period
    available = (data.n_samples - first) // span if data.n_samples > first else 0
    m = min(plan.realisations, available)
    if m < 1:
        raise DataError(
            f"the record holds {max(data.n_samples - first, 0)} samples from start = {first}, "
            f"fewer than one realisation of the plan ({p_tr} transient + {p} measured periods "
            f"of {period} samples = {span}); check the plan file and start"
        )
    if m < plan.realisations:
        warn(f"the record holds {m} of the {plan.realisations} planned realisations; the BLA "
             "uses those", ServoidWarning)
    if m == 1 and p == 1:
        raise DataError("one realisation of one period leaves no variance to estimate; plan "
                        "P >= 2 periods or M >= 2 realisations")
    f0 = 1.0 / (period * data.dt)
    excited = np.asarray(plan.excited)
    lo = -np.inf if f_min is None else as_float("f_min", f_min, nonneg=True, unit="Hz")
    hi = np.inf if f_max is None else as_float("f_max", f_max, positive=True, unit="Hz")
    keep = (excited * f0 >= lo) & (excited * f0 <= hi)
    if not np.any(keep):
        raise DataError(f"no excited line of the plan lies in [{lo:g}, {hi:g}] Hz")
    detection = np.asarray(plan.detection, dtype=int)
    want = np.concatenate([excited, detection]).astype(int)
    spectra = {}
    for name, ch in (("u", u_ch), ("y", y_ch), ("r", r_ch)):
        if ch is not None:
            spectra[name] = _spectra(ch.values, first, m, p, p_tr, period, want)
    ne = excited.size
    stats_ = _period_stats(spectra, p)
    if r_ch is None:
        g, total, noise = _open_loop(stats_, ne, m, p)
    else:
        g, total, noise = _closed_loop(stats_, ne, m, p)
    if m >= 2:
        dof = float(m - 1)
        variance = total
    else:
        dof = float(p - 1)
        variance = noise
    noise_dof = float(m * (p - 1)) if p >= 2 else dof
    if p < 2:
        noise = variance
    nonlinear = np.maximum(total - noise, 0.0) if (m >= 2 and p >= 2) else None
    distortion = _distortion(stats_, ne, plan, m, p, period) if detection.size else None
    sel = np.flatnonzero(keep)
    return FrfMeasurement(
        frequency=excited[sel] * f0, response=g[sel], variance=variance[sel],
        noise_variance=noise[sel], nonlinear_variance=None if nonlinear is None
        else nonlinear[sel], dof=dof, noise_dof=noise_dof, stride=1,
        method="bla" if m >= 2 else "periodic", dt=data.dt, input_name=u_ch.name,
        output_name=y_ch.name, reference_name=None if r_ch is None else r_ch.name,
        input_unit=u_ch.unit, output_unit=y_ch.unit, realisations=m, periods=p,
        distortion=distortion)


def _record_period(plan: MultisinePlan, dt: float) -> int:
    """Samples per period at the record's rate (an integer decimation of the plan's)."""
    ratio = dt / plan.dt
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > _RATE_TOL * max(ratio, 1.0) or plan.period % factor:
        raise DataError(
            f"the record's sample period {dt:g} s does not fit the plan's {plan.dt:g} s: it must "
            f"be the same or an integer multiple that divides the period ({plan.period} "
            "samples); check [preprocess] decimate and the plan file"
        )
    period = plan.period // factor
    if plan.excited[-1] > (period - 1) // 2:
        raise DataError(f"the plan excites harmonic {plan.excited[-1]}, above the Nyquist "
                        f"line of the record's {period}-sample period; decimate less")
    return period


def _spectra(x: NDArray[np.float64], first: int, m: int, p: int, p_tr: int, period: int,
             want: NDArray[np.int_]) -> NDArray[np.complex128]:
    """DFT of every measured period on the wanted lines, shape (M, P, lines)."""
    out = np.empty((m, p, want.size), dtype=np.complex128)
    span = (p_tr + p) * period
    for k in range(m):
        begin = first + k * span + p_tr * period
        block = x[begin:begin + p * period].reshape(p, period)
        out[k] = np.fft.rfft(block, axis=1)[:, want]
    return out


def _period_stats(spectra: dict[str, NDArray[np.complex128]], p: int) -> dict[str, Any]:
    """Means over periods and the (co)variances of those means, per realisation and line."""
    out: dict[str, Any] = {}
    for name, s in spectra.items():
        mean = s.mean(axis=1)
        out[name] = mean
        if p >= 2:
            dev = s - mean[:, None, :]
            out[f"var_{name}"] = np.sum(dev.real**2 + dev.imag**2, axis=1) / (p * (p - 1))
            out[f"dev_{name}"] = dev
    if p >= 2:
        out["cov_yu"] = np.sum(out["dev_y"] * np.conj(out["dev_u"]), axis=1) / (p * (p - 1))
    return out


def _open_loop(st: dict[str, Any], ne: int, m: int, p: int,
               ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64]]:
    u, y = st["u"][:, :ne], st["y"][:, :ne]
    gm = y / u
    g = gm.mean(axis=0)
    dev = gm - g
    total = (np.sum(dev.real**2 + dev.imag**2, axis=0) / (m * (m - 1)) if m >= 2
             else np.zeros(ne))
    if p >= 2:
        vy, vu, cyu = st["var_y"][:, :ne], st["var_u"][:, :ne], st["cov_yu"][:, :ne]
        per = (vy + np.abs(gm) ** 2 * vu - 2.0 * np.real(np.conj(gm) * cyu)) / np.abs(u) ** 2
        noise = np.maximum(per, 0.0).sum(axis=0) / m**2
    else:
        noise = total
    return g, total, noise


def _closed_loop(st: dict[str, Any], ne: int, m: int, p: int,
                 ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64]]:
    r = st["r"][:, :ne]
    g_yr, g_ur = st["y"][:, :ne] / r, st["u"][:, :ne] / r
    mean_ur = g_ur.mean(axis=0)
    g = g_yr.mean(axis=0) / mean_ur
    d = (g_yr - g * g_ur) / mean_ur
    total = (np.sum(d.real**2 + d.imag**2, axis=0) / (m * (m - 1)) if m >= 2
             else np.zeros(ne))
    if p >= 2:
        vy, vu, cyu = st["var_y"][:, :ne], st["var_u"][:, :ne], st["cov_yu"][:, :ne]
        per = (vy + np.abs(g) ** 2 * vu - 2.0 * np.real(np.conj(g) * cyu)) / (
            np.abs(r) ** 2 * np.abs(mean_ur) ** 2)
        noise = np.maximum(per, 0.0).sum(axis=0) / m**2
    else:
        noise = total
    return g, total, noise


def _distortion(st: dict[str, Any], ne: int, plan: MultisinePlan, m: int, p: int,
                period: int) -> DistortionLevels:
    """Levels of the detection lines relative to the output on the excited lines."""
    scale = 2.0 / period**2  # DFT coefficient → power of the sinusoid on the line
    y_det = st["y"][:, ne:]
    power_m = scale * np.abs(y_det) ** 2  # (M, D)
    noise_m = scale * st["var_y"][:, ne:] if p >= 2 else np.full_like(power_m, np.nan)
    power, noise = power_m.mean(axis=0), noise_m.mean(axis=0)
    out_power = float(np.mean(scale * np.abs(st["y"][:, :ne]) ** 2))
    in_power = float(np.mean(scale * np.abs(st["u"][:, :ne]) ** 2))
    det = np.asarray(plan.detection)
    odd = det % 2 == 1
    f0 = 1.0 / (period * plan.dt * (plan.period / period))

    def level(mask: NDArray[np.bool_]) -> tuple[float | None, float | None, float | None]:
        if not np.any(mask):
            return None, None, None
        pw = power_m[:, mask]
        nz = float(np.mean(noise_m[:, mask])) if p >= 2 else 0.0
        mean = float(np.mean(pw))
        dof = 2 * pw.size
        upper = mean * dof / float(stats.chi2.ppf(0.05, dof))
        p_value = None
        if p >= 2:
            t = pw / np.maximum(noise_m[:, mask], np.finfo(float).tiny)
            fisher = 2.0 * (p - 1) * float(np.sum(np.log1p(t / (p - 1))))
            p_value = float(stats.chi2.sf(fisher, 2 * pw.size))
        return _db(mean - nz, out_power), _db(upper - nz, out_power), p_value

    t_db, t_up, _ = level(np.ones(det.size, dtype=bool))
    if plan.odd_only:
        o_db, o_up, o_p = level(odd)
        e_db, e_up, e_p = level(~odd)
    else:
        o_db = o_up = o_p = e_db = e_up = e_p = None
    return DistortionLevels(
        odd_db=o_db, even_db=e_db, total_db=t_db, odd_upper_db=o_up, even_upper_db=e_up,
        total_upper_db=t_up,
        noise_db=_db(float(np.mean(noise)), out_power) if p >= 2 else math.nan,
        odd_p=o_p, even_p=e_p, frequency=det * f0, power=power, noise=noise, odd=odd,
        output_power=out_power, input_power=in_power)


def _db(power: float, reference: float) -> float:
    if not reference > 0:
        return math.nan
    if not power > 0:
        return -math.inf
    return 10.0 * math.log10(power / reference)
