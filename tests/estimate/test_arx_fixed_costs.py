"""fit_arx's fixed costs were cut without changing what it returns or refuses.

Each shortcut is checked against the code it stands in for: the Schur–Cohn test
against the roots, the one-pass channel checks against check_magnitude and
check_not_constant, the compiled Gram solve against solve_gram's numpy formulas,
and the model built on first read against PolynomialModel.arx.
"""

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import DataError, IdentifiabilityError, ServoidError, ServoidWarning
from servoid.data import Experiment
from servoid.estimate import _arx, _ls, fit_arx
from servoid.estimate._channels import check_magnitude, check_not_constant
from servoid.models import PolynomialModel


def record(n=3000, seed=0, offset=0.0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    y = lfilter([0.0, 0.5, 0.3], [1.0, -1.5, 0.7], u) + 0.05 * rng.normal(size=n) + offset
    return Experiment.from_arrays(0.01, u=u, y=y)


def test_schur_cohn_agrees_with_the_roots():
    # an independent answer: the largest root magnitude from the companion eigenvalues
    rng = np.random.default_rng(0)
    radius = 1.0 + 1e-9
    for _ in range(3000):
        order = int(rng.integers(1, 7))
        roots = rng.uniform(0.2, 1.3, order) * np.exp(1j * rng.uniform(0, np.pi, order))
        roots = np.concatenate([roots, roots.conj()])[:order] if order > 1 else roots.real
        a = np.real(np.poly(roots))
        largest = np.abs(np.roots(a)).max()
        if abs(largest - radius) < 1e-6:  # too close to the boundary for either to decide
            continue
        assert _arx._strictly_stable(a, radius) == (largest < radius)
    assert not _arx._strictly_stable(np.array([1.0, np.nan]), radius)


def test_unstable_fit_still_warns_and_stable_does_not():
    rng = np.random.default_rng(2)
    u = rng.normal(size=400)
    y = lfilter([0.0, 1.0], [1.0, -1.02], u)  # an integrator that grows: pole at 1.02
    with pytest.warns(ServoidWarning, match="unstable"):
        fit_arx(Experiment.from_arrays(0.01, u=u, y=y), 1, 1, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit_arx(record(), 2, 2, 1)


@pytest.mark.parametrize("case", ["fine", "inf", "huge", "tiny", "constant", "nan",
                                  "two segments", "constant in both"])
@pytest.mark.parametrize("from_gram", [False, True])
def test_channel_checks_raise_what_the_checks_raise(case, from_gram):
    # the one-pass ranges must send every channel the checks would refuse to the checks
    exp = record(500)
    y, u = exp["y"].copy(), exp["u"].copy()
    if case == "inf":
        y[7] = np.inf
    elif case == "huge":
        u[3] = -1e200
    elif case == "tiny":
        y = y * 1e-160
    elif case == "constant":
        u[:] = 2.5
    elif case == "nan":
        y[5] = np.nan
        u[9] = 1e300  # NaN elsewhere does not stop the magnitude check of another channel
    segments = [(y, u)]
    if case == "two segments":
        segments = [(y[:200], u[:200]), (y[200:] * 1e3, u[200:])]
    if case == "constant in both":
        segments = [(y[:200], np.full(200, 1.0)), (y[200:], np.full(300, 1.0))]
    want = None
    try:
        check_magnitude("output", [z[0] for z in segments])
        check_magnitude("input 'u'", [z[1] for z in segments])
        check_not_constant("u", [z[1] for z in segments])
    except (DataError, IdentifiabilityError) as exc:
        want = exc
    ranges = None
    if from_gram:
        *_, tsig, tlag = _arx._structure(2, (2,), (1,), ("u",))
        ranges = [_arx.lagged_gram_ranges(z, tsig, tlag, 2)[1] for z in segments]
    if want is None:
        _arx._check_channels(segments, ("u",), ranges)
        return
    with pytest.raises(type(want)) as got:
        _arx._check_channels(segments, ("u",), ranges)
    assert str(got.value) == str(want)


def reference_solve(gram, n_rows):
    """solve_gram's formulas as plain numpy expressions (the code before the kernels)."""
    n = gram.shape[0] - 1
    scale = np.sqrt(np.diag(gram)[:n])
    g = gram[:n, :n] / np.outer(scale, scale)
    eig = np.linalg.eigvalsh(g)
    cov_s = np.linalg.inv(g)
    cov_s = 0.5 * (cov_s + cov_s.T)
    rhs = gram[:n, n] / scale
    theta_s = cov_s @ rhs
    rss = max(float(gram[n, n] - theta_s @ rhs), 0.0)
    cov = rss / max(n_rows - n, 1) * cov_s / np.outer(scale, scale)
    return theta_s / scale, cov, rss, float(np.sqrt(eig[-1] / eig[0]))


@pytest.mark.parametrize("seed", range(5))
def test_gram_solve_is_the_numpy_formula_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    phi = rng.normal(size=(400, 6)) * rng.uniform(0.1, 100.0, 6)
    gram = np.column_stack([phi, phi @ rng.normal(size=6) + rng.normal(size=400)])
    gram = gram.T @ gram
    got = _ls.solve_gram(gram, 400)
    theta, cov, rss, cond = reference_solve(gram, 400)
    np.testing.assert_array_equal(got.theta, theta)
    np.testing.assert_array_equal(got.covariance, cov)
    assert got.rss == rss and got.condition == cond


def test_model_built_on_first_read_equals_the_eager_one():
    est = fit_arx(record(offset=3.0), 2, [2], [1])
    assert "_model" in est.__dict__
    eager = PolynomialModel.arx(np.concatenate([[1.0], est.parameters[:2]]),
                                [est.parameters[2:]], [1], 0.01,
                                noise_variance=est.noise_variance)
    model = est.model
    assert est.model is model  # built once
    for name in ("a", "c", "d"):
        np.testing.assert_array_equal(getattr(model, name), getattr(eager, name))
    np.testing.assert_array_equal(model.b[0], eager.b[0])
    assert model.nk == eager.nk and model.noise_variance == eager.noise_variance
    # the covariance: solve_gram's, with the a-rows and -columns flipped (the regression
    # used −y lags), as the product with the outer product of the signs gave it
    exp = record(offset=3.0)
    _, _, _, tsig, tlag = _arx._structure(2, (2,), (1,), ("u",))
    gram = _arx.lagged_gram((exp["y"], exp["u"]), tsig, tlag, 2)
    sign = np.array([-1.0, -1.0, 1.0, 1.0])
    want = _ls.solve_gram(gram, exp.n_samples - 2).covariance * np.outer(sign, sign)
    np.testing.assert_array_equal(est.covariance, want)


def test_cached_structure_is_read_only_and_orders_are_still_checked():
    names, sig, lag, tsig, tlag = _arx._structure(2, (2,), (1,), ("u",))
    assert names == ("a1", "a2", "b0", "b1")
    for arr in (sig, lag, tsig, tlag):
        assert not arr.flags.writeable
    exp = record(300)
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(ServoidError):
            fit_arx(exp, bad, 2, 1)
