"""The shipped DaISy records load as documented."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

from servoid import OptionError
from servoid.datasets import DAISY_RECORDS, _daisy, daisy_path, load_daisy


@pytest.mark.parametrize(("name", "n", "dt"), [("robot_arm", 1024, 1.0), ("dryer", 1000, 0.08),
                                               ("ballbeam", 1000, 0.1)])
def test_records_load_with_their_size_and_rate(name, n, dt):
    exp = load_daisy(name)
    assert exp.n_samples == n and exp.dt == dt and exp.name == name
    assert len(exp.names_of("u")) == 1 and len(exp.names_of("y")) == 1
    assert "De Moor" in exp.notes["citation"]
    raw = np.loadtxt(daisy_path(name))
    np.testing.assert_array_equal(exp.u[:, 0], raw[:, 0])  # byte-for-byte data, no scaling


def test_dryer_input_is_the_documented_binary_signal():
    u = load_daisy("dryer")["heater"]
    assert set(np.round(np.unique(u), 2)) == {3.41, 6.41}


def test_unknown_record_lists_the_shipped_ones():
    with pytest.raises(OptionError, match="'robot_arm', 'dryer', 'ballbeam'"):
        load_daisy("cstr")
    assert DAISY_RECORDS == ("robot_arm", "dryer", "ballbeam")


def test_docstring_example_runs():
    assert doctest.testmod(_daisy).failed == 0
