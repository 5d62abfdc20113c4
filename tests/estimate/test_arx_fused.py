"""fit_arx's fused finishing steps give the bits the numpy expressions gave.

The compiled ``_finish`` (unscaling, a = [1, −θ_a], the covariance with the
a–b blocks' signs flipped, the Schur–Cohn test) and the compiled channel
screen ``_ranges_ok`` stand in for plain numpy/Python code; each is checked
here against that code, on inputs the kernels did not make.
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import DataError, IdentifiabilityError
from servoid.data import Experiment
from servoid.estimate import Estimate, _arx, _ls, fit_arx
from servoid.estimate._channels import (
    LARGEST_VALUE,
    SMALLEST_VALUE,
    check_magnitude,
    check_not_constant,
)


def reference_finish(theta_s, cov_s, scale, sigma2, na):
    """The numpy expressions fit_arx used before the fused kernel."""
    theta = theta_s / scale
    a = np.concatenate([[1.0], -theta[:na]])
    cov = sigma2 * cov_s / np.outer(scale, scale)
    cov[:na, na:] *= -1.0
    cov[na:, :na] *= -1.0
    return theta, a, np.concatenate([a[1:], theta[na:]]), cov


@pytest.mark.parametrize("seed", range(4))
def test_finish_is_the_numpy_expressions_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        n = int(rng.integers(1, 9))
        na = int(rng.integers(0, n + 1))
        m = rng.normal(size=(n, n))
        cov_s = 0.5 * (m @ m.T + (m @ m.T).T)
        scale = rng.uniform(1e-3, 1e3, n)
        theta_s = rng.normal(size=n)
        sigma2 = float(rng.uniform(1e-6, 10.0))
        theta, a, params, cov, stable = _arx._finish(theta_s, cov_s, scale, sigma2, na,
                                                     _arx._powers(na + 1))
        want = reference_finish(theta_s, cov_s, scale, sigma2, na)
        for got, ref in zip((theta, a, params, cov), want, strict=True):
            np.testing.assert_array_equal(got, ref)
            assert got.tobytes() == ref.tobytes()  # -0.0 and 0.0 too
        assert stable == (a.size < 2 or _arx._strictly_stable(a, 1.0 + 1e-9))


def test_compiled_stability_test_agrees_near_the_boundary():
    # poles placed at radius 1 ± δ: the decision the Python step-down makes, bit for bit
    rng = np.random.default_rng(7)
    for delta in (1e-3, 1e-7, 1e-9, 2e-9, 1e-12):
        for _ in range(200):
            order = int(rng.integers(1, 7))
            r = 1.0 + delta * rng.choice([-1.0, 1.0], order)
            poles = r * np.exp(1j * rng.uniform(0, np.pi, order))
            a = np.real(np.poly(np.concatenate([poles, poles.conj()])[:order]))
            assert _arx._schur_cohn(a, _arx._powers(a.size)) == _arx._strictly_stable(
                a, 1.0 + 1e-9)


def record(n=600, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    y = lfilter([0.0, 0.4, 0.2], [1.0, -1.3, 0.6], u) + 0.05 * rng.normal(size=n)
    return y, u


@pytest.mark.parametrize("case", ["fine", "inf", "huge", "tiny", "constant", "nan",
                                  "zero input", "big offset"])
def test_channel_screen_sends_every_refusal_to_the_checks(case):
    y, u = record()
    if case == "inf":
        y[7] = -np.inf
    elif case == "huge":
        u[3] = 1e200
    elif case == "tiny":
        u = u * 1e-170
    elif case == "constant":
        u[:] = -4.0
    elif case == "nan":
        y[5] = np.nan
    elif case == "zero input":
        u[:] = 0.0
    elif case == "big offset":  # not constant, only a small variation on a large level
        u = 1e6 + 1e-3 * u
    want = None
    try:
        check_magnitude("output", [y])
        check_magnitude("input 'u'", [u])
        check_not_constant("u", [u])
    except (DataError, IdentifiabilityError) as exc:
        want = exc
    _, _, _, tsig, tlag = _arx._structure(2, (2,), (1,), ("u",))
    ranges = _arx.lagged_gram_ranges((y, u), tsig, tlag, 2)[1]
    if want is not None:  # the screen must not let a refused record through
        assert not _arx._ranges_ok(ranges, LARGEST_VALUE, SMALLEST_VALUE)
        if not (np.isfinite(y).all() and np.isfinite(u).all()):
            return  # an Experiment refuses these itself, before fit_arx sees them
        with pytest.raises(type(want)) as got:
            fit_arx(Experiment.from_arrays(0.01, u=u, y=y), 2, 2, 1)
        assert str(got.value) == str(want)
    elif case == "fine":
        assert _arx._ranges_ok(ranges, LARGEST_VALUE, SMALLEST_VALUE)


@pytest.mark.parametrize("seed", range(3))
def test_two_input_fit_is_solve_gram_with_flipped_signs(seed):
    # the fused path against the public solve_gram on the same Gram matrix
    rng = np.random.default_rng(seed)
    n = 2000
    u1, u2 = rng.normal(size=n), rng.normal(size=n)
    y = (lfilter([0.0, 0.5], [1.0, -0.8, 0.2], u1) + lfilter([0.3, 0.1], [1.0, -0.8, 0.2], u2)
         + 0.1 * rng.normal(size=n))
    exp = Experiment.from_arrays(0.01, u=np.column_stack([u1, u2]), y=y)
    est = fit_arx(exp, 2, (1, 2), (1, 0))
    names = exp.names_of("u")
    _, _, _, tsig, tlag = _arx._structure(2, (1, 2), (1, 0), names)
    gram = _arx.lagged_gram((y, u1, u2), tsig, tlag, 2)
    ref = _ls.solve_gram(gram, n - 2)
    sign = np.array([-1.0, -1.0, 1.0, 1.0, 1.0])
    np.testing.assert_array_equal(est.parameters, sign * ref.theta)
    np.testing.assert_array_equal(est.covariance, ref.covariance * np.outer(sign, sign))
    assert est.noise_variance == ref.noise_variance
    assert est.options["solver"] == "gram" and est.options["condition"] == ref.condition


def test_estimate_still_checks_names_after_caching_good_ones():
    good = ("a1", "b0")
    for _ in range(2):  # the second time from the cache of checked tuples
        est = Estimate(model=None, parameters=[1.0, 2.0], names=good,
                       covariance=np.eye(2), noise_variance=1.0, n_samples=10, method="x")
        assert est.names is good and est.units == ("", "")
    listed = Estimate(model=None, parameters=[1.0, 2.0], names=["a1", "b0"],
                      covariance=np.eye(2), noise_variance=1.0, n_samples=10, method="x",
                      units=[])
    assert listed.names == good and listed.units == ("", "")
    for bad in (("a1", 2), "ab", None):
        with pytest.raises(Exception) as exc:
            Estimate(model=None, parameters=[1.0, 2.0], names=bad, covariance=np.eye(2),
                     noise_variance=1.0, n_samples=10, method="x")
        assert "names" in str(exc.value)


def test_trusted_estimate_holds_what_the_checked_constructor_holds():
    # fit_arx builds its Estimate without __post_init__'s conversions: every field must be
    # what Estimate(...) would have stored from the same values
    import dataclasses
    from types import MappingProxyType

    y, u = record(800, seed=3)
    est = fit_arx(Experiment.from_arrays(0.01, u=u, y=y), 2, 2, 1)
    ref = Estimate(**{f.name: getattr(est, f.name) for f in dataclasses.fields(Estimate)})
    for f in dataclasses.fields(Estimate):
        got, want = getattr(est, f.name), getattr(ref, f.name)
        if isinstance(want, np.ndarray):
            np.testing.assert_array_equal(got, want)
            assert type(got) is np.ndarray and got.dtype == want.dtype
            assert not got.flags.writeable
        elif f.name == "options":
            assert type(got) is MappingProxyType and dict(got) == dict(want)
        else:
            assert got == want or got is want, f.name
    assert est.units == ("",) * 4 and est.status == "ok"
    with pytest.raises(TypeError):
        est.options["na"] = 3  # read-only like the checked constructor's
    with pytest.raises(dataclasses.FrozenInstanceError):
        est.noise_variance = 1.0
    np.testing.assert_array_equal(dataclasses.replace(est, status="x").parameters,
                                  est.parameters)
    assert est.residuals.size == 798 and repr(est) == repr(ref)
