"""The EMA's virtual rig: what it logs, its files, its fleet and its commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import DataError, OptionTypeError, OutputExistsError
from servoid.data import load_experiment_spec
from servoid.plants.ema import (
    TVC_EMA,
    EmaBench,
    bench_reference,
    run_bench,
    truth_parameters,
    write_bench,
    write_fleet,
)
from servoid.plants.ema._filters import anti_alias_replica


def test_the_replica_filter_is_exact_for_its_hold():
    from scipy import signal as sps

    dt = 1e-4
    t = dt * np.arange(20000)
    z, p, k = sps.butter(4, 2 * np.pi * 2000.0, analog=True, output="zpk")
    h = sps.freqs_zpk(z, p, k, [2 * np.pi * 50.0])[1][0]
    y = anti_alias_replica(np.sin(2 * np.pi * 50 * t), dt, 4, 2000.0, "cubic")
    exact = abs(h) * np.sin(2 * np.pi * 50 * t + np.angle(h))
    # cubic hold: O((ωT)⁴) with ωT = 0.03, after the start (the steady state of x[0] is not
    # that of the sine)
    assert np.max(np.abs(y - exact)[2000:]) < 1e-7
    # a staircase through the zero-order-hold replica against a fine simulation
    u = np.sign(np.sin(2 * np.pi * 7 * t[:5000]))
    y = anti_alias_replica(u, dt, 4, 2000.0, "zoh")
    a, b, c, d = sps.zpk2ss(z, p, k)
    m = 50
    ad, bd, cd, dd, _ = sps.cont2discrete((a, b, c, d), dt / m, method="zoh")
    x0 = np.linalg.solve(-a, b).ravel() * u[0]
    fine = sps.dlsim((ad, bd, cd, dd, dt / m), np.repeat(u, m), x0=x0)[1].ravel()[::m]
    assert np.max(np.abs(y - fine)) < 1e-10  # both exact for a staircase


def test_the_logged_record_calibrates_to_the_simulated_signals():
    bench = EmaBench()
    run = run_bench(bench, bench_reference(bench, duration=1.0), rng=4)
    cal = bench.calibration()
    raw = run.raw
    assert raw.names == ("x_ref", "u_cmd", "i_motor", "theta_m", "x_load")
    out = run.response
    # digital channels: whole counts, exactly what the drive used
    for name in ("x_ref", "u_cmd", "theta_m"):
        assert np.all(raw[name] == np.round(raw[name]))
    assert np.array_equal(raw["x_ref"] * cal["x_ref"], run.reference)
    assert np.max(np.abs(raw["u_cmd"] * cal["u_cmd"] - out.voltage)) <= cal["u_cmd"] / 2
    assert np.allclose(raw["theta_m"] * cal["theta_m"], out.measured_angle, rtol=0, atol=1e-12)
    # analog channels: the signal through the logger's filter, within the filtered noise (the
    # sensors' 4 µm and 0.1 A at 100 kHz leave about a quarter of that through 2 kHz)
    for name, sim, noise in (("x_load", out.position, 4e-6), ("i_motor", out.current, 0.1)):
        filtered = anti_alias_replica(np.asarray(sim), bench.dt, 4, 2000.0, "cubic")
        assert np.std(raw[name] * cal[name] - filtered) < 0.5 * noise


def test_bench_files_and_experiment_file(bench_folder):
    spec = load_experiment_spec(bench_folder / "ema.toml")
    assert spec.identify["method"] == "ema"
    assert spec.rig.anti_alias_order == 4 and spec.rig.anti_alias_cutoff == 2000.0
    assert spec.loop["kp_x"] == 1.42e5
    truth = json.loads((bench_folder / "truth.json").read_text(encoding="utf-8"))
    assert truth["parameters"] == pytest.approx(truth_parameters(TVC_EMA))
    assert truth["derived"]["resonance_hz"] == pytest.approx(TVC_EMA.resonance_hz)
    exp = spec.load(detrend=False)
    assert exp.channel("x_load").unit == "m" and exp.n_samples == 80000
    assert abs(float(np.max(np.abs(exp["x_load"]))) - 0.022) < 2e-3  # the sweep and multisine


def test_same_seed_same_bytes(tmp_path):
    a = write_bench(tmp_path / "a", duration=0.5, format="csv", seed=3)
    b = write_bench(tmp_path / "b", duration=0.5, format="csv", seed=3)
    assert a[0].read_bytes() == b[0].read_bytes()
    c = write_bench(tmp_path / "c", duration=0.5, format="csv", seed=4)
    assert a[0].read_bytes() != c[0].read_bytes()


def test_files_are_not_overwritten_unless_asked(tmp_path):
    write_bench(tmp_path, duration=0.5)
    with pytest.raises(OutputExistsError):
        write_bench(tmp_path, duration=0.5)
    write_bench(tmp_path, duration=0.5, overwrite=True)


@pytest.mark.parametrize(("call", "error", "match"), [
    (lambda: run_bench(EmaBench(), np.full(100, 0.05), rng=0), DataError, "beyond the stroke"),
    (lambda: run_bench(EmaBench(), np.zeros(100), rng=-1), DataError, "seed must be >= 0"),
    (lambda: run_bench(EmaBench(), np.zeros(100), rng="x"), OptionTypeError, "rng="),
    (lambda: run_bench("bench", np.zeros(100), rng=0), OptionTypeError, "EmaBench"),
    (lambda: EmaBench(aa_cutoff=6000.0), DataError, "Nyquist"),
    (lambda: EmaBench(bits=4), DataError, "bits must lie in 8..24"),
    (lambda: bench_reference(EmaBench(), f_max=5000.0), DataError, "f_ctrl/4"),
    (lambda: bench_reference(EmaBench(), duration=1e4), DataError, "budget"),
])
def test_bad_bench_inputs_are_refused(call, error, match):
    with pytest.raises(error, match=match):
        call()


def test_a_fleet_has_its_bad_units_and_a_fleet_file(tmp_path):
    fleet = write_fleet(tmp_path, units=4, bad_every=2, corrupt=1, duration=1.0)
    assert fleet.bad == ("EMA-0002", "EMA-0004") and fleet.corrupt == ("EMA-0005",)
    rows = fleet.truth_file.read_text(encoding="utf-8").splitlines()
    assert len(rows) == 6 and "worn screw" in rows[2] and "tight gear" in rows[4]
    text = fleet.fleet_file.read_text(encoding="utf-8")
    assert "[limits.k_s]" in text and 'manifest = "units.csv"' in text


def test_bench_commands_write_and_report(tmp_path, capsys):
    from servoid.cli import main

    assert main(["bench", "ema", "--out", str(tmp_path / "one"), "--duration", "1",
                 "--format", "csv", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["n_samples"] == 10000 and doc["truth"]["k_s"] == TVC_EMA.k_s
    assert main(["bench", "ema", "--out", str(tmp_path / "one"), "--duration", "-1"]) != 0
    assert "--duration must be a finite number > 0" in capsys.readouterr().err
    assert main(["bench", "ema-fleet", "--out", str(tmp_path / "fleet"), "--units", "3",
                 "--duration", "1"]) == 0
    assert "next: servoid fleet" in capsys.readouterr().out
