"""Preprocessing: calibration, detrending, filtering, decimation, splitting.

Each function takes an :class:`Experiment` and returns a new one; the input
is never modified.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import (
    as_array,
    as_bool,
    as_float,
    as_int,
    as_mapping,
    as_str,
    type_error,
)
from .._errors import DataError, OptionTypeError, check_option
from ._experiment import Channel, Experiment, check_experiment

__all__ = [
    "calibrate",
    "decimate",
    "detrend",
    "filter",
    "lowpass",
    "split",
    "split_periods",
]

DetrendKind = Literal["mean", "linear", "offset"]

#: Highest Butterworth order accepted: beyond it the sections add nothing but rounding.
_MAX_ORDER = 20


def calibrate(
    exp: Experiment,
    gains: Mapping[str, float | tuple[float, float]],
    units: Mapping[str, str] | None = None,
) -> Experiment:
    """Apply ``value = gain·raw + offset`` per channel (volts → SI).

    Parameters
    ----------
    exp : Experiment
        The raw record.
    gains : mapping
        ``{channel: gain}`` or ``{channel: (gain, offset)}``.
    units : mapping, optional
        New unit per channel, e.g. ``{"position": "m"}``.
    """
    check_experiment(exp, "exp")
    as_mapping("gains", gains)
    units = dict(as_mapping("units", units) if units is not None else {})
    table: dict[str, tuple[float, float]] = {}
    for name, spec in gains.items():
        exp.channel(name)
        pair = [spec, 0.0] if isinstance(spec, Real) else spec
        if isinstance(pair, np.ndarray):
            pair = pair.tolist()
        if isinstance(pair, (str, bytes)) or not isinstance(pair, Sequence) or len(pair) != 2:
            raise type_error(f"gains[{name!r}]", spec, "a gain or a (gain, offset) pair")
        gain = as_float(f"gains[{name!r}] gain", pair[0])
        offset = as_float(f"gains[{name!r}] offset", pair[1])
        if gain == 0:
            raise DataError(f"calibration of {name!r} needs a finite non-zero gain, got {spec!r}")
        table[name] = (gain, offset)
    for name, unit in units.items():
        exp.channel(name)
        as_str(f"units[{name!r}]", unit, empty=True)
    return exp.replace_channels(
        ch.with_values(table[ch.name][0] * ch.values + table[ch.name][1], units.get(ch.name))
        if ch.name in table
        else ch.with_values(ch.values, units.get(ch.name))
        for ch in exp.channels
    )


def detrend(
    exp: Experiment,
    kind: DetrendKind = "mean",
    channels: Sequence[str] | None = None,
    offsets: Mapping[str, float] | None = None,
) -> Experiment:
    """Remove the mean, a linear trend, or a given operating point.

    Parameters
    ----------
    exp : Experiment
        The record.
    kind : {"mean", "linear", "offset"}
        ``"offset"`` subtracts ``offsets[channel]`` (an operating point).
    channels : sequence of str, optional
        Channels to treat; default all r, u and y channels (side channels keep their level).
    offsets : mapping, optional
        Operating point per channel, required for ``kind="offset"``.
    """
    from scipy import signal as sps  # deferred: importing scipy.signal costs ~1 s
    check_experiment(exp, "exp")
    check_option("kind", kind, ("mean", "linear", "offset"))
    if channels is None:
        channels = [ch.name for ch in exp.channels if ch.role != "side"]
    channels = _channel_list(exp, channels)
    if offsets is not None:
        as_mapping("offsets", offsets)
        offsets = {n: as_float(f"offsets[{n!r}]", v) for n, v in offsets.items()}
    if kind == "offset":
        if not offsets:
            raise DataError('detrend(kind="offset") needs offsets={channel: value}')
        missing = [n for n in channels if n not in offsets]
        channels = [n for n in channels if n in offsets] if missing else channels
        for n in offsets:
            exp.channel(n)

    def treat(ch: Channel) -> Channel:
        if ch.name not in channels:
            return ch
        if kind == "mean":
            return ch.with_values(ch.values - ch.values.mean())
        if kind == "linear":
            return ch.with_values(sps.detrend(ch.values, type="linear"))
        return ch.with_values(ch.values - float(offsets[ch.name]))  # type: ignore[index]

    return exp.replace_channels(treat(ch) for ch in exp.channels)


def decimate(exp: Experiment, q: int, ftype: Literal["fir", "iir"] = "fir") -> Experiment:
    """Anti-alias filter (zero phase), then keep every q-th sample.

    The anti-alias filter (scipy's ``decimate``, zero phase) removes content
    above the new Nyquist frequency instead of folding it back.

    Parameters
    ----------
    exp : Experiment
        The record sampled at ``1/dt``.
    q : int
        Decimation factor, >= 1.
    ftype : {"fir", "iir"}
        Anti-alias filter. ``"fir"``: a Hamming-window FIR of ``20q + 1`` taps
        applied once with its delay removed, the record extended by a fitted
        line at both ends; -6 dB at the new Nyquist frequency and at least
        50 dB down from 1.2 times it. ``"iir"``: an order-8
        Chebyshev I cutting at 0.8 times the new Nyquist frequency, applied
        forward and backward.
    """
    from scipy import signal as sps  # deferred: importing scipy.signal costs ~1 s
    check_experiment(exp, "exp")
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)):
        raise type_error("decimation factor q", q, "an integer >= 1")
    if q < 1:
        raise DataError(f"decimation factor q must be an integer >= 1, got {q!r}")
    check_option("ftype", ftype, ("fir", "iir"))
    if q == 1:
        return exp
    # FIR: resample_poly needs no padding, only two output samples; IIR: sosfiltfilt
    # pads 3·(2·4 sections + 1) = 27 samples and needs more than that.
    needed = q + 1 if ftype == "fir" else 28
    exp.require_samples(needed, f"decimation by {q}")
    q = int(q)
    if ftype == "fir":
        # scipy's decimate filter, but padded with a fitted line instead of zeros: with zero
        # padding a channel with an offset (volts, positions) rings at both ends.
        taps = sps.firwin(20 * q + 1, 1.0 / q, window="hamming")

        def run(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return sps.resample_poly(x, 1, q, window=taps, padtype="line")
    else:

        def run(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return sps.decimate(x, q, ftype="iir", zero_phase=True)

    return exp.replace_channels((ch.with_values(run(ch.values)) for ch in exp.channels),
                                dt=exp.dt * q)


def lowpass(
    exp: Experiment,
    cutoff: float,
    order: int = 4,
    zero_phase: bool = True,
    channels: Sequence[str] | None = None,
) -> Experiment:
    """Butterworth low-pass filter, zero phase or causal.

    Parameters
    ----------
    exp : Experiment
        The record.
    cutoff : float
        -3 dB frequency [Hz] of one pass; must lie below the Nyquist frequency.
    order : int
        Butterworth order.
    zero_phase : bool
        Filter forward and backward (no delay, squared magnitude) or only forward.
    channels : sequence of str, optional
        Channels to filter; default all.
    """
    from scipy import signal as sps  # deferred: importing scipy.signal costs ~1 s
    check_experiment(exp, "exp")
    nyquist = 0.5 / exp.dt
    cutoff = as_float("cutoff", cutoff, finite=False)
    order = as_int("order", order, minimum=1, maximum=_MAX_ORDER)
    if not 0 < cutoff < nyquist:
        raise DataError(
            f"cutoff must lie in (0, {nyquist:g}) Hz (the Nyquist frequency), got {cutoff}"
        )
    # Below one cycle per record the filter's transient outlasts the record: the output is
    # the record's mean plus a start-up ramp, and for cut-offs near 1e-9·fs the filter's
    # initial-condition solve is singular in double precision.
    lowest = 1.0 / exp.duration
    if cutoff < lowest:
        raise DataError(
            f"cutoff = {cutoff:g} Hz is below 1/(N·dt) = {lowest:.3g} Hz, the lowest frequency "
            f"a record of {exp.duration:.3g} s resolves: the filter would return little more "
            "than the mean. Raise the cutoff, or use detrend to remove the mean or a trend"
        )
    sos = sps.butter(order, cutoff, btype="low", fs=1.0 / exp.dt, output="sos")
    return filter(exp, sos, zero_phase=zero_phase, channels=channels)


def filter(
    exp: Experiment,
    sos: ArrayLike,
    zero_phase: bool = False,
    channels: Sequence[str] | None = None,
) -> Experiment:
    """Filter channels with a digital filter in second-order sections.

    Parameters
    ----------
    exp : Experiment
        The record.
    sos : array_like, shape (n_sections, 6)
        The filter, as from ``scipy.signal.butter(..., output="sos")`` at ``fs = 1/dt``.
    zero_phase : bool
        Forward–backward (``sosfiltfilt``) instead of causal (``sosfilt``).
    channels : sequence of str, optional
        Channels to filter; default all.
    """
    from scipy import signal as sps  # deferred: importing scipy.signal costs ~1 s
    check_experiment(exp, "exp")
    sos = np.atleast_2d(as_array("sos", sos))
    if sos.ndim != 2 or sos.shape[1] != 6 or sos.shape[0] < 1:
        raise DataError(f"sos must have shape (n_sections, 6), as from scipy.signal.butter(..., "
                        f"output='sos'), got {sos.shape}")
    if not np.all(sos[:, 3] != 0):
        raise DataError("sos must have a non-zero a0 (column 3) in every section, as from "
                        "scipy.signal.butter(..., output='sos')")
    radius = max((float(np.abs(np.roots(section[3:])).max(initial=0.0)) for section in sos),
                 default=0.0)
    if radius >= 1.0:
        raise DataError(
            f"the filter in sos is unstable (a pole of magnitude {radius:.6g} >= 1): its output "
            "would grow without bound. Design it again, e.g. scipy.signal.butter(..., "
            "output='sos', fs=1/dt)"
        )
    as_bool("zero_phase", zero_phase)
    names = exp.names if channels is None else tuple(_channel_list(exp, channels))
    if zero_phase:
        exp.require_samples(3 * (2 * sos.shape[0] + 1) + 1, "zero-phase filtering")
    run = sps.sosfiltfilt if zero_phase else sps.sosfilt
    out = {}
    for ch in exp.channels:
        if ch.name in names:
            try:
                values = run(sos, ch.values)
            except np.linalg.LinAlgError as exc:
                raise DataError(f"the filter cannot be applied to {ch.name!r} ({exc}): its "
                                "poles lie on or too close to the unit circle") from None
            if not np.all(np.isfinite(values)):
                raise DataError(
                    f"filtering {ch.name!r} gave non-finite values: the filter in sos is "
                    "unstable (a pole on or outside the unit circle) or overflows; check sos"
                )
            out[ch.name] = values
    return exp.replace_channels(
        ch.with_values(out[ch.name]) if ch.name in out else ch for ch in exp.channels
    )


def split(
    exp: Experiment, at: float = 0.5, period: int | None = None
) -> tuple[Experiment, Experiment]:
    """Split into an estimation part and a validation part.

    Parameters
    ----------
    exp : Experiment
        The record.
    at : float or int
        A fraction in (0, 1) of the record, or a sample index.
    period : int, optional
        Excitation period [samples]: the split point is moved down to a whole
        number of periods, and the second part is cut to whole periods too.
    """
    check_experiment(exp, "exp")
    n = exp.n_samples
    if isinstance(at, (float, np.floating)):
        if not 0 < at < 1:
            raise DataError(f"split fraction must lie in (0, 1), got {at}")
        index = round(at * n)
    elif isinstance(at, (int, np.integer)) and not isinstance(at, bool):
        index = int(at)
    else:
        raise OptionTypeError(f"at must be a fraction (float) or a sample index (int), got {at!r}")
    stop = n
    if period is not None:
        period = as_int("period", period)
        if period < 1:
            raise DataError(f"period must be >= 1 sample, got {period}")
        index = (index // period) * period
        stop = index + ((n - index) // period) * period
        if index == 0 or stop == index:
            raise DataError(
                f"{n} samples hold {n // period} whole period(s) of {period}; "
                "need at least 2 to split into estimation and validation"
            )
    if not 2 <= index <= n - 2:
        raise DataError(f"split at sample {index} of {n} leaves a part with fewer than 2 samples")
    return exp.slice(0, index), exp.slice(index, stop)


def split_periods(exp: Experiment, period: int, skip: int = 0) -> list[Experiment]:
    """Cut the record into whole excitation periods.

    Parameters
    ----------
    exp : Experiment
        The record.
    period : int
        Period of the excitation [samples].
    skip : int
        Leading periods to drop (transient).
    """
    check_experiment(exp, "exp")
    period = as_int("period", period)
    skip = as_int("skip", skip)
    if period < 2:
        raise DataError(f"period must be >= 2 samples, got {period}")
    if skip < 0:
        raise DataError(f"skip must be >= 0 periods, got {skip}")
    count = exp.n_samples // period
    if count - skip < 1:
        raise DataError(
            f"{exp.n_samples} samples hold {count} whole period(s) of {period}; "
            f"cannot skip {skip}"
        )
    return [exp.slice(k * period, (k + 1) * period) for k in range(skip, count)]




def _channel_list(exp: Experiment, channels: object) -> list[str]:
    """``channels`` as a list of names of ``exp``, each checked."""
    if isinstance(channels, str):
        channels = [channels]
    if isinstance(channels, (bytes, Mapping)) or not isinstance(channels, Sequence):
        raise type_error("channels", channels, "a list of channel names")
    for name in channels:
        if not isinstance(name, str):
            raise type_error("channels", channels, "a list of channel names")
        exp.channel(name)
    return list(channels)
