"""Hammerstein, Wiener and Hammerstein–Wiener fits: known answers and bad input.

The generators share no code with the estimator: the linear block runs as
an explicit difference-equation loop in plain Python/numpy (the fit uses
scipy's lfilter on parameters it builds itself), the static curves are
written out with numpy.where, and the continuous plant is integrated by
RK4 at 50 steps per sample.  White Gaussian noise of known σ; several
seeds.
"""

import numpy as np
import pytest

from servoid import (
    DataError,
    Experiment,
    IdentifiabilityError,
    ModelError,
    OptionError,
    OptionTypeError,
)
from servoid.models import PolynomialModel
from servoid.nonlinear import (
    AbsoluteValue,
    BlockModel,
    DeadZone,
    Polynomial,
    StaticFunction,
    fit_block,
    fit_hammerstein,
    fit_hammerstein_wiener,
    fit_wiener,
)
from servoid.validate import Replayable, validate

DT = 0.01
N = 3000
SIGMA = 0.02
B, F = (0.5, 0.3), (-1.2, 0.5)  # poles 0.6 ± 0.37j, nk = 1
LOWER, UPPER = -0.4, 0.6
CENTER = 0.3
SEEDS = (0, 1, 2, 3, 4)


def difference_equation(v, b=B, f=F, nk=1, state=(0.0, 0.0)):
    """x(t) = Σ b_j v(t−nk−j) − Σ f_i x(t−i), past x given by ``state`` (x(−1), x(−2))."""
    x = np.zeros(v.size)
    past = list(state)
    for t in range(v.size):
        acc = 0.0
        for j, bj in enumerate(b):
            k = t - nk - j
            if k >= 0:
                acc += bj * v[k]
        for i, fi in enumerate(f, start=1):
            acc -= fi * (x[t - i] if t - i >= 0 else past[i - 1 - t] if i - 1 - t < len(past)
                         else 0.0)
        x[t] = acc
    return x


def dead_zone(u, lower=LOWER, upper=UPPER):
    return np.where(u > upper, u - upper, np.where(u < lower, u - lower, 0.0))


def record(rng, y, u):
    return Experiment.from_arrays(DT, u=u, y=y + SIGMA * rng.standard_normal(u.size))


def poles_with_std(est, names=("f1", "f2")):
    """Poles of 1 + f1 q⁻¹ + f2 q⁻² and the std of their real and imaginary parts (delta)."""
    idx = [est.names.index(n) for n in names]
    f = est.parameters[idx]
    cov = est.covariance[np.ix_(idx, idx)]

    def parts(coef):
        p = np.roots(np.r_[1.0, coef])
        p = p[np.argsort(-p.imag)]
        return np.r_[p.real, p.imag]

    base = parts(f)
    jac = np.column_stack([(parts(f + h) - parts(f - h)) / (2e-7)
                           for h in np.eye(f.size) * 1e-7])
    return base, np.sqrt(np.diag(jac @ cov @ jac.T))


def true_poles(f=F):
    p = np.roots(np.r_[1.0, f])
    p = p[np.argsort(-p.imag)]
    return np.r_[p.real, p.imag]


@pytest.mark.parametrize("seed", SEEDS)
def test_hammerstein_dead_zone_within_4_sigma(seed):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, N)
    est = fit_hammerstein(record(rng, difference_equation(dead_zone(u)), u), "deadzone")
    std = dict(zip(est.names, est.std, strict=True))
    # 4σ: a Gaussian deviation beyond it has probability 6e-5 per parameter
    assert abs(est["deadzone.lower"] - LOWER) < 4 * std["deadzone.lower"]
    assert abs(est["deadzone.upper"] - UPPER) < 4 * std["deadzone.upper"]
    poles, pole_std = poles_with_std(est)
    assert np.all(np.abs(poles - true_poles()) < 4 * pole_std)
    # σ̂² estimates σ²: relative sampling std of a variance is √(2/N) ≈ 0.026, 4 of them
    assert abs(est.noise_variance / SIGMA**2 - 1) < 4 * np.sqrt(2 / N)


@pytest.mark.parametrize("seed", SEEDS)
def test_wiener_absolute_value_within_4_sigma(seed):
    rng = np.random.default_rng(100 + seed)
    u = rng.uniform(-2.0, 2.0, N)
    x = difference_equation(u, b=(0.4, 0.2), f=(-1.1, 0.4))
    est = fit_wiener(record(rng, np.abs(x - CENTER), u), "abs")
    std = dict(zip(est.names, est.std, strict=True))
    # the positive-gain twin is returned (G → −G, centre → −centre is the same model)
    assert abs(est["abs.center"] - CENTER) < 4 * std["abs.center"]
    poles, pole_std = poles_with_std(est)
    assert np.all(np.abs(poles - true_poles((-1.1, 0.4))) < 4 * pole_std)
    assert abs(est["b0"] - 0.4) < 4 * std["b0"] and abs(est["b1"] - 0.2) < 4 * std["b1"]


def test_noise_free_record_is_recovered():
    rng = np.random.default_rng(20)
    u = rng.uniform(-2.0, 2.0, N)
    data = Experiment.from_arrays(DT, u=u, y=difference_equation(dead_zone(u)))
    est = fit_hammerstein(data, DeadZone(-0.3, 0.5))
    truth = {"deadzone.lower": LOWER, "deadzone.upper": UPPER, "b0": B[0], "b1": B[1],
             "f1": F[0], "f2": F[1]}
    for name, value in truth.items():
        # the search stops at a relative step of 1e-10; the kinks make the last digits rough
        assert est[name] == pytest.approx(value, rel=1e-7, abs=1e-9), name


def test_validate_replays_on_a_fresh_record_with_its_own_initial_state():
    rng = np.random.default_rng(7)
    u = rng.uniform(-2.0, 2.0, N)
    est = fit_hammerstein(record(rng, difference_equation(dead_zone(u)), u), "deadzone")
    assert isinstance(est.model, Replayable)
    u2 = rng.uniform(-2.0, 2.0, N)
    fresh = record(rng, difference_equation(dead_zone(u2), state=(3.0, 2.5)), u2)
    report = validate(est, fresh)
    assert report.initial == "estimate"
    # noise σ = 0.02 on an output of std ≈ 1.2: a right model fits to about 98 %
    assert report.fit_percent > 97.0
    start = validate(est, fresh, initial="zero")
    assert start.fit_percent < report.fit_percent  # from rest, the start-up transient costs


def test_wiener_replay_fits_the_initial_state_through_the_static_curve():
    rng = np.random.default_rng(8)
    u = rng.uniform(-2.0, 2.0, N)
    x = difference_equation(u, b=(0.4, 0.2), f=(-1.1, 0.4))
    est = fit_wiener(record(rng, np.abs(x - CENTER), u), "abs")
    u2 = rng.uniform(-2.0, 2.0, N)
    x2 = difference_equation(u2, b=(0.4, 0.2), f=(-1.1, 0.4), state=(1.5, -0.5))
    fresh = record(rng, np.abs(x2 - CENTER), u2)
    y_sim, first, rule = est.model.replay(fresh["y"], fresh["u"])
    assert rule == "estimate" and first == 0
    # the first samples carry the initial state: matched to the noise level (5σ)
    assert np.max(np.abs(y_sim[:20] - fresh["y"][:20])) < 5 * SIGMA
    assert validate(est, fresh).fit_percent > 95.0


def test_hammerstein_wiener_runs_and_fits():
    rng = np.random.default_rng(9)
    u = rng.uniform(-2.0, 2.0, N)
    x = difference_equation(dead_zone(u))
    est = fit_hammerstein_wiener(record(rng, np.abs(x - 0.2), u), "deadzone", "abs")
    assert est.method == "hammerstein-wiener"
    assert est.names[0] == "input.deadzone.lower" and est.names[-1] == "output.abs.center"
    std = dict(zip(est.names, est.std, strict=True))
    for name, truth in (("input.deadzone.lower", LOWER), ("input.deadzone.upper", UPPER),
                        ("output.abs.center", 0.2)):
        assert abs(est[name] - truth) < 4 * std[name]  # 4σ


def test_continuous_linear_block_from_a_finely_integrated_plant():
    rng = np.random.default_rng(10)
    wn2, two_zeta_wn = 16.0, 3.2  # G(s) = 16/(s² + 3.2 s + 16)
    u = np.repeat(rng.uniform(-2.0, 2.0, N // 10), 10)
    v = dead_zone(u)
    # RK4 at 50 steps per sample of a held input: error far below the noise
    p, q, h, out = 0.0, 0.0, DT / 50, np.zeros(N)
    for t in range(N):
        out[t] = p
        w = wn2 * float(v[t])
        for _ in range(50):  # p' = q, q' = wn2·(v − p) − 2ζωn·q
            k1p, k1q = q, w - two_zeta_wn * q - wn2 * p
            k2p, k2q = q + h / 2 * k1q, w - two_zeta_wn * (q + h / 2 * k1q) - wn2 * (p + h / 2 * k1p)
            k3p, k3q = q + h / 2 * k2q, w - two_zeta_wn * (q + h / 2 * k2q) - wn2 * (p + h / 2 * k2p)
            k4p, k4q = q + h * k3q, w - two_zeta_wn * (q + h * k3q) - wn2 * (p + h * k3p)
            p += h / 6 * (k1p + 2 * k2p + 2 * k3p + k4p)
            q += h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
    est = fit_hammerstein(record(rng, out, u), "deadzone", linear="tf", n_poles=2, n_zeros=0)
    std = dict(zip(est.names, est.std, strict=True))
    for name, truth in (("a1", two_zeta_wn), ("a2", wn2), ("b0", wn2),
                        ("deadzone.lower", LOWER), ("deadzone.upper", UPPER)):
        assert abs(est[name] - truth) < 4 * std[name], name  # 4σ
    assert est.model.linear.dt is None


def test_free_scale_shape_fixes_the_linear_static_gain_to_one():
    rng = np.random.default_rng(11)
    u = rng.uniform(-1.5, 1.5, N)
    v = u + 0.3 * u**2 - 0.2 * u**3
    est = fit_hammerstein(record(rng, difference_equation(v), u), Polynomial.of_degree(3))
    lin = est.model.linear
    gain = lin.b[0].sum() / lin.f[0].sum()
    assert gain == pytest.approx(1.0, rel=1e-12)  # exact by construction, up to rounding
    # the true curve in this convention is G(1)·f: G(1) = 0.8/0.3
    scale = sum(B) / (1 + sum(F))
    std = dict(zip(est.names, est.std, strict=True))
    for k, c in enumerate((1.0, 0.3, -0.2), start=1):
        assert abs(est[f"poly.c{k}"] - scale * c) < 4 * std[f"poly.c{k}"]  # 4σ


def test_user_function_and_offset():
    rng = np.random.default_rng(12)
    u = rng.uniform(-2.0, 2.0, N)
    x = difference_equation(u, b=(0.4, 0.2), f=(-1.1, 0.4))
    data = record(rng, 1.5 * np.tanh(0.8 * x) + 0.7, u)

    def curve(z, th):
        return th[0] * np.tanh(th[1] * z)

    # th[1] absorbs any gain of G: the linear block's static gain is fixed to 1
    shape = StaticFunction(curve, [1.0, 1.0], labels=["gain", "slope"], has_free_scale=True)
    est = fit_wiener(data, shape, offset=True)
    std = dict(zip(est.names, est.std, strict=True))
    assert est.names[-3:] == ("f.gain", "f.slope", "offset")
    gain = sum((0.4, 0.2)) / (1 - 1.1 + 0.4)  # true G(1): the slope carries it
    for name, truth in (("offset", 0.7), ("f.gain", 1.5), ("f.slope", 0.8 * gain)):
        assert abs(est[name] - truth) < 4 * std[name], name  # 4σ
    # declared without a free scale, the same curve leaves G's gain and th[1] inseparable
    wrong = StaticFunction(curve, [1.0, 1.0], labels=["gain", "slope"], has_free_scale=False)
    with pytest.raises(IdentifiabilityError, match="f.slope"):
        fit_wiener(data, wrong, offset=True)


def test_replay_rules():
    linear = PolynomialModel([1.0], (B,), (1,), DT, f=((1.0, *F),))
    model = BlockModel("hammerstein", linear, DT, input_nonlinearity=DeadZone(LOWER, UPPER))
    u = np.linspace(-2, 2, 100)
    y = model.simulate(u)
    assert model.replay(y, u, initial="zero")[2] == "zero"
    np.testing.assert_allclose(model.replay(y, u)[0], y, atol=1e-9)  # from rest: state 0
    with pytest.raises(ModelError, match="ARX"):
        model.replay(y, u, initial="measured")
    with pytest.raises(DataError, match="one input"):
        model.simulate(np.ones((10, 2)))


# -- bad input ------------------------------------------------------------------------------


def _hammerstein_data(rng, u):
    return record(rng, difference_equation(dead_zone(u)), u)


def test_unknown_shape_name_lists_the_valid_ones():
    rng = np.random.default_rng(0)
    data = _hammerstein_data(rng, rng.uniform(-2, 2, 500))
    with pytest.raises(OptionError, match="deadzone"):
        fit_hammerstein(data, "dead-zone")


def test_breakpoints_in_the_wrong_order():
    with pytest.raises(DataError, match="wrong order"):
        DeadZone(0.5, -0.5)


def test_input_that_never_goes_below_the_dead_zone():
    rng = np.random.default_rng(1)
    u = rng.uniform(0.0, 2.0, 2000)  # never below LOWER = −0.4
    with pytest.raises(IdentifiabilityError, match="deadzone.lower"):
        fit_hammerstein(_hammerstein_data(rng, u), "deadzone")


def test_input_that_never_leaves_the_dead_zone():
    rng = np.random.default_rng(2)
    u = rng.uniform(-0.3, 0.5, 2000)  # inside [−0.4, 0.6]: the output is noise alone
    with pytest.raises(IdentifiabilityError):
        fit_hammerstein(_hammerstein_data(rng, u), "deadzone")


def test_two_free_scale_shapes_are_refused():
    rng = np.random.default_rng(3)
    data = _hammerstein_data(rng, rng.uniform(-2, 2, 500))
    with pytest.raises(IdentifiabilityError, match="gain"):
        fit_hammerstein_wiener(data, "polynomial", "piecewise-linear")


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"structure": "hammerstein", "output_nonlinearity": "abs",
      "input_nonlinearity": "deadzone"}, OptionError, "no output_nonlinearity"),
    ({"structure": "wiener"}, OptionError, "needs output_nonlinearity"),
    ({"structure": "hammerstein", "input_nonlinearity": 3}, OptionTypeError, "nonlinearity"),
    ({"structure": "narx", "input_nonlinearity": "abs"}, OptionError, "structure"),
    ({"structure": "hammerstein", "input_nonlinearity": "abs", "linear": "arx"},
     OptionError, "linear"),
    ({"structure": "hammerstein", "input_nonlinearity": "abs", "nb": 0}, DataError, "nb"),
])
def test_bad_options(kwargs, error, match):
    rng = np.random.default_rng(4)
    data = _hammerstein_data(rng, rng.uniform(-2, 2, 500))
    with pytest.raises(error, match=match):
        fit_block(data, **kwargs)


def test_wrapper_keywords_are_explicit():
    import inspect

    # every keyword is in the signature (help() lists it), so Python itself refuses a typo
    rng = np.random.default_rng(6)
    data = _hammerstein_data(rng, rng.uniform(-2, 2, 500))
    with pytest.raises(TypeError, match="n_b"):
        fit_hammerstein(data, "deadzone", n_b=2)
    with pytest.raises(TypeError, match="structure"):
        fit_hammerstein(data, "deadzone", structure="wiener")
    with pytest.raises(TypeError, match="output_nonlinearity"):
        fit_wiener(data, "abs", output_nonlinearity="abs")
    shared = set(inspect.signature(fit_block).parameters) - {
        "structure", "input_nonlinearity", "output_nonlinearity"}
    for wrapper in (fit_hammerstein, fit_wiener, fit_hammerstein_wiener):
        assert shared <= set(inspect.signature(wrapper).parameters), wrapper.__name__


def test_several_inputs_are_refused():
    rng = np.random.default_rng(5)
    u = rng.uniform(-2, 2, (500, 2))
    data = Experiment.from_arrays(DT, u=u, y=rng.standard_normal(500))
    with pytest.raises(DataError, match="one input"):
        fit_hammerstein(data, "abs")


def test_absolute_value_start_given():
    rng = np.random.default_rng(13)
    u = rng.uniform(-2.0, 2.0, N)
    x = difference_equation(u, b=(0.4, 0.2), f=(-1.1, 0.4))
    est = fit_wiener(record(rng, np.abs(x - CENTER), u), AbsoluteValue(0.1))
    assert est["abs.center"] == pytest.approx(CENTER, abs=0.01)  # 30σ of a good fit: converged


@pytest.mark.slow
def test_reported_standard_deviations_are_honest_over_many_seeds():
    """Normalised errors (θ̂ − θ)/σ̂ over 40 records: unit spread, 95 % inside ±2."""
    z = []
    for seed in range(40):
        rng = np.random.default_rng(1000 + seed)
        u = rng.uniform(-2.0, 2.0, N)
        est = fit_hammerstein(record(rng, difference_equation(dead_zone(u)), u), "deadzone")
        truth = np.array([LOWER, UPPER, *B, *F])
        z.append((est.parameters - truth) / est.std)
    z = np.array(z)
    # 240 normalised errors: their std lies within ±20 % of 1 unless the covariance is off
    assert 0.8 < z.std() < 1.2
    # Bin(240, 0.95) inside ±2σ: fewer than 216 has probability below 1e-3
    assert np.sum(np.abs(z) < 2) >= 216
