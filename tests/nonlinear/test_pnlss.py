"""PNLSS: known answers from generators it does not share, exact gradients, files, bad input.

The records come from continuous-time systems simulated far above the
sample rate (a Wiener–Hammerstein chain by fine ZOH filters, a Duffing
oscillator by RK4 at 20 steps a sample) under random-phase multisines, so
the model class never contains the generator exactly.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

from servoid import DataError, Experiment, OptionError, OptionTypeError, ServoidWarning
from servoid.models import StateSpace, c2d, load_model, save_model
from servoid.nonlinear import MONOMIALS, PnlssModel, fit_pnlss
from servoid.nonlinear._pnlss import exponents
from servoid.nonlinear._pnlss_kernel import jacobian, jacobian_block
from servoid.validate import Replayable, validate


def _multisine(n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
    """Random-phase multisine over (0, 0.3 fs], unit RMS."""
    k = np.arange(1, int(0.3 * n))
    t = np.arange(n) / fs
    u = np.cos(2 * np.pi * np.outer(t, k * fs / n) + rng.uniform(0, 2 * np.pi, k.size)).sum(1)
    return u / u.std()


def _wiener_hammerstein(u: np.ndarray, fs: float, over: int = 10) -> np.ndarray:
    """8 Hz resonance → v = x − 0.3 x³ → 15 Hz first-order lag, at over·fs."""
    dtf = 1 / (fs * over)
    w1, w2 = 2 * np.pi * 8, 2 * np.pi * 15
    b1, a1, _ = signal.cont2discrete(([w1**2], [1, 0.6 * w1, w1**2]), dtf, "zoh")
    b2, a2, _ = signal.cont2discrete(([w2], [1, w2]), dtf, "zoh")
    x = signal.lfilter(np.ravel(b1), a1, np.repeat(u, over))
    return signal.lfilter(np.ravel(b2), a2, x - 0.3 * x**3)[::over]


def _duffing(u: np.ndarray, fs: float, over: int = 20, k3: float = 0.5) -> np.ndarray:
    """x'' + 2ζω x' + ω²(x + k3 x³) = ω² u (a hardening spring, 5 Hz, ζ = 0.1), RK4."""
    w, z, h = 2 * np.pi * 5, 0.1, 1 / (fs * over)

    def f(s: np.ndarray, v: float) -> np.ndarray:
        return np.array([s[1], w * w * (v - s[0] - k3 * s[0] ** 3) - 2 * z * w * s[1]])

    s, y = np.zeros(2), np.empty(u.size)
    for t in range(u.size):
        y[t] = s[0]
        for _ in range(over):
            a = f(s, u[t])
            b = f(s + h / 2 * a, u[t])
            c = f(s + h / 2 * b, u[t])
            s = s + h / 6 * (a + 2 * b + 2 * c + f(s + h * c, u[t]))
    return y


def _record(kind: str, seed: int, noise: float, n: int = 3000) -> Experiment:
    rng = np.random.default_rng(seed)
    fs = 100.0 if kind == "wh" else 50.0
    if kind == "wh":
        u = _multisine(n, fs, rng)
        y = _wiener_hammerstein(u, fs)
    elif kind == "duffing":
        u = 0.3 * _multisine(n, fs, rng)
        y = _duffing(u, fs)
    else:  # a linear second-order plant, the same 8 Hz resonance as the WH chain's first block
        u = _multisine(n, fs, rng)
        w1 = 2 * np.pi * 8
        b, a, _ = signal.cont2discrete(([w1**2], [1, 0.6 * w1, w1**2]), 1 / (10 * fs), "zoh")
        y = signal.lfilter(np.ravel(b), a, np.repeat(u, 10))[::10]
    return Experiment.from_arrays(u=u, y=y + noise * rng.standard_normal(n), dt=1 / fs)


def _free_run_rms(model: PnlssModel, rec: Experiment) -> float:
    y_sim, _, _ = model.replay(rec["y"], rec["u"])
    return float(np.sqrt(np.mean((y_sim - rec["y"]) ** 2)))


# -- known answers ----------------------------------------------------------------------------


def test_duffing_reaches_the_noise_floor_once_the_degree_covers_the_cubic_spring():
    noise = 0.005
    est = fit_pnlss(_record("duffing", 1, noise), 2, 3)
    val = _record("duffing", 2, noise)
    # within 10 % of the noise floor on a fresh record: the known answer (measured 1.7 %)
    assert _free_run_rms(est.model, val) < 1.10 * noise
    linear = fit_pnlss(_record("duffing", 1, noise), 2, 1)
    # a linear model cannot follow the hardening spring: 20× the noise (measured 25×)
    assert _free_run_rms(linear.model, val) > 20 * noise


def test_duffing_with_state_monomials_only_also_reaches_the_noise_floor():
    noise = 0.005
    est = fit_pnlss(_record("duffing", 1, noise), 2, 3, monomials="state")
    # the spring is a function of the state alone (measured 4 % above the floor)
    assert _free_run_rms(est.model, _record("duffing", 2, noise)) < 1.10 * noise


def test_wiener_hammerstein_reaches_the_noise_floor_with_three_states():
    noise = 0.02
    est = fit_pnlss(_record("wh", 1, noise), 3, 3, max_iter=200)
    # 10 % over the floor: the second filter sees v(t) between samples, which no discrete model
    # holds exactly (measured 7.5 % above the floor after 300 iterations, 8.7 % after 100)
    assert _free_run_rms(est.model, _record("wh", 2, noise)) < 1.10 * noise


def test_a_linear_plant_gives_negligible_nonlinear_terms():
    noise = 0.01
    est = fit_pnlss(_record("linear", 1, noise), 2, 3)
    val = _record("linear", 2, noise)
    x0 = est.model.initial_state(val["y"], val["u"])
    full, lin = est.model.contribution(val["u"], x0)
    # E ζ and F η change the run by far less than the noise: they fit noise only (measured
    # 0.14 of the noise's std)
    assert np.sqrt(np.mean((full - lin) ** 2)) < 0.2 * noise
    assert _free_run_rms(est.model, val) < 1.05 * noise  # and the model is at the floor


def test_ridge_shrinks_the_nonlinear_coefficients():
    rec = _record("linear", 1, 0.01)
    free = fit_pnlss(rec, 2, 3).model
    held = fit_pnlss(rec, 2, 3, ridge=1.0).model
    size = np.linalg.norm(np.r_[free.E.ravel(), free.F])
    # a strong ridge takes them to nothing (measured 0.06 → 0.0003)
    assert np.linalg.norm(np.r_[held.E.ravel(), held.F]) < 0.1 * size


def test_the_given_initial_linear_model_is_the_start():
    rec = _record("duffing", 1, 0.005)
    w = 2 * np.pi * 5
    g = c2d(StateSpace([[0, 1], [-w * w, -w]], [[0], [w * w]], [[1, 0]], [[0]]), rec.dt, "zoh")
    est = fit_pnlss(rec, degree=3, initial=g)
    assert est.options["linear"] == "given"
    start = StateSpace(**{k: est.options["linear_start"][k] for k in "ABCD"}, dt=rec.dt)
    # the start is the given model, in the data's units (similarity-invariant: its poles)
    assert np.allclose(np.sort_complex(start.poles()), np.sort_complex(g.poles()))
    assert _free_run_rms(est.model, _record("duffing", 2, 0.005)) < 1.10 * 0.005



def test_max_iter_zero_keeps_the_model_and_fits_its_initial_states():
    # a lightly damped plant (0.95 ± 0.2j) that does not start at rest: with x(0) = 0 the
    # cost measured the start-up transient (0.25 by this measure); now the given
    # model's cost is its noise, the model itself untouched
    rng = np.random.default_rng(3)
    u = rng.standard_normal(400)
    g = StateSpace([[0.95, 0.2], [-0.2, 0.95]], [[1.0], [0.0]], [[1.0, 0.0]], [[0.0]], dt=0.01)
    y = np.asarray(g.simulate(u, x0=np.array([30.0, -20.0])), dtype=float)
    rec = Experiment.from_arrays(0.01, u=u, y=y + 0.01 * rng.standard_normal(u.size))
    est = fit_pnlss(rec, degree=1, initial=g, max_iter=0)
    assert est.options["iterations"] == 0
    assert np.sqrt(est.options["cost"] / rec.n_samples) < 1.5 * 0.01  # noise, not start-up
    assert np.allclose(np.sort_complex(est.model.linear_part().poles()),
                       np.sort_complex(g.poles()))


# -- the exact gradient -----------------------------------------------------------------------


def test_the_sensitivity_recursion_matches_central_differences():
    rng = np.random.default_rng(3)
    nx, nu = 2, 1
    powers = exponents(nx, nu, 3)
    nm = powers.shape[0]
    A = np.array([[0.5, 0.2], [-0.3, 0.6]])
    B = rng.standard_normal((nx, nu))
    C, D = rng.standard_normal(nx), rng.standard_normal(nu)
    E, F = 0.02 * rng.standard_normal((nx, nm)), 0.02 * rng.standard_normal(nm)
    u = 0.3 * rng.standard_normal((200, nu))
    x0 = np.array([0.1, -0.2])
    theta = np.r_[A.ravel(), B.ravel(), C, D, E.ravel(), F, x0]

    def run(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        parts = np.split(th, np.cumsum([nx * nx, nx * nu, nx, nu, nx * nm, nm]))
        y = np.empty(200)
        J = np.empty((200, th.size))
        where = jacobian(parts[0].reshape(nx, nx), parts[1].reshape(nx, nu), parts[2],
                         parts[3], parts[4].reshape(nx, nm), parts[5], powers, u, parts[6], 0,
                         y, J)
        assert where == -1  # a run that stays bounded
        return y, J

    _, J = run(theta)
    h = 1e-6
    fd = np.column_stack([(run(theta + h * e)[0] - run(theta - h * e)[0]) / (2 * h)
                          for e in np.eye(theta.size)])
    # central differences are good to ~1e-8 here; the recursion is exact
    assert np.max(np.abs(J - fd)) < 1e-6 * max(1.0, np.max(np.abs(fd)))


def test_the_initial_state_columns_alone_match_the_full_jacobian():
    est = fit_pnlss(_record("duffing", 1, 0.005, n=600), 2, 2)
    m = est.model
    un = np.ascontiguousarray(((m.u_mean * 0 + _record("duffing", 2, 0.0, 600)["u"])[:, None]
                               - m.u_mean) / m.u_scale)
    x0 = np.array([0.3, -0.1])
    y1, y2 = np.empty(600), np.empty(600)
    full = np.empty((600, m.n_parameters + 2))
    only = np.empty((600, 2))
    jacobian(*m._kernel_args(), un, x0, 0, y1, full)
    jacobian(*m._kernel_args(), un, x0, m.n_parameters, y2, only)
    assert np.array_equal(y1, y2) and np.allclose(full[:, -2:], only, rtol=1e-12, atol=0)


def test_the_jacobian_in_blocks_is_the_whole_jacobian_bit_for_bit():
    est = fit_pnlss(_record("duffing", 1, 0.005, n=600), 2, 2)
    m = est.model
    un = np.ascontiguousarray(((_record("duffing", 2, 0.0, 600)["u"])[:, None] - m.u_mean)
                              / m.u_scale)
    x0 = np.array([0.3, -0.1])
    npar = m.n_parameters + 2
    y1, whole = np.empty(600), np.empty((600, npar))
    jacobian(*m._kernel_args(), un, x0, 0, y1, whole)
    x, S = x0.copy(), np.zeros((2, npar))
    S[:, -2:] = np.eye(2)
    y2, blocks = np.empty(600), np.empty((600, npar))
    for a, b in ((0, 1), (1, 250), (250, 600)):  # uneven blocks, one of a single sample
        jacobian_block(*m._kernel_args(), un[a:b], x, S, 0, y2[a:b], blocks[a:b])
    assert np.array_equal(y1, y2) and np.array_equal(whole, blocks)


def test_pruning_keeps_the_monomials_the_plant_uses():
    # a cubic at the input of a second-order filter, simulated exactly: of the 17 monomials
    # (2 states, 1 input, degree 3, with the constant) the plant uses u^3 alone (u^2 and the
    # constant follow from the normalisation's mean); every monomial with a state is zero in
    # any state basis, so the pruning must remove all 14 of them
    rng = np.random.default_rng(5)
    u = rng.standard_normal(2000)
    y = signal.lfilter([0, 0.2, 0.1], [1, -1.2, 0.5], u + 0.4 * u**3)
    exp = Experiment.from_arrays(0.01, u=u, y=y + 0.02 * rng.standard_normal(2000))
    est = fit_pnlss(exp, 2, 3, prune=0.01)
    names = est.model.monomial_names
    kept = [m for m in names if m not in est.options["pruned"]]
    assert "u^3" in kept and set(kept) <= {"1", "u^2", "u^3"}
    gone = [names.index(m) for m in est.options["pruned"]]
    assert np.all(est.model.E[:, gone] == 0) and np.all(est.model.F[gone] == 0)
    # the pruned model still reaches the noise floor (σ = 0.02; 5 %: in-sample, 14 × 3 fewer
    # parameters than the full fit)
    assert np.sqrt(est.options["cost"]) < 1.05 * 0.02
    # their covariance is zero (fixed), the kept coefficients' is not
    std = np.sqrt(np.diag(est.covariance))
    e_u3 = list(est.names).index("E[1,u^3]")
    assert std[list(est.names).index("E[1,x1^2]")] == 0 and std[e_u3] > 0


def test_from_the_bla_the_linear_part_matches_the_bla_within_its_sigma():
    # the Wiener–Hammerstein chain (simulated at 10 × the sample rate) under an odd random-phase
    # multisine, 4 realisations × 2 periods: the BLA with its variance (noise and stochastic
    # nonlinear), its ML fit in z turned into state space as the start; the linear model refined
    # by output error on the time record estimates the same BLA
    from servoid.frequency import estimate_bla, fit_ml
    from servoid.signals import plan_multisine, random_multisine

    plan = plan_multisine(0.01, 0.1, 30.0, period=1024, lines="odd", realisations=4,
                          periods=2, transient_periods=1)
    u = 0.5 * random_multisine(plan, rng=1).values  # RMS 0.5: the curve's 0.3x³ is felt
    rng = np.random.default_rng(2)
    y = _wiener_hammerstein(u, 100.0) + 0.02 * rng.standard_normal(u.size)
    exp = Experiment.from_arrays(0.01, u=u, y=y)
    bla = estimate_bla(exp, plan)
    start = fit_ml(bla, 3, 3, domain="z")
    est = fit_pnlss(exp, degree=1, initial=start)
    assert est.options["linear"] == "given"
    w = 2 * np.pi * bla.frequency

    def z(model) -> np.ndarray:
        return np.abs(model.freqresp(w).ravel() - bla.response) / np.sqrt(bla.variance)

    # |ΔG|/σ of an unbiased estimate is about Rayleigh: RMS 1, 98 % below 2 (here 1.11, 95 %;
    # σ² from M = 4 realisations is itself uncertain, so the bounds allow 1.25 and 90 %)
    found = z(est.model.linear_part())
    assert np.sqrt(np.mean(found**2)) < 1.25 and np.mean(found < 2) > 0.9
    # the bounds discriminate: the same model with its gain 5 % off fails them (RMS 1.34)
    off = z(est.model.linear_part().to_tf() * 1.05)
    assert np.sqrt(np.mean(off**2)) > 1.25 or np.mean(off < 2) <= 0.9


# -- the model as a servoid model ---------------------------------------------------------------


@pytest.fixture(scope="module")
def fitted():
    return fit_pnlss(_record("duffing", 1, 0.005), 2, 3)


def test_it_is_replayable_and_validates_from_an_estimated_initial_state(fitted):
    assert isinstance(fitted.model, Replayable)
    val = _record("duffing", 2, 0.005)
    # a record that does not start at rest: drop the first 137 samples
    late = val.slice(137, None)
    report = validate(fitted, late)
    assert report.initial == "estimate"
    assert report.rmse < 1.10 * 0.005  # the estimated x(0) puts it on the floor from sample 0
    zero, _, rule = fitted.model.replay(late["y"], late["u"], initial="zero")
    assert rule == "zero"
    # from rest the first samples are wrong: the estimate is what makes the fit (measured 3.2×)
    assert np.sqrt(np.mean((zero - late["y"]) ** 2)) > 2 * report.rmse


def _output_std(est, rec: Experiment) -> float:
    """RMS over a record of the simulated output's std by the delta method (basis-free)."""
    m = est.model
    un = np.ascontiguousarray(((rec["u"][:, None]) - m.u_mean) / m.u_scale)
    y = np.empty(rec.n_samples)
    J = np.empty((rec.n_samples, m.n_parameters + m.n_states))
    jacobian(*m._kernel_args(), un, np.zeros(m.n_states), 0, y, J)
    J = J[:, :m.n_parameters] * m.y_scale
    return float(np.sqrt(np.mean(np.einsum("ij,jk,ik->i", J, est.covariance, J))))


def test_the_covariance_is_finite_and_shrinks_with_more_data(fitted):
    assert fitted.covariance.shape == (fitted.parameters.size,) * 2
    assert np.all(np.isfinite(fitted.covariance))
    short = fit_pnlss(_record("duffing", 1, 0.005, n=750), 2, 3)
    val = _record("duffing", 2, 0.0)
    long_std, short_std = _output_std(fitted, val), _output_std(short, val)
    # 4× the data: 1/√N halves the output uncertainty; the short fit (60 parameters on 750
    # samples) is further from the asymptote, which widens it (measured 0.37)
    assert 0.25 < long_std / short_std < 0.65
    # and that uncertainty is a small share of the noise, as for p parameters over N samples
    assert long_std < 0.005 * np.sqrt(3 * fitted.parameters.size / val.n_samples)


def test_the_model_file_round_trip_is_bit_exact(fitted, tmp_path):
    path = save_model(fitted, tmp_path / "pnlss.json")
    back = load_model(path)
    assert isinstance(back, PnlssModel)
    for key in ("A", "B", "C", "D", "E", "F", "powers", "u_mean", "u_scale", "covariance"):
        assert np.array_equal(getattr(back, key), getattr(fitted.model, key)), key
    assert (back.y_mean, back.y_scale, back.dt) == (fitted.model.y_mean, fitted.model.y_scale,
                                                    fitted.model.dt)
    u = _record("duffing", 2, 0.0)["u"]
    assert np.array_equal(back.simulate(u), fitted.model.simulate(u))


def test_display(fitted):
    html = fitted.model._repr_html_()
    assert "PNLSS model" in html and "x1^3" in html
    assert "degree 3" in repr(fitted.model)
    assert "x1(t+1)" in str(fitted.model)
    assert fitted.model.linear_part().n_states == 2


def test_a_diverging_run_warns_and_gives_nan(fitted):
    u = 50 * _record("duffing", 2, 0.0)["u"]  # far outside the fitted amplitude
    with pytest.warns(ServoidWarning, match="diverges at sample"):
        y = fitted.model.simulate(u)
    assert np.isnan(y[-1])


def test_monomial_sets():
    assert exponents(2, 1, 3, "full").shape == (1 + 6 + 10, 3)  # the constant, 6 squares, 10 cubes
    assert exponents(2, 1, 3, "state").shape == (1 + 3 + 4, 3)
    assert not exponents(2, 1, 3, "input")[:, :2].any()
    assert exponents(2, 1, 1).shape == (0, 3)
    assert MONOMIALS == ("full", "state", "input")


# -- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(("kwargs", "error", "words"), [
    ({"degree": 0}, DataError, "degree"),
    ({"degree": 7}, DataError, "degree"),
    ({"n_states": 0}, DataError, "n_states"),
    ({"monomials": "cross"}, OptionError, "monomials"),
    ({"linear": "arx"}, OptionError, "linear"),
    ({"ridge": -1.0}, DataError, "ridge"),
    ({"prune": 1.5}, OptionError, "significance level"),
    ({"prune": -0.1}, DataError, "prune"),
    ({"initial": "n4sid"}, OptionTypeError, "initial"),
    ({"initial": StateSpace([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.5)}, DataError, "dt"),
])
def test_bad_options_are_refused_naming_them(kwargs, error, words):
    rec = _record("duffing", 1, 0.005, n=300)
    with pytest.raises(error, match=words):
        fit_pnlss(rec, **kwargs)


def test_too_short_a_record_is_refused():
    with pytest.raises(DataError, match="parameters"):
        fit_pnlss(_record("duffing", 1, 0.005, n=60), 3, 3)


def test_a_constant_input_is_refused():
    rec = Experiment.from_arrays(u=np.ones(500), y=np.random.default_rng(0).standard_normal(500),
                                 dt=0.01)
    with pytest.raises(Exception, match="constant|excit"), warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        fit_pnlss(rec, 2, 2)


def test_measured_initial_is_refused(fitted):
    val = _record("duffing", 2, 0.005, n=300)
    with pytest.raises(Exception, match="measured"):
        fitted.model.replay(val["y"], val["u"], initial="measured")
