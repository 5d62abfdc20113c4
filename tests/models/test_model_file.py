"""Models that travel: model files, MATLAB export, and interop for every model type."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import io as sio

from servoid import FileFormatError, MissingFileError, ModelError, OptionError, OutputExistsError
from servoid.models import (
    FrequencyResponseData,
    PolynomialModel,
    StateSpace,
    TransferFunction,
    c2d,
    export_mat,
    from_control,
    from_scipy,
    load_model,
    save_model,
    to_control,
    to_scipy,
)

G = TransferFunction([3451.7], [1 / 163.3**2, 2 * 0.249 / 163.3, 1.0, 0.0])
G_DELAY = TransferFunction([2.0, 1.0], [0.1, 1.2, 1.0], delay=0.0125)
BJ = PolynomialModel([1.0, -0.6], ([0.0, 0.3, 0.1],), (2,), 0.01, c=[1.0, 0.2],
                     d=[1.0, -0.4], f=([1.0, -0.5],), noise_variance=0.03)
MISO = PolynomialModel([1.0, -0.9, 0.2], ([1.0], [0.5, 0.25]), (1, 3), 0.002,
                       input_names=("u1", "u2"), output_name="y")
MODELS = {
    "tf continuous": G,
    "tf with delay": G_DELAY,
    "tf tustin prewarp": c2d(G, 1e-3, "tustin", prewarp=100.0),
    "ss continuous": G.to_ss(),
    "ss zoh": c2d(G.to_ss(), 1e-3),
    "ss mimo": StateSpace(np.diag([-1.0, -2.0]), np.eye(2), [[1.0, 1.0]], [[0.0, 0.5]]),
    "arx": PolynomialModel.arx([1.0, -0.5], [0.0, 1.0], 0, dt=0.01),
    "bj": BJ,
    "two inputs": MISO,
}
FIELDS = {
    TransferFunction: ("num", "den", "dt", "method", "prewarp", "delay"),
    StateSpace: ("A", "B", "C", "D", "dt", "method", "prewarp"),
    PolynomialModel: ("a", "b", "nk", "c", "d", "f", "dt", "noise_variance", "input_names",
                      "output_name"),
}


def _same(a, b):
    assert type(a) is type(b)
    for name in FIELDS[type(a)]:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, tuple) and x and isinstance(x[0], np.ndarray):
            assert len(x) == len(y) and all(np.array_equal(p, q) for p, q in zip(x, y)), name
        elif isinstance(x, np.ndarray):
            assert np.array_equal(x, y), name  # repr floats in JSON read back bit for bit
        else:
            assert x == y, name


# -- model file ---------------------------------------------------------------------------


@pytest.mark.parametrize("model", MODELS.values(), ids=MODELS.keys())
def test_model_file_round_trip_is_exact(tmp_path, model):
    path = save_model(model, tmp_path / "m.json")
    _same(model, load_model(path))
    data = json.loads(path.read_text())
    assert data["servoid_model"] == 1 and data["type"] == type(model).__name__


def test_model_file_keeps_covariance_and_units(tmp_path):
    cov = [[0.04, 0.001], [0.001, 0.09]]
    path = save_model(G_DELAY, tmp_path / "g.json", covariance=cov, units={"u": "V", "y": "mm"})
    data = json.loads(path.read_text())
    assert data["covariance"] == cov and data["units"] == {"u": "V", "y": "mm"}
    assert data["delay"] == 0.0125 and data["dt"] is None


def test_save_model_refuses_to_overwrite(tmp_path):
    path = save_model(G, tmp_path / "g.json")
    with pytest.raises(OutputExistsError, match="overwrite=True"):
        save_model(G_DELAY, path)
    save_model(G_DELAY, path, overwrite=True)
    assert load_model(path).delay == 0.0125


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"covariance": [[1.0, 0.0]]}, ValueError, "square"),
        ({"covariance": [[np.nan]]}, ValueError, "non-finite"),
        ({"units": {"u": 1}}, TypeError, "unit strings"),
    ],
)
def test_save_model_bad_extras(tmp_path, kwargs, error, match):
    with pytest.raises(error, match=match):
        save_model(G, tmp_path / "g.json", **kwargs)
    assert not list(tmp_path.iterdir())  # nothing half written


def test_save_model_refuses_a_measured_response(tmp_path):
    frd = FrequencyResponseData([1.0, 2.0], [1.0 + 0j, 0.5 - 0.5j])
    with pytest.raises(TypeError, match="FrequencyResponseData"):
        save_model(frd, tmp_path / "frd.json")


def test_load_model_of_another_version(tmp_path):
    path = save_model(G, tmp_path / "g.json")
    data = json.loads(path.read_text())
    path.write_text(json.dumps({**data, "servoid_model": 2}))
    with pytest.raises(FileFormatError, match=r"g\.json has format version 2.*reads version 1"):
        load_model(path)


def test_load_model_of_a_damaged_file(tmp_path):
    path = save_model(BJ, tmp_path / "bj.json")
    path.write_text(path.read_text()[:-40])  # truncated
    with pytest.raises(FileFormatError, match=r"bj\.json is not valid JSON.*save_model"):
        load_model(path)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"servoid_model": None}, "format version None"),
        ({"type": "GreyBox"}, "must be one of"),
        ({"den": [0.0]}, "damaged.*den must not be all zero"),
        ({"num": "one"}, "damaged"),
        ({"num": None}, "damaged"),
        ({"dt": -1.0}, "damaged.*dt must be > 0"),
    ],
)
def test_load_model_of_bad_contents(tmp_path, change, match):
    path = save_model(G, tmp_path / "g.json")
    path.write_text(json.dumps({**json.loads(path.read_text()), **change}))
    with pytest.raises(FileFormatError, match=match):
        load_model(path)


def test_load_model_of_a_file_that_is_not_a_model(tmp_path):
    path = tmp_path / "results.json"
    path.write_text('{"model": {}}')
    with pytest.raises(FileFormatError, match="not a servoid model file.*save_model"):
        load_model(path)
    bad = save_model(G, tmp_path / "g.json")
    data = json.loads(bad.read_text())
    del data["den"]
    bad.write_text(json.dumps(data))
    with pytest.raises(FileFormatError, match="has no 'den'"):
        load_model(bad)


def test_load_model_missing_file(tmp_path):
    with pytest.raises(MissingFileError, match="nope.json: no such file"):
        load_model(tmp_path / "nope.json")


# -- MATLAB export ------------------------------------------------------------------------


def _mat(path, name="G"):
    return sio.loadmat(path, squeeze_me=True, struct_as_record=False)[name]


def test_export_mat_transfer_function(tmp_path):
    export_mat(G_DELAY, tmp_path / "g.mat")
    s = _mat(tmp_path / "g.mat")
    assert s.type == "tf" and s.Ts == 0.0 and s.InputDelay == 0.0125
    assert np.array_equal(s.num, G_DELAY.num) and np.array_equal(s.den, G_DELAY.den)
    d = c2d(G, 1e-3, "tustin")
    export_mat(d, tmp_path / "d.mat", name="Gd")
    s = _mat(tmp_path / "d.mat", "Gd")
    assert s.Ts == 1e-3 and s.Method == "tustin" and np.array_equal(s.den, d.den)


def test_export_mat_state_space(tmp_path):
    model = MODELS["ss mimo"]
    export_mat(model, tmp_path / "ss.mat")
    s = _mat(tmp_path / "ss.mat")
    assert s.type == "ss" and s.Ts == 0.0
    for name in "ABCD":
        assert np.array_equal(np.atleast_2d(getattr(s, name)), getattr(model, name)), name


def test_export_mat_polynomial_as_idpoly(tmp_path):
    export_mat(MISO, tmp_path / "p.mat")
    s = _mat(tmp_path / "p.mat")
    assert s.type == "idpoly" and s.Ts == 0.002
    assert np.array_equal(s.A, MISO.a) and np.array_equal(s.nk, [1, 3])
    # one row per input, nk leading zeros (MATLAB's idpoly), zero padded on the right
    assert np.array_equal(s.B, [[0.0, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.5, 0.25]])
    assert np.array_equal(np.reshape(s.F, (2, -1)), [[1.0], [1.0]])  # loadmat squeezes


def test_export_mat_bad_name_and_type(tmp_path):
    with pytest.raises(OptionError, match="MATLAB variable name"):
        export_mat(G, tmp_path / "g.mat", name="1G")
    with pytest.raises(TypeError, match="parametric"):
        export_mat("G", tmp_path / "g.mat")
    assert not list(tmp_path.iterdir())


def test_export_mat_refuses_to_overwrite(tmp_path):
    export_mat(G, tmp_path / "g.mat")
    with pytest.raises(OutputExistsError):
        export_mat(G, tmp_path / "g.mat")
    export_mat(BJ, tmp_path / "g.mat", overwrite=True)
    assert _mat(tmp_path / "g.mat").type == "idpoly"


# -- interop for every model type ---------------------------------------------------------


@pytest.mark.parametrize("model", [G, c2d(G, 1e-3), G.to_ss(), c2d(G.to_ss(), 1e-3), BJ])
def test_servoid_control_scipy_round_trip(model):
    pytest.importorskip("control")
    plain = model.transfer_function(input=0) if isinstance(model, PolynomialModel) else model
    back = from_scipy(to_scipy(from_control(to_control(model))))
    again = from_control(to_control(from_scipy(to_scipy(model))))
    for result in (back, again):
        assert type(result) is type(plain) and result.dt == plain.dt
        names = ("num", "den") if isinstance(plain, TransferFunction) else ("A", "B", "C", "D")
        for name in names:
            # copies of the same coefficients; 1e-12 allows a normalisation by den[0]
            np.testing.assert_allclose(getattr(result, name), getattr(plain, name),
                                       rtol=1e-12, atol=0)


def test_polynomial_model_travels_as_its_transfer_function():
    control = pytest.importorskip("control")
    sys = to_control(BJ)
    assert isinstance(sys, control.TransferFunction) and sys.dt == BJ.dt
    tf = BJ.transfer_function(input=0)
    np.testing.assert_allclose(sys.num[0][0], tf.num, rtol=1e-12)  # same polynomial
    np.testing.assert_allclose(to_scipy(BJ).den, tf.den, rtol=1e-12)  # same polynomial


@pytest.mark.parametrize("convert", [to_scipy, to_control])
def test_what_the_target_cannot_hold(convert):
    pytest.importorskip("control")
    with pytest.raises(ModelError, match=r"2 inputs.*transfer_function\(input=i\)"):
        convert(MISO)
    with pytest.raises(ModelError, match="no delay.*c2d"):
        convert(G_DELAY)
    with pytest.raises(TypeError, match="PolynomialModel"):
        convert(FrequencyResponseData([1.0], [1.0 + 0j]))
