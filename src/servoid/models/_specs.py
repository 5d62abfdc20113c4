"""Spec numbers of a frequency response: bandwidth, phase lag, resonance.

Actuator specifications are written in these three numbers.  Each
function takes any SISO model with ``freqresp(omega)`` (transfer
function, state space; continuous or discrete) or a measured
:class:`~servoid.models.FrequencyResponseData`.

The *low-frequency level* they refer to is, unless a
``reference_frequency`` is given, the static gain |G(0)| of a model
(``z = 1`` for a discrete one) and the magnitude on the lowest measured
line of a frequency response record.  A model without a finite non-zero
static gain (an integrator, a differentiator) needs a
``reference_frequency``.

For a model the response is evaluated on a logarithmic grid spanning its
poles and zeros (to Nyquist for a discrete model), the grid is refined
where the phase moves fast, and crossings are then located to machine
precision and peaks to about √ε relative in frequency (Brent's methods;
a maximum is flat, so its place is known less well than its height).
For a measured record the numbers come from its lines: crossings are
interpolated linearly in (log f, dB) between neighbouring lines, and the
peak is the highest line, so their resolution is the line spacing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, ModelError, OptionTypeError
from .._lazy import optimize
from ._frd import FrequencyResponseData

__all__ = ["ResonancePeak", "bandwidth", "phase_lag", "resonance_peak"]

_PER_DECADE = 200  # grid density before refinement
_MAX_PHASE_STEP = np.radians(20.0)  # refine the grid until neighbouring phases are this close
_REFINE_ROUNDS = 30


@dataclass(frozen=True)
class ResonancePeak:
    """Resonance peak of a frequency response.

    Attributes
    ----------
    peak_db : float
        Highest magnitude over the low-frequency level [dB]; 0 when the
        magnitude never rises above that level.
    frequency : float
        Where the peak is [Hz] (the reference frequency, 0 for the static
        gain, when there is no peak).
    magnitude : float
        |G| at the peak [output unit / input unit].
    reference_db : float
        The low-frequency level 20·log10|G_ref| [dB].
    """

    peak_db: float
    frequency: float
    magnitude: float
    reference_db: float


def bandwidth(
    model: Any, level_db: float = -3.0, *, reference_frequency: float | None = None
) -> float:
    """First frequency where |G| falls `level_db` below low frequency.

    Parameters
    ----------
    model : model with ``freqresp`` or FrequencyResponseData
        SISO response.
    level_db : float
        Drop that defines the bandwidth [dB], < 0 (−3 dB: half power).
    reference_frequency : float, optional
        Frequency [Hz] whose magnitude is the low-frequency level; default
        the static gain of a model, the lowest line of measured data.

    Returns
    -------
    float
        The bandwidth [Hz]: the lowest frequency above the reference at
        which ``20·log10(|G|/|G_ref|)`` reaches `level_db`.

    Raises
    ------
    ModelError
        The magnitude does not fall that far (within the measured lines,
        or below Nyquist / far above the highest pole of a model).

    Examples
    --------
    A first-order lag 1/(s + 1) is down 3 dB at ω = √(10^0.3 − 1) rad/s
    (half power, 3.0103 dB, would be at exactly 1 rad/s):

    >>> from servoid.models import TransferFunction, bandwidth
    >>> round(bandwidth(TransferFunction([1.0], [1.0, 1.0])) * 2 * 3.141592653589793, 6)
    0.997628
    """
    level = _level(level_db)
    if isinstance(model, FrequencyResponseData):
        f, mag_db, ref_f, ref_db = _measured(model, reference_frequency)
        above = f > ref_f
        f, mag_db = np.concatenate([[ref_f], f[above]]), np.concatenate([[ref_db], mag_db[above]])
        below = np.flatnonzero(mag_db - ref_db <= level)
        if below.size == 0:
            raise ModelError(
                f"the measured magnitude does not fall {-level:g} dB below its low-frequency "
                f"level within the lines (up to {model.frequency[-1]:g} Hz); measure to higher "
                "frequencies or fit a model (fit_frf)"
            )
        i = int(below[0])
        x0, x1 = np.log(max(f[i - 1], 1e-300)), np.log(f[i])
        y0, y1 = mag_db[i - 1] - ref_db - level, mag_db[i] - ref_db - level
        if f[i - 1] <= 0.0 or y0 == y1:
            return float(f[i])
        return float(np.exp(x0 + (x1 - x0) * y0 / (y0 - y1)))
    resp = _Response(model, reference_frequency)
    grid = resp.grid()
    rel = resp.db(grid) - resp.ref_db - level
    below = np.flatnonzero(rel <= 0.0)
    if below.size == 0:
        raise ModelError(
            f"the magnitude of the model does not fall {-level:g} dB below its low-frequency "
            f"level up to {grid[-1]:g} Hz"
        )
    i = int(below[0])
    if i == 0:
        return float(grid[0])

    def crossing(logf: float) -> float:
        return float(resp.db(np.array([math.exp(logf)]))[0] - resp.ref_db - level)

    return float(math.exp(optimize.brentq(crossing, math.log(grid[i - 1]), math.log(grid[i]),
                                          xtol=1e-14, rtol=1e-14)))


def phase_lag(model: Any, frequency: float) -> float:
    """Phase lag −∠G [deg] at a frequency, unwrapped from DC up.

    Parameters
    ----------
    model : model with ``freqresp`` or FrequencyResponseData
        SISO response.
    frequency : float
        Where to read the lag [Hz], > 0 (within the lines of measured
        data).

    Returns
    -------
    float
        ``−∠G(j·2π·frequency)`` [deg]; the phase is followed continuously
        up from low frequency, where it is taken in (−180°, 180°] (the
        lowest line for measured data), so a lag can exceed 180°.  A lag
        is positive: a first-order lag gives 45° at its corner.

    Examples
    --------
    >>> from servoid.models import TransferFunction, phase_lag
    >>> round(phase_lag(TransferFunction([1.0], [1.0, 1.0]), 1 / (2 * 3.141592653589793)), 9)
    45.0
    """
    if isinstance(frequency, bool) or not isinstance(frequency, (int, float, np.floating)) \
            or not math.isfinite(frequency) or frequency <= 0:
        raise DataError(f"frequency must be a finite number > 0 Hz, got {frequency!r}")
    f_req = float(frequency)
    if isinstance(model, FrequencyResponseData):
        return -_measured_phase(model, f_req)
    resp = _Response(model, None, need_level=False)
    if resp.dt is not None and f_req > resp.f_hi:
        raise DataError(f"frequency must lie below the Nyquist frequency {0.5 / resp.dt:g} Hz "
                        f"of this discrete model, got {f_req:g}")
    g_req = complex(resp.g(np.array([f_req]))[0])
    if not (np.isfinite(g_req) and g_req != 0):
        raise DataError(f"the model's response at frequency = {f_req:g} Hz is {g_req} in double "
                        "precision, so it has no phase there; choose a lower frequency")
    lo = min(resp.f_lo, f_req * 1e-3)
    grid = resp.refine(np.geomspace(lo, f_req, _points(lo, f_req)))
    phase = np.unwrap(np.angle(resp.g(grid)))
    return float(-np.degrees(phase[-1]))


def resonance_peak(model: Any, *, reference_frequency: float | None = None) -> ResonancePeak:
    """Peak of |G| over its low-frequency level, and where it is.

    Parameters
    ----------
    model : model with ``freqresp`` or FrequencyResponseData
        SISO response.
    reference_frequency : float, optional
        Frequency [Hz] whose magnitude is the low-frequency level; default
        the static gain of a model, the lowest line of measured data.

    Returns
    -------
    ResonancePeak
        Peak over the level [dB] (0 without a peak), its frequency [Hz],
        the magnitude there and the level [dB].  For measured data the
        peak is the highest line above the reference.

    Examples
    --------
    ζ = 0.1: M_r = 1/(2ζ·√(1 − ζ²)) at ω_n·√(1 − 2ζ²):

    >>> from servoid.models import TransferFunction, resonance_peak
    >>> peak = resonance_peak(TransferFunction([1.0], [1.0, 0.2, 1.0]))
    >>> round(peak.peak_db, 6), round(peak.frequency * 2 * 3.141592653589793, 6)
    (14.023048, 0.989949)
    """
    if isinstance(model, FrequencyResponseData):
        f, mag_db, ref_f, ref_db = _measured(model, reference_frequency)
        above = f >= ref_f
        if not np.any(above) or np.max(mag_db[above]) <= ref_db:
            return ResonancePeak(0.0, ref_f, 10 ** (ref_db / 20), ref_db)
        i = int(np.argmax(np.where(above, mag_db, -np.inf)))
        return ResonancePeak(float(mag_db[i] - ref_db), float(f[i]),
                             float(10 ** (mag_db[i] / 20)), ref_db)
    resp = _Response(model, reference_frequency)
    grid = resp.grid()
    mag_db = resp.db(grid)
    i = int(np.argmax(mag_db))
    if mag_db[i] <= resp.ref_db:
        return ResonancePeak(0.0, resp.ref_f, 10 ** (resp.ref_db / 20), resp.ref_db)
    a, b = math.log(grid[max(i - 1, 0)]), math.log(grid[min(i + 1, grid.size - 1)])
    best = optimize.minimize_scalar(
        lambda lf: -float(resp.db(np.array([math.exp(lf)]))[0]), bounds=(a, b),
        method="bounded", options={"xatol": 1e-12},
    )
    f_pk, db_pk = float(math.exp(best.x)), float(-best.fun)
    if db_pk < mag_db[i]:  # the bounded search never does worse than the grid point
        f_pk, db_pk = float(grid[i]), float(mag_db[i])
    return ResonancePeak(db_pk - resp.ref_db, f_pk, 10 ** (db_pk / 20), resp.ref_db)


# -- models -------------------------------------------------------------------------------------
class _Response:
    """A parametric model's response in Hz, with its low-frequency level."""

    def __init__(
        self, model: Any, reference_frequency: float | None, need_level: bool = True
    ) -> None:
        if not callable(getattr(model, "freqresp", None)):
            raise OptionTypeError(f"model must have a freqresp(omega) method or be a "
                                  f"FrequencyResponseData, got {type(model).__name__}")
        self.model = model
        self.dt = getattr(model, "dt", None)
        _check_stable(model, self.dt)
        lo, hi = _root_band(model, self.dt)
        self.f_hi = 0.5 / self.dt * (1 - 1e-9) if self.dt is not None else hi
        if not need_level:
            self.ref_f, self.ref_db, self.f_lo = 0.0, math.nan, min(lo, self.f_hi * 1e-6)
        elif reference_frequency is None:
            g0 = complex(self.g(np.zeros(1))[0])
            if not (np.isfinite(g0) and abs(g0) > 0):
                raise ModelError(
                    "the model has no finite non-zero static gain (an integrator or a "
                    "differentiator), so it has no low-frequency level; pass "
                    "reference_frequency=<Hz>"
                )
            self.ref_f, self.ref_db = 0.0, 20 * math.log10(abs(g0))
            self.f_lo = min(lo, self.f_hi * 1e-6)
        else:
            ref = _positive("reference_frequency", reference_frequency)
            if ref >= self.f_hi:
                raise DataError(f"reference_frequency must lie below {self.f_hi:g} Hz, got {ref:g}")
            g_ref = complex(self.g(np.array([ref]))[0])
            if not (np.isfinite(g_ref) and abs(g_ref) > 0):
                raise ModelError(f"the model's response at reference_frequency = {ref:g} Hz is "
                                 f"{g_ref}; choose another reference")
            self.ref_f, self.ref_db, self.f_lo = ref, 20 * math.log10(abs(g_ref)), ref

    def g(self, f: NDArray[np.float64]) -> NDArray[np.complex128]:
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.asarray(self.model.freqresp(2 * np.pi * f), dtype=np.complex128)
        if out.shape != f.shape:
            if out.size != f.size:
                raise ModelError(f"spec numbers need a SISO model; freqresp returned shape "
                                 f"{out.shape} for {f.size} frequencies")
            out = out.reshape(f.shape)
        return out

    def db(self, f: NDArray[np.float64]) -> NDArray[np.float64]:
        with np.errstate(divide="ignore"):
            return 20 * np.log10(np.abs(self.g(f)))

    def grid(self) -> NDArray[np.float64]:
        return self.refine(np.geomspace(self.f_lo, self.f_hi, _points(self.f_lo, self.f_hi)))

    def refine(self, grid: NDArray[np.float64]) -> NDArray[np.float64]:
        """Insert midpoints (in log f) where the phase jumps between points."""
        for _ in range(_REFINE_ROUNDS):
            step = np.abs(np.angle(self.g(grid[1:]) / self.g(grid[:-1])))
            # A NaN step (a response that over- or underflows) cannot be refined away.
            fast = np.flatnonzero(np.isfinite(step) & ~(step < _MAX_PHASE_STEP))
            if fast.size == 0:
                break
            mids = np.sqrt(grid[fast] * grid[fast + 1])
            grid = np.sort(np.concatenate([grid, mids]))
        return grid


def _check_stable(model: Any, dt: float | None) -> None:
    """Refuse a model with a pole in the right half plane (outside the unit circle)."""
    poles = getattr(model, "poles", None)
    if not callable(poles):
        return
    try:
        p = np.asarray(poles(), dtype=np.complex128).ravel()
    except (TypeError, ValueError, np.linalg.LinAlgError):
        return
    if p.size == 0:
        return
    # An integrator (a pole at s = 0 or z = 1) is allowed: it has a frequency response.
    if dt is None:
        worst = p[np.argmax(p.real)]
        unstable = worst.real > 1e-9 * max(1.0, float(np.abs(p).max()))
        where = f"s = {worst:.4g}, in the right half plane"
    else:
        worst = p[np.argmax(np.abs(p))]
        unstable = abs(worst) > 1.0 + 1e-9
        where = f"z = {worst:.4g}, outside the unit circle"
    if unstable:
        raise ModelError(
            f"the model is unstable (a pole at {where}): it has no steady-state frequency "
            "response, so no bandwidth, phase lag or resonance peak. Pass a stable model "
            "(close the loop first, or re-identify)"
        )


def _root_band(model: Any, dt: float | None) -> tuple[float, float]:
    """Frequencies [Hz] a decade-rich grid should span: around poles and zeros."""
    roots: list[complex] = []
    for name in ("poles", "zeros"):
        fn = getattr(model, name, None)
        if callable(fn):
            try:
                roots += list(np.ravel(fn()))
            except (TypeError, ValueError, np.linalg.LinAlgError):
                pass
    r = np.asarray(roots, dtype=np.complex128)
    if dt is not None:
        r = r[np.abs(r) > 0]
        w = np.abs(np.log(r)) / dt
    else:
        w = np.abs(r)
    w = w[np.isfinite(w) & (w > 0)]
    if w.size == 0:
        return 1e-6, 1e6
    return float(w.min() / (2 * np.pi) * 1e-4), float(w.max() / (2 * np.pi) * 1e4)


def _points(lo: float, hi: float) -> int:
    return max(int(_PER_DECADE * math.log10(hi / lo)) + 1, 2)


# -- measured data ------------------------------------------------------------------------------
def _measured(
    frd: FrequencyResponseData, reference_frequency: float | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    f, mag_db = frd.frequency, frd.magnitude_db
    if reference_frequency is None:
        return f, mag_db, float(f[0]), float(mag_db[0])
    ref = _positive("reference_frequency", reference_frequency)
    if not f[0] <= ref <= f[-1]:
        raise DataError(f"reference_frequency must lie within the measured lines "
                        f"{f[0]:g}..{f[-1]:g} Hz, got {ref:g}")
    g_ref = abs(complex(frd.freqresp(np.array([2 * np.pi * ref]))[0]))
    if not g_ref > 0:
        raise ModelError(f"the measured response is zero at reference_frequency = {ref:g} Hz")
    return f, mag_db, ref, 20 * math.log10(g_ref)


def _measured_phase(frd: FrequencyResponseData, f_req: float) -> float:
    f = frd.frequency
    if not f[0] <= f_req <= f[-1] * (1 + 1e-9):
        raise DataError(f"frequency must lie within the measured lines {f[0]:g}..{f[-1]:g} Hz, "
                        f"got {f_req:g}")
    return float(np.interp(f_req, f, frd.phase_deg))


def _level(level_db: object) -> float:
    if isinstance(level_db, bool) or not isinstance(level_db, (int, float, np.floating)) \
            or not math.isfinite(level_db) or level_db >= 0:
        raise DataError(f"level_db must be a finite number < 0 dB (e.g. -3.0), got {level_db!r}")
    return float(level_db)


def _positive(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise DataError(f"{name} must be a finite number > 0 Hz, got {value!r}")
    return float(value)
