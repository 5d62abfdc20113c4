"""The general grey-box output-error estimator fit_tf_greybox."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    ServoidWarning,
)
from servoid.data import Experiment
from servoid.estimate import fit_tf_greybox
from servoid.models import TransferFunction

DT = 0.01
TRUE = np.array([2.0, 0.15])  # gain [-], time constant [s]


def first_order(theta: np.ndarray) -> TransferFunction:
    """Exact ZOH image of K/(τs + 1): pole e^(−dt/τ)."""
    k, tau = theta
    a = np.exp(-DT / tau)
    return TransferFunction([k * (1 - a)], [1.0, -a], DT, "zoh")


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(42)
    u = np.repeat(rng.choice([-1.0, 1.0], 1000), 5)  # random binary, 5 samples/bit
    y0 = first_order(TRUE).simulate(u)
    sigma = 0.05
    return Experiment.from_arrays(DT, u=u, y=y0 + rng.normal(0, sigma, u.size)), sigma


def test_known_answer_noise_free():
    rng = np.random.default_rng(1)
    u = rng.normal(size=2000)
    exp = Experiment.from_arrays(DT, u=u, y=first_order(TRUE).simulate(u))
    est = fit_tf_greybox(exp, first_order, [1.0, 0.05], ("K", "tau"), ("-", "s"),
                         transform=("log", "log"))
    # model inside the structure, no noise: LM tolerance 1e-10 limits the agreement
    np.testing.assert_allclose(est.parameters, TRUE, rtol=1e-8)
    assert est.method == "tf_greybox" and est.status == "ok"
    assert est.options["solver"] == "lm" and est.options["nfev"] > 0


def test_statistics(data):
    exp, sigma = data
    est = fit_tf_greybox(exp, first_order, [1.0, 0.5], ("K", "tau"), transform=("log", "log"))
    # errors within 4σ of σ̂²(JᵀJ)⁻¹; σ̂² within 4·√(2/N) of σ² (χ² with N − 2 dof)
    assert np.all(np.abs(est.parameters - TRUE) < 4 * est.std)
    assert est.noise_variance == pytest.approx(sigma**2, rel=4 * np.sqrt(2 / exp.n_samples))
    assert est.residuals.size == exp.n_samples
    assert est.model.dt == DT


def test_bounds_use_trf_and_warn_on_an_active_bound(data):
    exp, _ = data
    with pytest.warns(ServoidWarning, match="sits on its upper bound"):
        est = fit_tf_greybox(exp, first_order, [1.0, 0.1], ("K", "tau"),
                             bounds=([0.1, 0.01], [1.5, 1.0]))
    assert est.options["solver"] == "trf"
    assert est["K"] == pytest.approx(1.5)


def test_convergence_error(data):
    exp, _ = data
    with pytest.raises(ConvergenceError, match="did not converge"):
        fit_tf_greybox(exp, first_order, [1.0, 0.5], ("K", "tau"), max_nfev=1)


def test_rank_deficient_parameters(data):
    exp, _ = data

    def product(theta: np.ndarray) -> TransferFunction:
        return first_order(np.array([theta[0] * theta[1], 0.15]))

    with pytest.raises(IdentifiabilityError, match="rank deficient"):
        fit_tf_greybox(exp, product, [1.0, 1.5], ("a", "b"))


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"transform": ("log", "sqrt")}, OptionError, "transform must be one of"),
        ({"theta0": [-1.0, 0.1], "transform": ("log", "log")}, DataError, "theta0 > 0: K"),
        ({"solver": "lm", "bounds": ([0, 0], [5, 5])}, OptionError, "does not take bounds"),
        ({"names": ("K",)}, DataError, "names needs one entry per parameter"),
        ({"input": "r"}, DataError, "no reference"),
        ({"model_fn": lambda t: (1, 2)}, TypeError, "must return a TransferFunction"),
        ({"model_fn": lambda t: TransferFunction([1.0], [1.0, 1.0])}, ModelError, "discrete"),
    ],
)
def test_bad_input(data, kwargs, error, match):
    exp, _ = data
    args = {"model_fn": first_order, "theta0": [1.0, 0.1], "names": ("K", "tau")} | kwargs
    with pytest.raises(error, match=match):
        fit_tf_greybox(exp, args.pop("model_fn"), args.pop("theta0"), args.pop("names"), **args)
