"""IDIM-LS and closed-loop OE: simulated axes and the EMPS reference."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import ChannelError, DataError, IdentifiabilityError, OptionError
from servoid.data import Experiment
from servoid.datasets import load_emps
from servoid.plants.rigid import (
    CascadeController,
    RigidAxis,
    fit_closed_loop_oe,
    fit_inverse_dynamics,
    inverse_dynamics_regression,
    simulate_rigid_loop,
)

DT = 1e-3
CTRL = CascadeController(kp=160.18, kv=243.45, gtau=35.15)
SYMMETRIC = RigidAxis(95.0, 200.0, 20.0, -3.0)
ASYMMETRIC = RigidAxis(95.0, 170.0, 20.0, 0.0, 240.0, 21.0)
TRUTH = {"symmetric": [95.0, 200.0, 20.0, -3.0], "asymmetric": [95.0, 170.0, 20.0, 240.0, 21.0]}

# Janot, Gautier, Brunot, Data Set and Reference Models of EMPS (2019)
PUBLISHED = {
    "symmetric": ([95.1089, 203.5034, 20.3935, -3.1648], 4.0834),
    "asymmetric": ([95.1540, 166.7061, 20.1440, 240.4236, 20.6277], 3.1117),
}
PUBLISHED_STD = [0.1085, 1.1460, 0.1012, 0.0444]


def _record(axis: RigidAxis, sigma_q: float = 0.0, sigma_f: float = 0.0,
            seed: int = 0) -> Experiment:
    """20 s of back-and-forth moves in the EMPS loop, with optional sensor noise."""
    t = DT * np.arange(20000)
    r = 0.1 * (1 - np.cos(2 * np.pi * 0.2 * t)) + 0.02 * np.sin(2 * np.pi * 1.3 * t)
    sim = simulate_rigid_loop(axis, CTRL, r, DT)
    rng = np.random.default_rng(seed)
    q = sim.position + sigma_q * rng.standard_normal(r.size)
    f = sim.force + sigma_f * rng.standard_normal(r.size)
    return Experiment.from_arrays(DT, r=r, y=q, side={"force": f})


@pytest.fixture(scope="module")
def emps() -> Experiment:
    return load_emps()


# -- simulated axes with known friction ------------------------------------------------------


@pytest.mark.parametrize("model", ["symmetric", "asymmetric"])
def test_recovers_known_friction_noise_free(model):
    axis = SYMMETRIC if model == "symmetric" else ASYMMETRIC
    est = fit_inverse_dynamics(_record(axis), model=model)
    # method error of IDIM-LS, not noise: the sign(q̇) column is smoothed by the low-pass and
    # the decimation filter across reversals, and the ZOH force leads the central differences
    # by half a sample; measured 1.4 % (Fv) and 1.8 % (Fv+) on this trajectory, 2.5 % bounds it
    np.testing.assert_allclose(est.parameters, TRUTH[model], rtol=0.025)
    np.testing.assert_allclose(est["M"], 95.0, rtol=0.005)  # inertia is the best determined
    assert est.names == (("M", "Fv", "Fc", "offset") if model == "symmetric"
                         else ("M", "Fv+", "Fc+", "Fv-", "Fc-"))
    assert isinstance(est.model, RigidAxis)


@pytest.mark.parametrize("model", ["symmetric", "asymmetric"])
def test_noise_moves_the_estimate_within_four_sigma(model):
    axis = SYMMETRIC if model == "symmetric" else ASYMMETRIC
    clean = fit_inverse_dynamics(_record(axis), model=model)
    # 1 µm position noise (about 20 encoder counts) and 2 N force noise
    noisy = fit_inverse_dynamics(_record(axis, 1e-6, 2.0, seed=3), model=model)
    # noise-induced deviation against the returned covariance: 4σ (statistical bound)
    assert np.all(np.abs(noisy.parameters - clean.parameters) < 4 * noisy.std)
    np.testing.assert_allclose(noisy.parameters, TRUTH[model], rtol=0.03)  # 2.5 % + 4σ


def test_regression_shapes_and_time_base():
    exp = _record(SYMMETRIC)
    reg = inverse_dynamics_regression(exp, pipeline="servoid", decimation=10, trim=1)
    n = exp.n_samples - 2  # central differences lose one sample at each end
    assert reg.regressors.shape == (-(-n // 10) - 2, 4)
    assert reg.dt == pytest.approx(10 * DT)
    assert reg.t0 == pytest.approx(DT + 10 * DT)  # first difference, then one trimmed row
    np.testing.assert_allclose(reg.regressors[:, 3], 1.0, atol=1e-9)  # the offset column


def test_backward_differences_are_biased_by_their_delay():
    exp = _record(SYMMETRIC)
    central = fit_inverse_dynamics(exp, pipeline="servoid")
    backward = fit_inverse_dynamics(exp, pipeline="servoid", differentiation="backward")
    assert backward.options["relative_error"] > central.options["relative_error"]


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"model": "coulomb"}, OptionError, "model"),
        ({"decimation_filter": "cheby"}, OptionError, "decimation_filter"),
        ({"differentiation": "spline"}, OptionError, "differentiation"),
        ({"decimation": 0}, DataError, "decimation"),
        ({"trim": -1}, DataError, "trim"),
        ({"trim": 10000}, DataError, "too few"),
        ({"cutoff": 600.0}, DataError, "cutoff"),
        ({"force": "torque"}, ChannelError, "torque"),
    ],
)
def test_rejects_bad_settings(kwargs, error, match):
    with pytest.raises(error, match=match):
        fit_inverse_dynamics(_record(SYMMETRIC), **{"pipeline": "servoid", **kwargs})


def test_one_direction_only_is_not_identifiable_asymmetrically():
    t = DT * np.arange(5000)
    # always moving forwards: the q̇ < 0 columns are identically zero
    exp = Experiment.from_arrays(DT, y=0.05 * t + 0.001 * np.sin(2 * np.pi * t),
                                 side={"force": 20 + np.sin(t)})
    with pytest.raises(IdentifiabilityError):
        fit_inverse_dynamics(exp, model="asymmetric")


def test_closed_loop_oe_recovers_the_truth_inside_the_structure():
    exp = _record(SYMMETRIC)
    start = RigidAxis(100.0, 180.0, 25.0, -1.0)
    est = fit_closed_loop_oe(exp, CTRL, start, q0=float(exp["y"][0]))
    # noise-free data simulated by the same exact simulator: solver tolerance
    np.testing.assert_allclose(est.parameters, TRUTH["symmetric"], rtol=1e-6)
    assert est.options["relative_error"]["force"] < 1e-6


def test_closed_loop_oe_takes_an_estimate_and_keeps_its_model():
    exp = _record(ASYMMETRIC)
    ls = fit_inverse_dynamics(exp, model="asymmetric")
    est = fit_closed_loop_oe(exp, CTRL, ls, output="force")
    assert est.names == ls.names
    assert est.options["relative_error"]["force"] < ls.options["relative_error"]
    np.testing.assert_allclose(est.parameters, TRUTH["asymmetric"], rtol=1e-5)


# -- the EMPS reference (known answers) ------------------------------------------------------


@pytest.mark.parametrize("model", ["symmetric", "asymmetric"])
@pytest.mark.parametrize("ftype", ["fir", "iir"])
def test_emps_reproduces_the_published_idim_ls(emps, model, ftype):
    est = fit_inverse_dynamics(emps, model=model, pipeline="servoid", decimation_filter=ftype)
    values, rel = PUBLISHED[model]
    # acceptance of issue 5: parameters within 1 %, relative error within 0.5 percentage point
    np.testing.assert_allclose(est.parameters, values, rtol=0.01)
    assert abs(est.options["relative_error"] - rel) < 0.5


def test_emps_servoid_pipeline_matches_closely(emps):
    est = fit_inverse_dynamics(emps, pipeline="servoid")
    # servoid's settings (FIR parallel decimation, one trimmed sample at each end) land much
    # closer than the acceptance band: 0.25 % on parameters, 0.01 point on the relative error
    np.testing.assert_allclose(est.parameters, PUBLISHED["symmetric"][0], rtol=0.0025)
    assert abs(est.options["relative_error"] - 4.0834) < 0.01
    # standard deviations: same σ̂²(ΦᵀΦ)⁻¹ on the same number of rows, within 1 %
    np.testing.assert_allclose(est.std, PUBLISHED_STD, rtol=0.01)
    assert est.options["condition_unscaled"] == pytest.approx(25.99, abs=0.05)


def test_emps_closed_loop_simulation(emps):
    est = fit_inverse_dynamics(emps)
    ctrl = CascadeController(emps.notes["kp"], emps.notes["kv"], emps.notes["gtau"], 10.0)
    sim = simulate_rigid_loop(est.model, ctrl, emps["qg"], emps.dt)  # at rest on qg(0)
    pos = 100 * np.linalg.norm(emps["qm"] - sim.position) / np.linalg.norm(emps["qm"])
    force = 100 * np.linalg.norm(emps["force"] - sim.force) / np.linalg.norm(emps["force"])
    # published 5.85 %; same loop and parameters within 0.25 %: within 0.5 point
    assert abs(force - 5.85) < 0.5
    # published 0.0138 %; this simulation tracks ten times closer (about 0.0015 %)
    assert pos < 0.0138
