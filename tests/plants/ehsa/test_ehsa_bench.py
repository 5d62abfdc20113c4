"""The virtual EHSA rig: chain, noise budget, files, truth, errors."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import scipy.signal as sps

from servoid import DataError, OptionError, OutputExistsError, ServoidWarning
from servoid.data import RigSpec, decimate, detrend, load_experiment_spec
from servoid.plants.ehsa import (
    CHANNELS,
    SET_B,
    SET_C,
    EhsaBench,
    ReducedEhsa,
    digitize,
    full_order_closed_loop,
    run,
    write_bench_files,
)
from servoid.signals import prbs

SPEC_PERIOD = 20_470  # one PRBS n = 11 period at clock 10 (models-spec §4)


def _snr(signal: np.ndarray, noise: np.ndarray) -> float:
    return 20 * math.log10(np.std(signal) / np.std(noise))


def _clean_at_fs(rec, name: str) -> np.ndarray:
    """The clean channel as the TOML makes it: calibrated, decimated, mean removed."""
    gain = rec.calibration()[name]
    exp = detrend(decimate(rec.clean, rec.bench.decimation), "mean")
    return gain * exp[name]


@pytest.fixture(scope="module")
def spec_run():
    """Set B, reduced, SNR 30 dB, 16 bits: the spec's E4 record through the rig."""
    ex = prbs(11, clock=10, amplitude=1e-3, dt=1e-3)
    return run(EhsaBench(), ex, rng=2026)


@pytest.fixture(scope="module")
def spec_files(spec_run, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bench")
    return write_bench_files(spec_run, folder)


# -- the written files -------------------------------------------------------------------------


def test_files_written(spec_files):
    assert [p.name for p in spec_files] == ["ehsa.tdms", "ehsa.toml", "truth.json"]
    assert all(p.is_file() for p in spec_files)


def test_toml_loads_back_in_si_at_fs(spec_run, spec_files):
    spec = load_experiment_spec(spec_files[1])
    exp = spec.load()
    assert exp.n_samples == SPEC_PERIOD
    assert exp.dt == pytest.approx(1e-3, rel=1e-12)
    assert exp.names == tuple(CHANNELS)
    assert [exp.unit(n) for n in exp.names] == ["m", "m", "Pa", "Pa", "°C"]
    assert exp.names_of("r") == ("yr_cmd",) and exp.names_of("y") == ("y_pos",)
    assert spec.preprocess.decimate == 5 and spec.preprocess.detrend == "mean"
    assert spec.split.fraction == 0.5 and spec.split.period is None  # one period: halves
    assert dict(spec.loop) == {"c": pytest.approx(0.01), "F": pytest.approx(0.01)}
    assert dict(spec.identify) == {"method": "closedloop", "approach": ("indirect", "one-step"),
                                   "na": 3, "nb": 4, "nk": 0, "discretization": "auto"}
    # the rig declared: the filter the position went through and how r was logged
    assert spec.rig == RigSpec(4, 1000.0, "readback")
    assert dict(spec.report) == {"truth": "truth.json"}
    est, val = spec.split_data(exp)
    assert est.n_samples == val.n_samples == SPEC_PERIOD // 2

    # The calibrated position is the clean one plus the budgeted noise: its rms is
    # noise_std within 3 % (the std of N = 20 470 near-white samples is known to
    # 1/sqrt(2N) = 0.5 %; 3 % is 6 of those), and no sample is off by more than 5.5 σ
    # (P(|z| > 5.5) = 4e-8 per sample, 8e-4 over the record).
    err = exp["y_pos"] - _clean_at_fs(spec_run, "y_pos")
    assert np.std(err) == pytest.approx(spec_run.noise_std, rel=0.03)
    assert np.max(np.abs(err)) < 5.5 * spec_run.noise_std
    # The command has no sensor noise: only quantisation, half an LSB at f_acq.
    cmd_err = exp["yr_cmd"] - _clean_at_fs(spec_run, "yr_cmd")
    half_lsb_m = 0.5 * spec_run.bench.lsb / spec_run.bench.command_sensitivity
    assert np.max(np.abs(cmd_err)) <= half_lsb_m * 1.01  # FIR gain sum |h| ≈ 1.01

    # Side channels in SI: 21 MPa supply with 0.1 MPa ripple, return ≈ 0, oil ≈ 40 °C.
    raw = spec.load().side  # detrend leaves side channels alone
    assert np.mean(raw["p_supply"]) == pytest.approx(SET_B.P_s, abs=5e3)  # ripple averages out
    assert abs(np.mean(raw["p_return"])) < 5e3  # 35 kPa noise / sqrt(N) ≈ 0.3 kPa
    assert np.mean(raw["t_oil"]) == pytest.approx(40.0 + 0.5 / 60 * 10.235, abs=0.01)


def test_realised_snr_matches_request(spec_run, spec_files):
    y = load_experiment_spec(spec_files[1]).load()["y_pos"]
    clean = _clean_at_fs(spec_run, "y_pos")
    # ±1 dB asked; the budget is exact in expectation, the estimate scatters 0.04 dB.
    assert _snr(clean, y - clean) == pytest.approx(30.0, abs=0.2)
    assert spec_run.snr_db == pytest.approx(30.0, abs=1e-9)


@pytest.mark.parametrize(("bits", "snr"), [(16, 20.0), (16, 50.0), (10, 30.0)])
def test_realised_snr_other_levels(bits, snr):
    # 10 bits: quantisation (6 µm at f_s) is a third of the noise; the budget counts it.
    ex = prbs(9, clock=10, amplitude=1e-3, dt=1e-3)
    rec = run(EhsaBench(bits=bits, snr_db=snr), ex, rng=11)
    gain = rec.calibration()["y_pos"]
    y = gain * detrend(decimate(rec.raw, 5), "mean")["y_pos"]
    clean = _clean_at_fs(rec, "y_pos")
    assert _snr(clean, y - clean) == pytest.approx(snr, abs=1.0)  # the ±1 dB of the brief


def test_truth_json(spec_run, spec_files):
    truth = json.loads(spec_files[2].read_text(encoding="utf-8"))
    assert truth["fidelity"] == "reduced" and truth["exact"] is True
    assert truth["K"] == pytest.approx(3451.7, rel=1e-4)
    assert truth["omega_hp"] == pytest.approx(163.3, rel=1e-3)
    assert truth["delta_hp"] == pytest.approx(0.249, rel=1e-3)
    assert truth["c"] == pytest.approx(0.01) and truth["F"] == pytest.approx(0.01)
    assert truth["snr_db"] == 30.0 and truth["seed"] == 2026
    assert truth["parameters"]["M_t"] == 1500.0
    assert truth["excitation"]["period"] == SPEC_PERIOD


# -- the DAQ -------------------------------------------------------------------------------------


@pytest.mark.parametrize("bits", [16, 12])
def test_quantisation_step(bits):
    bench = EhsaBench(bits=bits)
    assert bench.lsb == 20.0 / 2**bits  # range/2^bits with the ±10 V span
    rec = run(bench, prbs(6, clock=10, amplitude=1e-3, dt=1e-3), rng=0)
    for name in rec.raw.names:
        codes = rec.raw[name] / bench.lsb
        assert np.array_equal(codes, np.round(codes)), name
    steps = np.diff(np.unique(rec.raw["y_pos"]))
    assert steps.min() == pytest.approx(bench.lsb, rel=1e-9)


def test_anti_alias_attenuates_tone_above_nyquist():
    # 80 kHz analog rate: the first-order hold's sinc² costs 0.04 dB at 3 kHz.
    bench = EhsaBench(oversample=16, bits=24)
    f_an = bench.f_acq * bench.oversample
    t = np.arange(int(0.2 * f_an)) / f_an
    tone = 3000.0  # above f_acq/2 = 2500 Hz: aliases to 2000 Hz
    out = digitize(bench, np.sin(2 * np.pi * tone * t), hold="foh")
    ts = np.arange(out.size) / bench.f_acq
    keep = ts > 0.02  # the filter's transient is gone (slowest pole: 0.4 ms)
    alias = bench.f_acq - tone
    basis = np.column_stack([np.sin(2 * np.pi * alias * ts), np.cos(2 * np.pi * alias * ts)])
    amp = np.hypot(*np.linalg.lstsq(basis[keep], out[keep], rcond=None)[0])
    design = abs(bench.anti_alias().freqresp([2 * np.pi * tone])[0])
    assert 20 * np.log10(design) == pytest.approx(-38.17, abs=0.01)  # 4th order at 1 kHz
    hold = np.sinc(tone / f_an) ** 2
    assert 20 * np.log10(amp) == pytest.approx(20 * np.log10(design * hold), abs=0.01)


def test_anti_alias_step_is_butterworth():
    # The command path (zero-order hold) is exact: the sampled analog step response.
    bench = EhsaBench(bits=24)
    x = np.ones(4 * 200)
    out = digitize(bench, x, hold="zoh")
    b, a = sps.butter(4, 2 * np.pi * bench.aa_cutoff, analog=True)
    t = np.arange(out.size) / bench.f_acq
    _, ref = sps.step((b, a), T=t)
    assert np.max(np.abs(out - ref)) < bench.lsb  # 24-bit quantisation, half an LSB


# -- the actuator --------------------------------------------------------------------------------


def test_reduced_reproduces_closed_loop():
    bench = EhsaBench(snr_db=None, bits=24)
    ex = prbs(8, clock=10, amplitude=1e-3, dt=1e-3)
    rec = run(bench, ex, rng=0)
    # The DAC at 24 bits plays the design within half an LSB (0.6 nm).
    assert np.max(np.abs(rec.command - np.repeat(ex.values, 5))) <= (
        0.5 * bench.lsb / bench.command_sensitivity)
    loop = ReducedEhsa.from_parameters(SET_B).closed_loop(bench.c, bench.F)
    expected = loop.simulate(rec.command, dt=bench.dt_acq)
    # Both are exact ZOH responses of the same loop: round-off only (1e-10 of 1 mm seen).
    np.testing.assert_allclose(rec.position, expected, rtol=0, atol=1e-12)
    assert rec.truth.exact and rec.truth.closed_loop().den.tolist() == loop.den.tolist()
    # No sensor noise: the raw position is the clean one quantised (half an LSB).
    assert np.max(np.abs(rec.raw["y_pos"] - rec.clean["y_pos"])) <= 0.5 * bench.lsb * 1.000001
    assert rec.sensor_noise_std == 0.0


def test_full_reproduces_eighth_order_loop():
    ex = prbs(7, clock=10, amplitude=1e-3, dt=1e-3)
    rec = run(EhsaBench(fidelity="full", snr_db=None), ex, rng=0)
    assert not rec.truth.exact
    expected = full_order_closed_loop(SET_B).simulate(rec.command, dt=2e-4)
    # The reference runs lfilter on the 8th-order polynomials, good to ~1e-8 relative at
    # 5 kHz (it degrades to 1e-3 at 20 kHz, which is why the bench uses sections).
    np.testing.assert_allclose(rec.position, expected, rtol=0, atol=1e-10)


def test_nonlinear_runs_within_stroke():
    ex = prbs(7, clock=10, amplitude=0.5e-3, dt=1e-3)  # within Set C's limits (0.52 mm)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        rec = run(EhsaBench(fidelity="nonlinear", params=SET_C), ex, rng=3)
    # the one warning: 1 kHz cannot resolve Set C's 1.42 kHz resonance (said before the run)
    assert [str(w.message)[:35] for w in caught] == ["f_s = 1000 Hz cannot resolve this a"]
    assert rec.warnings == (str(caught[0].message),)
    assert np.max(np.abs(rec.position)) <= SET_C.stroke
    # It follows the reduced loop's response to the same command up to its 1 ms dead
    # time, friction and valve dynamics (correlation 0.97 seen; 0.9 is a loose floor).
    lin = ReducedEhsa.from_parameters(SET_C).closed_loop(bench_c := SET_C.reference_gain,
                                                          SET_C.K_fb)
    assert bench_c == pytest.approx(0.01)
    expected = lin.simulate(rec.command, dt=rec.bench.dt_acq)
    assert np.corrcoef(rec.position, expected)[0, 1] > 0.9
    big = prbs(7, clock=10, amplitude=15e-3, dt=1e-3)
    with pytest.warns(ServoidWarning, match="asks more than the actuator can do: load pressure "
                      r".*spool opening .*the bench shows it"):
        rec = run(EhsaBench(fidelity="nonlinear"), big, rng=3)
    assert np.max(np.abs(rec.position)) <= SET_B.stroke
    assert any("spool" in w for w in rec.warnings)


# -- reproducibility and files ---------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["tdms", "csv"])
def test_seed_reproduces_bit_identical_files(tmp_path, fmt):
    ex = prbs(7, clock=10, amplitude=1e-3, dt=1e-3)
    a = write_bench_files(run(EhsaBench(), ex, rng=5), tmp_path / "a", format=fmt)
    b = write_bench_files(run(EhsaBench(), ex, rng=5), tmp_path / "b", format=fmt)
    c = write_bench_files(run(EhsaBench(), ex, rng=6), tmp_path / "c", format=fmt)
    for pa, pb in zip(a, b, strict=True):
        assert pa.read_bytes() == pb.read_bytes(), pa.name
    assert a[0].read_bytes() != c[0].read_bytes()
    exp = load_experiment_spec(a[1]).load()
    assert exp.n_samples == ex.n_samples


def test_two_periods_split_on_whole_periods(tmp_path):
    ex = prbs(6, clock=10, amplitude=1e-3, periods=2, dt=1e-3)
    files = write_bench_files(run(EhsaBench(), ex, rng=1), tmp_path)
    spec = load_experiment_spec(files[1])
    assert spec.split.period == 630
    est, val = spec.split_data()
    assert est.n_samples == val.n_samples == 630


def test_never_overwrites_unless_asked(tmp_path):
    rec = run(EhsaBench(), prbs(6, clock=10, amplitude=1e-3, dt=1e-3), rng=1)
    (tmp_path / "truth.json").write_text("{}", encoding="utf-8")
    with pytest.raises(OutputExistsError, match="truth.json"):
        write_bench_files(rec, tmp_path)
    assert not (tmp_path / "ehsa.tdms").exists()  # checked before anything is written
    files = write_bench_files(rec, tmp_path, overwrite=True)
    assert json.loads(files[2].read_text(encoding="utf-8"))["seed"] == 1


# -- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"fidelity": "linear"}, OptionError, "'reduced', 'full', 'nonlinear'"),
        ({"f_acq": 4500.0}, DataError, "integer multiple of f_s.*try f_acq = 5000"),
        ({"f_acq": 500.0}, DataError, "integer multiple"),
        ({"bits": 7}, DataError, "bits must lie in 8..24"),
        ({"bits": 25}, DataError, "bits must lie in 8..24"),
        ({"bits": 16.0}, TypeError, "bits must be an integer"),
        ({"snr_db": float("nan")}, DataError, "snr_db must be finite"),
        ({"snr_db": float("inf")}, DataError, "snr_db=None for no sensor noise"),
        ({"aa_cutoff": 3000.0}, DataError, "below the acquisition Nyquist"),
        ({"adc_range": -10.0}, DataError, "adc_range must be finite and > 0"),
        ({"params": "B"}, TypeError, "EhsaParameters"),
    ],
)
def test_bad_bench(kwargs, error, match):
    with pytest.raises(error, match=match):
        EhsaBench(**kwargs)


@pytest.mark.parametrize(
    ("bench", "ex", "match"),
    [
        (EhsaBench(), prbs(6, clock=10, amplitude=1e-3, dt=2e-4), r"1/f_s = 0.001 s"),
        (EhsaBench(), prbs(6, clock=10, amplitude=24e-3, dt=1e-3),
         "command range ±23 mm; lower the amplitude"),
        (EhsaBench(command_range=0.03), prbs(6, clock=10, amplitude=26e-3, dt=1e-3),
         "exceeds the stroke ±25 mm; lower the amplitude"),
        (EhsaBench(command_sensitivity=500.0), prbs(6, clock=10, amplitude=21e-3, dt=1e-3),
         "beyond the DAC range ±10 V; lower the amplitude"),
    ],
)
def test_bad_excitation(bench, ex, match):
    with pytest.raises(DataError, match=match):
        run(bench, ex, rng=0)


def test_rng_required():
    ex = prbs(6, clock=10, amplitude=1e-3, dt=1e-3)
    with pytest.raises(TypeError, match="integer seed"):
        run(EhsaBench(), ex, rng=None)  # type: ignore[arg-type]


def test_warnings_for_clipping_and_quantisation():
    ex = prbs(6, clock=10, amplitude=1e-3, dt=1e-3)
    with pytest.warns(ServoidWarning, match="'y_pos' clipped at ±10 V.*sensitivity"):
        run(EhsaBench(position_sensitivity=12_000.0), ex, rng=0)
    with pytest.warns(ServoidWarning, match="quantisation alone.*more bits"):
        rec = run(EhsaBench(bits=8, snr_db=60.0), ex, rng=0)
    assert rec.noise_std == rec.quantisation_std
