"""The residual tests' kernels centre and scale block by block: against plain numpy.

The reference is the definition written out: centre, scale, then one np.dot per lag
(:func:`direct`); the kernels never store a centred copy, so these check that the
values they form inside each block (and past the record's end) are the right ones.
"""

import pickle
import tracemalloc

import numpy as np
import pytest

from servoid.data import Experiment
from servoid.estimate import fit_arx
from servoid.validate import _residuals as res_mod
from servoid.validate import residual_analysis, validate


def direct(a, b, lags):
    """Σ_t a(t)·b(t + τ) for each τ (zero outside the record), one np.dot per lag."""
    n = a.size
    return np.array([a[: n - t] @ b[t:] if t < n else 0.0 for t in lags])


def centred(x, mean, scale):
    return (x - mean) * scale


@pytest.mark.parametrize(("n", "m"), [(9, 4), (300, 25), (2047, 30), (2049, 25), (5000, 1),
                                      (6000, 120)])
def test_fused_sums_against_one_dot_per_lag(n, m):
    # fixed offsets and spreads of different sizes: the centring inside the kernel matters
    rng = np.random.default_rng(n + m)
    e = 3.0 + 0.01 * rng.normal(size=n)
    u = -200.0 + 50.0 * rng.normal(size=n)
    ce = res_mod._Centred.of(e, float(np.mean(e)))
    cu = res_mod._Centred.of(u, float(np.mean(u)))
    ee, ue, eu, uu = res_mod._fused_sums(ce, cu, m)
    a, b = centred(e, ce.mean, ce.scale), centred(u, cu.mean, cu.scale)
    lags, lags2 = np.arange(m + 1), np.arange(2 * m + 1)
    # sums of n products of values below 1 in magnitude: rounding ~ε·√n·n at most
    tol = 1e-14 * n
    np.testing.assert_allclose(ee, direct(a, a, lags), rtol=0, atol=tol)
    np.testing.assert_allclose(ue, direct(b, a, lags), rtol=0, atol=tol)
    np.testing.assert_allclose(eu, direct(a, b, lags), rtol=0, atol=tol)
    np.testing.assert_allclose(uu, direct(b, b, lags2), rtol=0, atol=tol)


@pytest.mark.parametrize(("n", "first", "last"), [(10, 0, 9), (10, 3, 14), (5000, 26, 101),
                                                  (4099, 1, 50), (2048, 0, 2047)])
def test_pair_kernel_against_one_dot_per_lag(n, first, last):
    rng = np.random.default_rng(n + last)
    x, y = 1e3 + rng.normal(size=n), rng.normal(size=n) ** 3
    cx, cy = (res_mod._Centred.of(v, float(np.mean(v))) for v in (x, y))
    got = res_mod._centred_lags(cx, cy, first, last)
    want = direct(centred(x, cx.mean, cx.scale), centred(y, cy.mean, cy.scale),
                  np.arange(first, last + 1))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * n)
    assert np.all(got[np.arange(first, last + 1) >= n] == 0.0)  # past the record: no products


def test_scale_is_the_power_of_two_above_the_peak():
    for peak in (1e-310, 3e-200, 0.75, 1.0, 5.0, 1e300):
        x = np.array([0.0, peak, -peak / 3])
        c = res_mod._Centred.of(x, 0.0)
        top = np.max(np.abs(x)) * c.scale
        assert 0.5 <= top < 1.0 or peak < 1e-300  # capped at 2^1023 for subnormal peaks
        assert np.isfinite(c.scale) and c.scale > 0
    assert res_mod._Centred.of(np.full(5, 2.0), 2.0).scale == 1.0  # constant: unscaled zeros
    # centred values where they are used (the independence test's record ends)
    rng = np.random.default_rng(0)
    x = rng.normal(size=50) + 7.0
    c = res_mod._Centred.of(x, float(np.mean(x)))
    idx = np.array([-3, 0, 10, 49, 50, 80])
    want = np.where((idx >= 0) & (idx < 50), (x[np.clip(idx, 0, 49)] - c.mean) * c.scale, 0.0)
    np.testing.assert_array_equal(c.at(idx), want)


def test_no_copy_of_the_record():
    # centring inside the kernels: no N-sample array at all (the old code kept two, 16·N bytes)
    rng = np.random.default_rng(4)
    n = 200_000
    e, u = rng.normal(size=n), rng.normal(size=n)
    residual_analysis(e, u)
    tracemalloc.start()
    try:
        residual_analysis(e, u)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 * n / 4  # buffers and per-lag arrays: a few hundred kB, not 1.6 MB


def test_report_time_is_built_on_first_read_and_pickles():
    rng = np.random.default_rng(1)
    u = rng.normal(size=2000)
    y = np.convolve(u, [0.0, 0.5, 0.3])[:2000] + 0.01 * rng.normal(size=2000)
    exp = Experiment.from_arrays(0.01, u=u, y=y)
    report = validate(fit_arx(exp, 1, 2, 1), exp)
    assert callable(report.__dict__["_time"])  # not built by validate
    np.testing.assert_array_equal(report.time, exp.time)
    assert report.time is report.time  # built once
    back = pickle.loads(pickle.dumps(validate(fit_arx(exp, 1, 2, 1), exp)))
    np.testing.assert_array_equal(back.time, exp.time)
    with pytest.raises(AttributeError):
        report.time = np.zeros(3)  # frozen as before
