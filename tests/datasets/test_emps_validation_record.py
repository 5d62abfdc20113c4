"""The shipped second EMPS record (force pulses): bytes, channels and what the pulses are."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from servoid import OptionError
from servoid.datasets import emps_path, load_emps

SHA256 = "0eab75bb1f6b16228ee78791343a88bf9bfd9a51036ac9807d7b5fc11c0e1704"


def test_file_is_the_published_one():
    path = emps_path("validation")
    assert path.name == "DATA_EMPS_PULSES.mat"
    assert path.stat().st_size == 630990
    assert hashlib.sha256(path.read_bytes()).hexdigest() == SHA256
    assert "DATA_EMPS_PULSES.mat" in (path.parent / "PROVENANCE.md").read_text(encoding="utf-8")


def test_channels_units_and_notes_match_the_estimation_record():
    val, est = load_emps("validation"), load_emps()
    assert val.name == "EMPS_PULSES" and val.n_samples == 24841
    assert val.names == ("qg", "vir", "qm", "force", "pulses", "pulse_force")
    assert [val.unit(n) for n in val.names] == ["m", "V", "m", "N", "V", "N"]
    for key in ("kp", "kv", "gtau", "saturation", "citation"):
        assert val.notes[key] == est.notes[key]
    assert val.notes["sha256"] == SHA256
    np.testing.assert_array_equal(val["pulse_force"], val.notes["gtau"] * val["pulses"])


def test_the_pulses_are_volts_inside_the_recorded_voltage():
    val = load_emps("validation")
    p, v = val["pulses"], val["vir"]
    assert set(np.unique(p)) == {0.0, 5.0}
    edges = np.flatnonzero(np.diff(p)) + 1
    assert len(edges) == 49 and np.all(np.diff(edges) == 500)  # a 1 Hz square wave
    # at each edge vir jumps by the pulse step: the loop cannot move in one sample, so the
    # jump is the added 5 V to within the controller's one-sample change (measured <= 0.17 V)
    jumps = (v[edges] - v[edges - 1]) / (p[edges] - p[edges - 1])
    np.testing.assert_allclose(jumps, 1.0, atol=0.08)


def test_unknown_record_is_refused():
    with pytest.raises(OptionError, match="record must be one of 'estimation', 'validation'"):
        load_emps("pulses")
