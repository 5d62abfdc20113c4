"""Deterministic excitations: multisines, chirps and step sequences."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import DataError, OptionTypeError, ServoidWarning, check_option
from .._warn import warn
from ._checks import (
    MAX_SAMPLES,
    RngLike,
    as_dt,
    as_float,
    as_int,
    as_rng,
    as_signal,
    check_samples,
    nyquist,
    rng_label,
)
from ._excitation import Excitation

__all__ = [
    "ChirpMethod",
    "Harmonics",
    "MultisineScale",
    "Phases",
    "chirp",
    "multisine",
    "steps",
]

Phases = Literal["schroeder", "random", "zero"]
Harmonics = Literal["all", "odd", "log"]
MultisineScale = Literal["peak", "rms"]
ChirpMethod = Literal["linear", "logarithmic"]

_PHASES: tuple[Phases, ...] = ("schroeder", "random", "zero")
_HARMONICS: tuple[Harmonics, ...] = ("all", "odd", "log")
_SCALES: tuple[MultisineScale, ...] = ("peak", "rms")
_CHIRP_METHODS: tuple[ChirpMethod, ...] = ("linear", "logarithmic")
# Frequencies given as k/(P·dt) by hand land within this relative distance of k
_GRID_TOL = 1e-9


def multisine(
    period: int,
    dt: float,
    f_min: float,
    f_max: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    periods: int = 1,
    phases: Phases = "schroeder",
    harmonics: Harmonics = "all",
    per_decade: int = 10,
    scale: MultisineScale = "peak",
    rng: RngLike | None = None,
    *,
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Periodic sum of equal-amplitude cosines on a harmonic grid.

    The lines are the harmonics ``k/(period·dt)`` inside ``[f_min, f_max]``
    (DC and the Nyquist line excluded). Each period is exactly periodic, so
    the DFT over whole periods has power only on those lines.

    Parameters
    ----------
    period : int
        Samples per period P (>= 4); the line spacing is ``1/(P·dt)`` [Hz].
    dt : float
        Sample period [s], > 0.
    f_min, f_max : float
        Band to excite [Hz], ``0 <= f_min <= f_max < 1/(2·dt)``.
    amplitude : float
        Peak deviation from ``offset`` (``scale="peak"``) or RMS about it
        (``scale="rms"``), > 0 [signal unit].
    offset : float
        Operating point [signal unit].
    periods : int
        Whole periods to generate (>= 1).
    phases : {"schroeder", "random", "zero"}
        ``"schroeder"``: ``phi_k = -pi·k·(k-1)/K`` for the k-th of K lines,
        a low crest factor without search. ``"random"``: uniform on
        [0, 2·pi) from ``rng``. ``"zero"``: all cosines in phase (worst
        crest factor, ``sqrt(2K)``; for comparison).
    harmonics : {"all", "odd", "log"}
        ``"all"`` harmonics in the band; ``"odd"`` only odd ones (even
        harmonics stay empty and reveal even nonlinearities); ``"log"``
        about ``per_decade`` lines per decade, rounded to the grid.
    per_decade : int
        Lines per decade for ``harmonics="log"`` (>= 1); otherwise unused.
    scale : {"peak", "rms"}
        What ``amplitude`` fixes.
    rng : numpy.random.Generator or int, optional
        Required for ``phases="random"``; otherwise unused.
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``band`` spans the lowest and highest excited line;
        ``amplitude`` is the peak deviation from ``offset``;
        ``description`` lists the harmonic numbers, frequencies [Hz],
        phases [rad] and the crest factor.

    Examples
    --------
    >>> from servoid.signals import multisine
    >>> x = multisine(1000, dt=1e-3, f_min=1.0, f_max=50.0)
    >>> len(x.description["harmonics"]), x.band
    (50, (1.0, 50.0))
    >>> round(float(abs(x.values).max()), 12)
    1.0
    """
    period = as_int("period", period, minimum=4, what=" (samples per period)")
    dt = as_dt(dt)
    f_min = as_float("f_min", f_min, nonneg=True, unit=" Hz")
    f_max = as_float("f_max", f_max, positive=True, unit=" Hz")
    if f_max >= nyquist(dt):
        raise DataError(
            f"f_max must be below the Nyquist frequency 1/(2·dt) = {nyquist(dt):g} Hz, "
            f"got {f_max:g} Hz"
        )
    if f_min > f_max:
        raise DataError(f"f_min must be <= f_max = {f_max:g} Hz, got {f_min:g} Hz")
    amplitude = as_float("amplitude", amplitude, positive=True)
    offset = as_float("offset", offset)
    periods = as_int("periods", periods)
    check_samples(period * periods, f"the multisine ({periods} period(s) of {period})",
                  max_samples)
    check_option("phases", phases, _PHASES)
    check_option("harmonics", harmonics, _HARMONICS)
    check_option("scale", scale, _SCALES)
    per_decade = as_int("per_decade", per_decade)
    gen = as_rng(rng, 'multisine(phases="random")') if phases == "random" else None

    f0 = 1.0 / (period * dt)
    k_lo = max(1, math.ceil(f_min / f0 - _GRID_TOL))
    k_hi = min(math.floor(f_max / f0 + _GRID_TOL), (period - 1) // 2)
    lines = _select_lines(k_lo, k_hi, harmonics, per_decade)
    if lines.size == 0:
        raise DataError(
            f"no {'odd ' if harmonics == 'odd' else ''}harmonic of 1/(period·dt) = {f0:g} Hz "
            f"lies in [{f_min:g}, {f_max:g}] Hz; lengthen the period or widen the band"
        )
    n_lines = lines.size
    if f_min > 0 and lines[0] * f0 > f_min * (1 + 1e-9) and lines[0] * f0 > 1.5 * f_min:
        warn(
            f"the lowest excited line is {lines[0] * f0:g} Hz, not f_min = {f_min:g} Hz: the "
            f"frequency grid of this period is {f0:g} Hz. A period of "
            f"{math.ceil(1 / (f_min * dt))} samples puts a line on {f_min:g} Hz",
            ServoidWarning,
        )
    if n_lines < 3:
        warn(
            f"only {n_lines} line(s) in [{f_min:g}, {f_max:g}] Hz on the {f0:g} Hz grid: "
            "that is a sine, not a broadband test; lengthen the period or widen the band",
            ServoidWarning,
        )
    if phases == "schroeder":
        index = np.arange(1, n_lines + 1)
        phi = -np.pi * index * (index - 1) / n_lines
    elif phases == "random":
        assert gen is not None
        phi = gen.uniform(0.0, 2.0 * np.pi, n_lines)
    else:
        phi = np.zeros(n_lines)
    spectrum = np.zeros(period // 2 + 1, dtype=complex)
    spectrum[lines] = np.exp(1j * phi)
    one = np.fft.irfft(spectrum, n=period)
    peak, rms = float(np.max(np.abs(one))), float(np.sqrt(np.mean(one**2)))
    gain = amplitude / (peak if scale == "peak" else rms)
    one *= gain
    return Excitation(
        values=np.tile(one, periods) + offset,
        dt=dt,
        kind="multisine",
        period=period,
        band=(float(lines[0] * f0), float(lines[-1] * f0)),
        amplitude=peak * gain,
        offset=offset,
        clock=None,
        description={
            "harmonics": tuple(int(k) for k in lines),
            "frequencies": tuple(float(k * f0) for k in lines),
            "phases": tuple(float(p) for p in phi),
            "phase_rule": phases,
            "scale": scale,
            "rms": rms * gain,
            "crest_factor": peak / rms,
            "periods": periods,
            "rng": None if gen is None else rng_label(rng),
        },
    )


def chirp(
    *,
    dt: float,
    f0: float,
    f1: float,
    n_samples: int | None = None,
    duration: float | None = None,
    amplitude: float = 1.0,
    offset: float = 0.0,
    method: ChirpMethod = "linear",
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Swept sine from ``f0`` at t = 0 to ``f1`` at the last sample.

    ``offset + amplitude·sin(theta(t))`` with ``theta(0) = 0``, so the sweep
    starts at the operating point without a jump. The instantaneous
    frequency ``theta'/(2·pi)`` runs linearly or geometrically from ``f0``
    to ``f1`` over ``T = (N - 1)·dt`` (the laws of ``scipy.signal.chirp``
    with ``phi=-90``, evaluated as a sine so the first sample is exact).

    Parameters
    ----------
    dt : float
        Sample period [s], > 0.
    f0, f1 : float
        Start and end frequency [Hz], >= 0 (> 0 for logarithmic) and below
        the Nyquist frequency; ``f1 < f0`` sweeps down.
    n_samples : int, optional
        Length N >= 2. Give exactly one of ``n_samples`` and ``duration``.
    duration : float, optional
        Length [s], rounded to ``N = round(duration/dt)`` samples.
    amplitude : float
        Peak deviation from ``offset``, > 0 [signal unit].
    offset : float
        Operating point [signal unit].
    method : {"linear", "logarithmic"}
        Frequency law; logarithmic spends equal time per octave.
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``period = None``; ``band = (min(f0, f1), max(f0, f1))``.

    Examples
    --------
    >>> from servoid.signals import chirp
    >>> x = chirp(dt=1e-3, f0=1.0, f1=100.0, duration=10.0, method="logarithmic")
    >>> x.n_samples, x.band
    (10000, (1.0, 100.0))
    """
    dt = as_dt(dt)
    if (n_samples is None) == (duration is None):
        raise DataError(
            f"give exactly one of n_samples and duration, got n_samples={n_samples!r}, "
            f"duration={duration!r}"
        )
    if duration is not None:
        duration = as_float("duration", duration, positive=True, unit=" s")
        n_samples = round(duration / dt)
        if n_samples < 2:
            raise DataError(f"duration = {duration:g} s is under 2 samples of dt = {dt:g} s")
    n_samples = as_int("n_samples", n_samples, minimum=2)
    check_samples(n_samples, "the chirp", max_samples)
    check_option("method", method, _CHIRP_METHODS)
    positive = method == "logarithmic"
    for name, f in (("f0", f0), ("f1", f1)):
        value = as_float(name, f, positive=positive, nonneg=True, unit=" Hz")
        if value >= nyquist(dt):
            raise DataError(
                f"{name} must be below the Nyquist frequency 1/(2·dt) = {nyquist(dt):g} Hz, "
                f"got {value:g} Hz"
            )
    f0, f1 = float(f0), float(f1)
    amplitude = as_float("amplitude", amplitude, positive=True)
    offset = as_float("offset", offset)
    t = np.arange(n_samples, dtype=np.float64) * dt
    sweep_time = float(t[-1])
    values = offset + amplitude * np.sin(_chirp_phase(t, f0, f1, sweep_time, method))
    return Excitation(
        values=values,
        dt=dt,
        kind="chirp",
        period=None,
        band=(min(f0, f1), max(f0, f1)),
        amplitude=amplitude,
        offset=offset,
        clock=None,
        description={"f0": f0, "f1": f1, "method": method, "sweep_time": sweep_time},
    )


def steps(
    levels: ArrayLike,
    hold_samples: int | Sequence[int],
    dt: float = 1.0,
    mirror: bool = False,
    *,
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Piecewise-constant sequence of levels (staircase, up-down).

    Parameters
    ----------
    levels : array_like of float
        Levels in order [signal unit], at least one.
    hold_samples : int or sequence of int
        Samples each level is held (>= 1): one value for all, or one per
        level.
    dt : float
        Sample period [s], > 0.
    mirror : bool
        Append the levels in reverse without repeating the last one, e.g.
        ``[0, 1, 2]`` becomes ``0, 1, 2, 1, 0`` (up-down test for
        hysteresis and backlash). Holds are mirrored with them.
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``period = None``; ``offset`` is the midpoint of the levels and
        ``amplitude`` half their range. ``band = (1/(N·dt), 1/(2·h·dt))``
        with ``h`` the shortest hold, capped at Nyquist: indicative only,
        since a step's spectrum falls as 1/f rather than ending.

    Examples
    --------
    >>> from servoid.signals import steps
    >>> steps([0.0, 1.0, 2.0], hold_samples=2, mirror=True).values.tolist()
    [0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 1.0, 1.0, 0.0, 0.0]
    """
    level_arr = as_signal("levels", levels, min_samples=1)
    dt = as_dt(dt)
    if isinstance(hold_samples, (Sequence, np.ndarray)):
        holds = [as_int("hold_samples", h) for h in hold_samples]
        if len(holds) != level_arr.size:
            raise DataError(
                f"hold_samples has {len(holds)} entries for {level_arr.size} levels; give one "
                "per level or a single integer"
            )
    else:
        holds = [as_int("hold_samples", hold_samples)] * level_arr.size
    if not isinstance(mirror, bool):
        raise OptionTypeError(f"mirror must be a bool, got {type(mirror).__name__}")
    hold_arr = np.asarray(holds)
    check_samples(int(hold_arr.sum()) * (2 if mirror else 1), "the step sequence", max_samples)
    if mirror and level_arr.size > 1:
        level_arr = np.concatenate([level_arr, level_arr[-2::-1]])
        hold_arr = np.concatenate([hold_arr, hold_arr[-2::-1]])
    values = np.repeat(level_arr, hold_arr)
    if values.size < 2:
        raise DataError(f"steps needs at least 2 samples in total, got {values.size}")
    lo, hi = float(level_arr.min()), float(level_arr.max())
    f_hi = min(0.5 / (int(hold_arr.min()) * dt), nyquist(dt))
    return Excitation(
        values=values,
        dt=dt,
        kind="steps",
        period=None,
        band=(min(1.0 / (values.size * dt), f_hi), f_hi),
        amplitude=(hi - lo) / 2,
        offset=(hi + lo) / 2,
        clock=None,
        description={
            "levels": tuple(float(v) for v in level_arr),
            "hold_samples": tuple(int(h) for h in hold_arr),
            "mirror": mirror,
        },
    )


def _chirp_phase(
    t: NDArray[np.float64], f0: float, f1: float, sweep_time: float, method: str
) -> NDArray[np.float64]:
    """Phase theta(t) [rad] with theta(0) = 0 and theta'(t)/(2·pi) the sweep law."""
    if method == "linear":
        return 2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * sweep_time))
    if f0 == f1:
        return 2 * np.pi * f0 * t
    ratio = f1 / f0
    return 2 * np.pi * f0 * sweep_time / np.log(ratio) * (ratio ** (t / sweep_time) - 1)


def _select_lines(k_lo: int, k_hi: int, harmonics: str, per_decade: int) -> NDArray[np.int_]:
    """Harmonic numbers to excite between ``k_lo`` and ``k_hi``."""
    if k_hi < k_lo:
        return np.zeros(0, dtype=int)
    if harmonics == "all":
        return np.arange(k_lo, k_hi + 1)
    if harmonics == "odd":
        return np.arange(k_lo + (1 - k_lo % 2), k_hi + 1, 2)
    count = max(2, math.ceil(per_decade * math.log10(k_hi / k_lo)) + 1)
    if count - 1 > k_hi * math.log(k_hi / k_lo):
        # Gaps of the geometric grid are below one harmonic everywhere: every harmonic is
        # chosen, so skip building a grid of `count` points (per_decade may be huge).
        return np.arange(k_lo, k_hi + 1)
    return np.unique(np.round(np.geomspace(k_lo, k_hi, count)).astype(int))
