"""PolynomialModel.simulate / predict run a compiled filter; lfilter is the reference.

Orders 0 to 7 cover the FIR branch, the register recursion (order <= 4)
and the general one, one and two inputs (the second adds into the first).
"""

import numpy as np
import pytest
import scipy.signal as sps

from servoid.models import PolynomialModel

DT = 0.01


def _poly(roots):
    return np.real(np.poly(roots)) if len(roots) else np.ones(1)


@pytest.mark.parametrize("f_roots", [[], [0.9], [0.9, -0.5], [0.95, 0.5, 0.3, -0.2],
                                     [0.9, 0.8, 0.7, 0.3, -0.3, -0.6, 0.1]])
@pytest.mark.parametrize("inputs", [1, 2])
def test_simulate_equals_lfilter(f_roots, inputs):
    rng = np.random.default_rng(len(f_roots) + 10 * inputs)
    f = _poly(f_roots)
    bs = [rng.standard_normal(3) for _ in range(inputs)]
    model = PolynomialModel([1.0, -0.2], bs, [1] * inputs, DT, f=[f] * inputs)
    u = rng.standard_normal((5000, inputs))
    ref = sum(sps.lfilter(np.r_[0.0, b], np.convolve([1.0, -0.2], f), u[:, i])
              for i, b in enumerate(bs))
    got = model.simulate(u if inputs > 1 else u[:, 0])
    # direct form against lfilter's transposed form: rounding of a stable recursion
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11 * np.max(np.abs(ref)))


@pytest.mark.parametrize("horizon", [1, 3])
def test_predict_equals_lfilter_formulation(horizon):
    rng = np.random.default_rng(4)
    model = PolynomialModel([1.0, -1.2, 0.4], [np.array([0.5, 0.2])], [1], DT,
                            c=[1.0, 0.5], d=[1.0, -0.3], f=[np.array([1.0, -0.6])])
    u = rng.standard_normal(4000)
    y = model.simulate(u) + 0.1 * rng.standard_normal(4000)
    # the predictor y_hat = (1 - W_k) y + W_k G u written out with lfilter (Ljung §3.2)
    ad = np.convolve(model.a, model.d)
    fk = sps.lfilter(model.c, ad, np.r_[1.0, np.zeros(horizon - 1)])
    rest = np.zeros(max(model.c.size, fk.size + ad.size - 1))
    rest[: model.c.size] += model.c
    rest[: fk.size + ad.size - 1] -= np.convolve(fk, ad)
    rest[:horizon] = 0.0
    ref = sps.lfilter(rest, model.c, y)
    num = np.convolve(np.convolve(fk, model.d), np.r_[0.0, model.b[0]])
    ref += sps.lfilter(num, np.convolve(model.c, model.f[0]), u)
    got = model.predict(y, u, horizon=horizon)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11 * np.max(np.abs(ref)))
    if horizon == 1:
        np.testing.assert_allclose(model.residuals(y, u), y - ref, rtol=0,
                                   atol=1e-11 * np.max(np.abs(ref)))


def test_static_gain_and_initial_conditions_keep_working():
    m = PolynomialModel([1.0], [np.array([2.0])], [0], DT)
    np.testing.assert_array_equal(m.simulate([1.0, -1.0, 3.0]), [2.0, -2.0, 6.0])
    # with past samples the lfilter path (lfiltic) runs, as before
    m2 = PolynomialModel([1.0, -0.5], [np.array([1.0])], [1], DT)
    np.testing.assert_allclose(m2.simulate([0.0, 0.0], y_init=[2.0]), [1.0, 0.5])
