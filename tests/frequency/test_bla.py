"""estimate_bla: Wiener–Hammerstein system under random-odd multisines, periodic FRF, closed loop.

The generator is the virtual rig: continuous linear blocks integrated exactly at 20× the
logging rate (:func:`servoid.bench.simulate_lti`), a static curve between them applied to the
logged samples, which the second block then holds.  Its BLA is known in closed form: the
product of the two sampled blocks times the Bussgang gain of the curve,
``E[f(x)·x]/E[x²] = 1 + 3a·σ²_x`` for ``f(x) = x + a·x³`` and a Gaussian x (a random-phase
multisine with many lines is Gaussian to O(1/F), F the number of lines).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from servoid import DataError
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.data import Experiment
from servoid.frequency import estimate_bla
from servoid.models import TransferFunction, c2d
from servoid.signals import plan_multisine, random_multisine

DT = 0.01
G1 = TransferFunction([2 * np.pi * 5.0], [1.0, 2 * np.pi * 5.0])  # first-order lag, 5 Hz
WN, ZETA = 2 * np.pi * 12.0, 0.2
G2 = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
A3 = 0.15


def _plan(seed=0, m=8, p=2):
    return plan_multisine(DT, 0.2, 30.0, period=512, lines="random-odd", rng=seed,
                          realisations=m, periods=p, transient_periods=1)


def _wiener_hammerstein(u, seed, noise=0.01, a2=0.0):
    x = simulate_lti(G1, u, DT)["y"]
    w = x + a2 * x**2 + A3 * x**3
    return x, simulate_lti(G2, w, DT, noise_std=noise, rng=seed)["y"]


def _truth(plan, x_var):
    om = 2 * np.pi * plan.frequencies
    return (c2d(G1, DT, "zoh").freqresp(om) * c2d(G2, DT, "zoh").freqresp(om)
            * (1.0 + 3.0 * A3 * x_var))


def test_bla_of_a_wiener_hammerstein_system_is_its_closed_form():
    plan = _plan()
    u = random_multisine(plan, rng=1).values
    x, y = _wiener_hammerstein(u, seed=2)
    frm = estimate_bla(Experiment.from_arrays(DT, u=u, y=y), plan)
    # one steady period (after the transient one): the power is the same in every realisation
    x_var = float(np.var(x[plan.period:2 * plan.period]))
    g = _truth(plan, x_var)
    assert frm.method == "bla" and frm.realisations == 8 and frm.dof == 7.0
    # the Bussgang gain is 1.10: a BLA 10 % above the linear path
    assert 1.0 + 3.0 * A3 * x_var == pytest.approx(1.10, abs=0.01)
    z = np.abs(frm.response - g) ** 2 / frm.variance
    # |Ĝ − G|²/σ̂² ~ F(2, 2(M−1)) for each line: mean 7/6 with a spread of the mean over the
    # 57 lines of 0.18 (the mean over 20 seeds is 1.25: the multisine's O(1/F) departure from
    # Gaussian adds a little), so 0.75..1.8 is 3.5σ; no line beyond F's 0.1 % point
    # corrected for the number of lines (Bonferroni)
    assert 0.75 < float(np.mean(z)) < 1.8
    assert float(np.max(z)) < stats.f.ppf(1 - 1e-3 / z.size, 2, 14)
    # the distortion, not the 1 % noise, makes the variance
    assert np.median(frm.nonlinear_variance / frm.noise_variance) > 10
    # odd curve: odd distortion well above the noise, even lines at the noise
    d = frm.distortion
    assert d.odd_db > d.noise_db + 10 and d.odd_p < 1e-6
    assert d.even_p > 1e-3 and (d.even_db == -np.inf or d.even_db < d.odd_db - 20)


def test_distortion_variance_matches_the_scatter_over_realisations():
    plan = _plan(m=6)
    runs = 60
    g, total = [], []
    for s in range(runs):
        u = random_multisine(plan, rng=100 + s).values
        _, y = _wiener_hammerstein(u, seed=500 + s, noise=0.0)
        frm = estimate_bla(Experiment.from_arrays(DT, u=u, y=y), plan)
        g.append(frm.response)
        total.append(frm.variance)
    scatter = np.var(np.array(g), axis=0)
    est = np.mean(np.array(total), axis=0)
    # each line's scatter over 60 runs is known to ±13 %; the band ratio far better: 20 %
    assert 0.8 < scatter.sum() / est.sum() < 1.2
    assert 0.8 < float(np.median(scatter / est)) < 1.2


def test_even_curve_shows_on_the_even_lines():
    plan = _plan(m=4)
    u = random_multisine(plan, rng=1).values
    _, y = _wiener_hammerstein(u, seed=2, a2=0.2)
    d = estimate_bla(Experiment.from_arrays(DT, u=u, y=y), plan).distortion
    assert d.even_db > d.noise_db + 10 and d.even_p < 1e-6
    assert d.odd_db > d.noise_db + 10  # the cubic term is still there


def test_periodic_frf_of_a_linear_plant_with_its_noise_variance():
    plan = plan_multisine(DT, 0.2, 30.0, period=512, lines="odd", realisations=1, periods=8)
    u = random_multisine(plan, rng=1).values
    runs = 50
    g, var = [], []
    for s in range(runs):
        y = simulate_lti(G2, u, DT, noise_std=0.05, rng=s)["y"]
        frm = estimate_bla(Experiment.from_arrays(DT, u=u, y=y), plan)
        g.append(frm.response)
        var.append(frm.variance)
    truth = c2d(G2, DT, "zoh").freqresp(2 * np.pi * frm.frequency)
    assert frm.method == "periodic" and frm.dof == 7.0 and frm.nonlinear_variance is None
    g = np.array(g)
    # after one transient period of 0.5 s (time constant 66 ms) nothing is left: no bias
    assert np.max(np.abs(g[0] - truth) / np.sqrt(var[0])) < 5.0
    ratio = np.var(g, axis=0).sum() / np.mean(var, axis=0).sum()
    assert 0.8 < ratio < 1.2  # 50 runs: ±14 % per line, far less on the band sum


def test_closed_loop_bla_from_the_reference():
    plan = plan_multisine(DT, 0.2, 30.0, period=512, lines="odd", realisations=4, periods=4)
    r = random_multisine(plan, rng=3).values
    controller = TransferFunction([0.1], [1.0], dt=DT)
    exp = simulate_lti_loop(G2, controller, r, DT, noise_std=0.5, rng=4)
    frm = estimate_bla(exp, plan, reference="r")
    truth = c2d(G2, DT, "zoh").freqresp(2 * np.pi * frm.frequency)
    z = np.abs(frm.response - truth) ** 2 / frm.variance
    # linear loop: F(2, 2·3) per line, mean 1.5; the noise is fed back but R is clean
    assert float(np.mean(z)) < 2.5
    naive = estimate_bla(exp, plan)  # Y/U per realisation: biased towards −1/C
    zn = np.abs(naive.response - truth) ** 2 / naive.variance
    assert float(np.mean(zn)) > float(np.mean(z))


def test_bad_inputs():
    plan = _plan(m=2)
    u = random_multisine(plan, rng=1).values
    exp = Experiment.from_arrays(DT, u=u, y=u)
    with pytest.raises(DataError, match="fewer than one realisation"):
        estimate_bla(Experiment.from_arrays(DT, u=u[:600], y=u[:600] * 2), plan)
    with pytest.raises(DataError, match="does not fit the plan"):
        estimate_bla(Experiment.from_arrays(0.0137, u=u, y=2 * u), plan)
    with pytest.raises(DataError, match="same channel"):
        estimate_bla(exp, plan, output="u")
    one = plan_multisine(DT, 0.2, 30.0, period=512, lines="odd", periods=1)
    with pytest.raises(DataError, match="no variance"):
        estimate_bla(Experiment.from_arrays(DT, u=u, y=2 * u), one)
