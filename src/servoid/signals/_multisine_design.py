"""Random-phase multisines for frequency-domain identification, and their test plan.

A test of the best linear approximation (BLA) plays M *realisations* of a
random-phase multisine, each for P measured periods after some transient
periods (Pintelon & Schoukens, *System Identification: A Frequency Domain
Approach*, 2nd ed., 2012, on the design of periodic excitations and the
"robust" BLA method; Schoukens, Pintelon, Dobrowiecki & Rolain,
*Automatica* 41, 2005).  :func:`plan_multisine` turns the band, the
frequency resolution, the settling time and the test time into that plan
(:class:`MultisinePlan`): the period N, the excited harmonics, the
*detection lines* left empty, M, P and the transient periods.
:func:`random_multisine` draws the realisations.

Line sets (harmonics k of ``f0 = 1/(N·dt)`` inside the band):

- ``"full"``: every harmonic;
- ``"odd"``: the odd harmonics.  A static nonlinearity of even degree
  answers on even harmonics only, so the even lines show the even
  distortion;
- ``"random-odd"``: the odd harmonics in consecutive groups of
  ``group``, one line of each group chosen at random and left out.  Odd
  distortion then shows on those odd detection lines, even distortion on
  the even lines, at levels representative of the excited lines.

A logarithmic grid spaces the lines ``per_decade`` per decade (rounded to
the harmonic grid, odd harmonics for the odd sets); every harmonic in
the band that it leaves out is a detection line.

Phases are independent and uniform on [0, 2π) in every realisation, the
class of signals the BLA theory assumes.  ``crest="clip"`` lowers the
crest factor of each realisation by the clipping algorithm of Van der
Ouderaa, Schoukens & Renneboog (*IEEE Trans. Instrum. Meas.* 37, 1988):
clip the time signal, keep the phases of its spectrum on the excited
lines, restore the amplitudes, repeat.  The optimised phases are no
longer uniform and independent; the realisations still differ (each
starts from its own random phases), so the BLA they measure is that of
this class of low-crest signals.

The plan travels with the DAQ file as JSON (:meth:`MultisinePlan.write`,
:func:`read_plan`), so that ``servoid identify`` knows the excited and
detection lines and where each realisation begins.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._atomic import atomic_path
from .._checks import read_json
from .._errors import DataError, FileFormatError, OptionTypeError, check_option
from ._checks import MAX_SAMPLES, RngLike, as_dt, as_float, as_int, as_rng, check_samples, nyquist
from ._excitation import Excitation

__all__ = [
    "CrestMethod",
    "LineGrid",
    "LineSet",
    "MultisinePlan",
    "plan_multisine",
    "random_multisine",
    "read_plan",
]

LineSet = Literal["full", "odd", "random-odd"]
LineGrid = Literal["linear", "log"]
CrestMethod = Literal["none", "clip"]

_LINE_SETS: tuple[LineSet, ...] = ("full", "odd", "random-odd")
_GRIDS: tuple[LineGrid, ...] = ("linear", "log")
_CREST: tuple[CrestMethod, ...] = ("none", "clip")
_SCALES = ("rms", "peak")
# frequencies given as k/(N·dt) by hand land within this relative distance of k
_GRID_TOL = 1e-9
#: What a plan file says it is (checked on reading).
PLAN_FORMAT = "servoid multisine plan"
_PLAN_VERSION = 1
# the clipping algorithm clips at this fraction of the current peak each round
_CLIP_FRACTION = 0.9


@dataclass(frozen=True)
class MultisinePlan:
    """A multisine test: period, lines, M realisations × P periods.

    Each realisation is played for ``transient_periods + periods`` whole
    periods, realisation after realisation; the first
    ``transient_periods`` of each are left for the transient to decay and
    the next ``periods`` are measured.

    Parameters
    ----------
    dt : float
        Sample period of the DAQ [s].
    period : int
        Samples per period N; the line spacing is ``1/(N·dt)`` [Hz].
    excited : tuple of int
        Excited harmonic numbers k (frequency ``k/(N·dt)``), increasing.
    realisations : int
        Number of random-phase realisations M >= 1.
    periods : int
        Measured periods per realisation P >= 1 (>= 2 for a noise
        variance per realisation).
    transient_periods : int
        Periods played before the measured ones in each realisation, >= 0.
    lines : {"full", "odd", "random-odd"}
        The line set (see the module notes).
    grid : {"linear", "log"}
        How the lines are spaced.
    group : int
        Odd lines per group of a random-odd design (one left out in each).
    seed : int or None
        Seed the detection lines (random-odd) were drawn with.

    Examples
    --------
    >>> from servoid.signals import plan_multisine
    >>> plan = plan_multisine(1e-3, 1.0, 100.0, resolution=1.0, lines="odd",
    ...                       realisations=4, periods=2)
    >>> plan.period, len(plan.excited), plan.n_samples
    (1000, 50, 12000)
    """

    dt: float
    period: int
    excited: tuple[int, ...]
    realisations: int = 1
    periods: int = 2
    transient_periods: int = 1
    lines: LineSet = "full"
    grid: LineGrid = "linear"
    group: int = 4
    seed: int | None = None
    _detection: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "dt", as_dt(self.dt))
        n = as_int("period", self.period, minimum=4, what=" (samples per period)")
        object.__setattr__(self, "period", n)
        check_option("lines", self.lines, _LINE_SETS)
        check_option("grid", self.grid, _GRIDS)
        object.__setattr__(self, "realisations", as_int("realisations", self.realisations))
        object.__setattr__(self, "periods", as_int("periods", self.periods))
        object.__setattr__(self, "transient_periods",
                           as_int("transient_periods", self.transient_periods, minimum=0))
        object.__setattr__(self, "group", as_int("group", self.group, minimum=2))
        if isinstance(self.excited, (str, bytes)) or not hasattr(self.excited, "__iter__"):
            raise OptionTypeError(f"excited must be a sequence of harmonic numbers, got "
                                  f"{type(self.excited).__name__}")
        ks = tuple(as_int("excited harmonic", k) for k in self.excited)
        if not ks:
            raise DataError("excited must name at least one harmonic")
        if any(b <= a for a, b in itertools.pairwise(ks)):
            raise DataError("excited harmonics must be strictly increasing")
        if ks[-1] > (n - 1) // 2:
            raise DataError(f"excited harmonic {ks[-1]} lies at or above the Nyquist line "
                            f"{n // 2} of a {n}-sample period")
        object.__setattr__(self, "excited", ks)
        if self.seed is not None:
            object.__setattr__(self, "seed", as_int("seed", self.seed, minimum=0))
        full = np.arange(ks[0], ks[-1] + 1)
        object.__setattr__(self, "_detection",
                           tuple(int(k) for k in np.setdiff1d(full, np.asarray(ks))))

    # -- derived ---------------------------------------------------------------------------------
    @property
    def resolution(self) -> float:
        """Line spacing ``1/(N·dt)`` [Hz]."""
        return 1.0 / (self.period * self.dt)

    @property
    def frequencies(self) -> NDArray[np.float64]:
        """Excited frequencies [Hz]."""
        return np.asarray(self.excited, dtype=float) * self.resolution

    @property
    def band(self) -> tuple[float, float]:
        """Lowest and highest excited frequency [Hz]."""
        return (self.excited[0] * self.resolution, self.excited[-1] * self.resolution)

    @property
    def odd_only(self) -> bool:
        """True when every excited harmonic is odd (even lines then show even distortion)."""
        return all(k % 2 == 1 for k in self.excited)

    @property
    def detection(self) -> tuple[int, ...]:
        """Harmonics inside the excited band that are not excited."""
        return self._detection

    @property
    def detection_odd(self) -> tuple[int, ...]:
        """Odd detection harmonics (odd distortion, for an odd design)."""
        return tuple(k for k in self._detection if k % 2 == 1)

    @property
    def detection_even(self) -> tuple[int, ...]:
        """Even detection harmonics (even distortion, for an odd design)."""
        return tuple(k for k in self._detection if k % 2 == 0)

    @property
    def periods_per_realisation(self) -> int:
        """Periods played per realisation, transient included."""
        return self.transient_periods + self.periods

    @property
    def n_samples(self) -> int:
        """Samples of the whole test ``M·(P_tr + P)·N``."""
        return self.realisations * self.periods_per_realisation * self.period

    @property
    def duration(self) -> float:
        """Length of the whole test [s]."""
        return self.n_samples * self.dt

    def realisation_start(self, m: int) -> int:
        """Sample where realisation m (from 0) starts, transient periods included."""
        return m * self.periods_per_realisation * self.period

    # -- files -----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The plan as plain data (what the plan file holds)."""
        return {
            "format": PLAN_FORMAT,
            "version": _PLAN_VERSION,
            "dt": self.dt,
            "period": self.period,
            "realisations": self.realisations,
            "periods": self.periods,
            "transient_periods": self.transient_periods,
            "lines": self.lines,
            "grid": self.grid,
            "group": self.group,
            "seed": self.seed,
            "resolution_hz": self.resolution,
            "band_hz": list(self.band),
            "n_samples": self.n_samples,
            "excited": list(self.excited),
            "detection_odd": list(self.detection_odd),
            "detection_even": list(self.detection_even),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "plan") -> MultisinePlan:
        """The plan :meth:`to_dict` wrote.

        Raises
        ------
        FileFormatError
            Not a plan, a missing key, or a value of the wrong kind.
        """
        if not isinstance(data, Mapping) or data.get("format") != PLAN_FORMAT:
            raise FileFormatError(f"{where} is not a servoid multisine plan (its \"format\" "
                                  f"must be {PLAN_FORMAT!r}); write one with servoid excite "
                                  "multisine")
        if data.get("version") != _PLAN_VERSION:
            raise FileFormatError(f"{where} has plan version {data.get('version')!r}; this "
                                  f"servoid reads version {_PLAN_VERSION}")
        keys = ("dt", "period", "realisations", "periods", "transient_periods", "lines",
                "grid", "group", "seed", "excited")
        missing = [k for k in keys if k not in data]
        if missing:
            raise FileFormatError(f"{where} lacks {', '.join(missing)}")
        try:
            return cls(dt=data["dt"], period=data["period"], excited=tuple(data["excited"]),
                       realisations=data["realisations"], periods=data["periods"],
                       transient_periods=data["transient_periods"], lines=data["lines"],
                       grid=data["grid"], group=data["group"], seed=data["seed"])
        except (DataError, OptionTypeError, ValueError, TypeError) as exc:
            raise FileFormatError(f"{where}: {exc}") from None

    def write(self, path: str | os.PathLike[str], overwrite: bool = False) -> Path:
        """Write the plan as JSON, atomically; return the path."""
        target = Path(path)
        with atomic_path(target, overwrite) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=1) + "\n", encoding="utf-8")
        return target


def read_plan(path: str | os.PathLike[str]) -> MultisinePlan:
    """Read a multisine plan file.

    Parameters
    ----------
    path : path-like
        The JSON file :meth:`MultisinePlan.write` wrote.

    Returns
    -------
    MultisinePlan

    Raises
    ------
    MissingFileError
        No such file.
    FileFormatError
        Not JSON, or not a plan.
    """
    return MultisinePlan.from_dict(read_json(path, "multisine plan"), where=f"plan {path}")


def plan_multisine(
    dt: float,
    f_min: float,
    f_max: float,
    *,
    period: int | None = None,
    resolution: float | None = None,
    lines: LineSet = "random-odd",
    grid: LineGrid = "linear",
    per_decade: int = 20,
    group: int = 4,
    settling_time: float | None = None,
    transient_periods: int | None = None,
    test_time: float | None = None,
    realisations: int | None = None,
    periods: int | None = None,
    rng: RngLike | None = None,
) -> MultisinePlan:
    """Plan a multisine test: band, resolution, transient, time.

    Parameters
    ----------
    dt : float
        Sample period of the DAQ [s].
    f_min, f_max : float
        Band to excite [Hz], ``0 <= f_min <= f_max`` below Nyquist.
    period : int, optional
        Samples per period N.  Give exactly one of `period` and
        `resolution`.
    resolution : float, optional
        Line spacing wanted [Hz]: ``N = ceil(1/(resolution·dt))``.
    lines : {"full", "odd", "random-odd"}
        Which harmonics to excite (module notes).
    grid : {"linear", "log"}
        Linear: every harmonic of the set; log: ``per_decade`` per decade.
    per_decade : int
        Lines per decade of a log grid (>= 1).
    group : int
        Group size of a random-odd design (>= 2; one line of each left out).
    settling_time : float, optional
        Time the system needs to settle after a new realisation starts
        [s]; the transient periods are ``ceil(settling_time/(N·dt))``.
        Default: one period (unless `transient_periods` is given).
    transient_periods : int, optional
        Transient periods per realisation, instead of `settling_time`.
    test_time : float, optional
        Time available for the whole test [s]: fills M (and P, with
        ``periods`` defaulting to 2) with as many realisations as fit.
    realisations : int, optional
        M; default from `test_time`, else 1.
    periods : int, optional
        Measured periods per realisation P; default 2 (the least that
        gives a noise variance per realisation).
    rng : numpy.random.Generator or int, optional
        Required for ``lines="random-odd"`` (draws the detection lines).

    Returns
    -------
    MultisinePlan

    Raises
    ------
    DataError
        No line in the band, a band above Nyquist, or a test time too
        short for one realisation.
    """
    dt = as_dt(dt)
    f_min = as_float("f_min", f_min, nonneg=True, unit=" Hz")
    f_max = as_float("f_max", f_max, positive=True, unit=" Hz")
    if f_max >= nyquist(dt):
        raise DataError(f"f_max must be below the Nyquist frequency 1/(2·dt) = "
                        f"{nyquist(dt):g} Hz, got {f_max:g} Hz")
    if f_min > f_max:
        raise DataError(f"f_min must be <= f_max = {f_max:g} Hz, got {f_min:g} Hz")
    check_option("lines", lines, _LINE_SETS)
    check_option("grid", grid, _GRIDS)
    per_decade = as_int("per_decade", per_decade)
    group = as_int("group", group, minimum=2)
    if (period is None) == (resolution is None):
        raise DataError(f"give exactly one of period and resolution, got period={period!r}, "
                        f"resolution={resolution!r}")
    if period is None:
        res = as_float("resolution", resolution, positive=True, unit=" Hz")
        period = math.ceil(1.0 / (res * dt) - _GRID_TOL)
    n = as_int("period", period, minimum=4, what=" (samples per period)")
    seed = None
    gen = None
    if lines == "random-odd":
        gen = as_rng(rng, 'plan_multisine(lines="random-odd")')
        seed = int(rng) if isinstance(rng, (int, np.integer)) else None
    excited = _lines(n, dt, f_min, f_max, lines, grid, per_decade, group, gen)
    if transient_periods is not None and settling_time is not None:
        raise DataError("give settling_time or transient_periods, not both")
    if transient_periods is not None:
        p_tr = as_int("transient_periods", transient_periods, minimum=0)
    elif settling_time is not None:
        settle = as_float("settling_time", settling_time, nonneg=True, unit=" s")
        p_tr = math.ceil(settle / (n * dt) - _GRID_TOL)
    else:
        p_tr = 1
    p = 2 if periods is None else as_int("periods", periods)
    if test_time is None:
        m = 1 if realisations is None else as_int("realisations", realisations)
    else:
        budget = as_float("test_time", test_time, positive=True, unit=" s")
        whole = math.floor(budget / (n * dt) + _GRID_TOL)
        fit = whole // (p_tr + p)
        m = fit if realisations is None else as_int("realisations", realisations)
        if fit < 1 or m > fit:
            need = (max(m, 1)) * (p_tr + p) * n * dt
            raise DataError(
                f"test_time = {budget:g} s holds {whole} period(s) of {n * dt:g} s; "
                f"{max(m, 1)} realisation(s) of {p_tr} transient + {p} measured periods need "
                f"{need:g} s. Allow more time, or use a coarser resolution (a shorter period), "
                "fewer realisations or periods, or a shorter settling time"
            )
    return MultisinePlan(dt=dt, period=n, excited=excited, realisations=m, periods=p,
                         transient_periods=p_tr, lines=lines, grid=grid, group=group, seed=seed)


def random_multisine(
    plan: MultisinePlan,
    rng: RngLike,
    *,
    amplitude: float = 1.0,
    offset: float = 0.0,
    scale: Literal["rms", "peak"] = "rms",
    crest: CrestMethod = "none",
    crest_iterations: int = 200,
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Draw the realisations of a planned random-phase multisine.

    Every excited line has the same amplitude; the phases are drawn
    independently for each realisation.  The realisations are laid end
    to end, each repeated for ``transient_periods + periods`` periods.

    Parameters
    ----------
    plan : MultisinePlan
        From :func:`plan_multisine`.
    rng : numpy.random.Generator or int
        Source of the phases (a seed for reproducibility).
    amplitude : float
        RMS about `offset` of every realisation (``scale="rms"``), or the
        largest peak deviation over all of them (``scale="peak"``; one gain
        for all, so they keep equal power), > 0 [signal unit].
    offset : float
        Operating point [signal unit].
    scale : {"rms", "peak"}
        What `amplitude` fixes.
    crest : {"none", "clip"}
        Crest-factor optimisation of each realisation (module notes).
    crest_iterations : int
        Rounds of the clipping algorithm (>= 1).
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``kind = "multisine"``; ``period`` is N for a single realisation
        and None for several (the signal is then not periodic);
        ``description["plan"]`` is the plan, ``description["crest_factors"]``
        the crest factor of each realisation.

    Examples
    --------
    >>> from servoid.signals import plan_multisine, random_multisine
    >>> plan = plan_multisine(1e-3, 1.0, 100.0, resolution=1.0, lines="random-odd", rng=1,
    ...                       realisations=3, periods=2)
    >>> x = random_multisine(plan, rng=2)
    >>> x.n_samples == plan.n_samples, round(float(x.values.std()), 12)
    (True, 1.0)
    """
    if not isinstance(plan, MultisinePlan):
        raise OptionTypeError(f"plan must be a MultisinePlan, got {type(plan).__name__}")
    gen = as_rng(rng, "random_multisine")
    amplitude = as_float("amplitude", amplitude, positive=True)
    offset = as_float("offset", offset)
    check_option("scale", scale, _SCALES)
    check_option("crest", crest, _CREST)
    iterations = as_int("crest_iterations", crest_iterations)
    check_samples(plan.n_samples, f"the multisine test ({plan.realisations} realisation(s) of "
                  f"{plan.periods_per_realisation} periods of {plan.period})", max_samples)
    n = plan.period
    k = np.asarray(plan.excited)
    periods = []
    crests = []
    for _ in range(plan.realisations):
        phi = gen.uniform(0.0, 2.0 * np.pi, k.size)
        one = _one_period(n, k, phi)
        if crest == "clip":
            one = _clip_crest(one, n, k, iterations)
        one = one / math.sqrt(float(np.mean(one**2)))  # unit RMS (zero mean: no DC line)
        crests.append(float(np.max(np.abs(one))))
        periods.append(one)
    gain = amplitude if scale == "rms" else amplitude / max(crests)
    repeat = plan.periods_per_realisation
    values = np.concatenate([np.tile(gain * one, repeat) for one in periods]) + offset
    return Excitation(
        values=values,
        dt=plan.dt,
        kind="multisine",
        period=n if plan.realisations == 1 else None,
        band=plan.band,
        amplitude=gain * max(crests),
        offset=offset,
        clock=None,
        description={
            "plan": plan.to_dict(),
            "rms": gain,
            "crest_factors": tuple(crests),
            "crest": crest,
            "phase_rule": "random",
            "harmonics": plan.excited,
        },
    )


# -- helpers -------------------------------------------------------------------------------------
def _lines(n: int, dt: float, f_min: float, f_max: float, lines: str, grid: str,
           per_decade: int, group: int, gen: np.random.Generator | None) -> tuple[int, ...]:
    """Excited harmonic numbers of a period of n samples."""
    f0 = 1.0 / (n * dt)
    k_lo = max(1, math.ceil(f_min / f0 - _GRID_TOL))
    k_hi = min(math.floor(f_max / f0 + _GRID_TOL), (n - 1) // 2)
    odd = lines in ("odd", "random-odd")
    if odd:
        k_lo += 1 - k_lo % 2
        k_hi -= 1 - k_hi % 2
    if k_hi < k_lo:
        raise DataError(
            f"no {'odd ' if odd else ''}harmonic of 1/(N·dt) = {f0:g} Hz lies in "
            f"[{f_min:g}, {f_max:g}] Hz; lengthen the period (finer resolution) or widen the band"
        )
    if grid == "linear":
        ks = np.arange(k_lo, k_hi + 1, 2 if odd else 1)
    else:
        count = max(2, math.ceil(per_decade * math.log10(max(k_hi / k_lo, 1.0))) + 1)
        raw = np.geomspace(k_lo, k_hi, count)
        ks = 2 * np.round((raw - 1) / 2) + 1 if odd else np.round(raw)
        ks = np.unique(np.clip(ks, k_lo, k_hi).astype(int))
    if lines == "random-odd":
        assert gen is not None
        whole = ks.size // group
        if whole == 0:
            raise DataError(
                f"a random-odd multisine leaves one line out of each group of {group}; the band "
                f"holds only {ks.size} odd line(s). Widen the band, refine the resolution or "
                "use lines = \"odd\""
            )
        drop = np.arange(whole) * group + gen.integers(0, group, whole)
        ks = np.delete(ks, drop)
    return tuple(int(k) for k in ks)


def _one_period(n: int, k: NDArray[np.int_], phi: NDArray[np.float64]) -> NDArray[np.float64]:
    spectrum = np.zeros(n // 2 + 1, dtype=complex)
    spectrum[k] = np.exp(1j * phi)
    return np.fft.irfft(spectrum, n=n)


def _clip_crest(x: NDArray[np.float64], n: int, k: NDArray[np.int_],
                iterations: int) -> NDArray[np.float64]:
    """Lower the crest factor by clipping and restoring the amplitude spectrum."""
    best, best_cf = x, _crest(x)
    for _ in range(iterations):
        level = _CLIP_FRACTION * float(np.max(np.abs(x)))
        spec = np.fft.rfft(np.clip(x, -level, level))
        x = _one_period(n, k, np.angle(spec[k]))
        cf = _crest(x)
        if cf < best_cf:
            best, best_cf = x, cf
    return best


def _crest(x: NDArray[np.float64]) -> float:
    return float(np.max(np.abs(x)) / math.sqrt(float(np.mean(x**2))))
