"""The one-pass moments behind the fit metrics and the residual stats.

``_kernels.add_moments`` forms, block by block and merged by Chan, Golub &
LeVeque's update, the moments every fit metric is a ratio of; ``error_pass``
forms them for an output-error model together with its residuals and their
sum and range; ``arx_pass`` forms them on the way for an ARX model. The
references here are exact sums (``math.fsum``) about exactly rounded means,
so a one-pass formula that cancels (Σy² − N·ȳ²) would fail the offset cases
by many orders of magnitude; the tolerances (a few 1e-13 relative) are the
rounding of a blocked float sum over up to 1e4 terms.
"""

import math

import numpy as np
import pytest

from servoid._errors import DataError
from servoid.data import Experiment
from servoid.models import PolynomialModel
from servoid.validate import fit_percent, validate
from servoid.validate._kernels import MOMENTS, add_moments, add_signal_stats, error_pass
from servoid.validate._report import _arx_outputs, _prediction_start

DT = 0.01


def _exact(y, h):
    """Count, means of y and d = y − h, centred sums of squares, Σd², Σy² by fsum."""
    d = y - h
    my, md = math.fsum(y) / y.size, math.fsum(d) / y.size
    ky, kd = y[0], d[0]  # the kernel keeps the means less these shifts (y − ky is exact)
    return np.array([y.size, math.fsum(y - ky) / y.size, math.fsum(d - kd) / y.size, math.fsum((y - my) ** 2), math.fsum((d - md) ** 2),
                     math.fsum(d * d), math.fsum(y * y), ky, kd])


@pytest.mark.parametrize("n", [1, 2, 1023, 1024, 1025, 4097, 10_000])
@pytest.mark.parametrize("offset", [0.0, 1e3, 1e8])
def test_moments_equal_exact_sums(n, offset):
    rng = np.random.default_rng(n)
    y = offset + rng.standard_normal(n)
    h = y - 0.1 * rng.standard_normal(n) - 0.05  # an error with a mean of its own
    got = np.zeros(MOMENTS)
    add_moments(y, h, got)
    want = _exact(y, h)
    assert got[0] == n
    np.testing.assert_allclose(got[1:3], want[1:3], rtol=1e-13, atol=1e-15)
    assert (got[7], got[8]) == (want[7], want[8])
    # centred sums: relative to themselves, whatever the offset (no cancellation)
    np.testing.assert_allclose(got[3:5], want[3:5], rtol=5e-13, atol=1e-300)
    np.testing.assert_allclose(got[5:7], want[5:7], rtol=1e-13)


def test_moments_merge_across_calls():
    # two calls on the halves give the moments of the whole (the merge is the same update)
    rng = np.random.default_rng(0)
    y, h = 50.0 + rng.standard_normal(3000), rng.standard_normal(3000)
    whole, parts = np.zeros(MOMENTS), np.zeros(MOMENTS)
    add_moments(y, h, whole)
    add_moments(y[:1234], h[:1234], parts)
    add_moments(y[1234:], h[1234:], parts)
    np.testing.assert_allclose(parts, whole, rtol=1e-13)


def test_moments_carry_a_non_finite_value_into_the_means():
    y, h = np.ones(3000), np.zeros(3000)
    for bad in (np.nan, np.inf):
        yb = y.copy()
        yb[2500] = bad
        acc = np.zeros(MOMENTS)
        add_moments(yb, h, acc)
        assert not np.all(np.isfinite(acc[1:3]))


def test_fit_of_a_large_offset_signal_is_exact():
    # y around 1e9 with unit spread: the fit depends on Σ(y − ȳ)² only
    rng = np.random.default_rng(5)
    y = 1e9 + rng.standard_normal(20_000)
    h = y + 0.2 * rng.standard_normal(20_000)
    ref = _exact(y, h)
    want = 100.0 * (1.0 - math.sqrt(ref[5]) / math.sqrt(ref[3]))
    assert fit_percent(y, h) == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("first", [0, 3, 2047, 2048, 2500])
def test_error_pass_is_the_subtraction_and_its_moments(first):
    rng = np.random.default_rng(first)
    n = 6000
    y, h = 3.0 + rng.standard_normal(n), rng.standard_normal(n)
    e = np.empty(n - first)
    mo = np.zeros(MOMENTS)
    st = np.array([[0.0, np.inf, -np.inf]])
    error_pass(y, h, first, e, mo, st)
    assert np.array_equal(e, y[first:] - h[first:])  # numpy's subtraction, to the bit
    ref = np.zeros(MOMENTS)
    add_moments(y[first:], h[first:], ref)
    assert np.array_equal(mo, ref)  # the same blocks, from `first` on
    assert st[0, 0] == pytest.approx(math.fsum(e), rel=1e-13, abs=1e-12)
    assert (st[0, 1], st[0, 2]) == (e.min(), e.max())


def test_signal_stats_are_sum_min_and_max():
    rng = np.random.default_rng(2)
    x = 7.0 + rng.standard_normal(5001)
    st = np.array([[0.0, np.inf, -np.inf]] * 2)
    add_signal_stats(x, st, 1)
    assert st[1, 0] == pytest.approx(math.fsum(x), rel=1e-14)
    assert (st[1, 1], st[1, 2]) == (x.min(), x.max())
    assert (st[0] == [0.0, np.inf, -np.inf]).all()  # other rows untouched


ARX = PolynomialModel([1.0, -1.5, 0.7], [np.array([1.0, 0.5])], 1, DT)


def _arx_record(n, seed):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = np.zeros(n)
    e = 0.3 * rng.standard_normal(n)
    for t in range(n):  # the ARX equation, sample by sample
        y[t] = e[t] + (1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] if t >= 2
                       else 0.0)
    return y, u


@pytest.mark.parametrize("skip", [0, 5, 3000])
@pytest.mark.parametrize("horizon", [1, 4])
def test_arx_pass_moments_are_those_of_its_outputs(skip, horizon):
    y, u = _arx_record(7000, skip + horizon)
    sim, m, pred, _, _, moments = _arx_outputs(ARX, y, u[:, None], horizon, skip)
    first = m + skip
    p0 = _prediction_start(first, horizon, y.size)
    for row, (out, start) in enumerate(((sim, first), (pred, p0))):
        np.testing.assert_allclose(moments[row], _exact(y[start:], out[start:]), rtol=1e-12)


def test_fused_arx_refuses_a_non_finite_initial_sample():
    # the moments cover y from `first` on; a NaN before it must still be refused. With
    # na = 1 and three input taps, first = m = 3 and neither the recursion (y(2) starts it)
    # nor a residual from t = 3 on (y(t − 1)) reads y(0): only the check of y[:first] sees it
    model = PolynomialModel([1.0, -0.5], [np.array([1.0, 0.5, 0.2])], 1, DT)
    y, u = _arx_record(500, 9)
    y[0] = np.nan
    with pytest.raises(DataError, match="finite"):
        _arx_outputs(model, y, u[:, None], 1)


def test_output_error_report_from_the_pass_equals_the_formulas():
    oe = PolynomialModel([1.0], [np.array([1.0, 0.5])], 1, DT, f=[np.array([1.0, -1.5, 0.7])])
    rng = np.random.default_rng(4)
    u = rng.standard_normal(5000)
    y = np.asarray(oe.simulate(u)) + 0.2 * rng.standard_normal(5000)
    report = validate(oe, Experiment.from_arrays(DT, u=u, y=y, name="v"), initial="zero")
    sim = np.asarray(oe.simulate(u))
    ref = _exact(y, sim)
    assert report.fit_percent == pytest.approx(100 * (1 - math.sqrt(ref[5] / ref[3])), rel=1e-12)
    assert report.rmse == pytest.approx(math.sqrt(ref[5] / ref[0]), rel=1e-12)
    assert report.vaf == pytest.approx(100 * (1 - ref[4] / ref[3]), rel=1e-12)
    e = y - sim
    e = e - e.mean()
    auto = [np.dot(e[: e.size - k], e[k:]) / np.dot(e, e) for k in range(26)]
    np.testing.assert_allclose(report.residuals.autocorrelation, auto, rtol=1e-10, atol=1e-13)
