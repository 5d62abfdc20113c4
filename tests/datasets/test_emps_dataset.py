"""The shipped EMPS record: bytes, channels, units and loop scalars."""

from __future__ import annotations

import hashlib
from importlib import resources

import numpy as np
import pytest

from servoid.datasets import emps_path, load_emps

SHA256 = "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e"


def test_file_is_the_published_one():
    path = emps_path()
    assert path.stat().st_size == 626039
    assert hashlib.sha256(path.read_bytes()).hexdigest() == SHA256


def test_package_data_is_found_through_importlib_resources():
    # what an installed (or editable) package sees, not a path relative to the repository
    folder = resources.files("servoid.datasets").joinpath("emps")
    assert folder.joinpath("DATA_EMPS.mat").is_file()
    assert "Janot" in folder.joinpath("PROVENANCE.md").read_text(encoding="utf-8")


def test_channels_roles_units_and_notes():
    exp = load_emps()
    assert exp.n_samples == 24841
    assert exp.dt == pytest.approx(1e-3, rel=1e-4)  # mean step of the time vector
    assert exp.names_of("r") == ("qg",)
    assert exp.names_of("u") == ("vir",)
    assert exp.names_of("y") == ("qm",)
    assert [exp.unit(n) for n in ("qg", "qm", "vir", "force")] == ["m", "m", "V", "N"]
    assert exp.notes["kp"] == 160.18
    assert exp.notes["kv"] == 243.45
    assert exp.notes["gtau"] == pytest.approx(35.15065188, abs=1e-8)
    assert exp.notes["saturation"] == 10.0
    assert "Janot" in exp.notes["citation"]
    np.testing.assert_array_equal(exp["force"], exp.notes["gtau"] * exp["vir"])
    assert -1e-4 < exp["qm"].min() and exp["qm"].max() < 0.25  # PROVENANCE: 0 … 0.2465 m
    assert np.abs(exp["vir"]).max() < 10  # the record never saturates
