"""select_arx_order: information criteria, validation fit and comparable losses."""

import math

import numpy as np
import pytest

from servoid import DataError, Experiment, OptionError
from servoid.estimate import fit_arx, select_arx_order
from servoid.models import PolynomialModel
from servoid.validate import fit_percent, simulate_from_data

DT = 1e-3
A = np.array([1.0, -1.5, 0.7])
B = np.array([1.0, 0.5])
GRID = {"na": range(1, 5), "nb": range(1, 5), "nk": (1,)}
N = 2000
SIGMA = 0.3


def record(seed, n=N):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    e = SIGMA * rng.normal(size=n)
    y = PolynomialModel.arx(A, B, 1, DT).simulate(u) + PolynomialModel.arx(
        A, [1.0], 0, DT
    ).simulate(e)
    return Experiment.from_arrays(DT, u=u, y=y)


@pytest.mark.parametrize("criterion", ["aic", "fpe", "mdl"])
def test_criteria_pick_the_true_orders_on_one_record(criterion):
    # fixed seed: AIC/FPE over-fit with probability ≈ 0.38 per record (see the many-record
    # test below), so this asserts the bookkeeping on a record where the truth wins
    sel = select_arx_order(record(0), **GRID, criterion=criterion)
    assert (sel.best.na, sel.best.nb, sel.best.nk) == (2, 2, 1)
    assert sel.estimate.options["na"] == 2 and sel.estimate.options["nb"] == [2]
    assert sel.ranked()[0] is sel.best
    assert len(sel.candidates) == 16


def test_criteria_over_many_records():
    criteria = ("aic", "fpe", "mdl")
    picks = {c: [] for c in criteria}
    dims = {c: [] for c in criteria}
    for seed in range(40):
        exp = record(100 + seed)
        for c in criteria:
            best = select_arx_order(exp, **GRID, criterion=c).best
            picks[c].append((best.na, best.nb))
            dims[c].append(best.n_parameters)
    for c, chosen in picks.items():
        # never under-fit: dropping a2 or b1 raises N·ln V by ≫ the penalty of 2 or ln N per parameter
        assert all(na >= 2 and nb >= 2 for na, nb in chosen), (c, chosen)
    # a larger penalty never picks more parameters: ln N = 7.6 > 2 per parameter
    assert all(m <= a for m, a in zip(dims["mdl"], dims["aic"], strict=True))
    # MDL is consistent: each extra parameter wins with P(χ²₁ > ln N) = 0.006, ≈ 0.012 per
    # record (a or b), 0.47 expected over-fits in 40 records; P(≥ 4) ≈ 1e-3
    assert sum(p == (2, 2) for p in picks["mdl"]) >= 37
    # AIC keeps the truth in a direction with P(χ²₁ < 2, χ²₂ < 4) = 0.79, ≈ 0.62 for both;
    # Binomial(40, 0.62) has sd 0.077, so 0.35 is 3.5 sd below
    assert sum(p == (2, 2) for p in picks["aic"]) >= 0.35 * 40
    # FPE = V(1 + d/N)/(1 − d/N): N ln FPE = N ln V + 2d + O(d³/N²), the same choices as AIC here
    assert picks["fpe"] == picks["aic"]


def test_scores_follow_the_formulas_on_a_common_start():
    exp = record(1)
    sel = select_arx_order(exp, **GRID)
    start = 4  # the longest lag in the grid: na = 4, nk + nb − 1 = 4
    for c in sel.candidates:
        est = fit_arx(exp, c.na, c.nb, c.nk, start=start)
        n, d = est.n_samples, c.n_parameters
        assert n == N - start
        resid = est.residuals
        v = resid @ resid / n
        # Gram-route RSS (yᵀy − θᵀΦᵀy) vs direct residuals: cancellation ε·yᵀy/RSS ≪ 1e-9
        assert c.loss == pytest.approx(v, rel=1e-9)
        assert c.aic == pytest.approx(n * math.log(c.loss) + 2 * d, rel=1e-12)  # same arithmetic
        assert c.mdl == pytest.approx(n * math.log(c.loss) + d * math.log(n), rel=1e-12)  # same
        assert c.fpe == pytest.approx(c.loss * (1 + d / n) / (1 - d / n), rel=1e-12)  # same
        assert math.isnan(c.fit)


def test_losses_do_not_increase_in_nested_models():
    sel = select_arx_order(record(2), **GRID)
    loss = {(c.na, c.nb): c.loss for c in sel.candidates}
    for na in range(1, 5):
        for nb in range(1, 5):
            # same equations, more columns: RSS cannot grow; slack for the Gram route's ε·cond² rounding
            if na < 4:
                assert loss[(na + 1, nb)] <= loss[(na, nb)] * (1 + 1e-10)
            if nb < 4:
                assert loss[(na, nb + 1)] <= loss[(na, nb)] * (1 + 1e-10)


def test_fit_criterion_uses_validation_data():
    est_data, val_data = record(3), record(4, n=1000)
    sel = select_arx_order(est_data, **GRID, criterion="fit", validation=val_data)
    fits = np.array([c.fit for c in sel.candidates])
    assert np.all(np.isfinite(fits))
    assert sel.best.fit == fits.max()
    assert sel.best.na >= 2 and sel.best.nb >= 2  # an under-fitted model simulates visibly worse
    # the best fit is that of the true model on the same data: the parameter error on 2000
    # samples adds ≈ d/N to the simulation error variance, ≈ (100 − fit)·d/(2N) ≈ 0.04 point
    y_true, first = simulate_from_data(
        PolynomialModel.arx(A, B, 1, DT), val_data["y"], val_data["u"]
    )
    true_fit = fit_percent(val_data["y"][first:], y_true[first:])
    assert abs(sel.best.fit - true_fit) < 1.0  # ≫ 0.04 point, and the chance gain of 7 parameters
    under = next(c for c in sel.candidates if (c.na, c.nb) == (1, 1))
    assert under.fit < sel.best.fit - 5.0  # ARX(1,1) misses the resonance: several % of fit


def test_fit_without_validation_raises():
    with pytest.raises(DataError, match=r'criterion="fit" needs validation data'):
        select_arx_order(record(0, n=300), criterion="fit")


def test_unknown_criterion_and_empty_grid():
    with pytest.raises(
        OptionError, match="criterion must be one of 'aic', 'fpe', 'mdl', 'fit'; got 'bic'"
    ):
        select_arx_order(record(0, n=300), criterion="bic")
    with pytest.raises(DataError, match="the order grid is empty"):
        select_arx_order(record(0, n=300), na=[])
