"""PolynomialModel: simulation, prediction, conversion and validation."""

import math

import numpy as np
import pytest

from servoid import DataError, ModelError
from servoid.models import PolynomialModel

DT = 1e-3
A = np.array([1.0, -1.5, 0.7])
B = np.array([0.5, 0.3])


def direct_loop(a, b, nk, u, y_past=(), u_past=()):
    """y(t) = −Σ a_j y(t−j) + Σ b_j u(t−nk−j), with explicit past values (most recent first)."""
    n = len(u)
    y = np.zeros(n)

    def yv(t):
        return y[t] if t >= 0 else (y_past[-t - 1] if -t - 1 < len(y_past) else 0.0)

    def uv(t):
        return u[t] if t >= 0 else (u_past[-t - 1] if -t - 1 < len(u_past) else 0.0)

    for t in range(n):
        y[t] = -sum(a[j] * yv(t - j) for j in range(1, len(a))) + sum(
            b[j] * uv(t - nk - j) for j in range(len(b))
        )
    return y


@pytest.fixture
def u():
    return np.random.default_rng(0).normal(size=300)


def test_simulate_equals_difference_equation(u):
    m = PolynomialModel.arx(A, B, 2, DT)
    # both are the same recursion; rounding only
    assert np.allclose(m.simulate(u), direct_loop(A, B, 2, u), rtol=0, atol=1e-12)


def test_simulate_honours_initial_conditions(u):
    m = PolynomialModel.arx(A, B, 1, DT)
    y_past, u_past = [0.4, -0.2], [1.0, 2.0]
    got = m.simulate(u, y_init=y_past, u_init=u_past)
    assert np.allclose(got, direct_loop(A, B, 1, u, y_past, u_past), rtol=0, atol=1e-12)
    assert not np.allclose(got, m.simulate(u))


def test_simulate_two_inputs_with_f_polynomials(u):
    u2 = np.column_stack([u, np.cos(np.arange(u.size))])
    f1 = np.array([1.0, -0.3])
    m = PolynomialModel(A, (B, np.array([1.0])), (0, 3), DT, f=(f1, np.ones(1)))
    # the same model built from two one-input parts, superposed
    part0 = PolynomialModel([1.0], (B,), (0,), DT, f=(np.convolve(A, f1),))
    part1 = PolynomialModel.arx(A, [1.0], 3, DT)
    expected = part0.simulate(u2[:, 0]) + part1.simulate(u2[:, 1])
    assert np.allclose(m.simulate(u2), expected, rtol=0, atol=1e-12)  # rounding only
    assert m.structure == "general" and m.nf == (1, 0) and m.n_inputs == 2


def test_predict_one_step_of_arx_is_the_regression(u):
    m = PolynomialModel.arx(A, B, 1, DT)
    y = m.simulate(u) + np.random.default_rng(1).normal(scale=0.1, size=u.size)
    yp, up = np.concatenate([[0.0, 0.0], y]), np.concatenate([[0.0, 0.0, 0.0], u])
    t = np.arange(u.size)
    phi = np.column_stack(
        [-yp[t + 1], -yp[t], up[t + 2], up[t + 1]]
    )  # y(t-1), y(t-2), u(t-1), u(t-2)
    theta = np.concatenate([A[1:], B])
    assert np.allclose(m.predict(y, u, 1), phi @ theta, rtol=0, atol=1e-12)  # same sums
    assert np.allclose(m.residuals(y, u), y - phi @ theta, rtol=0, atol=1e-12)


def test_predict_long_horizon_is_simulation(u):
    m = PolynomialModel(A, (B,), (1,), DT, c=[1.0, 0.5], d=[1.0, -0.2])
    y = m.simulate(u) + np.random.default_rng(2).normal(size=u.size)
    sim = m.simulate(u)
    assert np.array_equal(m.predict(y, u, None), sim)
    assert np.array_equal(m.predict(y, u, math.inf), sim)
    # H's impulse response decays like 0.84^k (poles of A): 0.84^400 ≈ 1e-30
    assert np.allclose(m.predict(y, u, 400), sim, rtol=0, atol=1e-10)


def test_predict_k_step_armax_matches_explicit_recursion(u):
    # ARMAX A y = B u + C e: one-step predictor C ŷ = (C − A) y + B u, run explicitly
    c = np.array([1.0, 0.5])
    m = PolynomialModel(A, (B,), (0,), DT, c=c)
    y = m.simulate(u) + np.random.default_rng(3).normal(size=u.size)
    yhat = np.zeros(u.size)
    for t in range(u.size):
        val = -c[1] * (yhat[t - 1] if t else 0.0)
        val += sum(
            ((c[j] if j < c.size else 0.0) - A[j]) * (y[t - j] if t >= j else 0.0)
            for j in range(1, 3)
        )
        val += B[0] * u[t] + B[1] * (u[t - 1] if t else 0.0)
        yhat[t] = val
    assert np.allclose(m.predict(y, u, 1), yhat, rtol=0, atol=1e-10)  # rounding only
    assert m.structure == "armax"


def test_oe_predictor_is_simulation_for_any_horizon(u):
    m = PolynomialModel([1.0], (B,), (1,), DT, f=([1.0, -0.6],))
    y = np.random.default_rng(4).normal(size=u.size)
    assert m.structure == "oe"
    assert np.allclose(m.predict(y, u, 3), m.simulate(u), rtol=0, atol=1e-12)  # H = 1


def test_transfer_function_of_arx_has_the_right_poles():
    m = PolynomialModel.arx(A, B, 2, DT)
    g = m.transfer_function()
    assert g.dt == DT
    assert np.allclose(
        np.sort_complex(g.poles()[np.abs(g.poles()) > 0]), np.sort_complex(np.roots(A)), rtol=1e-12
    )  # ε·cond of degree-2 roots
    # q⁻² (0.5 + 0.3 q⁻¹)/A in z: (0.5z + 0.3)/(z(z² − 1.5z + 0.7)), one pole at the origin
    assert np.sum(np.abs(g.poles()) == 0) == 1
    impulse = g.impulse(6).y
    pulse = np.zeros(6)
    pulse[0] = 1.0
    assert np.allclose(impulse, m.simulate(pulse), atol=1e-14)  # same filter
    h = m.noise_transfer_function()
    assert np.allclose(np.sort_complex(h.poles()), np.sort_complex(np.roots(A)), rtol=1e-12)


def test_round_trip_through_transfer_function():
    m = PolynomialModel.arx(A, B, 2, DT)
    back = m.transfer_function().to_polynomial()
    assert back.nk == (2,) and back.structure == "arx"
    assert np.allclose(back.a, A) and np.allclose(back.b[0], B)  # exact up to one division
    oe = m.transfer_function().to_polynomial("oe")
    assert oe.structure == "oe" and np.allclose(oe.f[0], A)


def test_properties_and_read_only():
    m = PolynomialModel(
        A,
        (B,),
        1,
        DT,
        c=[1.0, 0.2],
        d=[1.0, 0.1],
        f=([1.0, 0.3],),
        noise_variance=0.5,
        input_names=("i_c",),
        output_name="y",
    )
    assert (m.na, m.nb, m.nc, m.nd, m.nf) == (2, (2,), 1, 1, (1,))
    assert m.structure == "general"
    assert PolynomialModel([1.0], (B,), (0,), DT, c=[1, 0.2], f=([1, 0.3],)).structure == "bj"
    with pytest.raises(ValueError, match="read-only"):
        m.a[0] = 2.0
    with pytest.raises(ValueError, match="read-only"):
        m.b[0][0] = 2.0


def test_arx_accepts_several_inputs():
    m = PolynomialModel.arx(A, [B, [1.0, 2.0, 3.0]], [0, 2], DT)
    assert m.n_inputs == 2 and m.nb == (2, 3) and m.nk == (0, 2)
    assert PolynomialModel.arx(A, [B, B], 1, DT).nk == (1, 1)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"a": [2.0, 1.0]}, ModelError, r"a must be monic"),
        ({"c": [0.5, 1.0]}, ModelError, r"c must be monic"),
        ({"f": ([1.0], [1.0])}, ModelError, "one polynomial per input"),
        ({"nk": (-1,)}, ModelError, ">= 0"),
        ({"nk": (0, 1)}, ModelError, "one delay per input"),
        ({"dt": 0.0}, ModelError, "dt must be > 0"),
        ({"dt": None}, ModelError, "discrete-time only"),
        ({"dt": True}, TypeError, "dt must be a float"),
        ({"b": np.array([1.0, 2.0])}, TypeError, "one per input"),
        ({"noise_variance": -1.0}, ModelError, ">= 0"),
        ({"input_names": ("a", "b")}, ModelError, "input_names"),
        ({"a": [1.0, np.nan]}, ModelError, "finite"),
    ],
)
def test_bad_construction_raises(kwargs, error, match):
    args = {"a": A, "b": (B,), "nk": (0,), "dt": DT} | kwargs
    with pytest.raises(error, match=match):
        PolynomialModel(**args)


def test_bad_signals_raise(u):
    m = PolynomialModel.arx(A, B, 0, DT)
    with pytest.raises(DataError, match=r"u must have shape \(N,\) or \(N, 1\)"):
        m.simulate(np.ones((10, 2)))
    with pytest.raises(DataError, match="y must have shape"):
        m.predict(np.ones(5), u)
    with pytest.raises(ModelError, match="horizon must be an int >= 1"):
        m.predict(u, u, 0)
    with pytest.raises(DataError, match="most recent first"):
        m.simulate(u, y_init=np.ones((2, 2)))
