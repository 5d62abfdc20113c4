"""The amplitude rule of servoid.signals: known answers and bad input."""

from __future__ import annotations

import math

import pytest

from servoid._errors import DataError
from servoid.signals import Limit, largest_amplitude, prbs


def test_binding_limit_and_margin():
    limits = [Limit("pressure", 3e10, 7e6, "Pa"), Limit("stroke", 1.0, 0.023, "m", static=0.003)]
    rule = largest_amplitude(limits)
    assert rule.binding == "pressure" and rule.amplitude == pytest.approx(7e6 / 3e10)
    assert [lim.name for lim in rule.exceeded(1e-3)] == ["pressure"]
    assert rule.table(1e-3)[1]["peak"] == pytest.approx(0.004)
    half = largest_amplitude(limits, margin=0.5)
    assert half.amplitude == pytest.approx(rule.amplitude / 2)
    assert largest_amplitude([Limit("none", 0.0, 1.0)]).amplitude == math.inf


def test_bad_limits():
    with pytest.raises(DataError, match="one or more"):
        largest_amplitude([])
    with pytest.raises(DataError, match="margin must lie in"):
        largest_amplitude([Limit("x", 1.0, 1.0)], margin=2.0)
    with pytest.raises(DataError, match="the operating point alone puts the stroke"):
        largest_amplitude([Limit("stroke", 1.0, 0.02, "m", static=0.03)])


def test_with_amplitude_scales_about_the_offset():
    ex = prbs(5, amplitude=2.0, offset=1.0, dt=1e-3)
    small = ex.with_amplitude(0.5)
    assert small.values.max() == pytest.approx(1.5) and small.values.min() == pytest.approx(0.5)
    assert small.amplitude == 0.5 and small.period == ex.period
