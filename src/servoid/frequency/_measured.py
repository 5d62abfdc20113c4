"""A measured frequency response with its variances, and the distortion levels.

:class:`FrfMeasurement` is what the nonparametric estimators of
:mod:`servoid.frequency` return: the response on its lines with the
variance of each line split as far as the experiment allows (noise, and
for M random-phase realisations the stochastic nonlinear distortion), the
degrees of freedom of those variance estimates (which the sample
maximum-likelihood fit and its cost test need), and how many lines apart
two estimates are independent.  :class:`DistortionLevels` holds what the
detection lines of a multisine say about odd and even nonlinear
distortion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, OptionTypeError, check_option
from ..models import FrequencyResponseData

__all__ = ["DistortionLevels", "FrfMeasurement", "VarianceKind"]

VarianceKind = Literal["total", "noise"]
_KINDS: tuple[VarianceKind, ...] = ("total", "noise")


@dataclass(frozen=True, eq=False)
class DistortionLevels:
    """Nonlinear distortion on the detection lines of a multisine.

    Levels are in dB relative to the output: the mean power per
    detection line (the noise part removed) over the mean output power
    per excited line, so -40 dB means the distortion on a line is a
    hundredth of the output's amplitude there.  For an odd design (every
    excited harmonic odd) the odd detection lines carry the odd
    distortion and the even lines the even distortion; for other designs
    only ``total_db`` is defined.

    Attributes
    ----------
    odd_db, even_db, total_db : float or None
        Distortion level [dB re output]; -inf when the lines hold no more
        than the noise; None where there is no such line.
    odd_upper_db, even_upper_db, total_upper_db : float or None
        One-sided 95 % upper bound of the level (the chi-square law of
        the summed line powers, equal power on the lines assumed).
    noise_db : float
        Noise level on the same lines [dB re output].
    odd_p, even_p : float or None
        p-value of "noise alone" on the odd / even detection lines
        (Fisher's combination of the per-line F tests).
    frequency : ndarray
        Detection lines [Hz].
    power : ndarray
        Output power on each, averaged over realisations [output unit²]
        (a sine of amplitude A has A²/2).
    noise : ndarray
        Noise part of that power (the variance of the period average).
    odd : ndarray of bool
        Which detection lines are odd harmonics.
    output_power : float
        Mean output power per excited line [output unit²].
    input_power : float
        Mean input power per excited line [input unit²] (to draw the
        levels on a Bode magnitude: ``sqrt(power/input_power)``).
    """

    odd_db: float | None
    even_db: float | None
    total_db: float | None
    odd_upper_db: float | None
    even_upper_db: float | None
    total_upper_db: float | None
    noise_db: float
    odd_p: float | None
    even_p: float | None
    frequency: NDArray[np.float64]
    power: NDArray[np.float64]
    noise: NDArray[np.float64]
    odd: NDArray[np.bool_]
    output_power: float
    input_power: float

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (non-finite numbers as None)."""
        return {
            "odd_db": _num(self.odd_db), "even_db": _num(self.even_db),
            "total_db": _num(self.total_db), "odd_upper_db": _num(self.odd_upper_db),
            "even_upper_db": _num(self.even_upper_db),
            "total_upper_db": _num(self.total_upper_db), "noise_db": _num(self.noise_db),
            "odd_p": _num(self.odd_p), "even_p": _num(self.even_p),
            "output_power": _num(self.output_power), "input_power": _num(self.input_power),
            "frequency": _list(self.frequency), "power": _list(self.power),
            "noise": _list(self.noise), "odd": [bool(v) for v in self.odd],
        }


@dataclass(frozen=True, eq=False)
class FrfMeasurement:
    """A nonparametric frequency response with its variance per line.

    Attributes
    ----------
    frequency : ndarray
        Lines [Hz], increasing.
    response : ndarray of complex
        Ĝ on each line [output unit / input unit].
    variance : ndarray
        Total variance of Ĝ per line: noise plus, for the BLA from M
        realisations, the stochastic nonlinear distortion.
    noise_variance : ndarray
        The part of `variance` due to noise.
    nonlinear_variance : ndarray or None
        Variance of Ĝ_BLA due to the stochastic nonlinear distortion
        (``variance − noise_variance``, floored at 0); None when the
        experiment cannot separate it (one realisation, LPM).
    dof : float
        Complex degrees of freedom of the `variance` estimate (``inf``
        when known): q of the LPM, M − 1 for the BLA, P − 1 for one
        realisation of P periods.
    noise_dof : float
        The same for `noise_variance`.
    stride : int
        Lines apart beyond which two estimates are independent: 1 for
        periodic data, the window width of a local method.
    method : str
        ``"lpm"``, ``"lrm"``, ``"periodic"`` or ``"bla"``.
    dt : float or None
        Sample period of the data [s].
    input_name, output_name, reference_name, input_unit, output_unit : str
        Channels (``reference_name`` None for an open-loop estimate).
    realisations, periods : int
        M and P behind a periodic estimate (1, 1 for a local method).
    distortion : DistortionLevels or None
        The detection lines' verdict (multisine designs that leave lines
        empty).
    """

    frequency: NDArray[np.float64]
    response: NDArray[np.complex128]
    variance: NDArray[np.float64]
    noise_variance: NDArray[np.float64]
    nonlinear_variance: NDArray[np.float64] | None
    dof: float
    noise_dof: float
    stride: int
    method: str
    dt: float | None = None
    input_name: str = "u"
    output_name: str = "y"
    reference_name: str | None = None
    input_unit: str = ""
    output_unit: str = ""
    realisations: int = 1
    periods: int = 1
    distortion: DistortionLevels | None = None

    def __post_init__(self) -> None:
        f = _array("frequency", self.frequency, float)
        if f.ndim != 1 or f.size == 0 or np.any(np.diff(f) <= 0) or f[0] < 0:
            raise DataError("FrfMeasurement: frequency must be a non-empty increasing 1-D array "
                            "of lines >= 0 Hz")
        for name in ("response", "variance", "noise_variance", "nonlinear_variance"):
            value = getattr(self, name)
            if value is None:
                continue
            arr = _array(name, value, complex if name == "response" else float).copy()
            if arr.shape != f.shape:
                raise DataError(f"FrfMeasurement: {name} must have the shape of frequency "
                                f"{f.shape}, got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        f = f.copy()
        f.setflags(write=False)
        object.__setattr__(self, "frequency", f)

    # -- views -----------------------------------------------------------------------------------
    @property
    def n_lines(self) -> int:
        """Number of lines."""
        return int(self.frequency.size)

    @property
    def omega(self) -> NDArray[np.float64]:
        """Angular frequencies [rad/s]."""
        return 2.0 * np.pi * self.frequency

    @property
    def unit(self) -> str:
        """Unit of the response, ``output_unit/input_unit``."""
        if not (self.input_unit or self.output_unit):
            return ""
        return f"{self.output_unit or '1'}/{self.input_unit or '1'}"

    def variance_of(self, kind: VarianceKind = "total") -> tuple[NDArray[np.float64], float]:
        """The variance of one kind with its degrees of freedom."""
        check_option("variance", kind, _KINDS)
        if kind == "noise":
            return np.asarray(self.noise_variance), self.noise_dof
        return np.asarray(self.variance), self.dof

    def to_frd(self, variance: VarianceKind = "total") -> FrequencyResponseData:
        """The response as a :class:`~servoid.models.FrequencyResponseData`.

        Its ``n_averages`` is ``dof + 1`` (the periods of a periodic
        estimate), so :func:`servoid.estimate.fit_frf` and the spec
        functions read it as they read any measured response.
        """
        var, dof = self.variance_of(variance)
        n_avg = 1 if not math.isfinite(dof) else max(round(dof) + 1, 1)
        return FrequencyResponseData(
            frequency=self.frequency, response=self.response, variance=var, n_averages=n_avg,
            dt=self.dt, method=self.method, input_name=self.input_name,
            output_name=self.output_name, input_unit=self.input_unit,
            output_unit=self.output_unit, reference_name=self.reference_name)

    def select(self, f_min: float | None = None, f_max: float | None = None) -> FrfMeasurement:
        """The lines with ``f_min <= f <= f_max`` [Hz]."""
        lo = -np.inf if f_min is None else float(f_min)
        hi = np.inf if f_max is None else float(f_max)
        keep = (self.frequency >= lo) & (self.frequency <= hi)
        if not np.any(keep):
            raise DataError(f"no measured line lies in [{lo:g}, {hi:g}] Hz; the lines span "
                            f"{self.frequency[0]:g}..{self.frequency[-1]:g} Hz")
        return self.take(np.flatnonzero(keep))

    def take(self, index: NDArray[np.int_]) -> FrfMeasurement:
        """The lines at the given positions (increasing)."""
        nl = self.nonlinear_variance
        return replace(self, frequency=self.frequency[index], response=self.response[index],
                       variance=self.variance[index], noise_variance=self.noise_variance[index],
                       nonlinear_variance=None if nl is None else nl[index])

    def independent(self) -> FrfMeasurement:
        """Every ``stride``-th line: estimates whose errors are independent."""
        if self.stride <= 1:
            return self
        return self.take(np.arange(0, self.n_lines, self.stride))

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (complex as real and imaginary parts)."""
        nl = self.nonlinear_variance
        return {
            "method": self.method, "dt": self.dt, "input": self.input_name,
            "output": self.output_name, "reference": self.reference_name,
            "input_unit": self.input_unit, "output_unit": self.output_unit,
            "realisations": self.realisations, "periods": self.periods,
            "dof": _num(self.dof), "noise_dof": _num(self.noise_dof), "stride": self.stride,
            "frequency": _list(self.frequency), "real": _list(self.response.real),
            "imag": _list(self.response.imag), "variance": _list(self.variance),
            "noise_variance": _list(self.noise_variance),
            "nonlinear_variance": None if nl is None else _list(nl),
            "distortion": None if self.distortion is None else self.distortion.to_dict(),
        }

    def __repr__(self) -> str:
        return (f"<FrfMeasurement {self.method}: {self.n_lines} lines, "
                f"{self.frequency[0]:.4g}..{self.frequency[-1]:.4g} Hz, dof {self.dof:g}>")


def as_measurement(value: object, name: str = "frf") -> FrfMeasurement:
    """``value`` if it is an :class:`FrfMeasurement`, else a type error naming it."""
    if not isinstance(value, FrfMeasurement):
        raise OptionTypeError(f"{name} must be an FrfMeasurement (from estimate_lpm, "
                              f"estimate_lrm or estimate_bla), got {type(value).__name__}")
    return value


def _array(name: str, value: object, dtype: type) -> NDArray[Any]:
    try:
        return np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise DataError(f"FrfMeasurement: {name} must be an array of numbers, got "
                        f"{type(value).__name__}") from None


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _list(values: Any) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in np.asarray(values, dtype=float)]
