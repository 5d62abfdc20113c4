"""The bench declares its rig: logged command or read-back, and rates that resolve it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from servoid import OptionError, ServoidWarning
from servoid.cli import main
from servoid.data import RigSpec, detect_intersample, load_experiment_spec
from servoid.plants.ehsa import REFERENCES, SET_B, SET_C, EhsaBench, run, write_bench_files
from servoid.signals import prbs


def test_command_reference_is_the_dac_staircase(tmp_path):
    bench = EhsaBench(reference="command")
    rec = run(bench, prbs(7, clock=10, amplitude=1e-3, dt=bench.dt), rng=1)
    # the codes written to the DAC: no filter, no noise, held over each 1 ms period
    np.testing.assert_array_equal(rec.raw["yr_cmd"], rec.clean["yr_cmd"])
    np.testing.assert_allclose(rec.raw["yr_cmd"] / bench.command_sensitivity, rec.command,
                               rtol=1e-12)
    files = write_bench_files(rec, tmp_path)
    spec = load_experiment_spec(files[1])
    assert spec.rig == RigSpec(4, 1000.0, "command")
    assert dict(spec.identify)["discretization"] == "auto"
    r = spec.load().signal("r")[:, 0]
    assert detect_intersample(r).kind == "zoh"  # subsampled, still a staircase
    np.testing.assert_allclose(r + rec.command[::5].mean(), rec.command[::5], atol=1e-12)


def test_reference_option_is_checked():
    assert REFERENCES == ("readback", "command")
    with pytest.raises(OptionError, match="reference must be one of 'readback', 'command'"):
        EhsaBench(reference="dac")


@pytest.mark.parametrize(
    ("params", "fs", "resolved"),
    [(SET_B, 1000.0, True), (SET_C, 1000.0, False), (SET_C, 5000.0, False),
     (SET_C, 6000.0, True), (SET_C, 10000.0, True)],
)
def test_resolution_rule(params, fs, resolved):
    # resolved when the Nyquist frequency π·f_s is at least 2·ω_hp: f_s >= 4·f_hp = 5695 Hz
    note = EhsaBench(params=params, f_s=fs, f_acq=5 * fs).resolution_note()
    assert (note == "") == resolved
    if not resolved:
        assert "use f_s >= 5700 Hz" in note and "--fs 5700 --facq 28500" in note


def test_run_warns_before_simulating_an_unresolvable_rig():
    bench = EhsaBench(params=SET_C)
    with pytest.warns(ServoidWarning, match="cannot resolve this actuator"):
        rec = run(bench, prbs(6, clock=10, amplitude=1e-3, dt=bench.dt), rng=0)
    assert rec.warnings[0].startswith("f_s = 1000 Hz cannot resolve")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)  # at 10 kHz nothing to say
        fast = EhsaBench(params=SET_C, f_s=10000.0, f_acq=50000.0)
        run(fast, prbs(6, clock=10, amplitude=0.4e-3, dt=fast.dt), rng=0)  # within its limits


def test_cli_warns_first_and_takes_the_reference(tmp_path, capsys):
    code = main(["bench", "ehsa", "--set", "C", "-n", "6", "--reference", "command",
                 "--out", str(tmp_path / "slow")])
    out, err = capsys.readouterr()
    assert code == 0
    assert err.startswith("servoid: warning: f_s = 1000 Hz cannot resolve")
    assert "warning: f_s = 1000 Hz cannot resolve" in out  # and in the run's summary
    assert load_experiment_spec(tmp_path / "slow" / "ehsa.toml").rig.reference == "command"
    # --facq defaults to 5·fs, so a rate that resolves set C needs one flag
    assert main(["bench", "ehsa", "--set", "C", "-n", "6", "--fs", "10000", "--json",
                 "--out", str(tmp_path / "fast")]) == 0
    out, err = capsys.readouterr()
    assert err == "" and '"f_acq": 50000.0' in out and '"reference": "readback"' in out
