"""Round trips to and from scipy.signal and python-control."""

import sys

import numpy as np
import pytest
from scipy import signal

from servoid.models import (
    StateSpace,
    TransferFunction,
    c2d,
    from_control,
    from_scipy,
    to_control,
    to_scipy,
)

G = TransferFunction([3451.7], [1 / 163.3**2, 2 * 0.249 / 163.3, 1.0, 0.0])


@pytest.mark.parametrize("model", [G, c2d(G, 1e-3, "tustin"), G.to_ss(), c2d(G.to_ss(), 1e-3)])
def test_scipy_round_trip(model):
    obj = to_scipy(model)
    assert isinstance(obj, signal.dlti if model.dt else signal.lti)
    if model.dt:
        assert obj.dt == model.dt
    back = from_scipy(obj)
    assert type(back) is type(model) and back.dt == model.dt
    for name in ("num", "den") if isinstance(model, TransferFunction) else ("A", "B", "C", "D"):
        assert np.array_equal(getattr(back, name), getattr(model, name))  # copied, not computed


def test_from_scipy_zpk():
    back = from_scipy(signal.ZerosPolesGain([-1.0], [-2.0, -3.0], 4.0))
    assert np.allclose(back.num, [4.0, 4.0]) and np.allclose(back.den, [1.0, 5.0, 6.0])


@pytest.mark.parametrize("model", [G, c2d(G, 1e-3, "tustin"), G.to_ss(), c2d(G.to_ss(), 1e-3)])
def test_control_round_trip(model):
    control = pytest.importorskip("control")
    obj = to_control(model)
    assert obj.dt == (0 if model.dt is None else model.dt)
    w = np.array([1.0, 100.0])
    # python-control evaluates the same polynomials/matrices
    assert np.allclose(
        obj(1j * w if model.dt is None else np.exp(1j * w * model.dt)).ravel(),
        np.ravel(model.freqresp(w)),
        rtol=1e-10,
    )
    back = from_control(obj)
    assert type(back) is type(model) and back.dt == model.dt
    assert isinstance(obj, control.TransferFunction | control.StateSpace)


def test_missing_control_raises_helpful_import_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)
    with pytest.raises(ImportError, match=r"pip install servoid\[control\]"):
        to_control(G)


def test_bad_objects_raise():
    with pytest.raises(TypeError, match="lti or dlti"):
        from_scipy(G)
    with pytest.raises(TypeError, match="transfer_function"):
        to_scipy("G")
    with pytest.raises(TypeError, match="control.TransferFunction"):
        from_control(StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))
