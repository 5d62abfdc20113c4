"""Experiments wrap arrays without copying when that is safe or asked for."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.data import Experiment


def test_default_copies_a_writable_array_and_keeps_it_immutable():
    y = np.arange(10.0)
    exp = Experiment.from_arrays(1e-3, y=y)
    assert not np.shares_memory(exp.channel("y").values, y)
    y[0] = 99.0
    assert exp.channel("y").values[0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        exp.channel("y").values[1] = 5.0


def test_copy_false_wraps_the_callers_memory_read_only():
    y = np.arange(10.0)
    u = np.ones((10, 2))
    exp = Experiment.from_arrays(1e-3, u=u, y=y, copy=False)
    assert np.shares_memory(exp.channel("y").values, y) and np.shares_memory(exp.channels[0].values, u)
    assert y.flags.writeable  # the caller's array is not changed
    with pytest.raises(ValueError, match="read-only"):
        exp.channel("y").values[1] = 5.0


def test_immutable_input_and_slices_are_not_copied():
    y = np.arange(1000.0)
    y.setflags(write=False)
    exp = Experiment.from_arrays(1e-3, y=y)
    assert np.shares_memory(exp.channel("y").values, y)
    part = exp.slice(100, 200)
    assert np.shares_memory(part.channel("y").values, y)
    view = np.arange(10.0)
    ro = view.view()
    ro.setflags(write=False)  # read-only, but its base can still change: copied
    assert not np.shares_memory(Experiment.from_arrays(1e-3, y=ro).channel("y").values, view)


def test_read_only_memory_map_is_wrapped(tmp_path):
    path = tmp_path / "y.npy"
    np.save(path, np.linspace(0, 1, 5000))
    mapped = np.load(path, mmap_mode="r")
    exp = Experiment.from_arrays(1e-3, y=mapped)
    assert np.shares_memory(exp.channel("y").values, mapped)
    np.testing.assert_array_equal(exp.channel("y").values, np.linspace(0, 1, 5000))
