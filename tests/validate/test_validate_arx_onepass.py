"""The one-pass ARX validation against the unfused functions it replaces.

``validate`` of an ARX model takes the simulation from measured initial
conditions, the k-step prediction and the one-step residuals from one
compiled pass (``_report._arx_outputs``).  It must give what
``simulate_from_data``, ``PolynomialModel.predict`` and
``PolynomialModel.residuals`` give, and the whole report must equal the
report built the unfused way.  The pass uses the same filter coefficients
and sums the terms in the same order, so the signals agree to the last bit
in practice; the tolerances below (1e-12 relative to the signal's scale)
leave room only for a compiler that contracts a multiply–add.  The means
and ranges the residual tests centre by are summed in another order than
``np.mean`` (differences ~1e-16 relative), hence 1e-10 on the correlations.
"""

import numpy as np
import pytest
import scipy.signal as sps

from servoid._errors import DataError
from servoid.data import Experiment
from servoid.models import PolynomialModel
from servoid.validate import _report, simulate_from_data, validate
from servoid.validate._report import _arx_outputs

DT = 0.01

MODELS = {
    "ARX(2,2,1)": PolynomialModel([1.0, -1.5, 0.7], [np.array([1.0, 0.5])], 1, DT),
    "nk = 0": PolynomialModel([1.0, -0.6], [np.array([0.3, -0.2, 0.1])], 0, DT),
    "order 7 (general recursion)": PolynomialModel(
        np.real(np.poly([0.9, -0.8, 0.5 + 0.4j, 0.5 - 0.4j, 0.3, -0.2, 0.1])),
        [np.array([0.4, 0.1])], 2, DT),
    "two inputs, different delays": PolynomialModel(
        [1.0, -0.5, 0.06], [np.array([0.5]), np.array([0.2, 0.1, -0.05])], (1, 3), DT),
}


def _record(model, n, seed):
    """Data from an independent generator: scipy's lfilter of the ARX equation plus noise."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, model.n_inputs))
    a = np.asarray(model.a, dtype=float)
    y = sps.lfilter([1.0], a, 0.3 * rng.standard_normal(n))
    for i, (b, k) in enumerate(zip(model.b, model.nk, strict=True)):
        y += sps.lfilter(np.r_[np.zeros(k), b], a, u[:, i])
    return y, u


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("horizon", [1, 5, 13])
def test_fused_pass_equals_unfused_functions(name, seed, horizon):
    model = MODELS[name]
    # 5000 samples: more than two blocks of the kernel (2048), so block edges are crossed
    y, u = _record(model, 5000, seed)
    y_sim, first, y_pred, eps, _, _ = _arx_outputs(model, y, u, horizon)
    ref_sim, ref_first = simulate_from_data(model, y, u)
    uu = u if u.shape[1] > 1 else u[:, 0]
    scale = np.max(np.abs(y))
    assert first == ref_first
    np.testing.assert_allclose(y_sim, ref_sim, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(y_pred, model.predict(y, uu, horizon=horizon), rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(eps, model.residuals(y, uu), rtol=0, atol=1e-12 * scale)
    # the simulation starts from the measurement and then runs free: it is not the data
    assert np.array_equal(y_sim[:first], y[:first])
    assert np.max(np.abs(y_sim[first:] - y[first:])) > 1e-3 * scale


def _unfused_outputs(model, y, u, horizon, first=0):
    """What the fused pass replaces: the simulation, ``predict`` and ``residuals``."""
    y_sim, first = simulate_from_data(model, y, u)
    return (y_sim, first, model.predict(y, u, horizon=horizon), model.residuals(y, u), None,
            None)


def _unfused_report(monkeypatch, model, exp, **kw):
    with monkeypatch.context() as m:
        m.setattr(_report, "_arx_outputs", _unfused_outputs)
        return validate(model, exp, **kw)


@pytest.mark.parametrize("name", ["ARX(2,2,1)", "order 7 (general recursion)",
                                  "two inputs, different delays"])
@pytest.mark.parametrize("kw", [{}, {"horizon": 3, "transient": 7}, {"initial": "measured"}])
def test_validate_report_equals_unfused(monkeypatch, name, kw):
    model = MODELS[name]
    y, u = _record(model, 4000, 3)
    exp = Experiment.from_arrays(DT, y=y, u=u if u.shape[1] > 1 else u[:, 0], name="v")
    got = validate(model, exp, **kw)
    ref = _unfused_report(monkeypatch, model, exp, **kw)
    assert got.first == ref.first and got.prediction_first == ref.prediction_first
    assert got.initial == ref.initial == "measured"
    for field in ("simulated", "predicted"):
        np.testing.assert_allclose(getattr(got, field), getattr(ref, field), rtol=1e-12,
                                   atol=1e-12 * np.max(np.abs(y)))
    for field in ("fit_percent", "nrmse", "rmse", "vaf", "relative_error",
                  "prediction_fit_percent"):
        assert getattr(got, field) == pytest.approx(getattr(ref, field), rel=1e-10)
    r, q = got.residuals, ref.residuals
    np.testing.assert_allclose(r.autocorrelation, q.autocorrelation, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(r.cross_correlation, q.cross_correlation, rtol=1e-10, atol=1e-14)
    assert r.whiteness_pvalue == pytest.approx(q.whiteness_pvalue, rel=1e-9, abs=1e-14)
    assert r.independence_pvalue == pytest.approx(q.independence_pvalue, rel=1e-9, abs=1e-14)


def test_fused_refuses_non_finite_output():
    model = MODELS["ARX(2,2,1)"]
    y, u = _record(model, 500, 4)
    y[300] = np.nan
    with pytest.raises(DataError, match="finite"):
        _arx_outputs(model, y, u, 5)


def test_validate_takes_the_fused_pass_for_arx_only(monkeypatch):
    calls = []

    def spy(*args):
        calls.append(args[0])
        return _arx_outputs(*args)

    monkeypatch.setattr(_report, "_arx_outputs", spy)
    arx = MODELS["ARX(2,2,1)"]
    y, u = _record(arx, 1000, 5)
    exp = Experiment.from_arrays(DT, y=y, u=u[:, 0], name="v")
    validate(arx, exp)
    assert calls == [arx]
    oe = PolynomialModel([1.0], [np.array([1.0, 0.5])], 1, DT, f=[np.array([1.0, -1.5, 0.7])])
    validate(oe, exp)  # output error: the simulation is the predictor, no fused ARX pass
    validate(arx, exp, initial="zero")  # an explicit initial state other than measured
    assert calls == [arx]
