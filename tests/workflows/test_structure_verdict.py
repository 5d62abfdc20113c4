"""Verdicts on the returned structure: unstable models, poles beyond Nyquist, n4sid's order."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import OptionError
from servoid.bench import simulate_lti
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.estimate import fit_n4sid
from servoid.models import PolynomialModel, TransferFunction
from servoid.workflows import identify
from servoid.workflows._structure import structure_checks, structure_notes

DT = 0.01


def _outcomes(model, dt=DT):
    return {c.name: c.outcome for c in structure_checks(model, dt)}


def test_an_unstable_discrete_model_fails():
    unstable = PolynomialModel([1.0], (np.array([0.1]),), (1,), DT, f=((1.0, -1.05),))
    assert _outcomes(unstable) == {"stability": "fail"}
    assert "unstable" in structure_notes(unstable, DT)[0]


def test_an_integrator_and_a_stable_model_pass():
    integrator = TransferFunction([0.1], [1.0, -1.0], dt=DT)
    stable = TransferFunction([0.1], [1.0, -0.9], dt=DT)
    assert _outcomes(integrator) == {} and _outcomes(stable) == {}


def test_a_negative_real_pole_is_flagged():
    model = TransferFunction([0.1, 0.05], [1.0, -0.4, -0.45], dt=DT)  # poles 0.9 and -0.5
    checks = structure_checks(model, DT)
    assert [c.outcome for c in checks] == ["caution"]
    assert "negative real" in checks[0].meaning


def test_a_continuous_pole_beyond_nyquist_is_flagged():
    fast = TransferFunction([1e6], [1.0, 1000.0])  # pole at -1000 rad/s, Nyquist π/0.01 = 314
    slow = TransferFunction([10.0], [1.0, 10.0])
    assert _outcomes(fast) == {"poles beyond Nyquist": "caution"}
    assert _outcomes(slow) == {}
    assert _outcomes(TransferFunction([1.0], [1.0, -2.0])) == {"stability": "fail"}


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """A second-order plant at 100 Hz, its fast first-order actuator (2 kHz) beyond Nyquist."""
    folder = tmp_path_factory.mktemp("structure")
    wn, zeta = 2 * np.pi * 3.0, 0.4
    plant = TransferFunction([wn**2 * 1.2e4], np.polymul([1.0, 2 * zeta * wn, wn**2],
                                                          [1.0, 1.2e4]))
    for k, seed in enumerate((11, 12)):
        u = np.random.default_rng(seed).standard_normal(3000)
        exp = simulate_lti(plant, u, DT, noise_std=0.05, rng=seed)
        write_csv(exp, folder / f"run{k}.csv")
    return folder


def _toml(folder, name, identify_table):
    table = {"data": {"file": "run0.csv"},
             "channels": {"u": {"source": "u", "role": "u"}, "y": {"source": "y", "role": "y"}},
             "validation": {"file": "run1.csv"}, "identify": identify_table}
    path = folder / f"{name}.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_an_unstable_arx_is_a_verdict_in_the_console_json_and_report(rig, tmp_path):
    # ARX(3, 3) on a plant whose third pole (1.2e4 rad/s) lies far beyond Nyquist: the spare
    # pole nearly cancels a zero and lands far outside the unit circle on the negative axis
    with pytest.warns(Warning):
        result = identify(_toml(rig, "arx", {"method": "arx", "na": 3, "nb": 3, "nk": 1}),
                          tmp_path / "out")
    poles = result.estimate.model.transfer_function(0).poles()
    assert np.max(np.abs(poles)) > 2  # the premise of the test
    checks = {c.name: c.outcome for c in result.verdict().checks}
    assert checks["stability"] == "fail" and result.verdict().decision == "reject"
    assert checks["poles beyond Nyquist"] == "caution"
    assert "unstable" in str(result)
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert any(c["name"] == "stability" and c["outcome"] == "fail"
               for c in data["verdict"]["checks"])
    assert any("unstable" in n for n in data["notes"])
    assert "returned model is unstable" in (tmp_path / "out" / "report.html").read_text()


def test_arx_flags_a_negative_real_pole(tmp_path):
    # a discrete generator (not ARX's own): y = G(q)u + coloured noise with poles 0.9 and -0.6
    from scipy.signal import lfilter

    rng = np.random.default_rng(3)
    for k in range(2):
        u = rng.standard_normal(4000)
        y = lfilter([0.0, 1.0, 0.5], np.poly([0.9, -0.6]), u)
        y += lfilter([1.0], [1.0, -0.7], 0.05 * rng.standard_normal(4000))
        write_csv(Experiment.from_arrays(DT, u=u, y=y), tmp_path / f"run{k}.csv")
    with pytest.warns(Warning):
        result = identify(_toml(tmp_path, "neg", {"method": "oe", "nb": 2, "nf": 2, "nk": 1}),
                          write=False)
    checks = {c.name: c for c in result.verdict().checks}
    assert checks["poles beyond Nyquist"].outcome == "caution"
    assert "negative real" in checks["poles beyond Nyquist"].meaning
    assert "stability" not in checks


def test_n4sid_takes_a_stable_order_when_the_gap_rule_gives_an_unstable_one():
    # a stable second-order plant (poles 0.8 ± 0.3j) under a random-walk drift: the gap rule
    # takes order 3 with the drift as a pole just outside the unit circle; order 2 is stable
    from scipy.signal import lfilter

    rng = np.random.default_rng(0)
    u = rng.standard_normal(3000)
    y = lfilter([0, 0.2, 0.1], np.poly([0.8 + 0.3j, 0.8 - 0.3j]).real, u)
    y += np.cumsum(0.01 * rng.standard_normal(3000))
    with pytest.warns(Warning, match="rule chose order 3, whose model is unstable; order 2"):
        est = fit_n4sid(Experiment.from_arrays(DT, u=u, y=y), max_order=6)
    assert est.options["order"] == 2
    assert np.max(np.abs(est.model.poles())) < 1.0
    assert "stable model" in est.options["order_rule"]


def test_n4sid_refine_accepts_the_keys_the_advice_names(rig):
    result = identify(_toml(rig, "n4r", {"method": "n4sid", "order": 2, "refine": True,
                                         "multistart": 1, "initial": "estimate"}),
                      write=False)
    assert result.title.startswith("OE refined")
    assert result.estimate.options.get("multistart")  # the random start ran


def test_n4sid_refuses_refinement_keys_without_refine(rig):
    with pytest.raises(OptionError, match="refine = true"):
        identify(_toml(rig, "n4x", {"method": "n4sid", "multistart": 2}), write=False)


def test_the_stall_advice_drops_what_is_in_use():
    from servoid.estimate._pem import _advice

    assert _advice(0, "auto") == "multistart=5, initial='estimate', lower orders or detrended data"
    assert _advice(5, "estimate") == "lower orders or detrended data"
    assert "initial" not in _advice(0, "estimate") and "multistart" not in _advice(3, "zero")


def _first_order(f1, sigma):
    from servoid.estimate import Estimate

    def model(theta):
        return TransferFunction([0.1], [1.0, float(theta[0])], dt=DT)

    return Estimate(model=model([f1]), parameters=np.array([f1]), names=("f1",),
                    covariance=np.array([[sigma**2]]), noise_variance=1.0, n_samples=1000,
                    method="oe", model_function=model)


def test_a_pole_just_past_one_within_its_interval_is_an_integrator_not_a_failure():
    # pole at z = 1.0004 with σ(f1) = 0.001: z = 1 lies inside its 2σ region
    est = _first_order(-1.0004, 1e-3)
    checks = structure_checks(est.model, DT, est)
    assert [(c.name, c.outcome) for c in checks] == [("stability", "caution")]
    assert "integrator" in checks[0].value
    # the same pole known to 1e-5 is unstable: its region excludes z = 1
    tight = _first_order(-1.0004, 1e-5)
    assert [c.outcome for c in structure_checks(tight.model, DT, tight)] == ["fail"]


def test_the_floor_advice_never_names_the_covariance_in_use():
    from servoid.estimate._diagnostics import _floor_advice

    assert _floor_advice("white") == "use covariance='robust' or 'bootstrap'"
    assert _floor_advice("robust") == "use covariance='bootstrap'"
    assert "covariance=" not in _floor_advice("bootstrap")
