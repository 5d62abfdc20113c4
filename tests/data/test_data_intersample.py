"""detect_intersample: a logged DAC staircase against a band-limited read-back."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import DataError
from servoid.data import IntersampleCheck, decimate, detect_intersample
from servoid.plants.ehsa import EhsaBench, run
from servoid.signals import prbs


@pytest.fixture(scope="module")
def bench_channels():
    """The bench's reference, read back (filtered, decimated) and as the DAC command."""
    bench = EhsaBench(snr_db=None)  # the read-back carries only quantisation: the hard case
    rec = run(bench, prbs(9, clock=10, amplitude=1e-3, dt=bench.dt), rng=0)
    readback = decimate(rec.raw.select("yr_cmd"), bench.decimation)["yr_cmd"]
    return readback, rec.command[:: bench.decimation]


@pytest.mark.parametrize(
    ("signal", "kind"),
    [
        (np.repeat(np.random.default_rng(0).choice([-1.0, 1.0], 200), 10), "zoh"),  # clock 10
        (np.random.default_rng(1).choice([-1.0, 1.0], 2000), "zoh"),  # clock 1: two levels
        (np.random.default_rng(2).integers(-4, 5, 4000) * 0.25, "zoh"),  # 9 levels, clock 1
        (np.sin(0.01 * np.arange(3000)), "bandlimited"),
        (np.round(200 * np.sin(0.002 * np.arange(5000))) / 200, "bandlimited"),  # ADC codes
        (np.random.default_rng(3).standard_normal(1000), "bandlimited"),
    ],
    ids=["prbs-clock10", "prbs-clock1", "multilevel-clock1", "sine", "quantised-sine", "noise"],
)
def test_rule_table(signal, kind):
    check = detect_intersample(signal)
    assert isinstance(check, IntersampleCheck)
    assert check.kind == kind, check.reason
    assert check.reason.startswith("staircase" if kind == "zoh" else "band-limited")


def test_bench_readback_is_band_limited_and_command_a_staircase(bench_channels):
    readback, command = bench_channels
    # the noise-free read-back takes only ~100 values (one per bit pattern and phase), but its
    # transitions run over several samples: not a multi-level command
    back = detect_intersample(readback)
    assert back.kind == "bandlimited" and back.levels < 0.05 * readback.size
    cmd = detect_intersample(command)
    assert cmd.kind == "zoh"
    # clock 10: a jump can only fall on every 10th step, and half the bits change
    assert cmd.flat_fraction == pytest.approx(0.95, abs=0.01)
    assert cmd.isolated_jumps == 1.0


def test_evidence_fields():
    check = detect_intersample(np.repeat([1.0, -1.0, -1.0, 1.0], 10))
    assert check.levels == 2
    assert check.flat_fraction == pytest.approx(37 / 39)  # 39 steps, 2 of them jumps
    assert "repeat the previous one" in check.reason


@pytest.mark.parametrize(
    ("signal", "match"),
    [
        (np.ones(50), "constant"),
        (np.arange(5.0), "at least 8 samples"),
        (np.array([0.0, 1.0, np.nan, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]), "finite"),
        (np.zeros((10, 2)), "1-D"),
    ],
)
def test_bad_input(signal, match):
    with pytest.raises(DataError, match=match):
        detect_intersample(signal)
