"""The virtual servopneumatic rig and ``servoid bench pneumatic``."""

from __future__ import annotations

import importlib
import inspect
import json
import math
import re

import numpy as np
import pytest

from servoid import DataError, ModelError, OptionError, OutputExistsError, ServoidWarning
from servoid.cli import main
from servoid.data import load_experiment_spec
from servoid.plants.pneumatic import (
    PNEUMATIC_CHANNELS,
    PNEUMATIC_NOMINAL,
    PNEUMATIC_TESTS,
    PneumaticBench,
    PneumaticTest,
    run_pneumatic,
    write_pneumatic_campaign,
)

TESTS = ("valve", "thermo", "flow", "friction", "validation")
BASE = ("u", "x_v", "p_I", "p_II", "T_I", "T_II", "mdot_I", "mdot_II", "x_k", "v_k", "a_k")
EXPECTED_CHANNELS = {
    "valve": BASE,
    "thermo": ("u", "x_ref", *BASE[1:], "f_ext"),
    "flow": ("u", "x_ref", *BASE[1:]),
    "friction": ("u", "x_ref", *BASE[1:]),
    "validation": ("u", "x_ref", *BASE[1:], "f_ext"),
}
SNR_CHANNELS = ("x_v", "p_I", "p_II", "mdot_I", "mdot_II", "x_k", "v_k", "a_k", "f_ext")
DURATION = 1.0  # [s] per test: 10 000 samples, enough statistics, fast
SEED = 3


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("campaign")
    files = write_pneumatic_campaign(folder, duration=DURATION, seed=SEED)
    return folder, files


def _run(name: str, duration: float = DURATION, **bench):
    # The campaign's stream for this test (write_pneumatic_campaign: [seed, index]).
    rng = np.random.default_rng([SEED, TESTS.index(name)])
    return run_pneumatic(PneumaticBench(**bench), PNEUMATIC_TESTS[name].with_duration(duration),
                         rng=rng)


def _si(rec, source: str):
    return {c: g * getattr(rec, source)[c] + o for c, (g, o) in rec.calibration().items()}


def test_campaign_lists_every_file(campaign):
    folder, files = campaign
    assert [f.name for f in files] == [
        *(f"{t}.{ext}" for t in TESTS for ext in ("tdms", "toml")), "pneumatic.toml",
        "truth.json"]
    assert all(f.parent == folder and f.is_file() for f in files)


@pytest.mark.parametrize("name", TESTS)
def test_each_toml_loads_si_with_servoid_names(campaign, name):
    folder, _ = campaign
    spec = load_experiment_spec(folder / f"{name}.toml")
    assert spec.preprocess.detrend == "none"  # absolute pressures stay absolute
    exp = spec.load()
    assert exp.names == EXPECTED_CHANNELS[name]
    assert exp.dt == pytest.approx(1e-4, rel=1e-12)  # 10 kHz, no decimation
    assert exp.n_samples == round(DURATION * 1e4)
    for ch in exp.channels:
        role, unit = PNEUMATIC_CHANNELS[ch.name]
        assert (ch.role, ch.unit) == (role, unit), ch.name
    p = PNEUMATIC_NOMINAL
    # Physical ranges in SI: absolute pressures between exhaust and a little above
    # supply (the piston compresses a closed chamber), T at T_S within its 0.05 K noise.
    for ch in ("p_I", "p_II"):
        assert 0.9 * p.p_R < exp[ch].min() and exp[ch].max() < 1.1 * p.p_S, ch
    for ch in ("T_I", "T_II"):
        assert np.all(np.abs(exp[ch] - p.T_S) < 0.5), ch
    assert np.all(np.abs(exp["x_k"]) <= p.stroke / 2 + 2e-3)  # stops ± noise
    # The files hold exactly what the rig recorded (float64 TDMS, exact calibration).
    rec = _run(name)
    for ch, values in _si(rec, "raw").items():
        np.testing.assert_allclose(exp[ch], values, rtol=1e-12, atol=1e-15, err_msg=ch)


@pytest.mark.parametrize("name", ["valve", "thermo", "friction"])
def test_calibrated_signals_match_clean_within_noise(name):
    rec = _run(name)
    raw, clean = _si(rec, "raw"), _si(rec, "clean")
    for ch, (gain, _) in rec.calibration().items():
        # 6σ: over 1e4 Gaussian samples the chance of one beyond is 2e-5;
        # the ADC adds at most half a step.
        bound = 6.0 * rec.noise_std[ch] + 0.5 * rec.bench.lsb * gain
        assert np.max(np.abs(raw[ch] - clean[ch])) <= bound, ch


def test_calibrated_signals_match_simulation_within_noise_and_lag():
    rec = _run("flow")
    raw, m, res = _si(rec, "raw"), rec.bench.oversample, rec.response
    den = rec.bench.anti_alias().den
    lag = den[-2] / den[-1]  # DC group delay of the anti-alias filter [s] (0.21 ms)
    for ch, true in (("x_k", res.x_k), ("p_I", res.p_I), ("p_II", res.p_II)):
        true = true[::m]
        rate = np.max(np.abs(np.gradient(true, rec.bench.dt)))
        gain = rec.calibration()[ch][0]
        # noise as above + the filter's lag times the fastest slope (+20 %
        # for the curvature the first-order delay model leaves out)
        bound = 6.0 * rec.noise_std[ch] + 0.5 * rec.bench.lsb * gain + 1.2 * lag * rate
        assert np.max(np.abs(raw[ch] - true)) <= bound, ch


def test_mass_flow_channels_clip_at_4_g_per_s(campaign):
    folder, _ = campaign
    exp = load_experiment_spec(folder / "valve.toml").load()
    for ch in ("mdot_I", "mdot_II"):
        # ±4 g/s is the ADC full scale: the top code is one step below +10 V.
        assert exp[ch].min() >= -4e-3 and exp[ch].max() <= 4e-3, ch
        assert np.mean(np.abs(exp[ch]) > 3.99e-3) > 0.5, ch  # ±5 V drives ≈ 18 g/s
    truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    assert truth["tests"]["valve"]["hot_wire_saturation"]["mdot_I"] > 0.5
    for name in ("thermo", "flow", "friction", "validation"):
        assert max(truth["tests"][name]["hot_wire_saturation"].values()) == 0.0, name


def test_hot_wire_lags_at_1_khz():
    rec = _run("flow", snr_db=None)
    m, clean = rec.bench.oversample, _si(rec, "clean")["mdot_I"]
    true = rec.response.m_dot_I[::m]
    tau = 1.0 / (2 * np.pi * 1000.0)  # first-order hot-wire
    den = rec.bench.anti_alias().den
    shift = (tau + den[-2] / den[-1]) / rec.bench.dt  # sensor + AA delay [samples]
    k = np.arange(2000, true.size)
    # delayed truth by linear interpolation: residual only from the delay model's
    # curvature term, < 1 % of the flow's range
    delayed = np.interp(k - shift, np.arange(true.size), true)
    assert np.max(np.abs(clean[k] - delayed)) < 0.01 * np.ptp(true)


@pytest.mark.parametrize("snr", [40.0, 25.0])
def test_realised_snr_within_1_db(snr):
    rec = _run("thermo", duration=2.0, snr_db=snr)
    raw, clean = _si(rec, "raw"), _si(rec, "clean")
    for ch in SNR_CHANNELS:
        realised = 20 * math.log10(rec.signal_rms[ch] / np.std(raw[ch] - clean[ch]))
        # 2e4 samples of noise coloured by the 2 kHz filter: the std is known to
        # ≈1 % (0.1 dB); 1 dB leaves room for the uniform-quantisation model.
        assert realised == pytest.approx(snr, abs=1.0), ch
        assert rec.snr_db(ch) == pytest.approx(snr, abs=1e-9)
    assert np.std(raw["T_I"] - clean["T_I"]) == pytest.approx(0.05, rel=0.05)  # 4σ of 2e4


def test_campaign_file_lists_tests_truth_and_known_constants(campaign):
    folder, _ = campaign
    spec = load_experiment_spec(folder / "pneumatic.toml")
    assert spec.file == "validation.tdms"
    ident = dict(spec.identify)
    assert ident["method"] == "pneumatic-multistep"
    assert {t: ident[t] for t in TESTS} == {t: f"{t}.toml" for t in TESTS}
    p = PNEUMATIC_NOMINAL
    known = dict(ident["known"])
    # the hot-wire's lag is a known sensor dynamic the flow steps filter their regressors by
    assert known.pop("mdot_sensor_bandwidth") == 1000.0
    assert known == {k: pytest.approx(getattr(p, k), rel=1e-15) for k in (
        "A_I", "A_II", "V_0I", "V_0II", "m_k", "p_S", "p_R", "p_amb", "T_S", "g")}
    # the rig senses ẋ_k, ẍ_k, and its u passes the anti-alias filter (no staircase)
    assert ident["derivatives"] == "measured" and ident["valve_u_hold"] == "cubic"
    assert dict(spec.report) == {"truth": "truth.json"}
    # the validation record's loop (softer than the other tests': no stick–slip hunting)
    assert dict(spec.loop) == {"K_p": 100.0, "K_d": 5.0, "u_max": 10.0}
    assert spec.load().names == EXPECTED_CHANNELS["validation"]
    for t in TESTS:  # every named TOML exists beside it and loads
        load_experiment_spec(folder / ident[t])
    truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    for k in ("k_v", "xi_v", "omega_v", "ad_1", "ad_2", "ad_3", "ad_4", "R", "kappa",
              "F_haft", "v_krit", "c_k", "d_k", "p_krit", *known):
        expected = getattr(p, k)
        assert truth[k] == pytest.approx(expected, rel=1e-15), k
        assert k in truth["units"]
    assert truth["seed"] == SEED and truth["snr_db"] == 40.0
    assert truth["rig"]["f_acq"] == 1e4 and truth["rig"]["bits"] == 16
    assert set(truth["tests"]) == set(TESTS)
    assert truth["tests"]["thermo"]["controller"] == {"K_p": 300.0, "K_d": 5.0}


def test_seed_reproduces_identical_files(tmp_path):
    kw = {"tests": ["valve", "friction"], "duration": 0.2}
    a = write_pneumatic_campaign(tmp_path / "a", seed=11, **kw)
    b = write_pneumatic_campaign(tmp_path / "b", seed=11, **kw)
    for fa, fb in zip(a, b, strict=True):
        assert fa.read_bytes() == fb.read_bytes(), fa.name
    c = write_pneumatic_campaign(tmp_path / "c", seed=12, **kw)
    assert c[0].read_bytes() != a[0].read_bytes()
    # a test's record does not depend on which other tests run
    d = write_pneumatic_campaign(tmp_path / "d", seed=11, tests=["friction"], duration=0.2)
    assert d[0].read_bytes() == a[2].read_bytes()


def test_csv_format_and_subset(tmp_path):
    files = write_pneumatic_campaign(tmp_path, tests=["flow"], duration=0.2, format="csv")
    assert [f.name for f in files] == ["flow.csv", "flow.toml", "pneumatic.toml", "truth.json"]
    spec = load_experiment_spec(tmp_path / "pneumatic.toml")
    assert spec.file == "flow.csv"  # no validation record: the last test's
    assert "validation" not in spec.identify and spec.identify["flow"] == "flow.toml"
    exp = load_experiment_spec(tmp_path / "flow.toml").load()
    assert exp.names == EXPECTED_CHANNELS["flow"] and exp.n_samples == 2000


def test_overwrite_refused_before_anything_is_written(tmp_path):
    write_pneumatic_campaign(tmp_path, tests=["valve"], duration=0.1)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    with pytest.raises(OutputExistsError, match="overwrite"):
        write_pneumatic_campaign(tmp_path, tests=["valve"], duration=0.1, seed=5)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    write_pneumatic_campaign(tmp_path, tests=["valve"], duration=0.1, seed=5, overwrite=True)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"tests": ["valves"]}, OptionError, "'valve', 'thermo', 'flow', 'friction'"),
        ({"tests": ["flow", "flow"]}, DataError, "listed twice"),
        ({"tests": []}, DataError, "at least one"),
        ({"tests": "flow"}, TypeError, "sequence"),
        ({"snr_db": math.nan}, DataError, "finite"),
        ({"snr_db": math.inf}, DataError, "finite"),
        ({"seed": -1}, DataError, "seed"),
        ({"format": "mat"}, OptionError, "'tdms', 'csv'"),
        ({"params": PNEUMATIC_NOMINAL.with_(p_amb=0.0)}, DataError, "absolute pressure"),
        ({"params": PNEUMATIC_NOMINAL.with_(p_S=12e5)}, DataError, "pressure_range"),
        ({"duration": -1.0}, DataError, "duration"),
    ],
)
def test_bad_input(tmp_path, kwargs, error, match):
    with pytest.raises(error, match=match):
        write_pneumatic_campaign(tmp_path, **{"duration": 0.1, **kwargs})
    assert not list(tmp_path.iterdir())  # nothing written


def test_negative_absolute_pressure_is_an_error():
    with pytest.raises(ModelError, match="p_R must be > 0"):
        PNEUMATIC_NOMINAL.with_(p_R=-1e5)
    with pytest.raises(ModelError, match="p_amb must be >= 0"):
        PNEUMATIC_NOMINAL.with_(p_amb=-1e5)


def test_warnings(tmp_path):
    with pytest.warns(ServoidWarning, match="below 10 kHz.*20·f_v = 3183 Hz") as rec:
        write_pneumatic_campaign(tmp_path, tests=["valve", "flow"], duration=0.1, f_acq=5000.0)
    assert sum("below 10 kHz" in str(w.message) for w in rec) == 1  # once per campaign
    truth = json.loads((tmp_path / "truth.json").read_text(encoding="utf-8"))
    assert any("below 10 kHz" in w for w in truth["warnings"])
    hot = PneumaticTest("thermo", 2.0, PNEUMATIC_TESTS["thermo"].controller, r_amplitude=0.02,
                        r_frequency=1.0, force_amplitude=100.0, force_frequency=0.5)
    with pytest.warns(ServoidWarning, match="'mdot_.*' saturates at ±4 g/s"):
        run_pneumatic(PneumaticBench(), hot, rng=0)
    with pytest.warns(ServoidWarning, match="quantisation alone"):
        run_pneumatic(PneumaticBench(bits=8, snr_db=60.0),
                      PNEUMATIC_TESTS["flow"].with_duration(0.1), rng=0)


def test_test_and_bench_validation():
    with pytest.raises(OptionError, match="'valve', 'thermo'"):
        PneumaticTest("step", 1.0, u_amplitude=1.0, u_frequency=1.0)
    with pytest.raises(DataError, match="needs a controller"):
        PneumaticTest("flow", 1.0, u_amplitude=1.0, u_frequency=1.0, r_amplitude=0.01)
    with pytest.raises(DataError, match="u_amplitude"):
        PneumaticTest("valve", 1.0)
    with pytest.raises(DataError, match="finite"):
        PneumaticBench(snr_db=math.nan)
    with pytest.raises(OptionError, match="noise_std channel"):
        PneumaticBench(noise_std={"u": 0.1})
    with pytest.raises(DataError, match="half stroke"):
        PneumaticBench(position_range=0.05)
    rec = run_pneumatic(PneumaticBench(noise_std={"x_k": 1e-4}),
                        PNEUMATIC_TESTS["flow"].with_duration(0.2), rng=0)
    assert rec.noise_std["x_k"] == 1e-4


def test_cli_in_process(tmp_path, capsys):
    out = tmp_path / "rig"
    argv = ["bench", "pneumatic", "--out", str(out), "--tests", "valve", "flow",
            "--duration", "0.2", "--seed", "4", "--json"]
    assert main(argv) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["ok"] is True
    assert [p.rsplit("/", 1)[-1] for p in payload["files"]] == [
        "valve.tdms", "valve.toml", "flow.tdms", "flow.toml", "pneumatic.toml", "truth.json"]
    assert payload["tests"]["flow"]["n_samples"] == 2000
    assert payload["truth"]["omega_v"] == 1000.0 and payload["known"]["m_k"] == 3.0
    assert payload["seed"] == 4 and payload["snr_db"] == 40.0
    assert main(argv) == 1  # refuses to overwrite
    assert "--overwrite" in capsys.readouterr().err
    assert main([*argv[:-1], "--overwrite", "--format", "csv"]) == 0
    text = capsys.readouterr().out
    for word in ("pneumatic campaign at 10000 Hz", "valve ", "truth: k_v = 0.0001", "written:"):
        assert word in text
    assert main(["bench", "pneumatic", "--out", str(out), "--tests", "sine"]) == 1
    assert "'valve', 'thermo', 'flow', 'friction', 'validation'" in capsys.readouterr().err
    assert main(["bench", "pneumatic", "--out", str(out), "--snr", "nan"]) == 1
    assert "--snr must be a finite" in capsys.readouterr().err


def test_exports_pinned():
    from servoid import bench

    for name in bench.__all__:
        obj = getattr(bench, name)
        if inspect.isclass(obj) or inspect.isfunction(obj):
            summary = inspect.getdoc(obj).splitlines()[0]
            assert len(summary) < 64 and summary.endswith("."), name


PUBLIC = [PneumaticBench, PneumaticTest, run_pneumatic, write_pneumatic_campaign,
          PneumaticTest.with_duration, PneumaticTest.signals, PneumaticBench.calibration]


@pytest.mark.parametrize("obj", PUBLIC, ids=lambda o: o.__qualname__)
def test_docstrings_list_every_parameter(obj):
    doc = inspect.getdoc(obj)
    summary = doc.splitlines()[0]
    assert len(summary) < 64 and summary.endswith("."), summary
    params = [p for p in inspect.signature(obj).parameters if p != "self"]
    if not params:
        return
    section = doc.split("Parameters\n----------", 1)[1]
    section = re.split(r"\n(Returns|Raises|Warns|Examples|Notes)\n-+", section)[0]
    listed = {n for line in section.splitlines()
              if (match := re.match(r"^(\w+(?:, \w+)*) :", line))
              for n in match.group(1).split(", ")}
    assert not [p for p in params if p not in listed], obj.__qualname__


@pytest.mark.parametrize("module", ["servoid.plants.pneumatic._bench", "servoid.plants.pneumatic._bench_files"])
def test_modules_stay_small(module):
    assert inspect.getsource(importlib.import_module(module)).count("\n") < 800
