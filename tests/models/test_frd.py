"""FrequencyResponseData: construction checks, views, interpolation, selection, JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import DataError, ModelError
from servoid.models import FrequencyResponseData, NonlinearDistortion

F = np.array([1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0])
CORNER = 10.0  # first-order lag 1/(1 + j·f/10)
G = 1.0 / (1.0 + 1j * F / CORNER)


def _frd(**kw):
    args = {"variance": np.full(F.size, 1e-4), "coherence": np.full(F.size, 0.99)}
    args.update(kw)
    return FrequencyResponseData(F, G, **args)


def test_views_of_a_first_order_lag():
    frd = _frd()
    # closed forms of 1/(1 + j·f/fc): |G| = 1/√(1 + (f/fc)²), ∠G = −atan(f/fc); rounding only
    np.testing.assert_allclose(frd.magnitude_db, -10 * np.log10(1 + (F / CORNER) ** 2),
                               atol=1e-12)
    np.testing.assert_allclose(frd.phase_deg, -np.degrees(np.arctan(F / CORNER)), atol=1e-12)
    np.testing.assert_allclose(frd.omega, 2 * np.pi * F)
    np.testing.assert_allclose(frd.std, 1e-2)
    assert frd.n_lines == len(frd) == F.size


def test_arrays_are_read_only_copies():
    values = G.copy()
    frd = FrequencyResponseData(F, values)
    values[0] = 99.0
    assert frd.response[0] == G[0]
    with pytest.raises(ValueError, match="read-only"):
        frd.response[0] = 1.0


def test_freqresp_returns_lines_and_interpolates_between_them():
    f = np.linspace(1.0, 100.0, 991)
    dense = FrequencyResponseData(f, 1.0 / (1.0 + 1j * f / CORNER))
    on_lines = dense.freqresp(2 * np.pi * f[::10])
    np.testing.assert_array_equal(on_lines, dense.response[::10])
    mid = f[:-1] + 0.05  # halfway between lines 0.1 Hz apart
    got = dense.freqresp(2 * np.pi * mid)
    exact = 1.0 / (1.0 + 1j * mid / CORNER)
    # linear interpolation of log|G| and phase: error ≤ h²/8·max|f''| with h = 0.1 Hz and the
    # curvature of both below 0.02 /Hz² for this lag, so ≤ 3e-5
    assert np.max(np.abs(got / exact - 1)) < 3e-5


def test_freqresp_refuses_to_extrapolate():
    with pytest.raises(ModelError, match=r"measured on 1..100 Hz only.*fit_frf"):
        _frd().freqresp([2 * np.pi * 200.0])


def test_select_keeps_a_band():
    sub = _frd().select(f_min=2.0, f_max=50.0)
    np.testing.assert_array_equal(sub.frequency, [2.0, 5.0, 10.0, 20.0, 50.0])
    np.testing.assert_array_equal(sub.variance, 1e-4)
    assert sub.coherence.size == 5
    with pytest.raises(DataError, match="no line lies in"):
        _frd().select(f_min=200.0)


def test_to_dict_is_strict_json():
    distortion = NonlinearDistortion(True, 1e-9, 1e-3, np.array([3.0]), np.array([2.0]),
                                     np.array([0.5]), odd_db=6.02, even_db=None)
    frd = _frd(distortion=distortion, input_unit="V", output_unit="mm", method="periodic",
               n_averages=8, dt=1e-3)
    doc = json.loads(json.dumps(frd.to_dict(), allow_nan=False))
    assert doc["frequency"] == F.tolist()
    np.testing.assert_allclose(np.array(doc["real"]) + 1j * np.array(doc["imag"]), G)
    assert doc["distortion"]["detected"] is True and doc["distortion"]["even_db"] is None
    assert frd.unit == "mm/V" and doc["n_averages"] == 8
    # the DC line of a differentiator has −inf dB: null in JSON
    zero = FrequencyResponseData([0.0, 1.0], [0.0, 1j])
    assert json.loads(json.dumps(zero.to_dict(), allow_nan=False))["magnitude_db"][0] is None


def test_repr_says_what_it_is():
    assert repr(_frd()) == ("<FrequencyResponseData measured: 7 lines, 1..100 Hz, 1 averages, "
                            "u -> y>")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frequency": [1.0, 1.0]}, "strictly increasing"),
        ({"frequency": [-1.0, 1.0]}, ">= 0 Hz"),
        ({"response": [1.0]}, "shape of frequency"),
        ({"response": [np.nan, 1.0]}, "finite"),
        ({"variance": [-1.0, 1.0]}, "variance must be >= 0"),
        ({"coherence": [1.5, 1.0]}, r"coherence must lie in \[0, 1\]"),
        ({"n_averages": 0}, "n_averages must be an integer >= 1"),
        ({"dt": 0.1}, "above the Nyquist frequency 5 Hz"),
        ({"frequency": []}, "non-empty 1-D"),
    ],
)
def test_bad_construction(kwargs, match):
    args = {"frequency": [1.0, 10.0], "response": [1.0, 0.5]}
    args.update(kwargs)
    with pytest.raises(DataError, match=match):
        FrequencyResponseData(**args)


def test_distortion_shapes_are_checked():
    with pytest.raises(DataError, match="equal length"):
        NonlinearDistortion(False, 0.5, 1e-3, np.ones(2), np.ones(3), np.ones(2))
