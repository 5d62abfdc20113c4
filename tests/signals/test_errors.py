"""Every bad argument raises a clear error naming parameter, value and expectation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from servoid import DataError, OptionError
from servoid import signals as servoid_signals
from servoid.signals import (
    chirp,
    crest_factor,
    multisine,
    power_spectrum,
    prbs,
    prbs_clock,
    prbs_length,
    prbs_register_for,
    random_binary,
    steps,
)

BAD_INPUTS: list[tuple[str, Callable[[], object], type[Exception], str]] = [
    # prbs
    ("n too small", lambda: prbs(1), DataError, r"register length n must be in 2\.\.31, got 1"),
    ("n too big", lambda: prbs(32), DataError, r"register length n must be in 2\.\.31, got 32"),
    ("n float", lambda: prbs(7.0), TypeError, r"n must be an integer in 2\.\.31, got 7\.0"),  # type: ignore[arg-type]
    ("n bool", lambda: prbs(True), TypeError, r"register length n must be an integer"),  # type: ignore[arg-type]
    ("clock 0", lambda: prbs(5, clock=0), DataError,
     r"clock must be a positive integer \(samples per bit\), got 0"),
    ("clock 1.5", lambda: prbs(5, clock=1.5), TypeError,  # type: ignore[arg-type]
     r"clock must be a positive integer \(samples per bit\), got 1\.5"),
    ("amplitude 0", lambda: prbs(5, amplitude=0.0), DataError, r"amplitude must be > 0, got 0"),
    ("amplitude -1", lambda: prbs(5, amplitude=-1.0), DataError, r"amplitude must be > 0, got -1"),
    ("amplitude nan", lambda: prbs(5, amplitude=np.nan), DataError,
     r"amplitude must be finite, got nan"),
    ("offset inf", lambda: prbs(5, offset=np.inf), DataError, r"offset must be finite, got inf"),
    ("periods 0", lambda: prbs(5, periods=0), DataError,
     r"periods must be a positive integer, got 0"),
    ("dt 0", lambda: prbs(5, dt=0.0), DataError, r"dt must be > 0 s, got 0"),
    ("dt str", lambda: prbs(5, dt="1ms"), TypeError, r"dt must be a real number s, got str"),  # type: ignore[arg-type]
    ("seed 0", lambda: prbs(5, seed_state=0), DataError, r"seed_state must be a positive integer"),
    ("seed big", lambda: prbs(5, seed_state=32), DataError,
     r"seed_state must be a non-zero 5-bit register, 1\.\.31, got 32"),
    # random_binary
    ("rbs no rng", lambda: random_binary(10, rng=None), TypeError,  # type: ignore[arg-type]
     r"random_binary needs rng=, a numpy\.random\.Generator or an integer seed"),
    ("rbs negative seed", lambda: random_binary(10, rng=-1), DataError,
     r"rng seed must be >= 0, got -1"),
    ("rbs 1 sample", lambda: random_binary(1, rng=0), DataError,
     r"n_samples must be an integer >= 2, got 1"),
    # prbs_clock / prbs_register_for / prbs_length
    ("tau 0", lambda: prbs_clock(0.0, 1e-3), DataError, r"tau must be > 0 s, got 0"),
    ("ratio", lambda: prbs_clock(0.05, 1e-3, ratio=0.5), DataError,
     r"ratio = T_b/tau must be within \[0\.1, 1/3\] \(spec §3\.1\), got 0\.5"),
    ("f_max 0", lambda: prbs_clock(0.05, 1e-3, f_max=0.0), DataError,
     r"f_max must be > 0 Hz, got 0"),
    ("clock too fast", lambda: prbs_clock(1e-3, 1e-3), DataError,
     r"PRBS clock faster than the sample rate.*faster sample rate"),
    ("settling 0", lambda: prbs_register_for(0.0, 1, 1e-3), DataError,
     r"settling_time must be > 0 s, got 0"),
    ("factor", lambda: prbs_register_for(1.0, 1, 1e-3, factor=0.5), DataError,
     r"factor must be >= 1 \(period / settling time\), got 0\.5"),
    ("length n", lambda: prbs_length(40), DataError, r"register length n must be in 2\.\.31"),
    # multisine
    ("ms f_max nyquist", lambda: multisine(100, 1e-3, 1.0, 500.0), DataError,
     r"f_max must be below the Nyquist frequency 1/\(2·dt\) = 500 Hz, got 500 Hz"),
    ("ms f_min > f_max", lambda: multisine(100, 1e-3, 50.0, 20.0), DataError,
     r"f_min must be <= f_max = 20 Hz, got 50 Hz"),
    ("ms f_min < 0", lambda: multisine(100, 1e-3, -1.0, 20.0), DataError,
     r"f_min must be >= 0 Hz, got -1"),
    ("ms period", lambda: multisine(3, 1e-3, 1.0, 20.0), DataError,
     r"period must be an integer >= 4 \(samples per period\), got 3"),
    ("ms no line", lambda: multisine(100, 1e-3, 1.0, 5.0), DataError,
     r"no harmonic of 1/\(period·dt\) = 10 Hz lies in \[1, 5\] Hz; lengthen the period"),
    ("ms no odd line", lambda: multisine(100, 1e-3, 15.0, 25.0, harmonics="odd"), DataError,
     r"no odd harmonic"),
    ("ms amplitude", lambda: multisine(100, 1e-3, 10.0, 20.0, amplitude=0.0), DataError,
     r"amplitude must be > 0, got 0"),
    ("ms phases", lambda: multisine(100, 1e-3, 10.0, 20.0, phases="newman"), OptionError,  # type: ignore[arg-type]
     r"phases must be one of 'schroeder', 'random', 'zero'; got 'newman'"),
    ("ms harmonics", lambda: multisine(100, 1e-3, 10.0, 20.0, harmonics="even"), OptionError,  # type: ignore[arg-type]
     r"harmonics must be one of 'all', 'odd', 'log'; got 'even'"),
    ("ms scale", lambda: multisine(100, 1e-3, 10.0, 20.0, scale="pp"), OptionError,  # type: ignore[arg-type]
     r"scale must be one of 'peak', 'rms'; got 'pp'"),
    ("ms random no rng", lambda: multisine(100, 1e-3, 10.0, 20.0, phases="random"), TypeError,
     r'multisine\(phases="random"\) needs rng='),
    ("ms per_decade", lambda: multisine(100, 1e-3, 10.0, 20.0, per_decade=0), DataError,
     r"per_decade must be a positive integer, got 0"),
    # chirp
    ("chirp both lengths", lambda: chirp(dt=1e-3, f0=1.0, f1=2.0, n_samples=10, duration=1.0),
     DataError, r"give exactly one of n_samples and duration"),
    ("chirp no length", lambda: chirp(dt=1e-3, f0=1.0, f1=2.0), DataError,
     r"give exactly one of n_samples and duration, got n_samples=None, duration=None"),
    ("chirp short", lambda: chirp(dt=1e-3, f0=1.0, f1=2.0, duration=1e-3), DataError,
     r"duration = 0\.001 s is under 2 samples of dt = 0\.001 s"),
    ("chirp f1 nyquist", lambda: chirp(dt=1e-3, f0=1.0, f1=600.0, n_samples=10), DataError,
     r"f1 must be below the Nyquist frequency 1/\(2·dt\) = 500 Hz, got 600 Hz"),
    ("chirp f0 < 0", lambda: chirp(dt=1e-3, f0=-1.0, f1=2.0, n_samples=10), DataError,
     r"f0 must be >= 0 Hz, got -1"),
    ("chirp log f0 = 0",
     lambda: chirp(dt=1e-3, f0=0.0, f1=2.0, n_samples=10, method="logarithmic"), DataError,
     r"f0 must be > 0 Hz, got 0"),
    ("chirp method", lambda: chirp(dt=1e-3, f0=1.0, f1=2.0, n_samples=10, method="quadratic"),  # type: ignore[arg-type]
     OptionError, r"method must be one of 'linear', 'logarithmic'; got 'quadratic'"),
    ("chirp amplitude", lambda: chirp(dt=1e-3, f0=1.0, f1=2.0, n_samples=10, amplitude=-2.0),
     DataError, r"amplitude must be > 0, got -2"),
    # steps
    ("steps empty", lambda: steps([], 3), DataError, r"levels needs at least 1 samples, got 0"),
    ("steps nan", lambda: steps([0.0, np.nan], 3), DataError, r"levels must be finite"),
    ("steps hold 0", lambda: steps([0.0, 1.0], 0), DataError,
     r"hold_samples must be a positive integer, got 0"),
    ("steps hold float", lambda: steps([0.0, 1.0], 2.5), TypeError,  # type: ignore[arg-type]
     r"hold_samples must be a positive integer, got 2\.5"),
    ("steps hold count", lambda: steps([0.0, 1.0, 2.0], [3, 4]), DataError,
     r"hold_samples has 2 entries for 3 levels"),
    ("steps one sample", lambda: steps([1.0], 1), DataError,
     r"steps needs at least 2 samples in total, got 1"),
    ("steps mirror", lambda: steps([0.0, 1.0], 2, mirror="yes"), TypeError,  # type: ignore[arg-type]
     r"mirror must be a bool, got str"),
    # power_spectrum / crest_factor
    ("spectrum dt", lambda: power_spectrum(np.ones(8)), DataError,
     r"dt \[s\] is required when x is an array"),
    ("spectrum dt mismatch", lambda: power_spectrum(prbs(3, dt=1e-3), dt=1e-2), DataError,
     r"dt = 0\.01 s disagrees with the Excitation's dt = 0\.001 s"),
    ("spectrum period", lambda: power_spectrum(np.ones(8), 1.0, period=9), DataError,
     r"period = 9 samples is longer than the signal \(8\)"),
    ("spectrum nperseg", lambda: power_spectrum(np.ones(8), 1.0, periodic=False, nperseg=16),
     DataError, r"nperseg must be <= the signal length 8, got 16"),
    ("spectrum periodic", lambda: power_spectrum(np.ones(8), 1.0, periodic="yes"), TypeError,  # type: ignore[arg-type]
     r"periodic must be a bool or None, got str"),
    ("spectrum 2-D", lambda: power_spectrum(np.ones((4, 2)), 1.0), DataError,
     r"x must be 1-D, got an array of shape \(4, 2\)"),
    ("crest constant", lambda: crest_factor(np.ones(5)), DataError,
     r"crest factor of a constant signal is undefined"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [case[1:] for case in BAD_INPUTS],
    ids=[case[0] for case in BAD_INPUTS],
)
def test_bad_input(call: Callable[[], object], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        call()


def test_errors_are_value_errors_for_bad_values() -> None:
    # DataError and OptionError derive from ValueError, so plain except clauses work too
    with pytest.raises(ValueError):
        prbs(40)
    with pytest.raises(ValueError):
        multisine(100, 1e-3, 10.0, 20.0, phases="x")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: servoid_signals.prbs(31), r"2,147,483,647 samples .* raise max_samples"),
        (lambda: servoid_signals.chirp(dt=1e-3, f0=1.0, f1=10.0, duration=1e9), r"chirp would have"),
        (lambda: servoid_signals.multisine(100_000, 1e-3, 1.0, 10.0, periods=10_000), "multisine"),
        (lambda: servoid_signals.random_binary(10**9, rng=0), "random binary"),
        (lambda: servoid_signals.steps([0.0, 1.0], 10**9), "step sequence"),
    ],
)
def test_a_signal_over_the_sample_budget_is_refused_before_allocation(call, match):
    with pytest.raises(DataError, match=match):
        call()


def test_the_budget_can_be_raised_explicitly():
    assert servoid_signals.prbs(10, max_samples=2000).n_samples == 1023
    with pytest.raises(DataError, match="budget of 1,000"):
        servoid_signals.prbs(10, max_samples=1000)
