"""Measured frequency responses: Welch H1 and averaging over periods.

Two estimators of the frequency response from a record, both returning a
:class:`~servoid.models.FrequencyResponseData`:

*Welch (any input).*  The record is cut into K windowed segments (mean
removed per segment, as :func:`scipy.signal.csd` does by default) and
``Ĝ = S_yu/S_uu`` (H1), with the squared coherence
``γ² = |S_yu|²/(S_uu·S_yy)``.  Conditional on the input, the error of H1
is ``Ŝ_vu/Ŝ_uu`` (v the output noise), whose variance is
``S_vv/(n·S_uu)``; with the residual spectrum ``Ŝ_yy·(1 − γ̂²)``, which
loses one of the n averages to the fitted ratio, that gives

    σ²_G = |Ĝ|²·(1 − γ̂²) / (γ̂²·(n − 1)),

with n the equivalent number of independent segments of overlapping
windows (Welch 1967: ``K/(1 + 2·Σ_j (1 − j/K)·ρ_j²)``, ρ_j the window's
overlap correlation at a shift of j segments).  The window's leakage
adds a bias that this variance does not hold; it shrinks with longer
segments.

*Periodic (PRBS or multisine periods).*  After `skip_periods` transient
periods the M remaining whole periods are transformed one by one; with
the spectra Y_m, U_m on line k averaged over periods (Ŷ, Û), the
estimate is ``Ĝ = Ŷ/Û`` and its variance is the scatter across periods

    σ²_G = Σ_m |Y_m − Ĝ·U_m|² / ((M − 1)·M·|Û|²),

which is the sample variance of the per-period ratios over M when the
input is noise-free, and keeps the input noise (and its correlation with
the output noise) when it is not (Pintelon & Schoukens, *System
Identification: A Frequency Domain Approach*, 2nd ed., §2.4).  There is
no leakage on the excited lines, so there is no window and no bias from
it.  Only the excited lines are kept; the others are where nonlinear
distortion shows (:class:`~servoid.models.NonlinearDistortion`).

*Closed loop.*  Under feedback the input carries the output noise, so
H1 from u to y is biased: it tends towards the inverse controller −1/C
where the noise dominates the reference.  With ``reference="r"`` the
Welch estimate becomes the indirect ratio ``Ĝ = S_yr/S_ur``, consistent
because r is uncorrelated with the noise.  The periodic estimate
``Ŷ/Û`` is consistent in closed loop as it stands (the noise averages
out of both spectra over the periods); the reference then only tells
which lines are excited.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from numbers import Integral, Real
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import ChannelError, DataError, OptionError, OptionTypeError, check_option
from .._lazy import fft as sfft
from .._lazy import signal as sps
from .._lazy import stats
from ..data import ROLES, Channel, Experiment
from ..models import FrequencyResponseData, NonlinearDistortion
from ._channels import check_magnitude

__all__ = ["FrfMethod", "estimate_frf"]

FrfMethod = Literal["auto", "welch", "periodic"]
_METHODS: tuple[FrfMethod, ...] = ("auto", "welch", "periodic")

# significance level of the nonlinear-distortion test (false alarms on linear data: 1 in 1000)
_DISTORTION_ALPHA = 1e-3
# a line counts as excited when its averaged input power is above its noise variance by more
# than noise alone would be with this probability (F(2, 2(M − 1)) tail), ...
_EXCITED_FALSE_ALARM = 1e-6
# ... and this fraction of the strongest line (below it: rounding of a noise-free design)
_EXCITED_FLOOR = 1e-12
_MIN_WELCH_SAMPLES = 32
# the default segment stops growing here: a long record then buys averages, not finer lines
_MAX_DEFAULT_NPERSEG = 2**14
# samples per block of segments or periods: 256 kB of float64.  Whole-record temporaries
# would be mapped afresh on every call (page faults cost as much as the FFTs on a 1e6-sample
# record); blocks this small are recycled by the allocator and stay in cache.
_BLOCK_SAMPLES = 2**15


def estimate_frf(
    data: Experiment,
    *,
    input: str = "u",
    output: str | None = None,
    reference: str | None = None,
    method: FrfMethod = "auto",
    nperseg: int | None = None,
    window: str | tuple[Any, ...] = "hann",
    overlap: float = 0.5,
    period: int | None = None,
    skip_periods: int = 1,
    f_max: float | None = None,
) -> FrequencyResponseData:
    """Estimate the frequency response from input to output.

    Parameters
    ----------
    data : Experiment
        The record.
    input : str
        Input channel: a channel name, or a role (``"u"``, ``"r"``) that
        names exactly one channel.
    output : str, optional
        Output channel name (or role); default the only ``y`` channel.
    reference : str, optional
        Reference channel (name or role, e.g. ``"r"``) of a closed-loop
        record: Welch then estimates ``S_yr/S_ur`` (consistent under
        feedback, see the module notes); periodic estimation takes the
        excited lines from it.  Default None: direct estimate.
    method : {"auto", "welch", "periodic"}
        ``"periodic"`` averages over periods; ``"welch"`` is H1 for any
        input; ``"auto"`` picks "periodic" when `period` is given or the
        record's notes carry the design period (``notes["excitation"]
        ["period"]``, written by :meth:`servoid.signals.Excitation.
        to_experiment`), else "welch".
    nperseg : int, optional
        Welch segment length [samples]; the line spacing is
        ``1/(nperseg·dt)``.  Default: N/8 rounded down to a power of 2
        (at least 15 segments with 50 % overlap), at most 16384: beyond
        that a longer record buys averages rather than finer lines (pass a
        longer nperseg for a lightly damped mode, whose leakage bias falls
        with the line spacing).
    window : str or tuple
        Welch window, as :func:`scipy.signal.get_window` takes it.
    overlap : float
        Welch segment overlap, a fraction in [0, 1).
    period : int, optional
        Samples per excitation period (periodic method).  Default: from
        the record's notes.  A period must be a whole number of samples.
    skip_periods : int
        Leading periods dropped as transient (periodic method), >= 0; a
        trailing part period is dropped too.
    f_max : float, optional
        Highest frequency to keep [Hz]; default Nyquist.

    Returns
    -------
    FrequencyResponseData
        Welch: every line between DC and Nyquist (both excluded) where the
        input has power, with coherence and variance.  Periodic: the
        excited lines with their variance from the scatter across periods
        and the nonlinear-distortion assessment.

    Raises
    ------
    DataError
        Too few periods or samples, a constant input, a segment longer
        than the record, a period that is not a whole number of samples.
    OptionError
        An unknown method or an option that does not apply to it.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.data import Experiment
    >>> from servoid.estimate import estimate_frf
    >>> u = np.tile(np.random.default_rng(0).standard_normal(64), 5)
    >>> y = 0.5 * u + 0.25 * np.roll(u, 1)  # periodic input: roll = one-sample delay
    >>> frd = estimate_frf(Experiment.from_arrays(0.01, u=u, y=y), period=64)
    >>> g = 0.5 + 0.25 * np.exp(-1j * frd.omega * 0.01)  # the exact response
    >>> frd.method, frd.n_averages, bool(np.allclose(frd.response, g))
    ('periodic', 4, True)
    """
    if not isinstance(data, Experiment):
        raise OptionTypeError(f"data must be an Experiment, got {type(data).__name__}")
    check_option("method", method, _METHODS)
    u_ch, y_ch, r_ch = _io_channels(data, input, output, reference)
    check_magnitude(f"output channel {y_ch.name!r}", [y_ch.values])
    dt = data.dt
    nyquist = 0.5 / dt
    f_hi = nyquist if f_max is None else as_float("f_max", f_max, positive=True, unit="Hz")
    if f_hi > nyquist * (1 + 1e-12):
        raise DataError(f"f_max must be <= the Nyquist frequency {nyquist:g} Hz, got {f_hi:g}")

    noted = _noted_period(data)
    given = None if period is None else _as_period(period)
    if method == "auto":
        chosen = "periodic" if (given is not None or noted is not None) else "welch"
    else:
        chosen = method
    if chosen == "welch" and given is not None:
        raise OptionError("period applies to method='periodic'; drop it for method='welch'")
    if chosen == "periodic" and nperseg is not None:
        raise OptionError(
            "nperseg applies to method='welch'; the periodic estimate uses whole periods "
            "(pass method='welch' to use segments)"
        )
    u, y = u_ch.values, y_ch.values
    r = None if r_ch is None else r_ch.values
    meta = {
        "dt": dt,
        "input_name": u_ch.name,
        "output_name": y_ch.name,
        "input_unit": u_ch.unit,
        "output_unit": y_ch.unit,
        "reference_name": None if r_ch is None else r_ch.name,
    }
    if chosen == "welch":
        return _welch(u, y, r, dt, nperseg, window, overlap, f_hi, meta)
    p = given if given is not None else noted
    if p is None:
        raise DataError(
            "method='periodic' needs the excitation period: pass period=<samples per period>, "
            "or record the design with Excitation.to_experiment (its notes carry the period)"
        )
    skip = as_int("skip_periods", skip_periods, minimum=0)
    return _periodic(u, y, r, dt, p, skip, f_hi, meta)


# -- Welch ---------------------------------------------------------------------------------------
def _welch(
    u: NDArray[np.float64],
    y: NDArray[np.float64],
    r: NDArray[np.float64] | None,
    dt: float,
    nperseg: int | None,
    window: str | tuple[Any, ...],
    overlap: float,
    f_hi: float,
    meta: dict[str, Any],
) -> FrequencyResponseData:
    n = u.size
    if n < _MIN_WELCH_SAMPLES:
        raise DataError(f"a Welch estimate needs at least {_MIN_WELCH_SAMPLES} samples, the "
                        f"record has {n}; record longer")
    if nperseg is None:
        seg = min(max(2 ** int(math.floor(math.log2(n / 8))), 16), _MAX_DEFAULT_NPERSEG)
    else:
        seg = as_int("nperseg", nperseg, minimum=8)
        if seg > n:
            raise DataError(
                f"nperseg = {seg} samples is longer than the record ({n} samples); pass "
                f"nperseg <= {n // 2} so that there are segments to average, or leave it None "
                "(N/8 rounded down to a power of 2, at most 16384)"
            )
    ov = as_float("overlap", overlap)
    if not 0.0 <= ov < 1.0:
        raise DataError(f"overlap must be a fraction in [0, 1), got {ov:g}")
    step = max(seg - int(round(ov * seg)), 1)
    count = 1 + (n - seg) // step
    if count < 2:
        raise DataError(
            f"nperseg = {seg} leaves a single segment of the {n}-sample record: the coherence "
            f"and the variance need averages; use nperseg <= {n // 2}"
        )
    try:
        win = np.asarray(sps.get_window(window, seg), dtype=np.float64)
    except (ValueError, TypeError) as exc:
        raise OptionError(f"window {window!r} is not a scipy.signal.get_window window: {exc}") \
            from exc
    bins = np.arange(1, (seg + 1) // 2)  # DC and (even nperseg) Nyquist excluded
    bins = bins[bins / (seg * dt) <= f_hi * (1 + 1e-12)]
    if bins.size == 0:
        raise DataError(f"no Welch line below f_max = {f_hi:g} Hz: the line spacing is "
                        f"{1 / (seg * dt):g} Hz; raise f_max or nperseg")
    signals = [u, y] if r is None else [u, y, r]
    sums = _welch_sums(signals, seg, step, count, win, slice(int(bins[0]), int(bins[-1]) + 1))
    s_uu, s_yy = sums[(0, 0)].real, sums[(1, 1)].real
    s_yu = sums[(1, 0)]
    n_eff = _equivalent_segments(win, step, count)
    if r is None:
        keep = s_uu > _EXCITED_FLOOR * np.max(s_uu)
        g = s_yu[keep] / s_uu[keep]
        coh = _coherence(s_yu[keep], s_uu[keep], s_yy[keep])
        s_vv = s_yy[keep] * (1.0 - coh)
        var = s_vv / ((n_eff - 1.0) * s_uu[keep])
        method = "welch"
    else:
        s_rr, s_yr, s_ur = sums[(2, 2)].real, sums[(1, 2)], sums[(0, 2)]
        keep = (s_rr > _EXCITED_FLOOR * np.max(s_rr)) & (np.abs(s_ur) > 0)
        g = s_yr[keep] / s_ur[keep]
        coh = _coherence(s_yr[keep], s_rr[keep], s_yy[keep])
        # residual spectrum of v = y − Ĝ·u, the part of y the reference does not explain
        s_vv = (s_yy[keep] - 2.0 * np.real(np.conj(g) * s_yu[keep])
                + np.abs(g) ** 2 * s_uu[keep])
        var = np.maximum(s_vv, 0.0) * s_rr[keep] / ((n_eff - 1.0) * np.abs(s_ur[keep]) ** 2)
        method = "welch-indirect"
    if not np.any(keep):
        raise DataError("the input has no power on any Welch line; check the channel mapping")
    return FrequencyResponseData(
        frequency=bins[keep] / (seg * dt),
        response=g,
        variance=np.maximum(var, 0.0),
        coherence=np.clip(coh, 0.0, 1.0),
        n_averages=max(int(math.floor(n_eff)), 1),
        method=method,
        **meta,
    )


def _welch_sums(
    signals: list[NDArray[np.float64]], seg: int, step: int, count: int,
    win: NDArray[np.float64], band: slice,
) -> dict[tuple[int, int], NDArray[np.complex128]]:
    """Averaged auto and cross spectra ``mean_k X_i·conj(X_j)`` on the band.

    Segments go through in blocks of ``_BLOCK_SAMPLES`` (at least one
    segment each) so that the temporaries are recycled.
    """
    rows = max(1, _BLOCK_SAMPLES // seg)
    w_dft = sfft.rfft(win)
    # removing each segment's mean before windowing subtracts mean·DFT(window); that DFT is
    # non-zero on a few bins only (two for Hann), so correct those instead of the samples
    hit = np.flatnonzero(np.abs(w_dft) > 1e-12 * float(np.sum(win)))
    views = [np.lib.stride_tricks.sliding_window_view(x, seg)[: (count - 1) * step + 1 : step]
             for x in signals]
    pairs = [(i, i) for i in range(len(signals))] + [(1, 0)]
    if len(signals) == 3:
        pairs += [(1, 2), (0, 2)]
    # sums over every bin of the (contiguous) transform, cut to the band at the end
    sums = {pair: np.zeros(w_dft.size, dtype=np.complex128) for pair in pairs}
    for first in range(0, count, rows):
        block = []
        for view in views:
            part = view[first : first + rows]
            spec = sfft.rfft(part * win, axis=1)
            if hit.size:
                spec[:, hit] -= part.mean(axis=1)[:, None] * w_dft[hit]
            block.append(spec)
        for i, j in pairs:
            if i == j:
                flat = block[i].view(np.float64)
                sums[(i, i)] += np.einsum("kf,kf->f", flat, flat).reshape(-1, 2).sum(axis=1)
            else:
                sums[(i, j)] += np.einsum("kf,kf->f", block[i], block[j].conj())
    return {pair: total[band] / count for pair, total in sums.items()}


def _coherence(
    s_xy: NDArray[np.complex128], s_xx: NDArray[np.float64], s_yy: NDArray[np.float64]
) -> NDArray[np.float64]:
    """|S_xy|²/(S_xx·S_yy), formed as a product of ratios (no overflow); 0 where y is silent."""
    mag = np.abs(s_xy)
    ok = (s_xx > 0) & (s_yy > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ok, (mag / np.where(ok, s_xx, 1.0)) * (mag / np.where(ok, s_yy, 1.0)), 0.0)


def _equivalent_segments(win: NDArray[np.float64], step: int, count: int) -> float:
    """Welch's equivalent number of independent segments for overlapping windows."""
    # einsum, not BLAS: a lone ddot waking a sleeping BLAS thread pool costs ~10 ms here
    energy = float(np.einsum("i,i->", win, win))
    total = 0.0
    for j in range(1, count):
        shift = j * step
        if shift >= win.size:
            break
        rho = float(np.einsum("i,i->", win[shift:], win[: win.size - shift])) / energy
        total += (1.0 - j / count) * rho * rho
    return count / (1.0 + 2.0 * total)


# -- periodic ------------------------------------------------------------------------------------
def _periodic(
    u: NDArray[np.float64],
    y: NDArray[np.float64],
    r: NDArray[np.float64] | None,
    dt: float,
    period: int,
    skip: int,
    f_hi: float,
    meta: dict[str, Any],
) -> FrequencyResponseData:
    n = u.size
    whole = n // period
    m = whole - skip
    if m < 2:
        raise DataError(
            f"period = {period} samples: the {n}-sample record holds {whole} whole period(s) "
            f"and skip_periods = {skip} leaves {max(m, 0)}; the periodic FRF needs at least 2 "
            "(its variance is the scatter across periods). Record more periods, lower "
            "skip_periods, or use method='welch'"
        )
    lines = np.arange(1, (period + 1) // 2)  # DC and (even period) Nyquist excluded
    lines = lines[lines / (period * dt) <= f_hi * (1 + 1e-12)]
    if lines.size == 0:
        raise DataError(f"no harmonic of 1/(period·dt) = {1 / (period * dt):g} Hz lies below "
                        f"f_max = {f_hi:g} Hz")
    mom = _period_moments(u, y, r, period, skip, m, int(lines[-1]))
    z_mean, z_m2 = (mom.u_mean, mom.u_m2) if r is None else (mom.r_mean, mom.r_m2)
    z_pow = np.abs(z_mean) ** 2
    z_noise = z_m2 / ((m - 1) * m)
    # F(2, 2(M − 1)) tail: P(t > x) = (1 + x/(M − 1))^−(M − 1)
    t_crit = (m - 1) * (_EXCITED_FALSE_ALARM ** (-1.0 / (m - 1)) - 1.0)
    excited = (z_pow > _EXCITED_FLOOR * np.max(z_pow)) & (z_pow > t_crit * z_noise)
    if not np.any(excited):
        raise DataError(
            f"no line of the {'reference' if r is not None else 'input'} carries the "
            f"excitation at period = {period} samples; check the period and the channel mapping"
        )
    u_mean = mom.u_mean[excited]
    g = mom.y_mean[excited] / u_mean
    # Σ_m |Y_m − Ĝ·U_m|² from the centred moments (Σ_m (Y_m − Ĝ·U_m) = 0 by Ĝ's definition)
    resid = (mom.y_m2[excited] - 2.0 * np.real(np.conj(g) * mom.yu_m2[excited])
             + np.abs(g) ** 2 * mom.u_m2[excited])
    var = np.maximum(resid, 0.0) / ((m - 1) * m * np.abs(u_mean) ** 2)
    distortion = _distortion(mom.y_mean, mom.y_m2, lines, ~excited, period, dt, m)
    return FrequencyResponseData(
        frequency=lines[excited] / (period * dt),
        response=g,
        variance=var,
        coherence=None,
        n_averages=m,
        method="periodic",
        distortion=distortion,
        **meta,
    )


@dataclass
class _Moments:
    """Per-line means and centred sums of squares over periods."""

    u_mean: NDArray[np.complex128]
    y_mean: NDArray[np.complex128]
    u_m2: NDArray[np.float64]
    y_m2: NDArray[np.float64]
    yu_m2: NDArray[np.complex128]  # Σ (Y_m − Ŷ)·conj(U_m − Û)
    r_mean: NDArray[np.complex128] | None = None
    r_m2: NDArray[np.float64] | None = None


def _period_moments(
    u: NDArray[np.float64], y: NDArray[np.float64], r: NDArray[np.float64] | None,
    period: int, skip: int, m: int, top: int,
) -> _Moments:
    """DFT of every period on lines 1..top, reduced to means and centred moments.

    Periods go through in blocks of ``_BLOCK_SAMPLES`` (at least one
    period each) so that the temporaries are recycled.  The sums are taken
    about the first period's spectrum K,
    ``Σ(X_m − K)`` and ``Σ|X_m − K|²``: in steady state X_m − K is noise,
    so the centred moment ``Σ|X_m − K|² − |Σ(X_m − K)|²/M`` subtracts
    numbers of the noise's size, never the signal's.  When the period has a
    prime factor above its square root (the PRBS periods 2^13 − 1 and
    2^17 − 1 are prime), the FFT is Bluestein's and a real transform costs
    as much as a complex one, so u and y then share one complex FFT of
    ``u + j·y``, each centred and scaled to unit RMS so that neither drowns
    in the other's rounding.
    """
    rows = max(1, _BLOCK_SAMPLES // period)
    first = skip * period
    packed = _largest_prime_factor(period) ** 2 > period
    gu = gy = 1.0
    if packed:
        # centre and scale from the first block: they only balance rounding, any values do
        scales = []
        for x in (u, y):
            head = x[first : first + min(rows, m) * period]
            centre = float(np.mean(head))
            rms = float(np.sqrt(np.mean((head - centre) ** 2)))
            scales.append((centre, 1.0 / rms if rms > 0 else 1.0))
        (cu, gu), (cy, gy) = scales
        buffer = np.empty(min(rows, m) * period, dtype=np.complex128)
    lo, hi = 1, top + 1
    mirror = slice(period - 1, period - top - 1, -1)  # bins P − k for k = 1..top
    keys = ("u", "y") if r is None else ("u", "y", "r")
    shift: dict[str, NDArray[np.complex128]] = {}
    total = {k: np.zeros(top, dtype=np.complex128) for k in keys}
    square = {k: np.zeros(top) for k in keys}
    cross = np.zeros(top, dtype=np.complex128)
    for start in range(0, m, rows):
        b = min(rows, m - start)
        sl = slice(first + start * period, first + (start + b) * period)
        if packed:
            z = buffer[: b * period]
            np.subtract(u[sl], cu, out=z.real)
            z.real *= gu
            np.subtract(y[sl], cy, out=z.imag)
            z.imag *= gy
            spec = sfft.fft(z.reshape(b, period), axis=1)
            direct, flipped = spec[:, lo:hi], np.conj(spec[:, mirror])
            spectra = {"u": (direct + flipped) * (0.5 / gu),
                       "y": (direct - flipped) * (-0.5j / gy)}
        else:
            spectra = {"u": sfft.rfft(u[sl].reshape(b, period), axis=1)[:, lo:hi],
                       "y": sfft.rfft(y[sl].reshape(b, period), axis=1)[:, lo:hi]}
        if r is not None:
            spectra["r"] = sfft.rfft(r[sl].reshape(b, period), axis=1)[:, lo:hi]
        if not shift:
            shift = {k: v[0].copy() for k, v in spectra.items()}
        block = {k: v - shift[k] for k, v in spectra.items()}
        for k, v in block.items():
            total[k] += v.sum(axis=0)
            flat = v.view(np.float64)
            square[k] += np.einsum("kf,kf->f", flat, flat).reshape(-1, 2).sum(axis=1)
        cross += np.einsum("kf,kf->f", block["y"], np.conj(block["u"]))
    mean = {k: total[k] / m for k in keys}
    m2 = {k: square[k] - m * (mean[k].real ** 2 + mean[k].imag ** 2) for k in keys}
    return _Moments(
        u_mean=shift["u"] + mean["u"],
        y_mean=shift["y"] + mean["y"],
        u_m2=np.maximum(m2["u"], 0.0),
        y_m2=np.maximum(m2["y"], 0.0),
        yu_m2=cross - m * mean["y"] * np.conj(mean["u"]),
        r_mean=None if r is None else shift["r"] + mean["r"],
        r_m2=None if r is None else np.maximum(m2["r"], 0.0),
    )


def _largest_prime_factor(n: int) -> int:
    largest, k = 1, 2
    while k * k <= n:
        while n % k == 0:
            largest, n = k, n // k
        k += 1
    return max(largest, n) if n > 1 else largest


def _distortion(
    y_mean: NDArray[np.complex128],
    y_m2: NDArray[np.float64],
    lines: NDArray[np.int_],
    empty: NDArray[np.bool_],
    period: int,
    dt: float,
    m: int,
) -> NonlinearDistortion:
    """Output power at the non-excited lines against its scatter across periods."""
    scale = 2.0 / period**2  # DFT coefficient → power of the sinusoid on the line
    power_all = scale * np.abs(y_mean) ** 2
    power = power_all[empty]
    noise = scale * y_m2[empty] / ((m - 1) * m)
    freq = lines[empty] / (period * dt)
    if power.size == 0:
        return NonlinearDistortion(None, None, _DISTORTION_ALPHA, freq, power, noise)
    # a noise-free record has zero scatter: floor it at the FFT's rounding of the strongest line
    noise_floor = 1e-28 * float(np.max(power_all))
    t = power / np.maximum(noise, max(noise_floor, np.finfo(float).tiny))
    # t ~ F(2, 2(m − 1)) for noise alone: p = (1 + t/(m − 1))^−(m − 1); Fisher: −2·Σ ln p
    fisher = 2.0 * (m - 1) * float(np.sum(np.log1p(t / (m - 1))))
    p_value = float(stats.chi2.sf(fisher, 2 * power.size))
    odd = lines[empty] % 2 == 1
    return NonlinearDistortion(
        detected=p_value < _DISTORTION_ALPHA,
        p_value=p_value,
        alpha=_DISTORTION_ALPHA,
        frequency=freq,
        power=power,
        noise=noise,
        odd_db=_level_db(power[odd], noise[odd]),
        even_db=_level_db(power[~odd], noise[~odd]),
    )


def _level_db(power: NDArray[np.float64], noise: NDArray[np.float64]) -> float | None:
    if power.size == 0:
        return None
    total_noise = float(np.sum(noise))
    if total_noise <= 0.0:
        return math.inf if np.sum(power) > 0 else 0.0
    with np.errstate(divide="ignore"):
        return float(10.0 * np.log10(np.sum(power) / total_noise))


# -- checks --------------------------------------------------------------------------------------
def _io_channels(data: Experiment, input: object, output: object, reference: object
                 ) -> tuple[Channel, Channel, Channel | None]:
    """The input, output and (optional) reference channels of a frequency response, checked.

    Each is a channel name or a role naming one channel; the output defaults to
    role "y". The input and output must differ, and the input and reference vary.
    """
    u_ch = _channel(data, input, "input", "input")
    y_ch = _channel(data, "y" if output is None else output, "output", "output")
    r_ch = None if reference is None else _channel(data, reference, "reference", "reference")
    if u_ch.name == y_ch.name:
        raise DataError(f"input and output are the same channel {u_ch.name!r}")
    _check_varies(u_ch, "input")
    if r_ch is not None:
        _check_varies(r_ch, "reference")
    return u_ch, y_ch, r_ch


def _channel(exp: Experiment, key: object, what: str, param: str) -> Channel:
    if not isinstance(key, str):
        raise OptionTypeError(f"{param} must be a channel name or role, got {key!r}")
    if key in exp.names:
        return exp.channel(key)
    if key in ROLES:
        names = exp.names_of(key)  # type: ignore[arg-type]
        if len(names) == 1:
            return exp.channel(names[0])
        if len(names) > 1:
            raise DataError(f"several {what} channels of role {key!r} ({', '.join(names)}): "
                            f"pass {param}=<channel name>")
    raise ChannelError(f"no channel or role {key!r} for the {what}; this experiment has: "
                       f"{', '.join(f'{c.name} ({c.role})' for c in exp.channels)}")


def _check_varies(ch: Channel, what: str) -> None:
    x = ch.values
    hi, lo = float(np.max(x)), float(np.min(x))
    if hi - lo <= 1e-13 * max(abs(hi), abs(lo), np.finfo(float).tiny):
        raise DataError(
            f"the {what} channel {ch.name!r} is constant ({x[0]:g} throughout): a frequency "
            "response needs an input that excites the system; check the channel mapping or "
            "the record"
        )


def _as_period(value: object) -> int:
    if isinstance(value, bool):
        raise OptionTypeError(f"period must be a whole number of samples, got {value!r}")
    if isinstance(value, Integral):
        return as_int("period", value, minimum=2)
    if isinstance(value, Real) and math.isfinite(float(value)):
        if float(value).is_integer():
            raise OptionTypeError(
                f"period must be an integer number of samples, got {value!r} "
                f"({type(value).__name__}); pass period={int(value)}"
            )
        raise DataError(
            f"period = {float(value):g} samples is not a whole number of samples: the "
            "periodic FRF needs the excitation period to be an integer multiple of dt. "
            "Resample the record (or redesign the excitation) so that one period is an "
            "integer number of samples, or use method='welch'"
        )
    raise OptionTypeError(f"period must be a whole number of samples, got {value!r} "
                          f"({type(value).__name__})")


def _noted_period(exp: Experiment) -> int | None:
    record = exp.notes.get("excitation")
    if not hasattr(record, "get"):
        return None
    value = record.get("period")
    if isinstance(value, Integral) and not isinstance(value, bool) and value >= 2:
        return int(value)
    return None
