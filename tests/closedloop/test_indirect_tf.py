"""The indirect approach for any plant order with a known controller."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import DataError, IdentifiabilityError, ModelError, OptionError, OptionTypeError
from servoid.bench import simulate_lti_loop
from servoid.closedloop import fit_indirect_tf
from servoid.data import Experiment
from servoid.models import PolynomialModel, TransferFunction, c2d

DT = 0.05
WN, ZETA, TAU = 2 * np.pi * 1.0, 0.3, 0.2
# a 3rd-order plant: a 1 Hz resonance behind a 0.2 s lag
PLANT = TransferFunction([WN**2], np.polymul([1.0, 2 * ZETA * WN, WN**2], [TAU, 1.0]))
LEAD = TransferFunction([1.2, -1.2 * 0.85], [1.0, -0.5], DT)  # 1.2 (z − 0.85)/(z − 0.5)
PI = TransferFunction([0.3 + 0.8 * DT, -0.3], [1.0, -1.0], DT)  # kp = 0.3, ki = 0.8 /s
NOISE = ([1.0, 0.3], [1.0, -0.9])
TRUE = c2d(PLANT, DT, "zoh").to_polynomial("oe")
THETA = np.concatenate([TRUE.b[0], TRUE.f[0][1:]])  # b0, b1, b2, f1, f2, f3


def reference(n: int, seed: int) -> np.ndarray:
    return np.repeat(np.sign(np.random.default_rng(seed).standard_normal(n // 2)), 2)


def relative_error(est) -> float:
    return float(np.max(np.abs(est.parameters - THETA) / np.abs(THETA)))


@pytest.mark.parametrize("controller", [LEAD, PI], ids=["lead", "pi"])
def test_noise_free_loop_gives_the_plant(controller):
    exp = simulate_lti_loop(PLANT, controller, reference(2000, 0), DT)
    est = fit_indirect_tf(exp, controller, 3, 3, 1)
    # the rig integrates exactly; what is left is the rounding of 4th-order recursions (ε·cond)
    assert relative_error(est) < 1e-9
    assert est.status == "ok" and est.method == "indirect"


@pytest.mark.parametrize(("structure", "refine"), [("arx", False), ("oe", False), ("arx", True)])
def test_noise_free_routes_agree(structure, refine):
    # noise-free, the closed loop is exactly ARX and OE of the default orders, so every route
    # (with or without the one-step refinement) lands on the plant to rounding
    exp = simulate_lti_loop(PLANT, LEAD, reference(2000, 1), DT)
    est = fit_indirect_tf(exp, LEAD, 3, 3, 1, structure=structure, refine=refine)
    assert relative_error(est) < 1e-8  # ε·cond of the closed-loop fit
    assert est.options["refined"] is refine


def test_a_sensor_gain_in_the_feedback():
    # u = C·(r − 2y) is the rig's unit loop with controller 2C driven by r/2
    r = reference(2000, 2)
    run = simulate_lti_loop(PLANT, LEAD * 2.0, r / 2.0, DT)
    exp = Experiment.from_arrays(DT, r=r, u=run["u"], y=run["y"])
    est = fit_indirect_tf(exp, LEAD, 3, 3, 1, feedback=2.0)
    assert relative_error(est) < 1e-9  # ε·cond, as above


def test_a_dynamic_feedback_filter():
    # the loop closed with the models package's own algebra, a sensor lag F = 0.4/(z − 0.6)
    sensor = TransferFunction([0.4], [1.0, -0.6], DT)
    r = reference(2000, 3)
    closed = (c2d(PLANT, DT, "zoh") * LEAD).feedback(sensor)
    exp = Experiment.from_arrays(DT, r=r, y=closed.simulate(r))
    est = fit_indirect_tf(exp, LEAD, 3, 3, 1, feedback=sensor)
    assert relative_error(est) < 1e-8  # ε·cond of a 5th-order closed loop
    assert (est.options["closed_loop"]["nb"], est.options["closed_loop"]["nf"]) == (5, 5)


def test_an_unstable_plant_that_only_runs_in_closed_loop():
    # a double integrator (a ball on a beam) held by a lead controller
    plant = TransferFunction([1.0], [1.0, 0.0, 0.0])
    lead = TransferFunction([4.0, -3.6], [1.0, -0.5], DT)
    true = c2d(plant, DT, "zoh").to_polynomial("oe")
    theta = np.concatenate([true.b[0], true.f[0][1:]])  # b0, b1, f1 = −2, f2 = 1
    r = 0.2 * reference(4000, 8)
    exact = fit_indirect_tf(simulate_lti_loop(plant, lead, r, DT), lead, 2, 2, 1)
    np.testing.assert_allclose(exact.parameters, theta, rtol=1e-9)  # ε·cond
    noisy = simulate_lti_loop(plant, lead, r, DT, noise_std=0.01, noise_model=NOISE, rng=8)
    est = fit_indirect_tf(noisy, lead, 2, 2, 1)
    assert np.all(np.abs((est.parameters - theta) / est.std) < 4)  # 4σ


@pytest.mark.parametrize("seed", range(4))
def test_coloured_noise_in_the_loop(seed):
    exp = simulate_lti_loop(PLANT, LEAD, reference(6000, 100 + seed), DT, noise_std=0.05,
                            noise_model=NOISE, rng=seed)
    est = fit_indirect_tf(exp, LEAD, 3, 3, 1)
    z = (est.parameters - THETA) / est.std
    assert np.all(np.abs(z) < 4)  # 4σ of the sandwich covariance


def test_result_carries_the_plant_and_its_uncertainty():
    exp = simulate_lti_loop(PLANT, LEAD, reference(3000, 5), DT, noise_std=0.05,
                            noise_model=NOISE, rng=5)
    est = fit_indirect_tf(exp, LEAD, 3, 3, 1)
    assert isinstance(est.model, PolynomialModel) and est.model.structure == "oe"
    assert est.names == ("b0", "b1", "b2", "f1", "f2", "f3")
    assert est.model.input_names == ("u",) and est.model.output_name == "y"
    g = est.model.transfer_function()
    assert g.dt == DT and g.order == 3
    again = est.model_at(est.parameters)
    np.testing.assert_array_equal(again.f[0], est.model.f[0])
    np.testing.assert_allclose(est.covariance, est.covariance.T)
    assert np.all(np.linalg.eigvalsh(est.covariance) > 0)
    assert est.residuals.size == exp.n_samples
    options = est.options
    assert options["loop"] == "u = C·(r − F·y)"
    assert options["closed_loop"]["nb"] == 4 and options["closed_loop"]["nk"] == 1
    assert set(options["closed_loop"]["parameters"]) == {"b0", "b1", "b2", "b3", "f1", "f2",
                                                         "f3", "f4"}
    assert options["refined"] is True and options["start"] in {"oe", "iv"}


@pytest.mark.parametrize(
    ("controller", "kwargs", "error", "match"),
    [
        (TransferFunction([1.2, -1.0], [1.0, -0.5], 0.1), {}, ModelError,
         r"dt = 0.1 s but the data have dt = 0.05 s"),
        # a controller that ran between the recorded samples: no loop at the record's rate
        (TransferFunction([1.2, -1.0], [1.0, -0.5], 0.01), {}, ModelError,
         r"ran every 0.01 s, faster than the record's 0.05 s.*method = \"cliv\""),
        # a continuous controller is discretised (test_controller_discretisation.py); a
        # continuous feedback path is not
        (LEAD, {"feedback": TransferFunction([1.0], [0.01, 1.0])}, ModelError,
         r"c2d\(feedback, 0.05"),
        ("PI", {}, OptionTypeError, "controller must be a discrete TransferFunction"),
        (0.0, {}, ModelError, "controller is zero"),
        (LEAD, {"feedback": 0.0}, ModelError, "the loop is open"),
        (LEAD, {"structure": "bj"}, OptionError, "structure must be one of 'oe', 'arx'"),
        (LEAD, {"closed_loop": (2, 2, 1)}, ModelError, r"cannot hold the closed loop"),
        (LEAD, {"closed_loop": 4}, OptionTypeError, r"closed_loop must be a tuple"),
        (TransferFunction([1.0], [1.0], DT), {"nk": 0}, ModelError, "algebraic loop"),
    ],
)
def test_bad_loops_name_the_fix(controller, kwargs, error, match):
    exp = simulate_lti_loop(PLANT, LEAD, reference(600, 6), DT)
    nk = kwargs.pop("nk", 1)
    with pytest.raises(error, match=match):
        fit_indirect_tf(exp, controller, 3, 3, nk, **kwargs)


def test_bad_records_name_the_fix():
    exp = simulate_lti_loop(PLANT, LEAD, reference(600, 7), DT)
    without_r = Experiment.from_arrays(DT, u=exp["u"], y=exp["y"])
    with pytest.raises(DataError, match="no reference"):
        fit_indirect_tf(without_r, LEAD, 3, 3, 1)
    flat = Experiment.from_arrays(DT, r=np.ones(600), y=exp["y"])
    with pytest.raises(IdentifiabilityError, match="constant reference"):
        fit_indirect_tf(flat, LEAD, 3, 3, 1)


@pytest.mark.slow
def test_scatter_matches_the_covariance_over_many_seeds():
    """30 seeds, N = 6000: the z-scores of the plant coefficients have unit scatter."""
    z = []
    for seed in range(200, 230):
        exp = simulate_lti_loop(PLANT, LEAD, reference(6000, seed), DT, noise_std=0.05,
                                noise_model=NOISE, rng=seed)
        est = fit_indirect_tf(exp, LEAD, 3, 3, 1)
        z.append((est.parameters - THETA) / est.std)
    z = np.array(z)
    # the sample sd of 30 unit normals has sd 0.13: 0.6–1.5 is about ±3 of it (measured 0.8–0.9)
    assert np.all((z.std(axis=0) > 0.6) & (z.std(axis=0) < 1.5))
    assert np.all(np.abs(z.mean(axis=0)) < 0.6)  # bias below 0.6σ: 3.3 sd of a 30-mean
    assert np.all(np.abs(z) < 4.5)  # 180 draws, correlated: 4.5σ is never reached by chance
