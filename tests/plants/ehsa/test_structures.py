"""Plant structures and the structure test: do the data reject the reduced model?

Known answers (issue 9, item 3): on the bench's ``"reduced"`` fidelity the test rejects
at about its level; on ``"full"`` and ``"nonlinear"`` data, per run, either the reduced
model's 95 % intervals cover the truth or the test rejects the reduced model, in >= 95 %
of runs.  Plus invariants: the larger structures contain the reduced one exactly, nested
fits never cost more, and the lag fitted to reduced data is zero within its interval.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import numpy as np
import pytest
import scipy.signal as sps
from scipy import stats

from servoid import DataError, OptionError, ServoidWarning
from servoid.data import Experiment, decimate, detrend
from servoid.models import TransferFunction, c2d
from servoid.plants.ehsa import (
    SET_B,
    SET_C,
    STRUCTURES,
    ClosedLoopResult,
    EhsaBench,
    FeedbackLoop,
    NestedTest,
    PlantStructure,
    StructureFit,
    StructureTest,
    compare_structures,
    fit_one_step,
    full_order_plant,
    full_order_structure,
    reduced_plant,
    run,
)
from servoid.signals import prbs

TRUTH = (SET_B.K, SET_B.omega_hp, SET_B.delta_hp)
LOOP = FeedbackLoop(c=0.01, F=0.01)
DT = 1e-3
ALL = ("reduced", "reduced+lag", "full-order")
LEVEL = 0.01

# -- the structures ------------------------------------------------------------------------------


def test_registry():
    assert tuple(STRUCTURES) == ALL
    for s in STRUCTURES.values():
        assert len(s.names) == len(s.units) == len(s.transforms) == s.n_parameters
        assert s.nests in (None, "reduced")
    assert STRUCTURES["reduced"].bounds is None
    lag = STRUCTURES["reduced+lag"]
    assert lag.extra_names == ("tau_v",) and lag.units[-1] == "s"
    assert lag.is_on_bound() == (True,)  # τ_v >= 0 and the reduced model is τ_v = 0


@pytest.mark.parametrize("name", ["reduced+lag", "full-order"])
def test_larger_structures_contain_the_reduced_plant(name):
    s = STRUCTURES[name]
    g = s.plant(np.array([*TRUTH, *s.null]))
    g0 = reduced_plant(TRUTH)
    # τ_v = 0 zeroes the leading coefficients, which TransferFunction trims: the same arrays
    np.testing.assert_array_equal(g.num, g0.num)
    np.testing.assert_array_equal(g.den, g0.den)


def test_full_order_at_its_nominal_delay_is_the_eighth_order_plant():
    s = full_order_structure(SET_B)
    tau = s.fixed["tau_nom"]
    assert tau == pytest.approx(2 * 0.5 / SET_B.omega_f + 1e-3 + 2 * 0.6 / SET_B.omega_sp,
                                rel=1e-15)
    g = s.plant(np.array([*TRUTH, tau]))
    ref = full_order_plant(SET_B)
    assert g.order == ref.order == 8
    w = np.logspace(0, 4, 50)
    # Same polynomials formed in another order: rounding of 8th-degree products (~1e-13).
    np.testing.assert_allclose(g.freqresp(w), ref.freqresp(w), rtol=1e-10)


@pytest.mark.parametrize("tau", [1.5e-3, 1e-6, 1e-9])  # nominal; below each floor
@pytest.mark.parametrize("name", ["reduced+lag", "full-order"])
def test_tau_v_is_the_valve_mean_delay(name, tau):
    # −∠(G/G_reduced)(jω)/ω → τ_v as ω → 0, for either valve shape, also where a floor
    # replaces the stiff valve (full-order below 1.5 µs, the lag below 0.6 µs)
    s = STRUCTURES[name]
    w = 1e-2
    valve = s.plant(np.array([*TRUTH, tau])).freqresp(w) / reduced_plant(TRUTH).freqresp(w)
    # The next term of the phase is O((ωτ)³): 1e-15 relative at ω = 0.01 rad/s; the
    # division leaves rounding of 1e-16 rad, 1e-14 s, against the smallest τ_v.
    assert -np.angle(valve) / w == pytest.approx(tau, rel=1e-9, abs=1e-13)


@pytest.mark.parametrize("name", ["reduced+lag", "full-order"])
def test_valve_floors_are_continuous(name):
    # Where the stiff valve gives way to its low-order stand-in the closed loop must not jump:
    # the two agree to (ω·τ_floor)², 1e-8 at 100 rad/s, 7e-6 at Nyquist (3142 rad/s).
    s = STRUCTURES[name]
    floor = 1e-4 / TRUTH[1] if name == "reduced+lag" else 1e-3 * s.fixed["tau_nom"]
    w = np.array([10.0, 100.0, 1000.0, 3142.0])
    below, above = (LOOP.close(s.plant(np.array([*TRUTH, floor * (1 + e)]))).freqresp(w)
                    for e in (-1e-9, 1e-9))
    assert np.all(np.abs(below / above - 1) <= 1e-5 * (w / 3142.0) ** 2 + 1e-12)


def test_start_and_reduced_maps():
    for s in STRUCTURES.values():
        theta0 = s.start(TRUTH)
        assert theta0.shape == (s.n_parameters,)
        np.testing.assert_array_equal(theta0[:3], TRUTH)
        assert s.reduced(theta0) == TRUTH
    # the valve starts ten times faster than the hydraulics, off the bound τ_v = 0
    assert STRUCTURES["reduced+lag"].start(TRUTH)[3] == pytest.approx(0.1 / TRUTH[1])


def test_full_order_takes_the_users_nominal_set():
    s = full_order_structure(SET_C.with_(omega_s1=500.0))
    assert s.fixed["omega_s1"] == 500.0 and s.name == "full-order"
    assert s.fixed["tau_nom"] > STRUCTURES["full-order"].fixed["tau_nom"]
    with pytest.raises(TypeError, match="EhsaParameters"):
        full_order_structure("B")  # type: ignore[arg-type]


def test_lag_keeps_the_jacobian_regular_at_the_reduced_model():
    # Why τ_v and not ω_v = 1/τ_v: at the reduced model (τ_v → 0) ∂ŷ/∂τ_v stays finite while
    # ∂ŷ/∂(log ω_v) = −τ_v·∂ŷ/∂τ_v vanishes with τ_v.
    r = prbs(8, clock=10, amplitude=1e-3, dt=DT).values
    s = STRUCTURES["reduced+lag"]

    def y(theta):
        return _closed_loop(s, theta).simulate(r)

    h = 1e-7  # [s] a tenth of a microsecond: linear regime of the lag
    col_tau = (y(np.array([*TRUTH, h])) - y(np.array([*TRUTH, 0.0]))) / h
    assert np.linalg.norm(col_tau) > 1e-2 * np.linalg.norm(y(np.array([*TRUTH, 0.0]))) / DT


# -- fitting ---------------------------------------------------------------------------------


def _closed_loop(structure: PlantStructure, theta) -> TransferFunction:
    """The loop sampled with a first-order hold: the synthetic records' generator."""
    return c2d(LOOP.close(structure.plant(np.asarray(theta, dtype=float))), DT, "foh")


def _fit(name: str, data: Experiment, theta0, hold: str) -> ClosedLoopResult:
    # The fit's own diagnostics are not under test here (on reduced data τ_v = 0 sits on its
    # bound, where they rightly say its interval is one-sided).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        return fit_one_step(data, LOOP, np.asarray(theta0, dtype=float), structure=name,
                            discretization=hold)


def _fit_all(data: Experiment, names=ALL, hold: str = "bandlimited",
             both: bool = True) -> dict[str, ClosedLoopResult]:
    """The reduced fit, then each larger structure from two starts, the lower cost kept.

    One start is the reduced estimate with τ_v at its null value, so a larger fit can never
    end above the reduced one's cost; the other (``both``) is the structure's own start
    (τ_v = 0.1/ω_hp).
    """
    base = _fit("reduced", data, (TRUTH[0] * 1.2, TRUTH[1] * 0.9, 0.4), hold)
    fits = {"reduced": base}
    theta = base.source.parameters
    for name in names[1:]:
        s = STRUCTURES[name]
        starts = [np.array([*theta, *s.null])] + ([s.start(theta)] if both else [])
        tries = [_fit(name, data, start, hold) for start in starts]
        fits[name] = min(tries, key=lambda f: f.source.noise_variance)
    return fits


def _bench(fidelity: str, seed: int, n: int = 9, snr_db: float = 30.0) -> Experiment:
    """The bench record as its experiment TOML makes it: volts → m, decimated, mean removed."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # nonlinear: friction and saturation notes
        rec = run(EhsaBench(fidelity=fidelity, snr_db=snr_db),
                  prbs(n, clock=10, amplitude=1e-3, dt=DT), rng=seed)
    gain = rec.calibration()
    exp = detrend(decimate(rec.raw, rec.bench.decimation), "mean")
    return Experiment.from_arrays(exp.dt, r=gain["yr_cmd"] * exp["yr_cmd"],
                                  y=gain["y_pos"] * exp["y_pos"], units={"r": "m", "y": "m"})


def _test(fits, data) -> StructureTest:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        return compare_structures(fits, data, level=LEVEL)


def _covered(result: ClosedLoopResult, level: float = 0.95) -> bool:
    ci = result.estimate.confidence_intervals(level)
    return bool(np.all((ci[:, 0] <= TRUTH) & (TRUTH <= ci[:, 1])))


# -- compare_structures: known answers on exact data ---------------------------------------------


@pytest.fixture(scope="module")
def synthetic():
    """5110 samples of the FOH model itself, 30 dB white noise: reduced and with a 1.5 ms lag."""
    r = prbs(9, clock=10, amplitude=1e-3, dt=DT).values
    rng = np.random.default_rng(11)
    out = {}
    for name, theta in (("reduced", TRUTH), ("reduced+lag", (*TRUTH, 1.5e-3))):
        y0 = _closed_loop(STRUCTURES[name], theta).simulate(r)
        y = y0 + rng.normal(0.0, y0.std() / 10 ** (30 / 20), y0.size)
        data = Experiment.from_arrays(DT, r=r, y=y, units={"r": "m", "y": "m"})
        out[name] = (data, _fit_all(data, hold="foh"))
    return out


def test_right_reduced_model_is_not_rejected(synthetic):
    data, fits = synthetic["reduced"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)  # no rejection warning either
        result = compare_structures(fits, data, level=LEVEL)
    assert not result.rejected and not result.intervals_understate
    assert result.preferred == "reduced" and result.base == "reduced"
    assert "do not reject the reduced model" in result.verdict
    assert [t.larger for t in result.tests] == ["reduced+lag", "full-order"]
    for t in result.tests:
        # Nested: the larger structure never fits worse (both starts include the nested point;
        # the solver's relative cost tolerance is 1e-10, and τ_v may stop 1e-10 s off 0).
        assert result.fit(t.larger).cost <= result.fit("reduced").cost * (1 + 1e-8)
        assert t.df == 1 and t.one_sided and t.level == pytest.approx(LEVEL / 3)
        # White noise: the colour scale is 1 up to the AR order search (AIC keeps p ≈ 0).
        assert t.scale == pytest.approx(1.0, abs=0.1)
    lag = fits["reduced+lag"].source
    # The lag on data without one: zero within 4σ of its own standard deviation.
    assert abs(lag["tau_v"]) <= 4 * lag.std[3]


def test_missing_lag_is_rejected_and_says_so(synthetic):
    data, fits = synthetic["reduced+lag"]
    with pytest.warns(ServoidWarning, match="reject the reduced model"):
        result = compare_structures(fits, data, level=LEVEL)
    assert result.rejected and result.intervals_understate
    assert result.preferred == "reduced+lag"  # the truth has the lag's shape: lowest BIC
    lag_test = next(t for t in result.tests if t.larger == "reduced+lag")
    assert lag_test.rejected and lag_test.p_value < 1e-100
    # The reduced model's estimate is many of its σ from the truth; the verdict says how far.
    assert max(abs(z) for z in result.shifts["reduced+lag"].values()) > 10
    assert "understate the error" in result.verdict and "omega_hp" in result.verdict
    # The fitted lag recovers the truth within 4σ.
    lag = fits["reduced+lag"].source
    assert abs(lag["tau_v"] - 1.5e-3) <= 4 * lag.std[3]
    assert "reject the reduced model" in str(result)
    # fit_one_step names its structure, so a sequence of its results works as well
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        again = compare_structures(list(fits.values()), data, level=LEVEL)
    assert again.rejected and again.tests[0].lr == lag_test.lr
    d = json.loads(json.dumps(result.to_dict()))  # plain data all the way down
    assert d["rejected"] is True and d["intervals_understate"] is True
    assert {f["name"] for f in d["fits"]} == set(ALL)


def test_likelihood_ratio_and_criteria_formulas(synthetic):
    data, fits = synthetic["reduced+lag"]
    result = _test(fits, data)
    n = result.n_samples
    for f in result.fits:
        e = fits[f.name].source.residuals
        assert f.cost == pytest.approx(e @ e / n, rel=1e-12)
        assert f.aic == pytest.approx(n * math.log(f.cost) + 2 * f.n_parameters, rel=1e-12)
        assert f.bic == pytest.approx(n * math.log(f.cost) + f.n_parameters * math.log(n),
                                      rel=1e-12)
    t = result.tests[0]
    assert t.lr == pytest.approx(n * math.log(result.fit("reduced").cost
                                              / result.fit(t.larger).cost), rel=1e-12)
    assert t.lr_robust == pytest.approx(t.lr / t.scale, rel=1e-12)


def test_bounded_null_halves_the_tail():
    from servoid.plants.ehsa._structure_test import _pvalue

    # ½χ²(0) + ½χ²(1): the one-sided 1 % point is the two-sided 2 % point, 5.412
    assert _pvalue(stats.chi2.isf(0.02, 1), 1, True) == pytest.approx(0.01, rel=1e-12)
    assert _pvalue(3.0, 1, False) == pytest.approx(stats.chi2.sf(3.0, 1), rel=1e-12)
    assert _pvalue(0.0, 1, True) == 1.0


def test_coloured_noise_scale_matches_its_spectrum():
    # AR(1) noise v = w/(1 − 0.8q⁻¹) on data with a 1.5 ms lag: the LR statistic is c·χ²(1)
    # with c = Σ_τ ρ_v(τ)·Σ_t d̂(t)d̂(t + τ), ρ_v(τ) = 0.8^|τ|, d̂ the unit direction the lag
    # adds (ε_reduced − ε_lag).  The scale estimated from the residuals must find that c.
    r = prbs(9, clock=10, amplitude=1e-3, dt=DT).values
    rng = np.random.default_rng(5)
    y0 = _closed_loop(STRUCTURES["reduced+lag"], (*TRUTH, 1.5e-3)).simulate(r)
    w = rng.normal(0.0, y0.std() / 10 ** (30 / 20) * 0.6, r.size)
    v = sps.lfilter([1.0], [1.0, -0.8], w)
    data = Experiment.from_arrays(DT, r=r, y=y0 + v, units={"r": "m", "y": "m"})
    fits = _fit_all(data, names=ALL[:2], hold="foh")
    t = _test(fits, data).tests[0]
    d = fits["reduced"].source.residuals - fits["reduced+lag"].source.residuals
    d = d / np.linalg.norm(d)
    lags = np.arange(1, 200)  # 0.8^200 = 4e-20: the rest of the sum is nothing
    expected = 1.0 + 2.0 * sum(0.8**k * float(d[:-k] @ d[k:]) for k in lags)
    # The AR sieve estimates ρ_v from 5110 residuals: within 3 % of c on six seeds; 10 %.
    assert 5.0 < expected < 9.5
    assert t.scale == pytest.approx(expected, rel=0.1)
    assert t.lr_robust == pytest.approx(t.lr / t.scale)


# -- compare_structures: bad input ---------------------------------------------------------------


def test_bad_input(synthetic):
    data, fits = synthetic["reduced"]
    with pytest.raises(OptionError, match=r"level must lie in \(0, 1\)"):
        compare_structures(fits, data, level=1.5)
    with pytest.raises(OptionError, match="unknown structure 'reduced\\+spring'"):
        compare_structures({"reduced+spring": fits["reduced"]}, data)
    with pytest.raises(DataError, match="empty"):
        compare_structures({}, data)
    with pytest.raises(DataError, match="has 3 parameters"):
        compare_structures({"reduced+lag": fits["reduced"]}, data)
    with pytest.raises(DataError, match="does not name its structure"):
        compare_structures([dataclasses.replace(f.source, options={}) for f in fits.values()],
                           data)
    with pytest.raises(OptionError, match="do not all nest one of them"):
        compare_structures({k: fits[k] for k in ALL[1:]}, data)
    with pytest.raises(DataError, match="were the fits made on these data"):
        compare_structures(fits, data.slice(0, 4000))
    with pytest.raises(TypeError, match="ClosedLoopResult or an Estimate"):
        compare_structures({"reduced": "fit"}, data)  # type: ignore[dict-item]
    short = Experiment.from_arrays(DT, r=data["r"][:3000], y=data["y"][:3000])
    other = _fit("reduced", short, TRUTH, "foh")
    with pytest.raises(DataError, match="different numbers of residuals"):
        compare_structures({"reduced": other, "reduced+lag": fits["reduced+lag"]}, data)


def test_larger_fit_above_the_smaller_cost_is_flagged(synthetic):
    data, fits = synthetic["reduced"]
    small = fits["reduced"].source
    # A larger fit stopped short of its optimum: 1 % more cost than the nested point.
    stuck = dataclasses.replace(fits["reduced+lag"].source,
                                residual_function=lambda: 1.005 * small.residuals)
    with pytest.warns(ServoidWarning, match="missed its optimum"):
        result = compare_structures({"reduced": small, "reduced+lag": stuck}, data)
    assert result.tests[0].lr == 0.0 and "missed its optimum" in result.tests[0].note
    assert not result.rejected


# -- the bench: known answers of the issue -------------------------------------------------------

# Runs per fidelity in the default suite: 20, the minimum.  Reduced data: 5110 samples
# (PRBS n = 9, a quarter of the spec's record) and all three structures.  Full and nonlinear
# data: 2550 samples (n = 8) and the reduced model against the lag only, to keep the three
# studies near 30 s — the reduced model's misfit there is thousands of χ² units (LR ≈ 5000
# and 3000 at n = 8), so the record length does not decide the outcome; the slow study runs
# 100 records of 10 230 samples with every structure.
RUNS = 20


def _study(fidelity: str, seeds: range, n: int = 9,
           names: tuple[str, ...] = ALL) -> list[tuple[bool, bool, float]]:
    out = []
    for seed in seeds:
        data = _bench(fidelity, seed, n)
        fits = _fit_all(data, names, both=False)  # nested start: V_large <= V_small by design
        result = _test(fits, data)
        for t in result.tests:
            assert result.fit(t.larger).cost <= result.fit("reduced").cost * (1 + 1e-8)
        out.append((result.rejected, _covered(fits["reduced"]),
                    fits["reduced+lag"].source["tau_v"] / fits["reduced+lag"].source.std[3]))
    return out


def _false_alarm_bound(runs: int, level: float) -> int:
    # Largest count of rejections a right model gives with probability >= 99.9 %.
    return int(stats.binom.ppf(0.999, runs, level))


def test_bench_reduced_data_do_not_reject():
    rows = _study("reduced", range(RUNS))
    rejections = sum(r for r, _, _ in rows)
    assert rejections <= _false_alarm_bound(RUNS, LEVEL)  # 3 of 20 at 1 %
    # The lag fitted to reduced data is zero within 4σ in every run.
    assert all(abs(z) <= 4 for _, _, z in rows)


def test_full_order_structure_recovers_the_full_bench():
    # On the eighth-order bench the full-order structure is the truth (valve shape of Set B):
    # K, ω_hp, δ_hp and τ_v = τ_nom come back within 4σ, and BIC prefers it.
    data = _bench("full", 7)
    fits = _fit_all(data)
    result = _test(fits, data)
    assert result.rejected and result.preferred == "full-order"
    full = fits["full-order"]
    assert np.all(np.abs(full.estimate.parameters - TRUTH) <= 4 * full.estimate.std)
    tau = full.source["tau_v"]
    assert abs(tau - STRUCTURES["full-order"].fixed["tau_nom"]) <= 4 * full.source.std[3]
    # the reduced model is off by far more than its interval says, and the verdict says so
    assert abs(result.shifts["full-order"]["omega_hp"]) > 20
    assert result.fit("full-order").independence_pvalue > LEVEL


@pytest.mark.parametrize("fidelity", ["full", "nonlinear"])
def test_bench_mismatch_is_covered_or_rejected(fidelity):
    rows = _study(fidelity, range(100, 100 + RUNS), n=8, names=ALL[:2])
    ok = sum(rej or cov for rej, cov, _ in rows)
    assert ok >= math.ceil(0.95 * RUNS)
    # Neither fidelity is the reduced model: every run rejects it (its ω_hp is 6 % off, tens
    # of its own σ).
    assert all(rej for rej, _, _ in rows)


@pytest.mark.slow
@pytest.mark.parametrize("fidelity", ["reduced", "full", "nonlinear"])
def test_bench_study_100_runs(fidelity):
    runs = 100
    rows = _study(fidelity, range(1000, 1000 + runs), n=10)
    rejections = sum(r for r, _, _ in rows)
    if fidelity == "reduced":
        assert rejections <= _false_alarm_bound(runs, LEVEL)  # 5 of 100 at 1 %
    else:
        assert sum(rej or cov for rej, cov, _ in rows) >= 95


@pytest.mark.slow
def test_coloured_noise_keeps_the_level():
    # A right reduced model under AR(1) noise 1/(1 − 0.8q⁻¹), 200 records of 5110 samples: the
    # white-noise LR rejects it in 16 % of runs at 1 % (the noise's low-frequency excess
    # inflates N·ln(V_S/V_L) by c ≈ 6); the scaled statistic keeps the level (1.5 % seen).
    r = prbs(9, clock=10, amplitude=1e-3, dt=DT).values
    y0 = _closed_loop(STRUCTURES["reduced"], TRUTH).simulate(r)
    runs, robust, white = 200, 0, 0
    for seed in range(runs):
        rng = np.random.default_rng(1000 + seed)
        v = sps.lfilter([1.0], [1.0, -0.8], rng.normal(0.0, y0.std() / 10 ** 1.5 * 0.6, r.size))
        data = Experiment.from_arrays(DT, r=r, y=y0 + v, units={"r": "m", "y": "m"})
        t = _test(_fit_all(data, names=ALL[:2], hold="foh", both=False), data).tests[0]
        robust += t.p_value < LEVEL
        white += t.p_value_white < LEVEL
    assert robust <= _false_alarm_bound(runs, LEVEL)  # 8 of 200
    assert white > 3 * _false_alarm_bound(runs, LEVEL)  # why the scale is needed


# -- the verdict's numbers -----------------------------------------------------------------------


def _one_test(tau: float, std: float) -> StructureTest:
    fits = (StructureFit("reduced", 3, 2.73e-10, -225318.0, -225296.0, 4.3e-13, 0.96),
            StructureFit("reduced+lag", 4, 2.73e-10, -225316.0, -225287.0, 4.3e-13, 0.96))
    test = NestedTest("reduced", "reduced+lag", 1, 0.0, 1.0, 0.0, True, 1.0, 1.0, LEVEL / 2,
                      {"tau_v": tau}, "", {"tau_v": std})
    return StructureTest("reduced", fits, (test,), LEVEL, 10232, False, (), "reduced")


def test_a_lag_inside_its_standard_deviation_is_none_with_the_resolution_stated():
    # the demo's numbers: the lag ends at 9.47e-29 s with a standard deviation of 4.94 µs
    verdict = _one_test(9.47e-29, 4.94e-6).verdict
    assert "tau_v: none resolved" in verdict and "standard deviation 4.94 µs" in verdict
    assert "e-2" not in verdict  # no 9.47e-23 µs
    assert "tau_v = 1.5 ms ± 20 µs" in _one_test(1.5e-3, 2e-5).verdict  # a resolved lag
