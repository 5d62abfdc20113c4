"""The one-step fit's compiled kernels and loose descents against independent code.

Each kernel is checked against what it replaces, computed another way:
scipy's lfilter (direct form II transposed) for the filters, scipy's
first-order-hold discretisation for the sampled model, numpy's SVD least
squares for the level regression, MINPACK (scipy.optimize.least_squares)
for the descents.  Tolerances are a few hundred ulps of the quantities
involved: the kernels reorder sums, so they agree to rounding, not bit for
bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from loop_records import DT, LOOP, TRUTH, halves, output_noise, record, reference
from scipy import optimize
from scipy import signal as sps

from servoid.data import as_segments
from servoid.plants.ehsa import _kernels as kernels
from servoid.plants.ehsa import _onestep as onestep
from servoid.plants.ehsa import fit_one_step, simulate_closed_loop
from servoid.plants.ehsa._descent import descend
from servoid.plants.ehsa._onestep_model import model_function
from servoid.plants.ehsa._sampling import polynomial_hold_arrays
from servoid.plants.ehsa._structures import STRUCTURES


def _stable(order: int, rng: np.random.Generator, pad: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A random stable (b, a), a monic, with `pad` poles at z = 0 (trailing zeros of a)."""
    half = order // 2
    poles = 0.97 * np.exp(1j * rng.uniform(0.05, 3.0, half))
    roots = np.concatenate([poles, poles.conj(), rng.uniform(-0.9, 0.95, order - 2 * half)])
    a = np.concatenate([np.real(np.poly(roots)), np.zeros(pad)])
    return rng.normal(size=a.size), a


@pytest.mark.parametrize("order,pad", [(1, 0), (2, 0), (3, 0), (3, 7), (4, 0), (5, 3), (8, 0)])
def test_lfilter_pair_is_lfilter(order, pad):
    rng = np.random.default_rng(order + 10 * pad)
    b, a = _stable(order, rng, pad)
    x = rng.normal(size=3000)
    sim, step = kernels.lfilter_pair(b, a, x)
    ref_sim, ref_step = sps.lfilter(b, a, x), sps.lfilter(b, a, np.ones(x.size))
    # poles at radius 0.97: the impulse response sums to ~30, so rounding grows to ~1e-13
    np.testing.assert_allclose(sim, ref_sim, rtol=0, atol=1e-12 * np.max(np.abs(ref_sim)))
    np.testing.assert_allclose(step, ref_step, rtol=0, atol=1e-12 * np.max(np.abs(ref_step)))


@pytest.mark.parametrize("theta", [(3451.7, 163.3, 0.249), (3451.7, 900.0, 0.05),
                                   (800.0, 40.0, 2.0)])
def test_first_order_hold_model_is_scipys_foh(theta):
    """Degree 1 of the polynomial hold is the triangle hold scipy's cont2discrete makes."""
    k, w, d = theta
    num = np.array([0.01 * k * w * w])
    den = np.array([1.0, 2.0 * d * w, w * w, 0.01 * k * w * w])
    b, a, advance = polynomial_hold_arrays(num, den, DT, 1)
    assert advance == 0
    bz, az, _ = sps.cont2discrete((num, den), DT, method="foh")
    freqs = np.linspace(0.01, 0.99, 25) * np.pi
    _, ours = sps.freqz(b, a, worN=freqs)
    _, ref = sps.freqz(np.ravel(bz), az, worN=freqs)
    # two exact discretisations of one model: agreement to rounding of the matrix exponential,
    # relative to the response's peak (it falls by 1e5 towards Nyquist)
    np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))


def _lstsq_level(b, a, r, y, s0):
    """The level regression as numpy's SVD least squares solves it (the former code)."""
    e = y - sps.lfilter(b, a, r)
    step = sps.lfilter(b, a, np.ones(r.size))
    decay = step[-1] - step
    columns = [decay, np.ones(r.size)]
    if float(decay[s0:] @ decay[s0:]) < 1e-6 * float(decay @ decay):
        columns = columns[1:]
    coef, *_ = np.linalg.lstsq(np.column_stack(columns)[s0:], e[s0:], rcond=None)
    level = float(coef[0]) if len(columns) == 2 else 0.0
    return (e - level * decay - coef[-1])[s0:], level, float(coef[-1])


@pytest.mark.parametrize("s0", [0, 3, 2900])
def test_level_residuals_are_the_least_squares_projection(s0):
    rng = np.random.default_rng(s0)
    b, a = _stable(3, rng, 7)
    r = np.cumsum(rng.normal(size=3000)) * 1e-3
    y = sps.lfilter(b, a, r) + 0.3 * (sps.lfilter(b, a, np.ones(r.size))[-1]
                                      - sps.lfilter(b, a, np.ones(r.size))) - 0.02
    y += rng.normal(0.0, 1e-4, r.size)
    e, level, offset = kernels.level_residuals(b, a, r, y, s0, True)
    ref_e, ref_level, ref_offset = _lstsq_level(b, a, r, y, s0)
    if s0 < 2900:  # the decay is still there: the held level 0.3 is found (noise 1e-4)
        assert level == pytest.approx(0.3, abs=1e-3)
    else:  # started after the decay: the offset alone
        assert level == 0.0
    assert level == pytest.approx(ref_level, rel=1e-9, abs=1e-12)
    assert offset == pytest.approx(ref_offset, rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(e, ref_e, rtol=0, atol=1e-10 * np.max(np.abs(y)))
    # "rest": nothing projected out
    e_rest, level_rest, offset_rest = kernels.level_residuals(b, a, r, y, s0, False)
    assert level_rest == offset_rest == 0.0
    np.testing.assert_allclose(e_rest, (y - sps.lfilter(b, a, r))[s0:], atol=1e-12)


def test_level_regression_of_a_diverging_trial_model_stays_finite():
    """Outputs near the overflow limit (an unstable trial θ): the sums are scaled."""
    b, a = np.array([1.0, 0.0]), np.array([1.0, -1.5])  # a pole at 1.5: 1.5^1700 ~ 1e299
    r = np.ones(1700)
    y = np.zeros(1700)
    _, level, offset = kernels.level_residuals(b, a, r, y, 0, True)
    assert np.isfinite(level) and np.isfinite(offset)


def test_grid_costs_are_lfilter_sums():
    rng = np.random.default_rng(3)
    r, y = rng.normal(size=2000), rng.normal(size=2000)
    models = [_stable(3, rng) for _ in range(4)]
    nums = np.array([m[0] for m in models])
    dens = np.array([m[1] for m in models])
    costs = kernels.tustin_costs(nums, dens, r, y)
    ref = [np.sum((y - sps.lfilter(b, a, r)) ** 2) for b, a in models]
    np.testing.assert_allclose(costs, ref, rtol=1e-11)
    p, g = 0.97, 0.03
    assert kernels.first_order_cost(p, g, r, y) == pytest.approx(
        np.sum((y - sps.lfilter([0.0, g], [1.0, -p], r)) ** 2), rel=1e-12)


def _exponentials(t, y):
    def residuals(z):
        with np.errstate(over="ignore", invalid="ignore"):  # far trial steps overflow
            out = y - z[0] * np.exp(-z[1] * t) - z[2]
        out[~np.isfinite(out)] = 1e30
        return out

    return residuals


@pytest.mark.parametrize("z0", [(1.0, 1.0, 0.0), (5.0, 0.1, 1.0), (0.2, 8.0, -1.0)])
def test_descent_reaches_minpacks_minimum(z0):
    """A nonlinear least-squares problem with a known minimum (noise-free data)."""
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 4.0, 4000)
    truth = np.array([2.5, 1.3, 0.4])
    y = truth[0] * np.exp(-truth[1] * t) + truth[2] + rng.normal(0.0, 1e-3, t.size)
    fun = _exponentials(t, y)
    ours = descend(fun, np.array(z0), ftol=1e-10, xtol=1e-10, gtol=1e-12, max_nfev=2000)
    ref = optimize.least_squares(fun, np.array(z0), method="lm", xtol=1e-10, ftol=1e-10,
                                 gtol=1e-12)
    assert ours.converged
    # one minimum: both solvers stop within their tolerance 1e-10 of it
    np.testing.assert_allclose(ours.x, ref.x, rtol=1e-6)
    assert ours.cost == pytest.approx(ref.cost, rel=1e-9)
    np.testing.assert_allclose(ours.x, truth, rtol=0.01)  # noise 1e-3 on 4000 samples


def test_descent_keeps_to_its_evaluation_budget():
    calls = []
    t = np.linspace(0.0, 4.0, 500)
    fun = _exponentials(t, 2.0 * np.exp(-t))

    def counted(z):
        calls.append(1)
        return fun(z)

    out = descend(counted, np.array([0.1, 5.0, 3.0]), ftol=0.0, xtol=0.0, gtol=0.0,
                  max_nfev=20)
    assert len(calls) <= 20 and out.nfev == len(calls)
    assert not out.converged


def test_later_starts_in_the_same_basin_join_the_first_optimum():
    """Three grid starts on a well-excited record: one basin, found once, shared."""
    r = reference()
    y = output_noise(simulate_closed_loop(TRUTH, r, DT, LOOP), 35.0, seed=2)
    est = halves(record(y, r))[0]
    segments = as_segments(est)
    structure = STRUCTURES["reduced"]
    _, coefficients, advance = model_function(structure, LOOP, DT, "tustin", None, None, 1)
    problem = onestep._Problem(onestep._aligned(segments, None, advance), ("r", "y"), DT,
                               advance, "level", False)
    starts = [np.array([3300.0, 160.0, 0.3]), np.array([3300.0, 370.0, 1.0]),
              np.array([3300.0, 240.0, 1.0])]
    evaluations = []

    def counted(theta):
        evaluations.append(1)
        return coefficients(theta)

    ranked = onestep._rank_starts(problem, counted, starts, structure, None, None)
    thetas = [theta for theta, _ in ranked]
    # the later descents stopped at the first optimum: the very same numbers
    assert all(np.array_equal(thetas[0], t) for t in thetas[1:])
    np.testing.assert_allclose(thetas[0], TRUTH, rtol=0.01)
    # and the fit from there is the fit of the one-start search from the best grid point
    full = fit_one_step(est, LOOP, discretization="tustin")
    single = fit_one_step(est, LOOP, theta0=starts[0], discretization="tustin")
    np.testing.assert_allclose(full.estimate.parameters, single.estimate.parameters, rtol=1e-7)
    assert len(evaluations) < 3 * 40  # three full descents take about 40 evaluations each
