"""Experiment construction, validation, immutability, slicing and sets."""

from __future__ import annotations

import numpy as np
import pytest

import servoid.data as sd
from servoid import ChannelError, DataError, Experiment, ExperimentSet
from servoid.data import Channel


def _exp(n: int = 100, dt: float = 0.01, **kw: object) -> Experiment:
    t = np.arange(n) * dt
    return Experiment.from_arrays(dt, u=np.sin(t), y=np.cos(t), **kw)


def test_exports_are_pinned() -> None:
    for name in sd.__all__:
        assert hasattr(sd, name)


def test_from_arrays_metadata() -> None:
    exp = Experiment.from_arrays(
        0.001, r=np.zeros(10), u=np.ones((10, 2)), y=np.arange(10.0),
        side={"p": np.ones(10)}, names={"y": "position", "u": ["i1", "i2"]},
        units={"position": "m", "p": "Pa"}, t0=2.0, name="run",
    )
    assert exp.names == ("r", "i1", "i2", "position", "p")
    assert exp.names_of("u") == ("i1", "i2")
    assert exp.unit("position") == "m" and exp.unit("r") == ""
    assert exp.u.shape == (10, 2) and exp.y.shape == (10, 1)
    assert exp.t0 == 2.0 and exp.dt == 0.001 and len(exp) == 10
    assert exp.time[0] == 2.0


def test_time_column_gives_dt_and_t0() -> None:
    t = 5.0 + 0.002 * np.arange(50)
    exp = Experiment.from_arrays(y=np.ones(50), time=t)
    # dt is the mean step of the stamps: equal up to rounding of the arange products.
    assert exp.dt == pytest.approx(0.002, rel=1e-12)
    assert exp.t0 == 5.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"y": [0.0, np.nan, 1.0]}, r"1 non-finite value\(s\), the first \(NaN\) at sample 1"),
        ({"y": [0.0, 1.0, np.inf]}, r"non-finite value\(s\), the first \(inf\) at sample 2"),
        ({"u": np.ones(10), "y": np.ones(11)}, r"equal lengths, got u: 10, y: 11"),
        ({"y": np.ones((3, 5))}, r"more channels than samples.*pass y\.T"),
        ({"y": np.ones(5), "dt": 0.0}, r"dt must be > 0 s, got 0"),
        ({"y": np.ones(5), "dt": -0.01}, r"dt must be > 0 s, got -0.01"),
        ({"y": np.ones(5), "dt": None}, r"give either dt \[s\] or a time column"),
        ({"y": [1.0], "dt": 0.1}, r"at least 2 samples"),
        (
            {"y": np.ones(5), "dt": None, "time": [0.0, 0.1, 0.2, 0.35, 0.4]},
            r"time stamps are not uniform: step 2",
        ),
        ({"y": np.ones(3), "dt": None, "time": [0.0, 0.1]}, r"time has shape \(2,\)"),
    ],
)
def test_construction_errors(kwargs: dict, message: str) -> None:
    kwargs = {"dt": 0.01, **kwargs}
    with pytest.raises(DataError, match=message):
        Experiment.from_arrays(kwargs.pop("dt"), **kwargs)


def test_dt_wrong_type() -> None:
    with pytest.raises(TypeError, match="dt must be a number of seconds"):
        Experiment((Channel("y", "y", np.ones(3)),), "0.1")  # type: ignore[arg-type]


def test_duplicate_names() -> None:
    with pytest.raises(DataError, match="repeated: a"):
        Experiment((Channel("a", "y", np.ones(3)), Channel("a", "u", np.ones(3))), 0.1)


def test_missing_role_names_what_exists() -> None:
    exp = _exp()
    with pytest.raises(DataError, match=r"no reference \('r'\) channel; it has: u \(u\), y \(y\)"):
        exp.signal("r")
    assert exp.r is None
    assert exp.signal("u").shape == (100, 1)


def test_missing_channel_lists_others() -> None:
    with pytest.raises(ChannelError, match="no channel named 'x'; this experiment has: u, y"):
        _exp().channel("x")


def test_inputs_not_modified_and_values_read_only() -> None:
    y = np.linspace(0, 1, 20)
    before = y.copy()
    exp = Experiment.from_arrays(0.1, y=y)
    y[0] = 99.0  # the experiment holds its own copy
    assert exp["y"][0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        exp["y"][1] = 5.0
    with pytest.raises(ValueError, match="read-only"):
        exp.y[0, 0] = 5.0
    processed = exp.detrend("mean").lowpass(1.0)
    np.testing.assert_array_equal(exp["y"], before)
    assert processed is not exp
    with pytest.raises(AttributeError):
        exp.dt = 1.0  # type: ignore[misc]


def test_slice_keeps_t0_and_metadata() -> None:
    exp = _exp(units={"y": "m"}, t0=1.0, name="run")
    part = exp.slice(30, 60)
    assert part.t0 == pytest.approx(1.0 + 30 * 0.01, abs=1e-15)  # one rounding of 30·dt
    assert part.n_samples == 30 and part.unit("y") == "m" and part.name == "run"
    np.testing.assert_array_equal(part["u"], exp["u"][30:60])
    with pytest.raises(DataError, match="leaves 1"):
        exp.slice(5, 6)


def test_channel_operations() -> None:
    exp = _exp().add_channel("p", np.ones(100), unit="Pa")
    assert exp.select("y", "u").names == ("y", "u")
    assert exp.drop("p").names == ("u", "y")
    assert exp.rename({"y": "pos"}).names == ("u", "pos", "p")
    assert exp.with_role("p", "r").names_of("r") == ("p",)
    with pytest.raises(ChannelError):
        exp.select("nope")


def test_experiment_set_checks() -> None:
    a, b = _exp(), _exp(50)
    ok = ExperimentSet((a, b))
    assert len(ok) == 2 and ok.n_samples == 150 and ok.dt == 0.01
    assert sd.as_segments(a) == (a,)
    with pytest.raises(DataError, match=r"segment 1 has dt = 0.02 s but segment 0 has 0.01 s"):
        ExperimentSet((a, _exp(dt=0.02)))
    with pytest.raises(DataError, match="segment 1 has channels"):
        ExperimentSet((a, a.rename({"y": "pos"})))
    with pytest.raises(DataError, match="at least one experiment"):
        ExperimentSet(())


def test_notes_are_read_only():
    exp = Experiment.from_arrays(0.1, y=[1.0, 2.0, 3.0])
    with pytest.raises(TypeError):
        exp.notes["x"] = 1  # type: ignore[index]


def test_indexing_by_slice_points_to_slice_method():
    exp = Experiment.from_arrays(0.1, y=np.arange(30.0))
    with pytest.raises(TypeError, match=r"exp.slice\(start, stop\)"):
        exp[10:20]  # type: ignore[index]
