"""Block models after review: integrators, unused keys refused, units, NARX arrays.

Records are made here with numpy/scipy (a dead zone by numpy.where, the
linear block by scipy.signal.lfilter, white noise), not by the fitting code.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sps

from servoid import IdentifiabilityError, OptionError
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.nonlinear import candidate_terms, fit_block, fit_hammerstein, fit_wiener
from servoid.workflows import identify

DT = 0.01
SIGMA = 0.02
LOWER, UPPER = -0.4, 0.6
INTEGRATOR = np.poly([1.0, 0.5])  # poles at z = 1 and 0.5: x(t) = 1.5x(t−1) − 0.5x(t−2) + …


def _record(u, x, seed):
    rng = np.random.default_rng(seed)
    return Experiment.from_arrays(DT, u=u, y=x + SIGMA * rng.standard_normal(u.size),
                                  names={"u": "valve", "y": "position"},
                                  units={"valve": "V", "position": "mm"})


def _dead_zone(u):
    return np.where(u > UPPER, u - UPPER, np.where(u < LOWER, u - LOWER, 0.0))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_free_scale_shape_on_an_integrator_is_refused(seed):
    # the reviewer's case: G(1) = 1 cannot hold when F(1) = 0; before, c1 came out ≈ 8e3
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.5, 1.5, 3000)
    x = sps.lfilter([0.0, 0.1], INTEGRATOR, u + 0.3 * u**2 - 0.2 * u**3)
    with pytest.raises(IdentifiabilityError, match=r"integrates .*unit-slope shape"):
        fit_hammerstein(_record(u, x, seed + 10), "polynomial", max_iter=50)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.filterwarnings("ignore:the fitted linear block is unstable")  # z = 1 counts
def test_a_unit_slope_shape_on_the_same_integrator_is_recovered(seed):
    # the advice of the refusal works: the linear block keeps the (infinite) gain
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, 3000)
    x = sps.lfilter([0.0, 0.1], INTEGRATOR, _dead_zone(u))
    est = fit_hammerstein(_record(u, x, seed + 20), "deadzone", nb=1, nf=2)
    std = dict(zip(est.names, est.std, strict=True))
    for name, value in {"deadzone.lower": LOWER, "deadzone.upper": UPPER}.items():
        assert abs(est[name] - value) < 4 * std[name], name  # 4σ
    # a unit root has non-standard asymptotics (the 4σ of a stationary pole does not apply):
    # the poles are checked to 0.01, a hundredth of the distance between them
    poles = np.sort(np.roots(est.model.linear.f[0]).real)
    assert poles == pytest.approx([0.5, 1.0], abs=0.01)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(3)
    u = rng.uniform(-2.0, 2.0, 1500)
    return _record(u, sps.lfilter([0.0, 0.5, 0.3], [1.0, -1.2, 0.5], _dead_zone(u)), 4)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"linear": "tf", "nk": 2}, r"nk = 2 is not used by linear = \"tf\".*delay"),
    ({"linear": "tf", "nb": 3}, r"nb = 3 is not used by linear = \"tf\""),
    ({"linear": "oe", "n_poles": 3}, r"n_poles = 3 is not used by linear = \"oe\""),
    ({"degree": 4}, r"degree is for a \"polynomial\" shape given by name.*\"deadzone\""),
    ({"breakpoints": [0.0]}, r"breakpoints is for a \"piecewise-linear\" shape"),
])
def test_a_keyword_the_choice_does_not_use_is_refused(data, kwargs, match):
    with pytest.raises(OptionError, match=match):
        fit_block(data, "hammerstein", input_nonlinearity="deadzone", **kwargs)


def test_units_follow_the_channels_and_the_scale_convention(data):
    est = fit_hammerstein(data, "deadzone")
    units = dict(zip(est.names, est.units, strict=True))
    assert units == {"deadzone.lower": "V", "deadzone.upper": "V", "b0": "mm/V", "b1": "mm/V",
                     "f1": "", "f2": ""}
    poly = fit_hammerstein(data, "polynomial", degree=2)
    units = dict(zip(poly.names, poly.units, strict=True))
    # G(1) = 1 is a pure number, so the curve carries mm per V^k
    assert units["poly.c1"] == "mm/V" and units["poly.c2"] == "mm/V^2" and units["b0"] == ""
    tf = fit_hammerstein(data, "deadzone", linear="tf", n_poles=2, n_zeros=0)
    units = dict(zip(tf.names, tf.units, strict=True))
    assert (units["b0"], units["a1"], units["a2"]) == ("mm/V/s^2", "1/s", "1/s^2")


def test_wiener_shape_units_are_the_output_unit():
    rng = np.random.default_rng(5)
    u = rng.uniform(-2.0, 2.0, 1500)
    x = sps.lfilter([0.0, 0.4, 0.2], [1.0, -1.1, 0.4], u)
    est = fit_wiener(_record(u, np.abs(x - 0.3), 6), "abs")
    units = dict(zip(est.names, est.units, strict=True))
    assert units["abs.center"] == "mm" and units["b0"] == "mm/V"


@pytest.fixture(scope="module")
def rig(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("keys")
    write_csv(data, folder / "run.csv")
    return folder


@pytest.mark.parametrize(("extra", "match"), [
    ({"linear": "tf", "nk": 2}, r"\[identify\] nk is not used by linear = \"tf\""),
    ({"linear": "tf", "nf": 2}, r"\[identify\] nf is not used"),
    ({"n_zeros": 1}, r"\[identify\] n_zeros is not used by linear = \"oe\""),
    ({"input_breakpoints": [0.0]}, r"\[identify\] input_breakpoints is for a piecewise-linear"),
    ({"input_degree": 4}, (r"\[identify\] input_degree is for a polynomial shape and "
                           r"input_nonlinearity = \"deadzone\"")),
    ({"input_nonlinearity": "polynomial", "input_degree": 2, "input_parameters": [1.0, 0.0]},
     r"input_degree and \[identify\] input_parameters both"),
])
def test_the_experiment_file_key_is_named(rig, extra, match):
    table = {"data": {"file": "run.csv"},
             "channels": {"valve": {"source": "valve", "role": "u", "unit": "V"},
                          "position": {"source": "position", "role": "y", "unit": "mm"}},
             "identify": {"method": "hammerstein", "input_nonlinearity": "deadzone", **extra}}
    path = rig / "bad.toml"
    write_experiment_spec(table, path, overwrite=True)
    with pytest.raises(OptionError, match=match):
        identify(path, write=False)


def test_candidate_terms_take_arrays_as_fit_narx_does():
    assert candidate_terms(1, np.array([1, 2]), 0) == candidate_terms(1, [1, 2], 0)
    assert candidate_terms(1, np.array([1, 2]), np.array([0, 1]), degree=2) == \
        candidate_terms(1, (1, 2), (0, 1), degree=2)
