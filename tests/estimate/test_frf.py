"""estimate_frf: periodic averaging, Welch H1, closed loop, nonlinear distortion, bad input.

The data come from :func:`servoid.bench.simulate_lti`, which integrates the continuous plant
exactly at 20× the logging rate.  With a periodic staircase (ZOH) input, no anti-alias filter
and the transient gone, the output on each excited line is exactly that of
``c2d(plant, dt, "zoh")``, which is therefore the truth the estimates are compared with.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal as sps

from servoid import ChannelError, DataError, OptionError, OptionTypeError
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.data import Experiment
from servoid.estimate import estimate_frf
from servoid.models import TransferFunction, c2d
from servoid.signals import multisine, prbs, random_binary

DT = 1e-3
WN, ZETA = 2 * np.pi * 20.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
TRUTH = c2d(PLANT, DT, "zoh")
SIGMA = 0.05


def _prbs_record(seed: int, periods: int = 12, n: int = 9, noise: float = SIGMA):
    ex = prbs(n, periods=periods, dt=DT)
    return ex, simulate_lti(PLANT, ex.values, DT, noise_std=noise, rng=seed)


# -- periodic ------------------------------------------------------------------------------------
def test_noise_free_periodic_frf_is_the_sampled_plant():
    ex, exp = _prbs_record(0, periods=4, noise=0.0)
    frd = estimate_frf(exp, period=ex.period)
    assert frd.method == "periodic" and frd.n_averages == 3 and frd.dt == DT
    # the first period settles the plant (time constant 27 ms ≪ 0.5 s): e^-19 of transient left;
    # then only the rig's fast-rate rounding remains, ~1e-11 of the unit-size output on every
    # line (so relative to the largest |G|, not to the 1e-4 of the highest lines)
    g = TRUTH.freqresp(frd.omega)
    assert np.max(np.abs(frd.response - g)) < 1e-9 * np.max(np.abs(g))
    # every line of a clock-1 PRBS is excited: 1..(P−1)/2 harmonics of 1/(P·dt)
    np.testing.assert_allclose(frd.frequency, np.arange(1, 256) / (511 * DT))
    # no empty line to look at: distortion cannot be assessed
    assert frd.distortion is not None and frd.distortion.detected is None


def test_periodic_variance_matches_the_scatter_across_seeds():
    seeds = 20
    ex, _ = _prbs_record(0)
    errors, estimated = [], []
    for seed in range(seeds):
        _, exp = _prbs_record(100 + seed)
        frd = estimate_frf(exp, period=ex.period)
        errors.append(np.abs(frd.response - TRUTH.freqresp(frd.omega)) ** 2)
        estimated.append(frd.variance)
    err, var = np.array(errors), np.array(estimated)
    m = frd.n_averages
    # true variance of the averaged line: white noise of variance σ² has E|V_k|² = P·σ² per
    # period's DFT, and the mean over M periods divides by M
    u_k = np.fft.rfft(ex.values[: ex.period])[1 : ex.period // 2 + 1]
    true_var = ex.period * SIGMA**2 / (m * np.abs(u_k) ** 2)
    # 20 seeds × 255 lines of |Ĝ − G|²/σ² ~ Exp(1): the pooled mean has s.e. 1/√5100 = 0.014;
    # 4 s.e. each way
    assert abs(np.mean(err / true_var) - 1) < 4 / np.sqrt(err.size)
    # the estimate against the empirical scatter across seeds, line by line: Σ_s|Ĝ − G|² over
    # Σ_s σ̂²; each ratio scatters by ≈ 1/√20 = 0.22, their mean over 255 lines by 0.014
    per_line = err.sum(axis=0) / var.sum(axis=0)
    assert abs(per_line.mean() - 1) < 4 * 0.22 / np.sqrt(per_line.size)
    # σ̂² is unbiased: χ²(2(M−1))/(2(M−1)) per line, s.e. of the pooled mean 1/√(5100·(M−1))
    assert abs(np.mean(var / true_var) - 1) < 4 / np.sqrt(err.size * (m - 1))
    # normalised with its own σ̂², the error is F(2, 2(M−1)): mean (M−1)/(M−2), variance
    # d³/((d−2)²(d−4)) with d = 2(M−1) → s.e. of the pooled mean √(var/5100); 4 s.e.
    d = 2.0 * (m - 1)
    se = np.sqrt(d**3 / ((d - 2) ** 2 * (d - 4)) / err.size)
    assert abs(np.mean(err / var) - (m - 1) / (m - 2)) < 4 * se


@pytest.mark.slow
def test_periodic_variance_study_200_seeds():
    ex, _ = _prbs_record(0)
    ratios = []
    for seed in range(200):
        _, exp = _prbs_record(5000 + seed)
        frd = estimate_frf(exp, period=ex.period)
        ratios.append(np.abs(frd.response - TRUTH.freqresp(frd.omega)) ** 2 / frd.variance)
    z = np.array(ratios)
    m = frd.n_averages
    d = 2.0 * (m - 1)
    se = np.sqrt(d**3 / ((d - 2) ** 2 * (d - 4)) / z.size)
    # F(2, 2(M−1)) mean within 4 s.e.; and its tail: P(F > x) = (1 + x/(M−1))^−(M−1)
    assert abs(z.mean() - (m - 1) / (m - 2)) < 4 * se
    x = 5.0
    tail = (1 + x / (m - 1)) ** -(m - 1)
    assert abs(np.mean(z > x) - tail) < 4 * np.sqrt(tail * (1 - tail) / z.size)


def test_periodic_closed_loop_keeps_the_input_noise_in_the_variance():
    # the controller feeds the output noise back into u: Ŷ/Û is still consistent (the noise
    # averages out of both spectra) and σ²_G holds the scatter of Y − Ĝ·U, input noise included
    ctl = TransferFunction([0.5, -0.45], [1.0, -1.0], dt=DT)
    ex = prbs(9, periods=12, dt=DT)
    z = []
    for seed in range(5):
        exp = simulate_lti_loop(PLANT, ctl, 0.2 * ex.values, DT, noise_std=SIGMA, rng=seed)
        frd = estimate_frf(exp, period=ex.period, reference="r")
        z.append(np.abs(frd.response - TRUTH.freqresp(frd.omega)) ** 2 / frd.variance)
    assert frd.reference_name == "r" and frd.n_lines == 255
    m = frd.n_averages
    d = 2.0 * (m - 1)
    # F(2, 2(M − 1)) per line to first order: mean (M − 1)/(M − 2) within 4 s.e. of 5 × 255
    se = np.sqrt(d**3 / ((d - 2) ** 2 * (d - 4)) / np.size(z))
    assert abs(np.mean(z) - (m - 1) / (m - 2)) < 4 * se


def test_auto_reads_the_period_from_the_design_record():
    ex = prbs(8, periods=5, dt=DT)
    sim = simulate_lti(PLANT, ex.values, DT, noise_std=0.0)
    exp = ex.to_experiment("u", role="u").add_channel("y", sim["y"], role="y")
    frd = estimate_frf(exp)
    assert frd.method == "periodic" and frd.n_averages == 4
    # without the notes the same record is analysed by Welch
    assert estimate_frf(Experiment.from_arrays(DT, u=exp["u"], y=exp["y"])).method == "welch"


def test_periodic_keeps_only_excited_lines_of_a_sparse_multisine():
    ex = multisine(1000, DT, 1.0, 200.0, periods=6, harmonics="odd", phases="random", rng=2)
    exp = simulate_lti(PLANT, ex.values, DT, noise_std=0.01, rng=3)
    frd = estimate_frf(exp, period=1000)
    np.testing.assert_allclose(frd.frequency, ex.description["frequencies"])
    assert frd.distortion.detected is False
    # the empty lines: the even ones in the band and everything up to Nyquist outside it
    assert frd.distortion.n_lines == 499 - len(ex.description["harmonics"])


# -- nonlinear distortion --------------------------------------------------------------------------
def _multisine_record(harmonics: str, seed: int):
    ex = multisine(1000, DT, 1.0, 100.0, periods=8, harmonics=harmonics, phases="random", rng=4)
    return simulate_lti(PLANT, ex.values, DT, noise_std=0.01, rng=seed)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(
    ("harmonics", "distort", "fires"),
    [
        ("log", None, False),
        ("log", lambda y: y + 0.05 * y**3, True),  # odd (cubic) nonlinearity
        ("log", lambda y: np.clip(y, -0.8, 0.8), True),  # saturation
        ("odd", lambda y: y + 0.05 * y**2, True),  # even nonlinearity shows on even lines
        # a cubic maps odd lines onto odd lines only, all excited here: nothing to see
        ("odd", lambda y: y + 0.05 * y**3, False),
    ],
)
def test_distortion_detector(seed, harmonics, distort, fires):
    exp = _multisine_record(harmonics, seed)
    y = exp["y"] if distort is None else distort(exp["y"])
    frd = estimate_frf(Experiment.from_arrays(DT, u=exp["u"], y=y), period=1000)
    d = frd.distortion
    # the test's false-alarm rate is α = 1e-3 per record; the nonlinear records show the
    # distortion 2-4 dB above the noise over hundreds of lines, which puts p far below α
    assert d.detected is fires, (d.p_value, d.odd_db, d.even_db)
    if fires:
        assert d.p_value < 1e-6
    if harmonics == "odd" and distort is not None and fires:
        assert d.even_db > 3.0  # the y² products land on the even lines


# -- Welch -----------------------------------------------------------------------------------------
def test_welch_equals_scipy_csd_and_coherence():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(20_000)
    y = sps.lfilter([0.2, 0.1], [1.0, -0.7], u) + 0.3 * rng.standard_normal(u.size)
    frd = estimate_frf(Experiment.from_arrays(DT, u=u, y=y), nperseg=512, window="hann")
    _, s_uy = sps.csd(u, y, nperseg=512)
    _, s_uu = sps.welch(u, nperseg=512)
    _, coh = sps.coherence(u, y, nperseg=512)
    # the same estimator computed another way: rounding only, ε·√(segments)
    np.testing.assert_allclose(frd.response, (s_uy / s_uu)[1:256], rtol=1e-11)
    np.testing.assert_allclose(frd.coherence, coh[1:256], atol=1e-12)


def test_welch_h1_recovers_the_magnitude_where_coherence_is_high():
    u = random_binary(2**15, rng=5).values
    exp = simulate_lti(PLANT, u, DT, noise_std=SIGMA, rng=6)
    frd = estimate_frf(exp, nperseg=1024)
    assert frd.method == "welch" and frd.coherence is not None
    g = TRUTH.freqresp(frd.omega)
    high = frd.coherence > 0.9
    assert high.sum() > 40
    # each |Ĝ| within 4σ of its own line (σ_|G| ≈ σ_G/√2 for a circular error)
    assert np.all(np.abs(np.abs(frd.response[high]) - np.abs(g[high]))
                  < 4 * np.sqrt(frd.variance[high] / 2) + 1e-12)
    # normalised errors average 1: 2·Σ of ~60 Exp(1)... s.e. ≈ 0.13; the Hann window's leakage
    # bias adds up to ~0.5 of the variance on the sharpest lines, hence 0.6..1.8
    z = np.abs(frd.response - g) ** 2 / frd.variance
    assert 0.6 < z[high].mean() < 1.8
    # the coherence is the noise-free fraction of the output power on each line: within 5 s.d.
    # of γ̂², √2·γ(1 − γ²)/√n, plus 0.015 for the bias of the Hann window's leakage, which
    # lowers γ̂² at the resonance
    s_y = np.abs(g) ** 2
    expected = s_y / (s_y + SIGMA**2)
    sd = np.sqrt(2 * expected) * (1 - expected) / np.sqrt(frd.n_averages)
    assert np.all(np.abs(frd.coherence[high] - expected[high]) < 5 * sd[high] + 0.015)


def test_closed_loop_h1_is_biased_and_the_indirect_ratio_is_not():
    ctl = TransferFunction([0.5, -0.45], [1.0, -1.0], dt=DT)
    r = 0.2 * random_binary(2**14, rng=7).values
    exp = simulate_lti_loop(PLANT, ctl, r, DT, noise_std=0.1, rng=8)
    direct = estimate_frf(exp, nperseg=512)
    indirect = estimate_frf(exp, nperseg=512, reference="r")
    assert indirect.method == "welch-indirect" and indirect.reference_name == "r"

    def normalised_errors(frd):
        low = frd.frequency < 60  # where the loop is driven well above the noise
        return (np.abs(frd.response - TRUTH.freqresp(frd.omega)) ** 2 / frd.variance)[low]

    # H1 converges to a mix of G and −1/C: its errors are many of its own σ
    assert normalised_errors(direct).mean() > 10
    # the indirect ratio is consistent: normalised errors average 1 (s.e. 0.18 over 30 lines,
    # and the Hann window's leakage at the loop's slow pole adds ~0.3) → 0.5..2
    assert 0.5 < normalised_errors(indirect).mean() < 2.0


def test_f_max_limits_the_lines():
    _, exp = _prbs_record(1, periods=3)
    frd = estimate_frf(exp, nperseg=256, f_max=100.0)
    assert frd.frequency[-1] <= 100.0 and frd.frequency[-1] > 100.0 - 1 / (256 * DT)


def test_record_metadata_and_json():
    ex, exp = _prbs_record(2, periods=4)
    exp = exp.rename({"u": "valve", "y": "position"})
    exp = exp.replace_channels([exp.channel("valve").with_values(exp["valve"], "V"),
                                exp.channel("position").with_values(exp["position"], "mm")])
    frd = estimate_frf(exp, input="valve", output="position", period=ex.period)
    assert (frd.input_name, frd.output_name, frd.unit) == ("valve", "position", "mm/V")
    doc = json.loads(json.dumps(frd.to_dict(), allow_nan=False))
    assert doc["method"] == "periodic" and len(doc["real"]) == frd.n_lines
    assert doc["distortion"]["detected"] is None


# -- bad input -------------------------------------------------------------------------------------
def _simple(n: int = 4000) -> Experiment:
    u = np.random.default_rng(0).standard_normal(n)
    return Experiment.from_arrays(DT, u=u, y=np.roll(u, 1))


@pytest.mark.parametrize(
    ("exp", "kwargs", "error", "match"),
    [
        (_simple(1500), {"period": 1000}, DataError,
         r"holds 1 whole period.*at least 2.*Record more periods"),
        (_simple(2500), {"period": 1000, "skip_periods": 1}, DataError,
         r"leaves 1;.*lower skip_periods"),
        (_simple(), {"nperseg": 5000}, DataError, r"longer than the record.*nperseg <= 2000"),
        (_simple(), {"nperseg": 4000}, DataError, r"single segment.*nperseg <= 2000"),
        (Experiment.from_arrays(DT, u=np.full(1000, 2.5), y=np.arange(1000.0)), {}, DataError,
         r"input channel 'u' is constant.*check the channel mapping"),
        (_simple(), {"period": 1000.5}, DataError,
         r"not a whole number of samples.*Resample the record"),
        (_simple(), {"period": 1000.0}, OptionTypeError, r"pass period=1000"),
        (_simple(), {"method": "periodic"}, DataError, r"pass period=<samples per period>"),
        (_simple(), {"method": "welch", "period": 1000}, OptionError, r"method='periodic'"),
        (_simple(), {"period": 1000, "nperseg": 256}, OptionError, r"pass method='welch'"),
        (_simple(), {"method": "spa"}, OptionError, r"'auto', 'welch', 'periodic'"),
        (_simple(), {"f_max": 600.0}, DataError, r"Nyquist frequency 500 Hz"),
        (_simple(), {"overlap": 1.0}, DataError, r"overlap must be a fraction in \[0, 1\)"),
        (_simple(), {"output": "force"}, ChannelError, r"no channel or role 'force'"),
        (_simple(20_000), {"period": 1000}, DataError,
         r"no line of the input carries the excitation"),
    ],
)
def test_bad_input_names_the_fix(exp, kwargs, error, match):
    with pytest.raises(error, match=match):
        estimate_frf(exp, **kwargs)


def test_data_must_be_an_experiment():
    with pytest.raises(TypeError, match="Experiment"):
        estimate_frf({"u": [1.0, 2.0]})  # type: ignore[arg-type]
