"""Test conditions in the verdict: rate, length, the excitation and its band."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from servoid.data import Experiment
from servoid.signals import multisine, prbs
from servoid.workflows._verdict import excited_band, record_conditions


@pytest.mark.parametrize("clock", [1, 5, 10])
def test_the_band_of_a_prbs_is_the_one_its_designer_declares(clock):
    ex = prbs(11, clock=clock, amplitude=1.0, dt=1e-3)
    (low, high), line = excited_band(ex.values, ex.dt)
    # the designer's -3 dB edge of the sinc² spectrum; the estimate's lies within the main
    # lobe of its Hann window, four of its lines wide
    assert abs(high - ex.band[1]) <= 4 * line
    assert low == pytest.approx(line)  # excited down to the lowest line


def test_the_band_of_a_multisine_is_its_excited_lines():
    ex = multisine(2000, 1e-3, 1.0, 50.0, periods=5)
    (low, high), line = excited_band(ex.values, ex.dt)
    assert abs(low - 1.0) <= line and abs(high - 50.0) <= line  # one line of the spectrum


def test_a_sine_over_a_few_periods_is_resolved_by_the_whole_record():
    t = np.arange(40_000) * 1e-4  # 4 s at 10 kHz: Welch's segments would see 2 Hz lines
    (low, high), line = excited_band(np.sin(2 * np.pi * 1.0 * t), 1e-4)
    assert line == pytest.approx(0.25)  # the whole record's lines
    assert low <= 1.0 <= high and high - low <= 2 * line  # the 1 Hz sine, one line either side


def test_a_constant_signal_has_no_band():
    assert excited_band(np.full(1000, 2.5), 1e-3) is None


def test_a_declared_excitation_gives_its_name_and_band():
    exp = prbs(9, clock=2, amplitude=1.0, dt=1e-3).to_experiment("x_ref", role="r", unit="m")
    c = record_conditions(exp, "estimation: run.csv")
    assert (c.excitation, c.channel, c.band_source) == ("prbs", "x_ref",
                                                        "declared by the excitation")
    assert c.band == exp.notes["excitation"]["band"]
    assert (c.sample_rate, c.n_samples) == (pytest.approx(1000.0), 1022)  # 511 bits × 2


def test_a_constant_reference_gives_way_to_the_input():
    u = np.sign(np.sin(2 * np.pi * 5.0 * np.arange(4000) * 1e-3))  # a 5 Hz square wave
    exp = dataclasses.replace(Experiment.from_arrays(1e-3, r=np.zeros(4000), u=u, y=u),
                              notes={"excitation": "square"})
    c = record_conditions(exp, "friction: friction.tdms")
    assert c.channel == "u" and c.excitation == "square"
    assert c.band[0] <= 5.0 <= c.band[1]
    assert "spectrum within 3 dB of its peak" in c.band_source
    assert c.text().startswith("friction: friction.tdms: 1 kHz, 4000 samples (4 s), "
                               "excitation square, band ")
