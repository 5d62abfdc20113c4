"""User grey-box ODEs: the integrator, the fit and the replay, against independent generators.

The truth of the known-answer tests is simulated by ``examples/greybox/make_data.py``:
numpy RK4 at 20 steps per sample period, the overflow as a projection after each
fine step (not the rate clamp servoid uses inside its stages), the pump
saturation as a clip, white sensor noise.  servoid integrates at one step per
sample (``substeps = 2`` here), so the model is not the generator's code path.
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from servoid import ModelError, ServoidWarning
from servoid.data import Experiment
from servoid.estimate import GreyboxParameter
from servoid.estimate._ode import make_system
from servoid.estimate._ode_model import OdeModel, fit_ode
from servoid.validate import Replayable, validate

EXAMPLE = Path(__file__).parents[2] / "examples" / "greybox"
G = 9.81


def _load(name: str):  # the example's files, imported from their path
    spec = importlib.util.spec_from_file_location(f"greybox_example_{name}", EXAMPLE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GEN = _load("make_data")
TANKS = _load("tanks")
TRUE = np.array([GEN.TRUE["k"], GEN.TRUE["a1"], GEN.TRUE["a2"]])
X_LO, X_HI = np.array([0.0, 0.0]), np.array([GEN.RIM, np.inf])
U_LO, U_HI = np.array([0.0]), np.array([GEN.U_MAX])


def _params(area_free: bool = False) -> list[GreyboxParameter]:
    return [GreyboxParameter("k", 2e-5, 1e-7, 1e-3), GreyboxParameter("a1", 2e-5, 1e-7, 1e-3),
            GreyboxParameter("a2", 2e-5, 1e-7, 1e-3),
            GreyboxParameter("A", 0.02 if area_free else GEN.TRUE["A"], 1e-3, 1.0,
                             fixed=not area_free)]


def _system(u: np.ndarray, *, compile: bool = True, rhs=None, output=None):
    p = np.array([p.value for p in _params()])
    return make_system(rhs or TANKS.rhs, TANKS.level if output is None else output,
                       x0=np.array([0.1, 0.1]), u=u.reshape(u.shape[0], -1), p=p,
                       state_lower=X_LO, state_upper=X_HI, input_lower=U_LO, input_upper=U_HI,
                       source="tanks.py:rhs", path=EXAMPLE / "tanks.py", compile=compile)


def _record(n: int, seed: int, h0: tuple[float, float]) -> tuple[Experiment, np.ndarray]:
    _, u, y, levels = GEN.record(n, seed, h0)
    return Experiment.from_arrays(u=u, y=y, dt=GEN.DT), levels


@pytest.fixture(scope="module")
def system():
    return _system(np.full(10, 5.0))


# -- the integrator ---------------------------------------------------------------------------


def test_integrator_matches_solve_ivp_on_a_smooth_model(system):
    from scipy.integrate import solve_ivp

    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(1.0, 6.0, 20), 10)  # below the pump limit, levels below the rim
    p = np.array([*TRUE, GEN.TRUE["A"]])
    x, ref = np.array([0.05, 0.04]), [0.04]
    for k in range(u.size - 1):  # the input held over each sample, as the integrator holds it
        sol = solve_ivp(lambda t, s, v=u[k]: TANKS.rhs(s, [v], p), (0.0, GEN.DT), x,
                        rtol=1e-12, atol=1e-14)
        x = sol.y[:, -1]
        ref.append(x[1])
    got = system.simulate(np.array([0.05, 0.04]), u[:, None], p, GEN.DT, 4)[:, 0]
    assert np.max(np.abs(got - ref)) < 1e-10  # RK4 at h = 0.25 s on τ ≈ 80 s: error ~ (h/τ)^4


def test_compiled_and_python_integrators_agree(system):
    assert system.compiled, system.note
    plain = _system(np.full(10, 5.0), compile=False)
    assert not plain.compiled and "compile = false" in plain.note
    u = np.repeat(np.random.default_rng(4).uniform(0.0, 10.0, 30), 40)[:, None]
    p = np.array([*TRUE, GEN.TRUE["A"]])
    a = system.simulate(np.array([0.2, 0.1]), u, p, 1.0, 2)
    b = plain.simulate(np.array([0.2, 0.1]), u, p, 1.0, 2)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)  # one source, two compilers


def test_saturations_clamp_the_state_and_clip_the_input(system):
    p = np.array([*TRUE, GEN.TRUE["A"]])
    full = np.full((2000, 1), 10.0)  # above the pump limit: fills the upper tank to its rim

    def upper(x, u, p):
        return x[0]

    top = _system(np.full(10, 5.0), output=upper)
    h1 = top.simulate(np.array([0.25, 0.1]), full, p, 1.0, 1)[:, 0]
    assert h1.max() == GEN.RIM  # the rim holds the level exactly (projection)
    np.testing.assert_array_equal(
        system.simulate(np.zeros(2), full, p, 1.0, 1),
        system.simulate(np.zeros(2), np.full((2000, 1), GEN.U_MAX), p, 1.0, 1))


def test_time_argument_and_vector_output():
    def rhs(t, x, u, p):
        return np.array([p[0] * math.cos(t)])

    def out(x, u, p):
        return np.array([x[0], 2.0 * x[0]])

    s = make_system(rhs, out, x0=np.zeros(1), u=np.zeros((5, 1)), p=np.ones(1),
                    state_lower=np.full(1, -np.inf), state_upper=np.full(1, np.inf),
                    input_lower=np.full(1, -np.inf), input_upper=np.full(1, np.inf),
                    source="m.py:rhs", output_source="m.py:out")
    assert s.takes_time and s.n_outputs == 2
    y = s.simulate(np.zeros(1), np.zeros((101, 1)), np.ones(1), 0.01, 2)
    t = np.arange(101) * 0.01
    np.testing.assert_allclose(y[:, 0], np.sin(t), atol=1e-10)  # x = sin t; RK4 h = 5 ms
    np.testing.assert_allclose(y[:, 1], 2 * y[:, 0])


def test_a_model_numba_cannot_compile_runs_in_python_with_a_note():
    from fractions import Fraction

    def rhs(x, u, p):
        return [float(Fraction(1, 2)) * u[0] - x[0]]

    s = make_system(rhs, 0, x0=np.zeros(1), u=np.ones((5, 1)), p=np.ones(1),
                    state_lower=np.full(1, -np.inf), state_upper=np.full(1, np.inf),
                    input_lower=np.full(1, -np.inf), input_upper=np.full(1, np.inf),
                    source="m.py:rhs")
    assert not s.compiled
    assert "does not compile with numba" in s.note and "Python integrator" in s.note
    y = s.simulate(np.zeros(1), np.ones((400, 1)), np.ones(1), 0.01, 1)[:, 0]
    assert abs(y[-1] - 0.5 * (1 - math.exp(-3.99))) < 1e-9  # first order, RK4 h = 10 ms


# -- the user's mistakes --------------------------------------------------------------------


def _bad(rhs, output=0, n_states=2):
    return make_system(rhs, output, x0=np.zeros(n_states), u=np.ones((5, 1)), p=np.ones(2),
                       state_lower=np.full(n_states, -np.inf),
                       state_upper=np.full(n_states, np.inf),
                       input_lower=np.full(1, -np.inf), input_upper=np.full(1, np.inf),
                       source="m.py:rhs", output_source="m.py:out", path=Path(__file__))


def test_rhs_raising_is_a_model_error_naming_the_file_and_line():
    def rhs(x, u, p):
        raise ValueError("no such valve")  # this line is named

    with pytest.raises(ModelError, match=r"test_ode.py, line \d+, in rhs: raise ValueError.*"
                                         r"ValueError: no such valve"):
        _bad(rhs)


@pytest.mark.parametrize("rhs, match", [
    (lambda x, u, p: (1.0, 2.0, 3.0), r"shape \(3,\) for 2 states"),
    (lambda x, u, p: "fast", r"dx/dt must be numbers"),
    (lambda x, u: (1.0, 2.0), r"takes 2 arguments; it must take \(x, u, p\) or \(t, x, u, p\)"),
])
def test_rhs_of_the_wrong_form_is_refused(rhs, match):
    with pytest.raises(ModelError, match=match):
        _bad(rhs)


def test_output_of_the_wrong_shape_is_refused():
    with pytest.raises(ModelError, match=r"output of shape \(2, 2\)"):
        _bad(lambda x, u, p: (0.0, 0.0), output=lambda x, u, p: np.zeros((2, 2)))


def test_an_error_during_the_fit_names_the_line(system):
    def rhs(x, u, p):
        if p[0] > 1.5:
            raise RuntimeError("out of range")
        return (u[0] - x[0], 0.0)

    s = make_system(rhs, 0, x0=np.zeros(2), u=np.ones((5, 1)), p=np.ones(2),
                    state_lower=np.full(2, -np.inf), state_upper=np.full(2, np.inf),
                    input_lower=np.full(1, -np.inf), input_upper=np.full(1, np.inf),
                    source="m.py:rhs", path=Path(__file__), compile=False)
    with pytest.raises(ModelError, match=r"line \d+, in rhs: raise RuntimeError"):
        s.simulate(np.zeros(2), np.ones((5, 1)), np.array([2.0, 1.0]), 0.1, 1)


# -- the fit ----------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [11, 12, 13, 14, 15])
def test_parameters_recovered_within_4_sigma(system, seed):
    exp, _ = _record(1500, seed, (0.12, 0.06))
    est = fit_ode(exp, system, _params(), states=["h1", "h2"], output="y", x0=[0.1, 0.1],
                  estimate_initial=["h1", "h2"], substeps=2)
    truth = np.array([*TRUE, 0.12, 0.06])
    z = (est.parameters - truth) / est.std
    assert np.all(np.abs(z) < 4.0), dict(zip(est.names, z.round(2), strict=True))  # 4σ
    # the residual variance is the sensor's: 1500 samples give it to ±4·√(2/1500) ≈ ±15 %
    assert abs(est.noise_variance / GEN.NOISE**2 - 1.0) < 0.15
    assert est.names == ("k", "a1", "a2", "h1(0)", "h2(0)")
    assert est.options["compiled"] is True


def test_products_of_parameters_are_warned_as_not_identifiable(system):
    exp, _ = _record(1500, 21, (0.1, 0.05))
    # k, a1, a2 and A enter only as k/A, a1/A, a2/A: one direction of θ leaves y unchanged
    with pytest.warns(ServoidWarning, match=r"not separately identifiable.*(k|A)"):
        fit_ode(exp, system, _params(area_free=True), states=["h1", "h2"], output="y",
                x0=[0.1, 0.1], estimate_initial=["h1", "h2"])


# -- the replay -------------------------------------------------------------------------------


def test_replay_on_a_second_record_refits_the_initial_state(system):
    exp, _ = _record(1500, 31, (0.1, 0.05))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)  # a clean fit
        est = fit_ode(exp, system, _params(), states=["h1", "h2"], output="y", x0=[0.1, 0.1],
                      estimate_initial=["h1", "h2"], substeps=2)
    model = est.model
    assert isinstance(model, OdeModel) and isinstance(model, Replayable)
    assert model.has_noise_model is False and model.dt == GEN.DT
    val, levels = _record(1500, 32, (0.05, 0.2))  # other input, other start
    y_sim, first, rule = model.replay(val["y"], val["u"])
    assert (first, rule) == (0, "estimate")
    # the replay error is what the parameters' uncertainty allows: its RMS is about the RMS of
    # σ_sim(t)² = ψ(t)ᵀPψ(t) (delta method, ψ = ∂ŷ/∂θ on this record); 4× is the 4σ
    # bound
    u, p, x0 = val["u"][:, None], model.theta, levels[0]
    psi = []
    for i in range(3):
        step = np.zeros_like(p)
        step[i] = 1e-6 * p[i]
        psi.append((system.simulate(x0, u, p + step, GEN.DT, 2)
                    - system.simulate(x0, u, p - step, GEN.DT, 2))[:, 0] / (2 * step[i]))
    psi = np.array(psi).T
    sigma_sim = np.sqrt(np.einsum("ij,jk,ik->i", psi, est.covariance[:3, :3], psi))
    error = y_sim - levels[:, 1]
    assert np.sqrt(np.mean(error**2)) < 4 * np.sqrt(np.mean(sigma_sim**2))
    y_zero, _, rule_zero = model.replay(val["y"], val["u"], initial="zero")
    assert rule_zero == "zero"
    assert np.sqrt(np.mean((y_zero - levels[:, 1]) ** 2)) > 5 * GEN.NOISE  # wrong start
    report = validate(est, val)  # servoid.validate replays it like a linear model
    assert report.initial == "estimate"
    np.testing.assert_allclose(report.simulated, y_sim, rtol=1e-9)
    with pytest.raises(ModelError, match='initial="measured"'):
        model.replay(val["y"], val["u"], initial="measured")


def test_noise_free_data_from_inside_the_structure_are_recovered(system):
    _, u, _, _ = GEN.record(1500, 51, (0.1, 0.05))
    p = np.array([*TRUE, GEN.TRUE["A"]])
    y = system.simulate(np.array([0.12, 0.06]), u[:, None], p, GEN.DT, 2)[:, 0]
    exp = Experiment.from_arrays(u=u, y=y, dt=GEN.DT)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # zero residuals: the checks have no σ
        est = fit_ode(exp, system, _params(), states=["h1", "h2"], output="y", x0=[0.1, 0.1],
                      estimate_initial=["h1", "h2"], substeps=2, tol=1e-14)
    # the same integrator made the data: only the solver's tolerance and cond(J) remain (1e-9)
    np.testing.assert_allclose(est.parameters, [*TRUE, 0.12, 0.06], rtol=1e-9)


def test_an_error_in_compiled_code_is_located_in_python():
    def rhs(x, u, p):
        if x[0] > 0.5:
            raise ValueError("the level left the tank")
        return (u[0], 0.0)

    s = make_system(rhs, 0, x0=np.zeros(2), u=np.ones((5, 1)), p=np.ones(2),
                    state_lower=np.full(2, -np.inf), state_upper=np.full(2, np.inf),
                    input_lower=np.full(1, -np.inf), input_upper=np.full(1, np.inf),
                    source="m.py:rhs", path=Path(__file__))
    assert s.compiled, s.note
    with pytest.raises(ModelError, match=r"test_ode.py, line \d+, in rhs: raise ValueError.*"
                                         r"the level left the tank"):
        s.simulate(np.zeros(2), np.ones((100, 1)), np.ones(2), 0.1, 1)
