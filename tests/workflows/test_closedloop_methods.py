"""two-stage, cliv, indirect and the feedback note from the experiment file, and method = frf."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import DataError, OptionError
from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.data import write_csv, write_experiment_spec
from servoid.models import TransferFunction, c2d
from servoid.signals import prbs
from servoid.workflows import identify

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.4
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
PI = TransferFunction([0.5 + 3.0 * DT, -0.5], [1.0, -1.0], DT)
TRUE = c2d(PLANT, DT, "zoh").to_polynomial("oe")
THETA_OE = np.concatenate([TRUE.b[0], TRUE.f[0][1:]])


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    folder = tmp_path_factory.mktemp("loop")
    for k, seed in enumerate((11, 12)):
        g = np.random.default_rng(seed)
        r = np.repeat(np.sign(g.standard_normal(2000)), 2)
        exp = simulate_lti_loop(PLANT, PI, r, DT, noise_std=0.1,
                                noise_model=([1.0, 0.3], [1.0, -0.9]), rng=seed)
        write_csv(exp, folder / f"loop{k}.csv")
    return folder


def _toml(folder, name, identify_table, loop=None):
    table = {"data": {"file": "loop0.csv"},
             "channels": {"r": {"role": "r", "unit": "V"}, "u": {"role": "u", "unit": "V"},
                          "y": {"role": "y", "unit": "mm"}},
             "validation": {"file": "loop1.csv"}, "identify": identify_table}
    if loop:
        table["loop"] = loop
    path = folder / f"{name}.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


@pytest.mark.parametrize(
    ("method", "extra", "loop_table"),
    [("two-stage", {"nb": 2, "nf": 2}, None),
     ("indirect", {"nb": 2, "nf": 2}, {"controller": {"num": [0.56, -0.5], "den": [1.0, -1.0]}}),
     ("bj", {"nb": 2, "nc": 1, "nd": 1, "nf": 2}, None)],
)
def test_closed_loop_methods_recover_the_plant(loop, method, extra, loop_table):
    result = identify(_toml(loop, method, {"method": method, **extra}, loop_table), write=False)
    est = result.estimate
    # consistent under feedback: the true c2d(zoh) plant within 4σ of the reported covariance
    assert np.all(np.abs(est.parameters[:4] - THETA_OE) < 4 * est.std[:4])
    assert result.validation.residuals.causal  # closed loop: only past inputs are tested
    # the in-loop noise (AR 0.9) is a large share of y: the true plant itself simulates to ~37 %
    assert result.validation.fit_percent > 30


def test_open_loop_oe_on_closed_loop_data_is_told(loop):
    with pytest.warns(UserWarning, match="looks closed loop"):
        result = identify(_toml(loop, "oe", {"method": "oe", "nb": 2, "nf": 2}), write=False)
    assert result.feedback is not None and result.feedback.has_feedback
    assert "two-stage" in " ".join(result.notes)


def test_cliv_runs_from_the_file(loop, tmp_path):
    result = identify(_toml(loop, "cliv", {"method": "cliv", "na": 2, "nb": 2}), tmp_path / "o")
    data = json.loads((tmp_path / "o" / "results.json").read_text())
    assert data["method"] == "cliv" and result.estimate.method == "cliv"


def test_indirect_needs_the_controller(loop):
    with pytest.raises(DataError, match=r"needs the controller: add \[loop\] controller"):
        identify(_toml(loop, "ind", {"method": "indirect"}, {"feedback": 1.0}), write=False)
    with pytest.raises(OptionError, match=r"unknown key\(s\) in \[loop\]: gain"):
        identify(_toml(loop, "ind2", {"method": "indirect"}, {"controller": 1.0, "gain": 2}),
                 write=False)


@pytest.fixture(scope="module")
def periodic(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frf")
    ex = prbs(9, clock=1, periods=8, amplitude=1.0, dt=DT)
    band_limited = TransferFunction([1.0], [1 / (2 * np.pi * 8.0), 1.0])  # the plant with a lag
    exp = simulate_lti(PLANT * band_limited, ex.values, DT, noise_std=0.01, rng=5)
    write_csv(exp, folder / "per.csv")
    table = {"data": {"file": "per.csv"},
             "channels": {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "mm"}},
             "split": {"period": 511, "fraction": 0.75},
             "identify": {"method": "frf", "estimator": "periodic", "period": 511,
                          "phase_frequency": 1.0}}
    path = folder / "frf.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_frf_method_gives_the_spec_numbers(periodic, tmp_path):
    result = identify(periodic, tmp_path / "o")
    numbers = result.numbers
    # the peak of a 2nd-order servo sits at f_n·√(1 − 2ζ²) = 1.65 Hz; lines are 0.098 Hz apart
    # and the 8 Hz lag pulls the peak a little lower: two lines of tolerance
    assert abs(numbers["resonance frequency [Hz]"] - 2.0 * np.sqrt(1 - 2 * ZETA**2)) < 0.2
    assert numbers["bandwidth (-3 dB) [Hz]"] > 2.0
    data = json.loads((tmp_path / "o" / "results.json").read_text())
    assert data["measured_frf"]["method"] == "periodic"
    assert "frf.png" in {p.name for p in result.files}


def test_frf_fit_recovers_a_servo_from_a_staircase_record(tmp_path):
    ex = prbs(10, clock=1, periods=6, amplitude=1.0, dt=0.01)
    wn, zeta = 2 * np.pi * 3.0, 0.15
    plant = TransferFunction([wn**2], [1.0, 2 * zeta * wn, wn**2])
    write_csv(simulate_lti(plant, ex.values, 0.01, noise_std=0.02, rng=1), tmp_path / "p.csv")
    table = {"data": {"file": "p.csv"},
             "channels": {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "mm"}},
             "split": {"period": 1023, "fraction": 0.67},
             "identify": {"method": "frf", "estimator": "periodic", "period": 1023,
                          "n_poles": 2, "n_zeros": 0}}
    path = tmp_path / "p.toml"
    write_experiment_spec(table, path)
    result = identify(path, write=False)
    rows = {r.name: r for r in result.characteristics}
    # the hold divided out of the staircase record's FRF: ω_n and ζ of the analog plant, 4σ
    assert abs(rows["wn1"].value - wn) < 4 * rows["wn1"].std
    assert abs(rows["zeta1"].value - zeta) < 4 * rows["zeta1"].std
    assert result.validation.residuals.is_independent


def test_frf_spec_numbers_sit_in_the_verdict_not_in_a_note(periodic, tmp_path):
    result = identify(periodic, tmp_path / "o")
    table = result.verdict().tables[0]
    assert table.caption == "Spec numbers"
    bandwidth = result.numbers["bandwidth (-3 dB) [Hz]"]
    assert dict(table.rows)["bandwidth (-3 dB) [Hz]"] == f"{bandwidth:.5g}"
    html = (tmp_path / "o" / "report.html").read_text(encoding="utf-8")
    box = html[html.index('<div class="box'):html.index("<h2>Measured frequency response")]
    assert '<div class="caption">Spec numbers</div>' in box and "phase lag at 1 Hz [deg]" in box
    # with a fitted model: measured and fitted side by side, and no note repeats them
    text = periodic.read_text(encoding="utf-8").replace('phase_frequency = 1.0',
                                                        'phase_frequency = 1.0\nn_poles = 3')
    fitted_toml = periodic.parent / "frf_fit.toml"
    fitted_toml.write_text(text, encoding="utf-8")
    fit = identify(fitted_toml, write=False)
    rows = {r[0]: r for r in fit.verdict().tables[0].rows}
    measured, model = fit.spec_numbers["bandwidth (-3 dB) [Hz]"]
    assert rows["bandwidth (-3 dB) [Hz]"][1:] == (f"{measured:.5g}", f"{model:.5g}")
    assert measured == result.numbers["bandwidth (-3 dB) [Hz]"]  # the same measured FRF
    assert not any(n.startswith(("measured: ", "fitted model: ")) for n in fit.notes)
    assert fit.to_dict()["spec_numbers"]["bandwidth (-3 dB) [Hz]"]["fitted"] == model
