"""The Excitation record and its conversion to an Experiment."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from servoid import DataError, Experiment, OptionError
from servoid.signals import Excitation, chirp, multisine, prbs, steps


@pytest.mark.parametrize("role", ["r", "u", "side"])
def test_to_experiment_round_trip(role: str) -> None:
    x = prbs(7, clock=3, amplitude=1e-3, periods=2, dt=1e-3)
    exp = x.to_experiment("x_ref", role=role, unit="m")  # type: ignore[arg-type]
    assert isinstance(exp, Experiment)
    assert exp.names == ("x_ref",)
    assert exp.names_of(role) == ("x_ref",)  # type: ignore[arg-type]
    assert np.array_equal(exp["x_ref"], x.values)
    assert exp.dt == x.dt and exp.unit("x_ref") == "m"
    np.testing.assert_array_equal(exp.time, x.time)
    assert exp.duration == x.duration
    record = exp.notes["excitation"]
    assert record["kind"] == "prbs" and record["period"] == x.period and record["clock"] == 3
    assert record["description"]["n"] == 7


def test_to_experiment_defaults_and_bad_role() -> None:
    exp = steps([0.0, 1.0], 3).to_experiment()
    assert exp.names_of("r") == ("r",)
    with pytest.raises(OptionError, match=r"role must be one of 'r', 'u', 'side'; got 'y'"):
        steps([0.0, 1.0], 3).to_experiment(role="y")  # type: ignore[arg-type]


def test_properties() -> None:
    x = chirp(dt=0.01, f0=1.0, f1=4.0, n_samples=50)
    assert x.n_samples == len(x) == 50
    assert x.duration == pytest.approx(0.5, rel=1e-15)  # one product
    np.testing.assert_allclose(x.time, 0.01 * np.arange(50), rtol=1e-15)  # one product each
    assert "chirp" in repr(x)


def test_values_are_a_read_only_copy_and_record_is_frozen() -> None:
    raw = np.array([0.0, 1.0, 0.0, 1.0])
    x = Excitation(raw, 1.0, "custom", period=2, band=(0.5, 0.5), amplitude=0.5, offset=0.5)
    raw[0] = 9.0
    assert x.values[0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        x.values[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        x.dt = 2.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        x.description["n"] = 3  # type: ignore[index]


@pytest.mark.parametrize(
    ("changes", "error", "match"),
    [
        ({"values": [1.0]}, DataError, r"values needs at least 2 samples, got 1"),
        ({"values": [[1.0, 2.0]]}, DataError, r"values must be 1-D"),
        ({"values": [1.0, np.nan]}, DataError, r"values must be finite, got nan at sample 1"),
        ({"dt": 0.0}, DataError, r"dt must be > 0 s, got 0"),
        ({"dt": "1"}, TypeError, r"dt must be a real number"),
        ({"kind": ""}, DataError, r"kind must be a non-empty string"),
        ({"period": 3}, DataError, r"period = 3 samples must divide the length 4"),
        ({"period": 0}, DataError, r"period must be a positive integer"),
        ({"clock": 1.5}, TypeError, r"clock must be a positive integer \(samples per bit\)"),
        ({"band": (0.3, 0.1)}, DataError, r"band must satisfy 0 <= f_lo <= f_hi <= 0.5 Hz"),
        ({"band": (0.0, 0.6)}, DataError, r"Nyquist\), got \(0, 0.6\)"),
        ({"amplitude": -1.0}, DataError, r"amplitude must be >= 0, got -1"),
    ],
)
def test_constructor_checks(changes: dict, error: type, match: str) -> None:
    base = {
        "values": [0.0, 1.0, 0.0, 1.0],
        "dt": 1.0,
        "kind": "custom",
        "period": 2,
        "band": (0.5, 0.5),
        "amplitude": 0.5,
        "offset": 0.5,
    }
    with pytest.raises(error, match=match):
        Excitation(**{**base, **changes})


def test_every_designer_records_consistent_fields() -> None:
    designs = [
        prbs(6, clock=2, dt=0.01),
        multisine(200, 0.01, 1.0, 20.0, periods=2),
        chirp(dt=0.01, f0=0.5, f1=10.0, n_samples=300),
        steps([1.0, 2.0], 50, dt=0.01),
    ]
    for x in designs:
        assert x.dt == 0.01
        assert 0 <= x.band[0] <= x.band[1] <= 0.5 / x.dt
        peak = np.max(np.abs(x.values - x.offset))
        if x.kind == "chirp":
            assert peak <= x.amplitude  # the samples may miss the sine's crest
        else:
            assert peak == pytest.approx(x.amplitude, rel=1e-12)  # one scaling
        if x.period is not None:
            assert x.n_samples % x.period == 0
