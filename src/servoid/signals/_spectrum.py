"""Spectrum and crest factor of an excitation."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, OptionTypeError
from .._lazy import signal as sps
from ._checks import as_dt, as_int, as_signal
from ._excitation import Excitation

__all__ = ["Spectrum", "SpectrumMethod", "crest_factor", "power_spectrum"]

SpectrumMethod = Literal["dft", "welch"]


@dataclass(frozen=True, eq=False)
class Spectrum:
    """One-sided power per frequency line of a signal.

    Parameters
    ----------
    frequency : ndarray of float
        Line frequencies [Hz], from 0 up to at most Nyquist.
    power : ndarray of float
        Power on each line [signal unit²]. The lines sum to the mean
        square of the signal (exactly for ``"dft"``, approximately for a
        broadband signal with ``"welch"``); a sine of amplitude A puts
        ``A²/2`` on its line (``"dft"``, on the grid).
    method : {"dft", "welch"}
        ``"dft"``: DFT of one period averaged over whole periods (or of
        the whole record); ``"welch"``: Hann-windowed Welch estimate
        (PSD times the bin width).
    """

    frequency: NDArray[np.float64]
    power: NDArray[np.float64]
    method: SpectrumMethod

    def __post_init__(self) -> None:
        for name in ("frequency", "power"):
            arr = np.array(as_array(name, getattr(self, name), finite=False), dtype=np.float64,
                           copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if self.frequency.shape != self.power.shape or self.frequency.ndim != 1:
            raise DataError(
                f"frequency and power must be 1-D of equal length, got shapes "
                f"{self.frequency.shape} and {self.power.shape}"
            )

    @property
    def power_db(self) -> NDArray[np.float64]:
        """Power in dB re 1 [signal unit²]; empty lines give -inf."""
        with np.errstate(divide="ignore"):
            return 10.0 * np.log10(self.power)


def power_spectrum(
    x: Excitation | ArrayLike,
    dt: float | None = None,
    *,
    periodic: bool | None = None,
    period: int | None = None,
    nperseg: int | None = None,
) -> Spectrum:
    """Power per frequency line, by DFT over periods or by Welch.

    For a periodic signal the DFT of whole periods is exact: power sits only
    on harmonics of ``1/(period·dt)``, with no leakage and no window. For a
    non-periodic one, Welch's averaged periodogram trades resolution for
    variance.

    Parameters
    ----------
    x : Excitation or array_like
        The signal; an :class:`Excitation` brings its ``dt`` and ``period``.
    dt : float, optional
        Sample period [s]; required for an array, must match an Excitation.
    periodic : bool, optional
        DFT (True) or Welch (False). Default: True for an array, and
        ``x.period is not None`` for an Excitation.
    period : int, optional
        Samples per period for the DFT: the record is cut to whole periods
        and averaged over them before the DFT (which averages out noise).
        Default: the Excitation's period, else the whole record is one
        period.
    nperseg : int, optional
        Welch segment length (default ``min(N, 256)``); frequency step
        ``1/(nperseg·dt)``.

    Returns
    -------
    Spectrum
        Frequencies [Hz] and power per line [signal unit²].

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.signals import power_spectrum
    >>> s = power_spectrum(np.cos(2 * np.pi * np.arange(8) / 8), dt=1.0)
    >>> s.frequency.tolist(), np.round(s.power, 12).tolist()
    ([0.0, 0.125, 0.25, 0.375, 0.5], [0.0, 0.5, 0.0, 0.0, 0.0])
    """
    if isinstance(x, Excitation):
        if dt is not None and not np.isclose(as_dt(dt), x.dt, rtol=1e-12):
            raise DataError(f"dt = {dt} s disagrees with the Excitation's dt = {x.dt} s")
        values, dt_ = x.values, x.dt
        if periodic is None:
            periodic = x.period is not None
        if period is None and periodic:
            period = x.period
    else:
        if dt is None:
            raise DataError("dt [s] is required when x is an array")
        values, dt_ = as_signal("x", x), as_dt(dt)
        if periodic is None:
            periodic = True
    if not isinstance(periodic, bool):
        raise OptionTypeError(f"periodic must be a bool or None, got {type(periodic).__name__}")
    if periodic:
        return _dft_power(values, dt_, period)
    if nperseg is None:
        nperseg = min(values.size, 256)
    nperseg = as_int("nperseg", nperseg, minimum=2)
    if nperseg > values.size:
        raise DataError(f"nperseg must be <= the signal length {values.size}, got {nperseg}")
    freq, psd = sps.welch(
        values, fs=1.0 / dt_, window="hann", nperseg=nperseg, detrend=False, scaling="density"
    )
    return Spectrum(freq, psd / (nperseg * dt_), "welch")


def crest_factor(x: Excitation | ArrayLike) -> float:
    """Peak over RMS, both taken about the mean.

    Measured about the mean so that an operating-point offset does not
    count: a sine has ``sqrt(2)``, a binary signal 1.

    Parameters
    ----------
    x : Excitation or array_like
        The signal (a whole number of periods for a periodic one).

    Returns
    -------
    float
        ``max|x - mean(x)| / sqrt(mean((x - mean(x))²))``, >= 1.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.signals import crest_factor
    >>> round(crest_factor(3.0 + np.sin(2 * np.pi * np.arange(100) / 100)), 6)
    1.414214
    """
    values = x.values if isinstance(x, Excitation) else as_signal("x", x)
    centred = values - values.mean()
    rms = float(np.sqrt(np.mean(centred**2)))
    if rms == 0.0:
        raise DataError("crest factor of a constant signal is undefined (RMS about the mean is 0)")
    return float(np.max(np.abs(centred))) / rms


def _dft_power(values: NDArray[np.float64], dt: float, period: int | None) -> Spectrum:
    """One-sided power on the DFT lines of one (averaged) period."""
    if period is None:
        period = values.size
    period = as_int("period", period, minimum=2, what=" (samples per period)")
    n_periods = values.size // period
    if n_periods == 0:
        raise DataError(f"period = {period} samples is longer than the signal ({values.size})")
    one = values[: n_periods * period].reshape(n_periods, period).mean(axis=0)
    coeff = np.fft.rfft(one) / period
    power = np.abs(coeff) ** 2
    # Lines other than DC and (for even P) Nyquist stand for a conjugate pair
    power[1 : (period + 1) // 2] *= 2.0
    return Spectrum(np.fft.rfftfreq(period, dt).astype(np.float64), power, "dft")
