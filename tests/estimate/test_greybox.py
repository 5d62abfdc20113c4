"""Grey-box ODE fit: mass-spring-damper known answer, 4σ, fixed subsets, bounds, divergence."""

import numpy as np
import pytest
from scipy import signal as sps

from servoid import ConvergenceError, DataError, Experiment, OptionError, ServoidWarning
from servoid.estimate import GreyboxModel, GreyboxParameter, fit_greybox

DT = 0.01
N = 600
M, C, K = 2.0, 3.0, 200.0  # ω_n = 10 rad/s, ζ = 0.106
T = np.arange(N) * DT


def msd_rhs(t, x, u, theta):
    m, c, k = theta
    return np.array([x[1], (u[0] - c * x[1] - k * x[0]) / m])


def force(seed):
    # a held multilevel force, changing every 5 samples: rich below 10 Hz
    rng = np.random.default_rng(seed)
    return np.repeat(rng.normal(size=N // 5), 5) * 10.0


def msd_record(seed, sigma=(0.0, 0.0), theta=(M, C, K)):
    """Position and velocity, exact ZOH discretisation (scipy), plus white noise."""
    m, c, k = theta
    a = np.array([[0.0, 1.0], [-k / m, -c / m]])
    b = np.array([[0.0], [1.0 / m]])
    ad, bd, *_ = sps.cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), DT, method="zoh")
    u = force(seed)
    x = np.zeros((N, 2))
    for i in range(N - 1):
        x[i + 1] = ad @ x[i] + bd[:, 0] * u[i]
    rng = np.random.default_rng(1000 + seed)
    y = x + rng.normal(size=(N, 2)) * np.asarray(sigma)
    return Experiment.from_arrays(
        DT, u=u, y=y, names={"y": ["pos", "vel"]}, units={"pos": "m", "vel": "m/s"}
    )


def start_parameters(fixed_m=False):
    return [
        GreyboxParameter("m", M if fixed_m else 1.5, 0.1, 10.0, "kg", fixed_m, "log"),
        GreyboxParameter("c", 2.0, 0.0, 50.0, "N·s/m", False, "log"),
        ("k", 150.0, 1.0, 1e4, "N/m"),
    ]


def test_noise_free_recovery():
    est = fit_greybox(msd_record(0), msd_rhs, [0.0, 0.0], start_parameters(), substeps=4)
    # RK4 with 4 substeps at ω_n h = 0.025: local error (ωh)⁵/120 ≈ 1e-10 → bias ≪ 1e-6
    np.testing.assert_allclose(est.parameters, [M, C, K], rtol=1e-6)
    assert est.names == ("m", "c", "k") and est.units == ("kg", "N·s/m", "N/m")
    assert isinstance(est.model, GreyboxModel) and est.model["k"] == pytest.approx(K, rel=1e-6)
    assert est.model.simulate().shape == (N, 2)
    assert est.options["outputs"] == ["pos", "vel"] and est.method == "greybox"


def test_noise_free_recovery_with_solve_ivp_and_one_output():
    rec = msd_record(0).slice(0, 100)  # an adaptive solver with a Python rhs is slow: 1 s
    est = fit_greybox(
        rec,
        msd_rhs,
        [0.0, 0.0],
        start_parameters(),
        outputs=["pos"],
        output=[0],
        integrator="solve_ivp",
        ivp_options={"method": "LSODA", "rtol": 1e-9, "atol": 1e-12},
    )
    np.testing.assert_allclose(est.parameters, [M, C, K], rtol=1e-6)  # integrator rtol 1e-9
    assert est.options["diff_step"] == pytest.approx(np.sqrt(1e-9))  # above the rtol jitter


def test_noise_within_four_sigma():
    sigma = np.array([1e-4, 2e-3])  # position ≈ 5e-2 m, velocity ≈ 0.5 m/s peak
    for seed in range(3):
        est = fit_greybox(
            msd_record(seed, sigma), msd_rhs, [0.0, 0.0], start_parameters(), noise_std=sigma
        )
        assert np.all(np.abs(est.parameters - [M, C, K]) < 4 * est.std), seed  # 4σ
        # weights 1/σ_j: σ̂² is χ²_(2N−3)/(2N−3) ≈ 1 ± 0.04; 4σ ≈ 0.16
        assert est.noise_variance == pytest.approx(1.0, abs=0.16)
        lo, hi = est.confidence_intervals(0.95).T
        assert np.all(lo < est.parameters) and np.all(est.parameters < hi)


def test_fixed_subset():
    est = fit_greybox(
        msd_record(0), msd_rhs, [0.0, 0.0], start_parameters(fixed_m=True), substeps=4
    )
    assert est.names == ("c", "k") and est.covariance.shape == (2, 2)
    assert est.options["fixed"] == {"m": M}
    np.testing.assert_allclose(est.parameters, [C, K], rtol=1e-6)  # RK4 bias, as above
    assert est.model.free == (False, True, True)


def test_output_map_and_tuple_data():
    rec = msd_record(0)
    data = (rec.time, rec.u[:, 0], rec["pos"])

    def position_mm(x, u, theta):
        return 1e3 * x[:, :1]

    est = fit_greybox(
        (data[0], data[1], data[2] * 1e3),
        msd_rhs,
        [0.0, 0.0],
        start_parameters(),
        output=position_mm,
        substeps=4,
    )
    np.testing.assert_allclose(est.parameters, [M, C, K], rtol=1e-6)


def test_compiled_simulator_route():
    rec = msd_record(0)
    calls = []

    def simulate(theta):
        calls.append(theta.copy())
        return msd_record(0, theta=tuple(theta)).y

    est = fit_greybox(rec, None, None, start_parameters(), simulate=simulate)
    np.testing.assert_allclose(est.parameters, [M, C, K], rtol=1e-8)  # same simulator: exact
    assert len(calls) >= est.options["nfev"]  # plus the start check and the Jacobians
    assert est.options["integrator"] == "simulate"


def test_start_outside_bounds_names_the_parameter():
    params = start_parameters()
    params[1] = GreyboxParameter("c", 60.0, 0.0, 50.0)
    with pytest.raises(DataError, match=r"parameter 'c': start value 60.0 lies outside"):
        fit_greybox(msd_record(0), msd_rhs, [0.0, 0.0], params)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ([("m", 1.0, 2.0, 1.0)], "bounds need lower < upper"),
        ([("m", -1.0, -5.0, 5.0, "", False, "log")], "log-transformed and needs a value > 0"),
        ([("m", 1.0, 0.0, 5.0, "", True)], "every parameter is fixed"),
        ([("m", 1.0), ("m", 2.0)], "names must be unique"),
    ],
)
def test_bad_parameters(params, match):
    with pytest.raises(DataError, match=match):
        fit_greybox(msd_record(0), msd_rhs, [0.0, 0.0], params)


def test_bad_options():
    rec = msd_record(0)
    with pytest.raises(OptionError, match="integrator must be one of"):
        fit_greybox(rec, msd_rhs, [0.0, 0.0], start_parameters(), integrator="euler")
    with pytest.raises(DataError, match="method='lm' does not take bounds"):
        fit_greybox(rec, msd_rhs, [0.0, 0.0], start_parameters(), method="lm")
    with pytest.raises(DataError, match="noise_std or weights, not both"):
        fit_greybox(rec, msd_rhs, [0.0, 0.0], start_parameters(), noise_std=1, weights=1)
    with pytest.raises(DataError, match="outputs of shape"):
        fit_greybox(rec, msd_rhs, [0.0, 0.0], start_parameters(), output=[0])
    with pytest.raises(TypeError, match="GreyboxParameter or"):
        fit_greybox(rec, msd_rhs, [0.0, 0.0], ["m"])


def unstable_rhs(t, x, u, theta):
    # a = theta[0]: stable for a < 0; the data come from a = −2
    return np.array([theta[0] * x[0] + u[0]])


def first_order_record():
    u = force(5)
    ad, bd = np.exp(-2.0 * DT), (1 - np.exp(-2.0 * DT)) / 2.0
    y = np.zeros(N)
    for i in range(N - 1):
        y[i + 1] = ad * y[i] + bd * u[i]
    return Experiment.from_arrays(DT, u=u, y=y)


def test_divergent_trial_steps_are_rejected_not_fatal():
    # the same model written as ẋ = −exp(log(−a))·x + u: NaN for every a ≥ 0. From a = −20 the
    # first Gauss–Newton steps overshoot past 0 (checked); those trials must be rejected
    tried = []

    def rhs(t, x, u, theta):
        tried.append(theta[0])
        return np.array([-np.exp(np.log(-theta[0])) * x[0] + u[0]])

    est = fit_greybox(first_order_record(), rhs, [0.0], [("a", -20.0, -50.0, 400.0)], substeps=2)
    assert max(tried) > 0  # a divergent trial happened
    assert est["a"] == pytest.approx(-2.0, rel=1e-6)  # RK4 vs exact ZOH: (2h)⁴/120 ≪ 1e-6


def test_divergence_at_the_start_raises():
    with pytest.raises(ConvergenceError, match="diverges .* at the start values"):
        fit_greybox(first_order_record(), unstable_rhs, [0.0], [("a", 300.0, -50.0, 400.0)])


def test_divergence_at_the_optimum_raises():
    # a model that fits only where it blows up: outputs beyond t = 3 s are NaN for a > 1
    def simulate(theta):
        y = np.zeros(N)
        y[N // 2 :] = theta[0]
        if theta[0] > 1.0:
            y[-1] = np.nan
        return y

    data = (T, np.zeros(N), np.where(T >= T[N // 2], 5.0, 0.0))
    with pytest.raises(ConvergenceError, match="diverges at or next to the solver's final point"):
        fit_greybox(data, None, None, [("a", 1.0, -10.0, 10.0)], simulate=simulate)


def test_warns_on_a_bound():
    params = start_parameters()
    params[2] = ("k", 150.0, 1.0, 180.0, "N/m")  # truth 200 lies beyond the bound
    with pytest.warns(ServoidWarning, match="k = 180 ends on its upper bound"):
        fit_greybox(msd_record(0), msd_rhs, [0.0, 0.0], params)
