"""Measured frequency responses: a nonparametric model (MATLAB's idfrd).

:class:`FrequencyResponseData` holds a frequency response measured on a
set of lines, with what says how far each line can be trusted: the
coherence (Welch estimates) and the variance σ²_G of each line (both
methods; for periodic data the scatter across periods), the number of
averages behind them, and for periodic data the nonlinear-distortion
assessment (:class:`NonlinearDistortion`).  It is built by
:func:`servoid.estimate.estimate_frf` or by hand from any complex array.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float
from .._errors import DataError, ModelError, OptionTypeError

__all__ = ["FrequencyResponseData", "NonlinearDistortion"]

_OWNER = "FrequencyResponseData"
# measured lines count as "the same frequency" within this relative distance (float rounding)
_LINE_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class NonlinearDistortion:
    """Nonlinear distortion seen at the lines the input leaves empty.

    A linear time-invariant system driven by a periodic input answers
    only at the excited lines; in steady state anything the output holds
    at the other lines beyond the noise is nonlinear distortion (or a
    transient or drift not yet gone).  With an odd multisine the even
    lines reveal even nonlinearities and any odd lines left out reveal
    odd ones (Pintelon & Schoukens, *System Identification: A Frequency
    Domain Approach*, 2nd ed., §3.4 and §4.3).

    At each detection line k the averaged output spectrum Ŷ_k is
    compared with its variance σ̂²_Ŷ,k from the scatter across the M
    periods: ``t_k = |Ŷ_k|²/σ̂²_Ŷ,k`` follows an F(2, 2(M − 1)) law
    for noise alone, and the per-line p-values are combined by Fisher's
    method, ``−2·Σ ln p_k ~ χ²(2L)`` over L lines.

    Attributes
    ----------
    detected : bool or None
        True when the combined p-value is below `alpha`; None when the
        design leaves no non-excited line to look at (a PRBS at clock 1,
        a multisine exciting every line up to Nyquist).
    p_value : float or None
        Combined p-value of "noise alone" (None when not testable).
    alpha : float
        Significance level used.
    frequency : ndarray of float
        Detection lines [Hz] (non-excited, between DC and Nyquist, both
        excluded, and below the FRF's ``f_max``).
    power : ndarray of float
        Output power |Ŷ_k|² on each detection line [output unit²], the
        power of a sinusoid on that line (a sine of amplitude A gives
        A²/2).
    noise : ndarray of float
        Variance of that power's estimate σ̂²_Ŷ,k, same scale [output unit²].
    odd_db, even_db : float or None
        ``10·log10(Σ power / Σ noise)`` over the odd (even) harmonic
        numbers among the detection lines [dB]: about 0 dB for noise
        alone; None when there is no such line.
    """

    detected: bool | None
    p_value: float | None
    alpha: float
    frequency: NDArray[np.float64]
    power: NDArray[np.float64]
    noise: NDArray[np.float64]
    odd_db: float | None = None
    even_db: float | None = None

    def __post_init__(self) -> None:
        arrays = [_readonly_real(n, getattr(self, n)) for n in ("frequency", "power", "noise")]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise DataError("NonlinearDistortion: frequency, power and noise must be 1-D of "
                            f"equal length, got shapes {[a.shape for a in arrays]}")
        for name, arr in zip(("frequency", "power", "noise"), arrays, strict=True):
            object.__setattr__(self, name, arr)
        alpha = as_float("alpha", self.alpha, where="NonlinearDistortion:")
        if not 0.0 < alpha < 1.0:
            raise DataError(f"NonlinearDistortion: alpha must lie in (0, 1), got {self.alpha}")

    @property
    def n_lines(self) -> int:
        """Number of detection lines."""
        return int(self.frequency.size)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data summary for JSON (non-finite numbers as None)."""
        return {
            "detected": self.detected,
            "p_value": _json_float(self.p_value),
            "alpha": self.alpha,
            "n_lines": self.n_lines,
            "odd_db": _json_float(self.odd_db),
            "even_db": _json_float(self.even_db),
            "frequency": _json_list(self.frequency),
            "power": _json_list(self.power),
            "noise": _json_list(self.noise),
        }


@dataclass(frozen=True, eq=False)
class FrequencyResponseData:
    """Frequency response measured on a set of lines.

    A nonparametric SISO model: the complex response G_k on increasing
    frequencies f_k, with how well each line is known.  Arrays are stored
    read-only.  For data recorded at a sample period ``dt`` the response
    is that of the sampled system from the logged input to the logged
    output (with a staircase input it includes the zero-order hold).

    Spec numbers (bandwidth, phase lag at a frequency, resonance peak)
    come from :func:`servoid.models.bandwidth`,
    :func:`~servoid.models.phase_lag` and
    :func:`~servoid.models.resonance_peak`, which take this type as
    well as parametric models.

    Parameters
    ----------
    frequency : array_like of float
        Line frequencies [Hz], >= 0 and strictly increasing.
    response : array_like of complex
        G at each line [output unit / input unit].
    variance : array_like of float, optional
        Variance σ²_G = E|Ĝ_k − G_k|² of each line, >= 0.
    coherence : array_like of float, optional
        Squared coherence γ² in [0, 1] of each line (Welch estimates).
    n_averages : int
        Number of averages behind each line: periods M (periodic) or the
        equivalent number of independent segments (Welch).
    dt : float or None
        Sample period [s] of the data, None when not from sampled data.
    method : str
        How the response was measured: ``"welch"``, ``"welch-indirect"``,
        ``"periodic"`` or anything for a hand-built response.
    input_name, output_name : str
        Channel names.
    reference_name : str or None
        Channel the estimate was referred to (the indirect closed-loop
        ratio ``S_yr/S_ur``), None for a direct estimate.
    input_unit, output_unit : str
        Channel units ('' when unknown).
    distortion : NonlinearDistortion or None
        Nonlinear-distortion assessment (periodic data), else None.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.array([1.0, 10.0, 100.0])
    >>> frd = FrequencyResponseData(f, 1.0 / (1.0 + 1j * f / 10.0))
    >>> np.round(frd.magnitude_db, 2).tolist()
    [-0.04, -3.01, -20.04]
    """

    frequency: NDArray[np.float64]
    response: NDArray[np.complex128]
    variance: NDArray[np.float64] | None = None
    coherence: NDArray[np.float64] | None = None
    n_averages: int = 1
    dt: float | None = None
    method: str = "measured"
    input_name: str = "u"
    output_name: str = "y"
    input_unit: str = ""
    output_unit: str = ""
    reference_name: str | None = None
    distortion: NonlinearDistortion | None = None

    def __post_init__(self) -> None:
        f = _readonly_real("frequency", self.frequency)
        if f.ndim != 1 or f.size == 0:
            raise DataError(f"{_OWNER}: frequency must be a non-empty 1-D array, got shape "
                            f"{f.shape}")
        if f[0] < 0 or np.any(np.diff(f) <= 0):
            raise DataError(f"{_OWNER}: frequency must be >= 0 Hz and strictly increasing")
        if self.response is None or isinstance(self.response, (str, bytes)):
            raise OptionTypeError(f"{_OWNER}: response must be an array of complex numbers, got "
                                  f"{type(self.response).__name__}")
        try:
            g = np.array(self.response, dtype=np.complex128, copy=True)
        except (TypeError, ValueError) as exc:
            raise OptionTypeError(f"{_OWNER}: response must be an array of complex numbers "
                                  f"({exc})") from None
        if g.shape != f.shape:
            raise DataError(f"{_OWNER}: response must have the shape of frequency {f.shape}, "
                            f"got {g.shape}")
        if not np.all(np.isfinite(g)):
            raise DataError(f"{_OWNER}: response must be finite; drop the lines without "
                            "excitation")
        g.setflags(write=False)
        object.__setattr__(self, "frequency", f)
        object.__setattr__(self, "response", g)
        if self.variance is not None:
            var = _readonly_real("variance", self.variance)
            if var.shape != f.shape or np.any(var < 0):
                raise DataError(f"{_OWNER}: variance must be >= 0 with the shape of frequency "
                                f"{f.shape}, got shape {var.shape}")
            object.__setattr__(self, "variance", var)
        if self.coherence is not None:
            coh = _readonly_real("coherence", self.coherence)
            if coh.shape != f.shape or np.any((coh < 0) | (coh > 1 + 1e-12)):
                raise DataError(f"{_OWNER}: coherence must lie in [0, 1] with the shape of "
                                f"frequency {f.shape}")
            object.__setattr__(self, "coherence", coh)
        n_avg = self.n_averages
        if isinstance(n_avg, bool) or not isinstance(n_avg, (int, np.integer)) or n_avg < 1:
            raise DataError(f"{_OWNER}: n_averages must be an integer >= 1, got {n_avg!r}")
        object.__setattr__(self, "n_averages", int(n_avg))
        if self.dt is not None:
            if isinstance(self.dt, bool) or not isinstance(self.dt, (int, float, np.floating)) \
                    or not math.isfinite(self.dt) or self.dt <= 0:
                raise DataError(f"{_OWNER}: dt must be > 0 s or None, got {self.dt!r}")
            object.__setattr__(self, "dt", float(self.dt))
            if f[-1] > 0.5 / self.dt * (1 + _LINE_TOL):
                raise DataError(f"{_OWNER}: the highest line {f[-1]:g} Hz lies above the "
                                f"Nyquist frequency {0.5 / self.dt:g} Hz of dt = {self.dt} s")
        if self.distortion is not None and not isinstance(self.distortion, NonlinearDistortion):
            raise OptionTypeError(f"{_OWNER}: distortion must be a NonlinearDistortion or None, "
                                  f"got {type(self.distortion).__name__}")

    # -- views ----------------------------------------------------------------------------------
    @property
    def n_lines(self) -> int:
        """Number of frequency lines."""
        return int(self.frequency.size)

    def __len__(self) -> int:
        return self.n_lines

    @property
    def omega(self) -> NDArray[np.float64]:
        """Angular frequencies 2π·f [rad/s]."""
        return 2.0 * np.pi * self.frequency

    @property
    def magnitude(self) -> NDArray[np.float64]:
        """|G| on each line [output unit / input unit]."""
        return np.abs(self.response)

    @property
    def magnitude_db(self) -> NDArray[np.float64]:
        """20·log10|G| on each line [dB]."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> NDArray[np.float64]:
        """Phase of G [deg], unwrapped from the lowest line up.

        Unwrapping assumes the phase moves by less than 180° between
        neighbouring lines; lines too sparse across a sharp resonance or
        a long delay can break that.
        """
        return np.degrees(np.unwrap(np.angle(self.response)))

    @property
    def std(self) -> NDArray[np.float64] | None:
        """Standard deviation σ_G of each line, or None."""
        return None if self.variance is None else np.sqrt(self.variance)

    @property
    def unit(self) -> str:
        """Unit of the response, ``output_unit/input_unit``."""
        if not (self.input_unit or self.output_unit):
            return ""
        return f"{self.output_unit or '1'}/{self.input_unit or '1'}"

    # -- evaluation -----------------------------------------------------------------------------
    def freqresp(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """Return G at angular frequencies ω, measured or interpolated.

        On a measured line the measured value is returned.  Between lines
        log|G| and the unwrapped phase are interpolated linearly in
        frequency, which is only as good as the line density; outside the
        measured range nothing is extrapolated.

        Parameters
        ----------
        omega : array_like
            Angular frequencies [rad/s] within the measured range.

        Returns
        -------
        ndarray of complex
            G, same shape as `omega`.

        Raises
        ------
        ModelError
            A frequency lies outside the measured lines.
        """
        f = as_array("omega", omega, finite=False) / (2.0 * np.pi)
        lo, hi = self.frequency[0], self.frequency[-1]
        tol = _LINE_TOL * max(hi, 1.0)
        if np.any(~np.isfinite(f)) or np.any(f < lo - tol) or np.any(f > hi + tol):
            raise ModelError(
                f"{_OWNER}.freqresp: the response is measured on {lo:g}..{hi:g} Hz only "
                "(nothing is extrapolated); fit a parametric model (fit_frf) to go beyond"
            )
        flat = np.clip(f.ravel(), lo, hi)
        idx = np.clip(np.searchsorted(self.frequency, flat), 0, self.n_lines - 1)
        prev = np.clip(idx - 1, 0, self.n_lines - 1)
        near = np.where(np.abs(self.frequency[prev] - flat) < np.abs(self.frequency[idx] - flat),
                        prev, idx)
        on_line = np.abs(self.frequency[near] - flat) <= tol
        out = np.empty(flat.shape, dtype=np.complex128)
        out[on_line] = self.response[near[on_line]]
        if not np.all(on_line):
            with np.errstate(divide="ignore"):
                log_mag = np.log(np.abs(self.response))
            phase = np.unwrap(np.angle(self.response))
            between = flat[~on_line]
            out[~on_line] = np.exp(np.interp(between, self.frequency, log_mag)
                                   + 1j * np.interp(between, self.frequency, phase))
        return out.reshape(f.shape)

    def select(
        self, f_min: float | None = None, f_max: float | None = None
    ) -> FrequencyResponseData:
        """Return the lines with ``f_min <= f <= f_max`` [Hz].

        Parameters
        ----------
        f_min, f_max : float, optional
            Band limits [Hz]; None leaves that side open.

        Returns
        -------
        FrequencyResponseData
            The same record on fewer lines (the distortion assessment is
            kept as measured).
        """
        lo = -np.inf if f_min is None else float(f_min)
        hi = np.inf if f_max is None else float(f_max)
        keep = (self.frequency >= lo) & (self.frequency <= hi)
        if not np.any(keep):
            raise DataError(f"{_OWNER}.select: no line lies in [{lo:g}, {hi:g}] Hz; the lines "
                            f"span {self.frequency[0]:g}..{self.frequency[-1]:g} Hz")
        return replace(
            self,
            frequency=self.frequency[keep],
            response=self.response[keep],
            variance=None if self.variance is None else self.variance[keep],
            coherence=None if self.coherence is None else self.coherence[keep],
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data record for JSON (complex as real/imag lists)."""
        return {
            "method": self.method,
            "dt": self.dt,
            "n_averages": self.n_averages,
            "input": self.input_name,
            "output": self.output_name,
            "reference": self.reference_name,
            "input_unit": self.input_unit,
            "output_unit": self.output_unit,
            "frequency": _json_list(self.frequency),
            "real": _json_list(self.response.real),
            "imag": _json_list(self.response.imag),
            "magnitude_db": _json_list(self.magnitude_db),
            "phase_deg": _json_list(self.phase_deg),
            "variance": None if self.variance is None else _json_list(self.variance),
            "coherence": None if self.coherence is None else _json_list(self.coherence),
            "distortion": None if self.distortion is None else self.distortion.to_dict(),
        }

    def __repr__(self) -> str:
        span = f"{self.frequency[0]:.4g}..{self.frequency[-1]:.4g} Hz"
        return (f"<FrequencyResponseData {self.method}: {self.n_lines} lines, {span}, "
                f"{self.n_averages} averages, {self.input_name} -> {self.output_name}>")


def _readonly_real(name: str, values: ArrayLike) -> NDArray[np.float64]:
    arr = np.array(as_array(name, values, finite=False, where=f"{_OWNER}:"), dtype=np.float64,
                   copy=True)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{_OWNER}: {name} must be finite")
    arr.setflags(write=False)
    return arr


def _json_float(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _json_list(values: NDArray[np.float64]) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in np.asarray(values, dtype=float)]
