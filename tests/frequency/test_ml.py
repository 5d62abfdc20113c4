"""fit_ml / select_ml_order: s-domain on band-limited multisine data, z-domain on LPM records.

Generators (none shares the estimator's model): the virtual rig integrates the continuous
plant at 20× the logging rate.  With a multisine played at that fast rate (``intersample =
"fast"``) and the same anti-alias filter on input and output, the periodic FRF on each
excited line is exactly G(jω)·(filter)/(filter) = G(jω): the truth for an s-domain fit.  With
a held (ZOH) random input the record's response is exactly ``c2d(plant, dt, "zoh")``: the
truth for a z-domain fit of an LPM estimate (transients included, coloured noise).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from servoid import DataError
from servoid.bench import simulate_lti
from servoid.frequency import estimate_bla, estimate_lpm, fit_ml, select_ml_order
from servoid.models import TransferFunction, c2d
from servoid.signals import plan_multisine, random_multisine

DT, OS = 0.01, 20
WN, ZETA = 2 * np.pi * 6.6, 0.05
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
THETA = np.array([WN**2, 2 * ZETA * WN, WN**2])  # b0, a1, a2
PLAN = plan_multisine(DT / OS, 0.1, 30.0, period=512 * OS, lines="odd", periods=6,
                      transient_periods=2)
U_FAST = random_multisine(PLAN, rng=1).values


def _periodic(seed, plant=PLANT, noise=0.02, anti_alias=40.0):
    exp = simulate_lti(plant, U_FAST, DT, intersample="fast", oversample=OS,
                       anti_alias=anti_alias, noise_std=noise, rng=seed)
    return estimate_bla(exp, PLAN)


@pytest.fixture(scope="module")
def s_fits():
    return [fit_ml(_periodic(1000 + s), 2, 0) for s in range(100)]


def test_s_domain_estimates_lie_within_4_sigma_and_intervals_cover(s_fits):
    z = np.array([(f.parameters - THETA) / f.std for f in s_fits])
    assert np.all(np.abs(z[0]) < 4.0)  # one record: 4σ (STYLE §6)
    # 95 % intervals: 300 coverages (3 parameters × 100 records), the 90–98 %
    cover = float(np.mean(np.abs(z) < stats.norm.ppf(0.975)))
    assert 0.90 <= cover <= 0.98, cover


def test_cost_test_holds_its_level_on_the_true_order(s_fits):
    p = np.array([f.p_value for f in s_fits])
    # rejections at 5 % over 100 records: binomial(100, 0.05) lies in 0..11 with 99.6 %
    assert int(np.sum(p < 0.05)) <= 11
    # the cost's spread agrees with its predicted one (100 records: ±14 % on the std)
    costs = np.array([f.cost for f in s_fits])
    assert np.std(costs) == pytest.approx(s_fits[0].cost_std, rel=0.3)
    assert np.mean(costs) == pytest.approx(s_fits[0].expected_cost, rel=0.05)


def test_cost_test_rejects_a_too_low_order_and_selection_picks_the_true_one():
    frm = _periodic(7)
    low = fit_ml(frm, 1, 0)
    assert low.p_value < 1e-6
    chosen, fits = select_ml_order(frm, [(1, 0), (2, 0), (3, 0), (4, 0)])
    assert (chosen.n_poles, chosen.n_zeros) == (2, 0) and len(fits) == 4


def test_delay_is_estimated_with_its_standard_deviation():
    late = TransferFunction(PLANT.num, PLANT.den, delay=0.004)
    # no anti-alias filter here: the rig filters its logged input after the plant's delay, so
    # a filtered input would carry the delay too
    fit = fit_ml(_periodic(3, plant=late, anti_alias=None), 2, 0, delay=None)
    assert fit.names[-1] == "tau"
    # 4σ; σ is tens of µs for this record
    assert abs(fit.parameters[-1] - 0.004) < 4 * fit.std[-1]
    assert fit.std[-1] < 2e-4


@pytest.mark.parametrize("start", ["wls", "gtls", "btls"])
def test_every_start_reaches_the_same_minimum(start):
    frm = _periodic(5)
    ref = fit_ml(frm, 2, 0)
    fit = fit_ml(frm, 2, 0, start=start)
    # the same minimum: the costs agree to the solver's tolerance
    assert fit.cost == pytest.approx(ref.cost, rel=1e-6)


def test_z_domain_fit_of_an_lpm_record_covers_the_sampled_plant():
    truth = c2d(PLANT, DT, "zoh")
    # z-domain form: (b0 + b1 z⁻¹) z⁻¹ / (1 + a1 z⁻¹ + a2 z⁻²)
    num = np.trim_zeros(truth.num, "f")
    theta = np.concatenate([num, truth.den[1:]])
    u = np.random.default_rng(0).standard_normal(4096)
    zs = []
    for s in range(60):
        exp = simulate_lti(PLANT, u, DT, noise_std=0.05, noise_model=([1.0, 0.5], [1.0, -0.8]),
                           rng=200 + s)
        fit = fit_ml(estimate_lpm(exp, f_min=0.5, f_max=30.0), 2, 1, domain="z",
                     delay_samples=1)
        zs.append((fit.parameters - theta) / fit.std)
    zs = np.array(zs)
    assert np.all(np.abs(zs[0]) < 4.0)
    # 240 coverages over 60 records (the LPM variance's q = 7 dof: the SML correction 7/5)
    cover = float(np.mean(np.abs(zs) < stats.norm.ppf(0.975)))
    assert 0.90 <= cover <= 0.98, cover


def test_noise_free_data_in_the_structure_is_recovered_exactly():
    f = np.linspace(0.1, 30.0, 300)
    g = PLANT.freqresp(2 * np.pi * f)
    from servoid.frequency import FrfMeasurement

    frm = FrfMeasurement(f, g, np.full(f.size, 1e-8), np.full(f.size, 1e-8), None, np.inf,
                         np.inf, 1, "periodic")
    fit = fit_ml(frm, 2, 0)
    np.testing.assert_allclose(fit.parameters, THETA, rtol=1e-9)  # round-off of the solve
    assert fit.cost < 1e-12


def test_bad_inputs():
    frm = _periodic(1)
    with pytest.raises(DataError, match="n_zeros <= n_poles"):
        fit_ml(frm, 2, 3)
    with pytest.raises(DataError, match="cannot fit"):
        fit_ml(frm.select(1.0, 1.5), 4, 3)
    with pytest.raises(DataError, match="delay_samples"):
        fit_ml(frm, 2, 1, domain="z", delay=None)
