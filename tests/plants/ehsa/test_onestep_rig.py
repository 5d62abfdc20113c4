"""One-step on rig data: exact sampled models, intersample stated, robust start, flags."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import signal as sps

import servoid.plants.ehsa._twostep as twostep
from servoid import DataError, OptionError, ServoidWarning
from servoid.cli import main
from servoid.data import Experiment, decimate, load_experiment_spec
from servoid.models import TransferFunction
from servoid.plants.ehsa import (
    DISCRETIZATIONS,
    SET_B,
    SET_C,
    EhsaBench,
    FeedbackLoop,
    fit_one_step,
    reduced_plant,
    run,
    simulate_closed_loop,
    write_bench_files,
)
from servoid.plants.ehsa._sampling import sampled_loop
from servoid.signals import multisine, prbs

LOOP = FeedbackLoop(0.01, 0.01)
TRUTH_B = np.array([SET_B.K, SET_B.omega_hp, SET_B.delta_hp])
TRUTH_C = np.array([SET_C.K, SET_C.omega_hp, SET_C.delta_hp])


def _rig(params=SET_B, fs=1000.0, reference="readback", snr_db=None, bits=24, register=10,
         excitation=None, seed=0):
    """A bench run loaded as the rig's TOML says: (estimation half, run, spec)."""
    bench = EhsaBench(params=params, f_s=fs, f_acq=5.0 * fs, snr_db=snr_db, bits=bits,
                      reference=reference)
    ex = excitation if excitation is not None else prbs(register, clock=10, amplitude=1e-3,
                                                          dt=bench.dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = run(bench, ex, rng=seed)
    return rec


def _loaded(rec, tmp_path):
    files = write_bench_files(rec, tmp_path, overwrite=True)
    spec = load_experiment_spec(files[1])
    est, _ = spec.split_data()
    return est, spec


def _chain(spec):
    rig = spec.rig
    num, den = sps.butter(rig.anti_alias_order, 2 * np.pi * rig.anti_alias_cutoff, analog=True)
    return {"anti_alias": TransferFunction(num, den), "decimation": spec.preprocess.decimate}


# -- exact sampled models ------------------------------------------------------------------------


@pytest.mark.parametrize("hold", ["zoh", "foh"])
def test_sampled_loop_equals_the_classic_holds(hold):
    closed = LOOP.close(reduced_plant(TRUTH_B))
    model, advance = sampled_loop(closed, 1e-3, hold)
    num, den, _ = sps.cont2discrete((closed.num, closed.den), 1e-3, method=hold)
    u = np.random.default_rng(0).standard_normal(500)
    expected = sps.lfilter(np.ravel(num), den, u)
    # same map, other arithmetic (Van Loan block exponential vs scipy's): rounding, scaled by
    # the loop's DC gain 1
    np.testing.assert_allclose(model.simulate(u), expected, rtol=0, atol=1e-12)
    assert advance == 0


def test_chain_reproduces_the_bench_record():
    # The command staircase through the continuous loop, the anti-alias filter, the ADC at
    # 5 kHz and servoid's FIR decimation: the chain model against the bench's own simulation.
    rec = _rig(register=8)
    b = rec.bench
    y = decimate(rec.clean.select("y_pos"), b.decimation)["y_pos"] / b.position_sensitivity
    r = rec.command[:: b.decimation]
    closed = LOOP.close(reduced_plant(TRUTH_B))
    model, advance = sampled_loop(closed, b.dt, "zoh", anti_alias=b.anti_alias(),
                                  decimation=b.decimation)
    assert advance == 10  # the FIR's half length, 50 taps at 5 kHz = 10 samples at 1 kHz
    y_model = simulate_closed_loop_like(model, advance, r)
    # 24-bit ADC: one LSB of the position is 20 V/2^24/400 V/m = 3e-9 m; the FIR's line
    # padding touches the first and last 10 samples
    np.testing.assert_allclose(y_model[10:-10], y[10:-10], rtol=0, atol=1e-8)


def simulate_closed_loop_like(model, advance, r):
    extended = np.concatenate([r, np.full(advance, r[-1])])
    return model.simulate(extended)[advance:]


def test_bandlimited_model_tracks_a_smooth_input():
    # u = a sum of sines; once the start-up has died out (2 s: the hydraulic pair decays at
    # 22 1/s, e^−44) the exact response is the steady state |H(jω)|·sin(ωt + ∠H(jω))
    closed = LOOP.close(reduced_plant(TRUTH_B))
    dt, n = 1e-3, 3000
    t = np.arange(n) * dt
    parts = ((1.0, 2 * np.pi * 3, 0.0), (0.5, 2 * np.pi * 17, 1.0))
    u = sum(a * np.sin(w * t + p) for a, w, p in parts)
    h = {w: complex(closed.freqresp([w])[0]) for _, w, _ in parts}
    y = sum(a * abs(h[w]) * np.sin(w * t + p + np.angle(h[w])) for a, w, p in parts)
    model, advance = sampled_loop(closed, dt, "bandlimited")
    assert advance == 3  # the 8-point interpolation reads 4 samples ahead
    y_model = simulate_closed_loop_like(model, advance, u)
    # degree-7 interpolation: O((ω·dt)^8) = 1e-8 at 17 Hz; the last samples see the reference
    # held beyond the record
    np.testing.assert_allclose(y_model[2000:-10], y[2000:-10], rtol=0, atol=1e-8)


def test_rig_chain_needs_a_staircase():
    closed = LOOP.close(reduced_plant(TRUTH_B))
    with pytest.raises(Exception, match="only for a staircase reference"):
        sampled_loop(closed, 1e-3, "bandlimited", decimation=5)


# -- recovery --------------------------------------------------------------------------------------


@pytest.mark.parametrize("discretization", ["zoh", "foh", "bandlimited"])
def test_noise_free_model_data_are_recovered(discretization):
    r = prbs(9, clock=10, amplitude=1e-3, dt=1e-3).values
    if discretization != "zoh":  # a smooth reference for the smooth holds
        r = sps.filtfilt(*sps.butter(4, 0.2), r)
    model, advance = sampled_loop(LOOP.close(reduced_plant(TRUTH_B)), 1e-3, discretization)
    y = simulate_closed_loop_like(model, advance, r)[: r.size - advance]
    data = Experiment.from_arrays(1e-3, r=r[: y.size], y=y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # the smooth r does not look like a zoh
        res = fit_one_step(data, LOOP, discretization=discretization)
    # noise-free, model inside the structure: limited by the LM tolerance 1e-10
    np.testing.assert_allclose(res.estimate.parameters, TRUTH_B, rtol=1e-7)
    assert res.intersample == discretization and res.advance == advance


@pytest.mark.parametrize("reference", ["readback", "command"])
def test_noise_free_bench_is_recovered_with_the_declared_rig(reference, tmp_path):
    est, spec = _loaded(_rig(reference=reference), tmp_path)
    chain = _chain(spec) if reference == "command" else {}
    res = fit_one_step(est, LOOP, discretization="auto", **chain)
    assert res.intersample == ("zoh" if reference == "command" else "bandlimited")
    # 24-bit converters (an LSB is 1e-6 of the ±1 mm signal) and, read back, the degree-7
    # interpolation: 8e-6 seen on K; the warped Tustin map is 2e-3 off on omega_hp
    np.testing.assert_allclose(res.estimate.parameters, TRUTH_B, rtol=3e-5)
    assert res.is_resolved and res.is_physical


def test_the_start_needs_no_two_step(monkeypatch, tmp_path):
    def refuse(*args, **kwargs):
        raise AssertionError("the one-step start must not call the two-step estimate")

    monkeypatch.setattr(twostep, "indirect_theta", refuse)
    monkeypatch.setattr(twostep, "fit_arx", refuse)
    est, _ = _loaded(_rig(snr_db=30.0, bits=16), tmp_path)
    res = fit_one_step(est, LOOP, discretization="auto")
    assert res.source.options["n_starts"] == 3
    err = np.abs(res.estimate.parameters - TRUTH_B)
    assert np.all(err < 4 * res.estimate.std)  # within 4σ of the returned covariance


def test_level_before_the_record_removes_the_start_up_bias(tmp_path):
    # The mean is removed (spec §3.2), so a record that starts at rest does not start at zero.
    # Set C at 10 kHz: the estimation half is 0.26 s against a 29 ms loop time constant.
    est, spec = _loaded(_rig(params=SET_C, fs=10000.0, reference="command", register=9),
                        tmp_path)
    rest = fit_one_step(est, LOOP, discretization="auto", initial="rest", **_chain(spec))
    level = fit_one_step(est, LOOP, discretization="auto", **_chain(spec))
    assert abs(rest.estimate["K"] / SET_C.K - 1) > 1e-3  # the transient biases the bandwidth
    # noise-free, 24-bit: the level absorbs it
    np.testing.assert_allclose(level.estimate.parameters, TRUTH_C, rtol=1e-4)
    # the level found is where the record's zero was before the means came off: −mean(r);
    # the output's offset is G(1)·mean(r) − mean(y), G(1) = c/F = 1
    raw = spec.load(detrend=False)
    m_r, m_y = (raw[name][: est.n_samples].mean() for name in ("yr_cmd", "y_pos"))
    assert level.source.options["initial_level"][0] == pytest.approx(-m_r, rel=1e-3)
    assert level.source.options["output_offset"][0] == pytest.approx(m_r - m_y, rel=1e-2)
    assert level.source.options["start"] == level.advance  # in the caller's samples


# -- what the result says ---------------------------------------------------------------------------


def test_result_states_the_intersample_assumption(tmp_path):
    est, spec = _loaded(_rig(reference="command", snr_db=35.0, bits=16), tmp_path)
    res = fit_one_step(est, LOOP, discretization="auto", **_chain(spec))
    note = res.intersample_note
    assert "staircase" in note and "anti-alias filter" in note and "decimation by 5" in note
    assert "detected staircase" in note
    data = res.to_dict()
    assert data["intersample"] == "zoh" and data["discretization"] == "auto"
    assert data["advance"] == 10 and data["flags"] == [] and data["is_resolved"] is True
    assert res.estimate.options["intersample"] == "zoh"
    assert "intersample: reference taken as a staircase" in str(res)
    json.dumps(data)
    # the aligned record simulates causally: the fitted model reproduces the data to the noise
    y_sim = simulate_closed_loop(res, est.signal("r")[:, 0])
    resid = est["y_pos"] - y_sim
    assert np.std(resid[50:-20]) < 1.2 * np.sqrt(res.source.noise_variance)  # noise, not model
    aligned = res.align(est)
    assert aligned.n_samples == est.n_samples - 10
    np.testing.assert_array_equal(aligned["yr_cmd"], est["yr_cmd"][10:])
    np.testing.assert_array_equal(aligned["y_pos"], est["y_pos"][:-10])


def test_tustin_says_what_it_is(tmp_path):
    est, _ = _loaded(_rig(snr_db=35.0, bits=16), tmp_path)
    res = fit_one_step(est, LOOP, discretization="tustin")
    assert res.intersample == "none" and res.discretization == "tustin"
    assert "no intersample model" in res.intersample_note
    assert "discretization='bandlimited'" in res.intersample_note  # the detected course


def test_declared_hold_contradicting_the_reference_warns(tmp_path):
    est, _ = _loaded(_rig(snr_db=35.0, bits=16), tmp_path)  # read back: band-limited
    with pytest.warns(ServoidWarning, match="assumes a staircase.*looks band-limited"):
        fit_one_step(est, LOOP, discretization="zoh")


@pytest.mark.parametrize(
    ("options", "error", "match"),
    [
        ({"discretization": "bandlimited", "decimation": 5}, OptionError, "use 'zoh' or 'auto'"),
        ({"discretization": "tustin", "anti_alias": TransferFunction([1.0], [1e-3, 1.0])},
         OptionError, "does not take them"),
        ({"structure": "quadratic"}, OptionError, "structure must be one of 'reduced'"),
        ({"discretization": "exact"}, OptionError, "'auto', 'tustin', 'prewarp'"),
        ({"initial": "moving"}, OptionError, "'level', 'rest'"),
        ({"anti_alias": TransferFunction([1.0], [1.0, 1.0], dt=1e-3)}, TypeError,
         "continuous TransferFunction"),
        ({"start": -1}, Exception, "start"),
    ],
)
def test_bad_options(options, error, match, tmp_path):
    est, _ = _loaded(_rig(register=8), tmp_path)
    with pytest.raises(error, match=match):
        fit_one_step(est, LOOP, **options)


def test_discrete_feedback_needs_a_map(tmp_path):
    est, _ = _loaded(_rig(register=8), tmp_path)
    loop = FeedbackLoop(0.01, TransferFunction([0.01], [1.0], dt=1e-3))
    with pytest.raises(OptionError, match="F is discrete"):
        fit_one_step(est, loop, discretization="zoh")


def test_structures_plug_in(tmp_path):
    est, _ = _loaded(_rig(snr_db=40.0, bits=16), tmp_path)
    res = fit_one_step(est, LOOP, structure="reduced+lag", discretization="auto")
    assert res.structure == "reduced+lag" and res.source.options["structure"] == "reduced+lag"
    assert res.source.parameters.size == 4
    assert res.estimate.names == ("K", "omega_hp", "delta_hp")
    # the data come from the reduced loop: the lag is ~0 and K, omega, delta are found again
    err = np.abs(res.estimate.parameters - TRUTH_B)
    assert np.all(err < 4 * res.estimate.std)


# -- what the data cannot say -------------------------------------------------------------------------


@pytest.mark.parametrize("discretization", ["prewarp", "auto"])
def test_set_c_below_its_resonance_is_flagged_not_crashed(discretization, tmp_path):
    # ω_hp = 8944 rad/s at f_s = 1 kHz (Nyquist 3142 rad/s): the prewarped map used to stop
    # with "dt must be > 0 s … got -0.0067"
    with pytest.warns(ServoidWarning, match="cannot resolve.*f_s >= 5700 Hz"):
        rec = run(EhsaBench(params=SET_C, snr_db=30.0), prbs(10, clock=10, amplitude=1e-3,
                                                               dt=1e-3), rng=3)
    est, _ = _loaded(rec, tmp_path)
    with pytest.warns(ServoidWarning, match="not resolved at f_s = 1000 Hz"):
        res = fit_one_step(est, LOOP, discretization=discretization)
    assert not res.is_resolved
    assert any("record at f_s >=" in f for f in res.flags)
    if discretization == "prewarp":
        assert res.estimate.parameters[1] < np.pi * 1000  # ω_hp kept below π/dt
    assert "note" not in res.flags[0] and res.flags[0] in res.notes()


def test_reference_without_the_resonance_is_flagged(tmp_path):
    # Set C at 10 kHz driven by a 0.5–2 Hz multisine: the 1.4 kHz resonance is not excited
    bench_fs = 10000.0
    ex = multisine(20000, 1 / bench_fs, 0.5, 2.0, amplitude=1e-3)
    est, _ = _loaded(_rig(params=SET_C, fs=bench_fs, snr_db=30.0, bits=16, excitation=ex),
                     tmp_path)
    with pytest.warns(ServoidWarning, match="do not determine the resonance"):
        res = fit_one_step(est, LOOP, discretization="auto")
    assert not res.is_resolved
    assert "excite up to the resonance" in res.flags[-1]


def test_start_leaves_too_few_samples(tmp_path):
    est, _ = _loaded(_rig(register=8), tmp_path)
    with pytest.raises(DataError, match="too few samples"):
        fit_one_step(est, LOOP, start=est.n_samples - 2)


def test_discretizations_listed():
    assert DISCRETIZATIONS == ("auto", "tustin", "prewarp", "zoh", "foh", "bandlimited")


# -- Set C end to end ------------------------------------------------------------------------------


def test_set_c_end_to_end_through_the_cli(tmp_path, capsys):
    folder = tmp_path / "c"
    assert main(["bench", "ehsa", "--set", "C", "--fs", "10000", "-n", "10", "--seed", "2",
                 "--out", str(folder)]) == 0
    capsys.readouterr()
    assert main(["identify", str(folder / "ehsa.toml"), "--out", str(tmp_path / "rep"),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    rows = {r["name"]: r for r in out["parameters"]}
    for name, row in rows.items():
        one = row["one-step"]
        # truth from the bench's truth.json; one-step within 4σ of its covariance
        assert abs(one["value"] - row["truth"]) < 4 * one["std"], name
    one_step = out["approaches"]["one-step"]
    assert one_step["intersample"] == "bandlimited" and one_step["flags"] == []
    results = json.loads((tmp_path / "rep" / "results.json").read_text())
    assert results["approaches"]["one-step"]["intersample_note"].startswith(
        "reference taken as band-limited")
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "intersample" in html and "robust" in html
