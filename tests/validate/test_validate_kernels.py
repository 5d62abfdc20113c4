"""The compiled validation passes against the lfilter/lstsq formulation they replace.

* ``initial="estimate"``: the free responses are cut where the impulse
  response of 1/den has died out; the result must equal the least-squares
  fit of all N rows of the lfilter free responses (``zi = e_j``).
* ``simulate_from_data``: the measured-start ARX simulation against
  ``lfiltic`` + ``lfilter``.
* ``metric_set``: bit for bit the five metric functions.
"""

import numpy as np
import pytest
import scipy.signal as sps

from servoid.models import PolynomialModel, TransferFunction
from servoid.validate import fit_percent, nrmse, relative_error, rmse, simulate_from_data, vaf
from servoid.validate._metrics import metric_set
from servoid.validate._simulate import simulate_model

DT = 0.01


def _lstsq_reference(model, y, u):
    """The full-length formulation: N × n free responses from lfilter, lstsq over N rows."""
    den = np.asarray(model._common_denominator()[0] if hasattr(model, "_common_denominator")
                     else model.den, dtype=float)
    forced = model.simulate(u)
    order = den.size - 1
    cols = []
    for j in range(order):
        zi = np.zeros(order)
        zi[j] = 1.0
        cols.append(sps.lfilter([1.0], den, np.zeros(y.size), zi=zi)[0])
    free = np.column_stack(cols)
    x0 = np.linalg.lstsq(free, y - forced, rcond=None)[0]
    return forced + free @ x0


def _oe(poles, nk=1):
    f = np.real(np.poly(poles))
    return PolynomialModel([1.0], [np.array([0.5, -0.2])], nk, DT, f=[f])


CASES = {
    "fast poles": _oe([0.9, 0.7]),
    "slow poles (free response over the whole record)": _oe([0.9995, 0.999]),
    "oscillatory": _oe([0.95 * np.exp(0.3j), 0.95 * np.exp(-0.3j)]),
    "fourth order": _oe([0.8, 0.5, -0.3, 0.6]),
    "unstable": _oe([1.002, 0.5]),
    "transfer function, den[0] = 2": TransferFunction([1.0, 0.4], [2.0, -1.2, 0.3], DT),
    "two inputs": PolynomialModel([1.0, -0.5], [np.array([0.5]), np.array([0.2, 0.1])], (1, 2),
                                  DT, f=[np.array([1.0, -0.8]), np.array([1.0, 0.3])]),
}


@pytest.mark.parametrize("name", list(CASES))
def test_estimated_initial_state_equals_the_full_least_squares(name):
    model = CASES[name]
    rng = np.random.default_rng(3)
    n = 4000
    u = rng.standard_normal((n, model.n_inputs) if hasattr(model, "n_inputs") and
                            model.n_inputs > 1 else n)
    # a record that does not start at rest: the free response matters
    y = model.simulate(u) + 3.0 * np.exp(-np.arange(n) / 50.0) + 0.01 * rng.standard_normal(n)
    got, first, how = simulate_model(model, y, u, initial="estimate")
    ref = _lstsq_reference(model, y, u)
    assert (first, how) == (0, "estimate")
    # the dropped rows hold free responses below 1e-20 of their peak: rounding only
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10 * np.max(np.abs(ref)))


def _from_data_reference(model, y, u):
    a = np.asarray(model.a)
    v = np.zeros(len(y))
    m = a.size - 1
    for b, k, col in zip(model.b, model.nk, u.reshape(len(y), -1).T, strict=True):
        bk = np.concatenate([np.zeros(k), b])
        v += sps.lfilter(bk, [1.0], col)
        m = max(m, bk.size - 1)
    zi = sps.lfiltic([1.0], a, y[m - 1 :: -1][: a.size - 1]) if a.size > 1 else None
    out = np.array(y, dtype=float)
    out[m:] = v[m:] if zi is None else sps.lfilter([1.0], a, v[m:], zi=zi)[0]
    return out, m


@pytest.mark.parametrize(("a", "bs", "nk"), [
    ([1.0, -1.5, 0.7], [[0.0, 0.5, 0.3]], [0]),
    ([1.0], [[0.5, 0.3, 0.1]], [2]),  # FIR: the initial conditions are past inputs only
    ([1.0, -0.9], [[1.0], [0.2, -0.1]], [1, 3]),
    (np.real(np.poly([0.9, 0.8, 0.5, -0.4, 0.3, 0.2])), [[0.1, 0.2]], [1]),  # order 6
])
def test_measured_start_simulation_equals_lfilter(a, bs, nk):
    model = PolynomialModel(a, [np.asarray(b) for b in bs], nk, DT)
    rng = np.random.default_rng(8)
    u = rng.standard_normal((3000, len(bs)))
    y = model.simulate(u) + 0.01 * rng.standard_normal(3000)
    got, first = simulate_from_data(model, y, u if len(bs) > 1 else u[:, 0])
    ref, m = _from_data_reference(model, y, u)
    assert first == m
    np.testing.assert_array_equal(got[:m], y[:m])
    # direct form against lfilter's transposed form: rounding of a stable recursion
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.max(np.abs(ref)))


def test_metric_set_is_the_five_metrics_bit_for_bit():
    rng = np.random.default_rng(2)
    y = 5.0 + rng.standard_normal(5000)
    y_hat = y + 0.3 * rng.standard_normal(5000)
    got = metric_set(y, y_hat)
    assert got == {"fit_percent": fit_percent(y, y_hat), "nrmse": nrmse(y, y_hat),
                   "rmse": rmse(y, y_hat), "vaf": vaf(y, y_hat),
                   "relative_error": relative_error(y, y_hat)}
