"""One-step on data from a continuous plant: Tustin's warp and its prewarped cure."""

from __future__ import annotations

import pytest

from servoid import OptionError
from servoid.data import load_experiment_spec
from servoid.plants.ehsa import EhsaBench, FeedbackLoop, fit_one_step, run, write_bench_files
from servoid.signals import prbs


@pytest.fixture(scope="module")
def bench_record(tmp_path_factory):
    # Noise-free continuous reduced loop recorded through the rig (24-bit ADC).
    bench = EhsaBench(snr_db=None, bits=24)
    record = run(bench, prbs(11, clock=10, amplitude=1e-3, dt=bench.dt), rng=1)
    folder = tmp_path_factory.mktemp("rig")
    toml = next(p for p in write_bench_files(record, folder) if p.suffix == ".toml")
    est, _ = load_experiment_spec(toml).split_data()
    return est, record.truth


def test_plain_tustin_overestimates_omega_by_the_warp(bench_record):
    est, truth = bench_record
    fit = fit_one_step(est, FeedbackLoop(truth.c, truth.F), discretization="tustin")
    warp = (truth.omega_hp * est.dt) ** 2 / 12  # tan(x)/x − 1 ≈ x²/3 with x = ωT/2
    error = fit.estimate["omega_hp"] / truth.omega_hp - 1
    assert error == pytest.approx(warp, rel=0.2)  # the warp explains the bias to 20 %


def test_prewarp_removes_the_bias(bench_record):
    est, truth = bench_record
    fit = fit_one_step(est, FeedbackLoop(truth.c, truth.F), discretization="prewarp")
    # left: the rig's filters and hold, far below the warp (0.22 %)
    assert fit.estimate["omega_hp"] == pytest.approx(truth.omega_hp, rel=3e-4)
    assert fit.estimate["delta_hp"] == pytest.approx(truth.delta_hp, rel=2e-3)
    assert fit.estimate["K"] == pytest.approx(truth.K, rel=2e-3)
    assert fit.plant.prewarp == pytest.approx(fit.estimate["omega_hp"])


def test_unknown_discretization_lists_valid(bench_record):
    est, truth = bench_record
    with pytest.raises(OptionError, match="'tustin', 'prewarp', 'zoh'"):
        fit_one_step(est, FeedbackLoop(truth.c, truth.F), discretization="bilinear")
