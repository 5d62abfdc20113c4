"""Binary excitations: PRBS, random binary signals, clock and length rules.

The design rules follow models-spec §3.1 (after Aguirre 2000): the bit time
``T_b = clock·dt`` lies in ``[tau/10, tau/3]`` for the smallest time
constant of interest ``tau``, and one period ``(2^n - 1)·T_b`` lasts at
least five settling times.
"""

from __future__ import annotations

import math

import numpy as np

from .._errors import DataError, OptionTypeError
from .._lazy import optimize
from ._checks import (
    MAX_SAMPLES,
    RngLike,
    as_dt,
    as_float,
    as_int,
    as_rng,
    check_samples,
    nyquist,
    rng_label,
)
from ._excitation import Excitation
from ._lfsr import PRBS_TAPS, mls_bits

__all__ = [
    "prbs",
    "prbs_clock",
    "prbs_length",
    "prbs_register_for",
    "random_binary",
]

_N_MIN, _N_MAX = 2, 31
_HALF_POWER = 1.0 / math.sqrt(2.0)


def prbs(
    n: int,
    clock: int = 1,
    amplitude: float = 1.0,
    offset: float = 0.0,
    periods: int = 1,
    dt: float = 1.0,
    seed_state: int | None = None,
    *,
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Maximum-length PRBS from an n-bit LFSR.

    One period has ``N = 2**n - 1`` bits, ``2**(n-1)`` of them high; each
    bit is held for ``clock`` samples and maps to ``offset ± amplitude``.
    The ±1 sequence has a two-valued circular autocorrelation (1 at lag 0,
    -1/N elsewhere), so its line spectrum is flat up to the hold's
    ``sinc²`` roll-off.

    Parameters
    ----------
    n : int
        Register length, 2..31; taps from :data:`PRBS_TAPS`. One period of
        n = 31 is 2.1e9 samples per clock step: mind the memory.
    clock : int
        Samples per bit (>= 1); the bit time is ``T_b = clock·dt`` [s].
    amplitude : float
        Half the peak-to-peak swing, > 0 [signal unit].
    offset : float
        Operating point the signal switches about [signal unit].
    periods : int
        Whole periods to generate (>= 1); record at least 2 for
        identification (spec §3.1).
    dt : float
        Sample period [s], > 0.
    seed_state : int, optional
        Initial register contents, 1..2**n - 1 (bit i is output bit i);
        default all ones. Other seeds give circular shifts of the sequence.
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``period = N·clock`` samples. ``band = (1/(N·T_b), f_3dB)``: from
        the first harmonic to the half-power point of the zero-order-hold
        envelope ``[sin(pi f T_b) / (clock·sin(pi f dt))]²``. That is
        0.5/T_b at clock = 2, 0.451/T_b at clock = 5 and 0.445/T_b at
        clock = 10, tending to the ``sinc²`` value 0.443/T_b behind the
        usual "flat to 0.44/T_b"; at clock = 1 it is the Nyquist frequency,
        since the sampled PRBS is then white.

    Examples
    --------
    >>> from servoid.signals import prbs
    >>> x = prbs(3, clock=2)
    >>> x.values.tolist()
    [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0, -1.0, -1.0]
    >>> x.period, x.clock
    (14, 2)
    """
    n = _check_register(n)
    clock = as_int("clock", clock, what=" (samples per bit)")
    amplitude = as_float("amplitude", amplitude, positive=True)
    offset = as_float("offset", offset)
    periods = as_int("periods", periods)
    check_samples((2**n - 1) * clock * periods, f"PRBS n = {n}, clock {clock}, {periods} "
                  "period(s)", max_samples)
    dt = as_dt(dt)
    n_bits = (1 << n) - 1
    if seed_state is None:
        seed_state = n_bits
    state = as_int("seed_state", seed_state, what=f" below 2**{n} (non-zero register)")
    if state > n_bits:
        raise DataError(f"seed_state must be a non-zero {n}-bit register, 1..{n_bits}, got {state}")
    levels = np.array([offset - amplitude, offset + amplitude])
    one_period = np.repeat(levels[mls_bits(n, n_bits, state)], clock)
    values = np.tile(one_period, periods)
    return Excitation(
        values=values,
        dt=dt,
        kind="prbs",
        period=n_bits * clock,
        band=(1.0 / (n_bits * clock * dt), _hold_half_power(clock, dt)),
        amplitude=amplitude,
        offset=offset,
        clock=clock,
        description={
            "n": n,
            "taps": PRBS_TAPS[n],
            "seed_state": state,
            "bits_per_period": n_bits,
            "periods": periods,
            "bit_time": clock * dt,
        },
    )


def random_binary(
    n_samples: int,
    clock: int = 1,
    amplitude: float = 1.0,
    offset: float = 0.0,
    dt: float = 1.0,
    *,
    rng: RngLike,
    max_samples: int = MAX_SAMPLES,
) -> Excitation:
    """Random binary signal: fair coin flips held ``clock`` samples.

    Not periodic, so analyse it with Welch (``power_spectrum(...,
    periodic=False)``); its expected spectrum has the same ``sinc²``
    envelope as a PRBS with the same clock.

    Parameters
    ----------
    n_samples : int
        Signal length N >= 2 [samples]; the last bit may be cut short.
    clock : int
        Samples per bit (>= 1).
    amplitude : float
        Half the peak-to-peak swing, > 0 [signal unit].
    offset : float
        Operating point the signal switches about [signal unit].
    dt : float
        Sample period [s], > 0.
    rng : numpy.random.Generator or int
        Source of the bits, or a seed for one. Required: no global state.
    max_samples : int
        Budget: a longer signal is refused before any memory is taken.

    Returns
    -------
    Excitation
        ``period = None``; ``band = (1/(N·dt), f_3dB)`` with ``f_3dB`` as
        in :func:`prbs`.

    Examples
    --------
    >>> from servoid.signals import random_binary
    >>> x = random_binary(8, clock=2, rng=1)
    >>> sorted(set(x.values.tolist()))
    [-1.0, 1.0]
    """
    n_samples = as_int("n_samples", n_samples, minimum=2)
    check_samples(n_samples, "the random binary signal", max_samples)
    clock = as_int("clock", clock, what=" (samples per bit)")
    amplitude = as_float("amplitude", amplitude, positive=True)
    offset = as_float("offset", offset)
    dt = as_dt(dt)
    gen = as_rng(rng, "random_binary")
    n_bits = -(-n_samples // clock)
    bits = gen.integers(0, 2, size=n_bits)
    levels = np.array([offset - amplitude, offset + amplitude])
    values = levels[bits][np.arange(n_samples) // clock]  # n_samples values, whatever the clock
    return Excitation(
        values=values,
        dt=dt,
        kind="random_binary",
        period=None,
        band=(1.0 / (n_samples * dt), _hold_half_power(clock, dt)),
        amplitude=amplitude,
        offset=offset,
        clock=clock,
        description={
            "n_samples": n_samples,
            "bit_time": clock * dt,
            "rng": rng_label(rng),
        },
    )


def prbs_clock(tau: float, dt: float, ratio: float = 0.2, f_max: float | None = None) -> int:
    """Samples per bit for a time constant (spec §3.1).

    The bit time ``T_b = clock·dt`` must lie in ``[tau/10, tau/3]``
    (Aguirre 2000) and, if ``f_max`` is given, also ``T_b <= 0.44/f_max`` so
    that the spectrum is flat to ``f_max``. Within that range the clock
    closest to ``ratio·tau/dt`` is returned; if ``f_max`` pushes the upper
    limit below ``tau/10`` the upper limit wins (a faster clock only moves
    power to higher frequencies).

    Parameters
    ----------
    tau : float
        Smallest time constant of interest [s], > 0 (from a step test).
    dt : float
        Sample period [s], > 0.
    ratio : float
        Target ``T_b/tau``, within [0.1, 1/3].
    f_max : float, optional
        Highest frequency that must be excited [Hz], > 0.

    Returns
    -------
    int
        Samples per bit, >= 1.

    Raises
    ------
    DataError
        If even ``clock = 1`` (``T_b = dt``) exceeds the upper limit, i.e.
        the PRBS clock would have to be faster than the sample rate.

    Examples
    --------
    >>> from servoid.signals import prbs_clock
    >>> prbs_clock(tau=0.05, dt=1e-3)
    10
    """
    tau = as_float("tau", tau, positive=True, unit=" s")
    dt = as_dt(dt)
    ratio = as_float("ratio", ratio)
    if not 0.1 - 1e-12 <= ratio <= 1 / 3 + 1e-12:
        raise DataError(f"ratio = T_b/tau must be within [0.1, 1/3] (spec §3.1), got {ratio:g}")
    t_hi, why = tau / 3, f"tau/3 = {tau / 3:g} s"
    if f_max is not None:
        f_max = as_float("f_max", f_max, positive=True, unit=" Hz")
        if 0.44 / f_max < t_hi:
            t_hi, why = 0.44 / f_max, f"0.44/f_max = {0.44 / f_max:g} s"
    # 1e-9 forgives rounding in tau/dt when tau is an exact multiple of dt
    clock_hi = math.floor(t_hi / dt * (1 + 1e-9))
    if clock_hi < 1:
        raise DataError(
            f"PRBS clock faster than the sample rate: the bit time must be <= {why}, but "
            f"one sample is dt = {dt:g} s. Use a faster sample rate, at least "
            f"{1 / t_hi:.4g} Hz"
        )
    clock_lo = max(1, math.ceil(tau / (10 * dt) * (1 - 1e-9)))
    return min(max(round(ratio * tau / dt), clock_lo), clock_hi)


def prbs_length(n: int, clock: int = 1, periods: int = 1) -> int:
    """Samples in ``periods`` periods of an n-bit PRBS.

    Parameters
    ----------
    n : int
        Register length, 2..31.
    clock : int
        Samples per bit (>= 1).
    periods : int
        Whole periods (>= 1).

    Returns
    -------
    int
        ``(2**n - 1)·clock·periods``.

    Examples
    --------
    >>> from servoid.signals import prbs_length
    >>> prbs_length(11, clock=10, periods=2)
    40940
    """
    n = _check_register(n)
    clock = as_int("clock", clock, what=" (samples per bit)")
    periods = as_int("periods", periods)
    return ((1 << n) - 1) * clock * periods


def prbs_register_for(settling_time: float, clock: int, dt: float, factor: float = 5.0) -> int:
    """Smallest register length whose period covers the settling time.

    Spec §3.1: one period ``(2**n - 1)·clock·dt`` must last at least
    ``factor`` (5) settling times, so that the response to one period has
    died out before the next and the period is long enough to resolve the
    low-frequency dynamics.

    Parameters
    ----------
    settling_time : float
        Settling time of the system under test [s], > 0.
    clock : int
        Samples per bit (>= 1), e.g. from :func:`prbs_clock`.
    dt : float
        Sample period [s], > 0.
    factor : float
        Required period / settling time, >= 1.

    Returns
    -------
    int
        Register length n in 2..31.

    Raises
    ------
    DataError
        If even n = 31 is too short.

    Examples
    --------
    >>> from servoid.signals import prbs_register_for
    >>> prbs_register_for(settling_time=0.5, clock=10, dt=1e-3)
    8
    """
    settling_time = as_float("settling_time", settling_time, positive=True, unit=" s")
    clock = as_int("clock", clock, what=" (samples per bit)")
    dt = as_dt(dt)
    factor = as_float("factor", factor)
    if factor < 1:
        raise DataError(f"factor must be >= 1 (period / settling time), got {factor:g}")
    bit_time = clock * dt
    needed = factor * settling_time
    for n in range(_N_MIN, _N_MAX + 1):
        if ((1 << n) - 1) * bit_time >= needed * (1 - 1e-12):
            return n
    raise DataError(
        f"no register length up to {_N_MAX} gives a period of {factor:g} x settling time = "
        f"{needed:g} s with a bit time of {bit_time:g} s; use a slower clock"
    )


def _check_register(n: object) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise OptionTypeError(
            f"register length n must be an integer in {_N_MIN}..{_N_MAX}, "
            f"got {n!r} ({type(n).__name__})"
        )
    if not _N_MIN <= n <= _N_MAX:
        raise DataError(f"register length n must be in {_N_MIN}..{_N_MAX}, got {n}")
    return int(n)


def _hold_half_power(clock: int, dt: float) -> float:
    """Half-power frequency [Hz] of a ``clock``-sample hold, capped at Nyquist.

    The hold multiplies the bit spectrum by ``[sin(pi x)/(m sin(pi x/m))]²``
    with ``x = f·clock·dt`` and ``m = clock``; it decreases from 1 on
    ``0 < x < 1`` and equals 1 everywhere when ``m = 1``.
    """
    if clock == 1:
        return nyquist(dt)

    def gain(x: float) -> float:
        return math.sin(math.pi * x) / (clock * math.sin(math.pi * x / clock)) - _HALF_POWER

    return optimize.brentq(gain, 1e-9, 1.0 - 1e-12, xtol=1e-14) / (clock * dt)
