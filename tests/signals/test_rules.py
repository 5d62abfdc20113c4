"""PRBS design rules of models-spec §3.1: clock, register length, samples."""

from __future__ import annotations

import math

import pytest

from servoid import DataError
from servoid.signals import prbs, prbs_clock, prbs_length, prbs_register_for

# (tau [s], dt [s], ratio, f_max [Hz], expected clock or error)
CLOCK_RULES = [
    (0.05, 1e-3, 0.2, None, 10),  # T_b = tau/5
    (0.05, 1e-3, 0.1, None, 5),  # lower edge tau/10
    (0.05, 1e-3, 1 / 3, None, 16),  # round(16.7) = 17 would exceed tau/3: clamped
    (1 / 30, 1e-3, 0.2, None, 7),  # spec: closed-loop tau ≈ 1/30 s at 1 kHz
    (0.003, 1e-3, 0.2, None, 1),  # tau/3 = dt exactly: the fastest legal clock
    (0.0035, 1e-3, 0.1, None, 1),  # tau/10 < dt: clock 1 is the only choice
    (0.05, 1e-3, 0.2, 100.0, 4),  # 0.44/f_max = 4.4 ms beats tau/3 and even tau/10
    (0.05, 1e-3, 0.2, 20.0, 10),  # 0.44/f_max = 22 ms does not bind
    (0.002, 1e-3, 0.2, None, DataError),  # tau/3 < dt
    (0.05, 1e-3, 0.2, 1000.0, DataError),  # 0.44/f_max < dt
]


@pytest.mark.parametrize(("tau", "dt", "ratio", "f_max", "expected"), CLOCK_RULES)
def test_prbs_clock_rule_table(
    tau: float, dt: float, ratio: float, f_max: float | None, expected: int | type
) -> None:
    if isinstance(expected, type):
        with pytest.raises(expected, match="PRBS clock faster than the sample rate"):
            prbs_clock(tau, dt, ratio=ratio, f_max=f_max)
    else:
        assert prbs_clock(tau, dt, ratio=ratio, f_max=f_max) == expected


def test_prbs_clock_error_suggests_a_sample_rate() -> None:
    with pytest.raises(DataError, match=r"tau/3 = 0\.002 s.*faster sample rate, at least 500 Hz"):
        prbs_clock(0.006, 0.01)
    with pytest.raises(DataError, match=r"0\.44/f_max"):
        prbs_clock(0.05, 1e-3, f_max=1000.0)


@pytest.mark.parametrize("tau_over_dt", [3.0, 4.5, 7.0, 10.0, 29.0, 31.0, 100.0, 1234.5])
@pytest.mark.parametrize("ratio", [0.1, 0.2, 0.3, 1 / 3])
def test_prbs_clock_lands_in_the_spec_interval(tau_over_dt: float, ratio: float) -> None:
    dt = 1e-3
    tau = tau_over_dt * dt
    clock = prbs_clock(tau, dt, ratio=ratio)
    assert clock * dt <= tau / 3 * (1 + 1e-9)  # 1e-9: tau/dt rounding
    # below tau/10 only when tau/10 < dt forces clock = 1
    assert clock * dt >= tau / 10 * (1 - 1e-9) or clock == 1
    # and it is the legal clock nearest the target ratio·tau/dt (brute force)
    legal = [m for m in range(1, 2000) if tau / 10 * (1 - 1e-9) <= m * dt <= tau / 3 * (1 + 1e-9)]
    target = ratio * tau_over_dt
    best = min(abs(m - target) for m in legal or [1])
    assert abs(clock - target) <= best + 1e-9  # 1e-9: float error in tau/dt


@pytest.mark.parametrize(
    ("settling_time", "clock", "dt", "expected"),
    [
        (0.5, 10, 1e-3, 8),  # needs 250 bits: 255 = 2^8 - 1
        (0.512, 10, 1e-3, 9),  # needs 256 bits
        (0.001, 1, 1e-3, 3),  # needs 5 bits: 7
        (1e-6, 1, 1e-3, 2),  # the shortest register
    ],
)
def test_prbs_register_for(settling_time: float, clock: int, dt: float, expected: int) -> None:
    n = prbs_register_for(settling_time, clock, dt)
    assert n == expected
    assert prbs(n, clock=clock, dt=dt).duration >= 5 * settling_time * (1 - 1e-12)  # rounding


def test_prbs_register_for_boundary_is_inclusive() -> None:
    # period of n = 8 at 10 ms per bit is 2.55 s = 5 x 0.51 s exactly (up to rounding)
    assert prbs_register_for(0.51, 10, 1e-3) == 8


def test_prbs_register_for_too_long() -> None:
    with pytest.raises(DataError, match=r"no register length up to 31.*use a slower clock"):
        prbs_register_for(1e9, 1, 1e-3)


def test_prbs_length() -> None:
    assert prbs_length(11, clock=10, periods=2) == 40940  # spec §4: 20 470 samples per period
    assert prbs_length(31) == 2**31 - 1
    assert prbs_length(7, clock=3) == prbs(7, clock=3).n_samples


def test_rules_compose_for_the_spec_design() -> None:
    dt, tau, settling = 1e-3, 1 / 30, 0.4
    clock = prbs_clock(tau, dt)
    n = prbs_register_for(settling, clock, dt)
    x = prbs(n, clock=clock, dt=dt, periods=2)
    assert tau / 10 <= x.clock * dt <= tau / 3
    assert x.period * dt >= 5 * settling
    assert math.isclose(x.n_samples, prbs_length(n, clock, periods=2))
