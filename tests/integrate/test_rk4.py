"""The one RK4 step: its arithmetic, its hooks, compiled and plain."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from servoid.integrate import advance, keep, rk4_step

A = np.array([[0.0, 1.0], [-40.0, -1.5]])  # a damped oscillator, ω_n ≈ 6.3 rad/s


@numba.njit(inline="always")
def _oscillator(t, x, w, ctx):  # type: ignore[no-untyped-def]
    return x[1], -40.0 * x[0] - 1.5 * x[1] + w


@numba.njit(inline="always")
def _oscillator_array(t, x, w, ctx):  # type: ignore[no-untyped-def]
    out = np.empty(2)
    out[0] = x[1]
    out[1] = -40.0 * x[0] - 1.5 * x[1] + w
    return out


@numba.njit
def _tuple_steps(x0, w, h, n):  # type: ignore[no-untyped-def]
    x = (x0[0], x0[1])
    for i in range(n):
        x, _ = rk4_step(_oscillator, keep, i * h, x, w, 0.0, h)
    return np.array([x[0], x[1]])


@numba.njit
def _array_steps(x0, w, h, n):  # type: ignore[no-untyped-def]
    x = x0.copy()
    for i in range(n):
        x, _ = rk4_step(_oscillator_array, keep, i * h, x, w, 0.0, h)
    return x


def _rk4_matrix(h: float) -> np.ndarray:
    """One RK4 step of ẋ = A x is the 4th-order Taylor polynomial of e^{hA}."""
    m = h * A
    return np.eye(2) + m + m @ m / 2 + m @ m @ m / 6 + m @ m @ m @ m / 24


def test_one_step_is_the_taylor_polynomial_of_the_exponential() -> None:
    x0 = np.array([0.3, -0.7])
    h = 1e-2
    want = _rk4_matrix(h) @ x0
    got = _tuple_steps(x0, 0.0, h, 1)
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=1e-16)  # a few ulps of arithmetic


def test_tuple_array_and_python_states_give_the_same_numbers() -> None:
    x0 = np.array([0.3, -0.7])
    a = _tuple_steps(x0, 0.5, 1e-3, 500)
    b = _array_steps(x0, 0.5, 1e-3, 500)
    c = x0.copy()
    for i in range(500):
        c, _ = rk4_step.py_func(_oscillator.py_func, keep.py_func, i * 1e-3, c, 0.5, 0.0, 1e-3)
    d = (0.3, -0.7)
    for i in range(500):
        d, _ = rk4_step.py_func(_oscillator.py_func, keep.py_func, i * 1e-3, d, 0.5, 0.0, 1e-3)
    np.testing.assert_array_equal(a, b)  # the same operations in the same order
    np.testing.assert_array_equal(a, c)
    np.testing.assert_array_equal(a, np.array(d))


@pytest.mark.parametrize("h", [4e-2, 2e-2, 1e-2])
def test_global_error_is_fourth_order(h: float) -> None:
    # free response against e^{tA}: halving h divides the error by 2⁴ = 16
    x0 = np.array([1.0, 0.0])
    t_end = 1.0
    n = round(t_end / h)
    exact = _expm(t_end * A) @ x0
    err = np.abs(_tuple_steps(x0, 0.0, h, n) - exact).max()
    err_half = np.abs(_tuple_steps(x0, 0.0, h / 2, 2 * n) - exact).max()
    assert 12.0 < err / err_half < 20.0  # 16 up to the next term of the expansion


def test_post_hook_sees_the_state_before_the_step() -> None:
    seen = []

    def rates(t, x, w, ctx):  # type: ignore[no-untyped-def]
        return (1.0,)

    def post(t, x_new, x_old, w, ctx):  # type: ignore[no-untyped-def]
        seen.append((t, x_old[0], x_new[0]))
        return (min(x_new[0], 0.25),)  # an end stop at 0.25

    x = (0.0,)
    for i in range(4):
        x, _ = rk4_step.py_func(rates, post, 0.1 * i, x, None, None, 0.1)
    assert seen[0] == pytest.approx((0.1, 0.0, 0.1))
    assert seen[-1][1] == 0.25 and seen[-1][2] == pytest.approx(0.35)
    assert x == (0.25,)


def test_extra_values_of_the_rates_come_back_with_the_first_stage() -> None:
    def rates(t, x, w, ctx):  # type: ignore[no-untyped-def]
        return -x[0], 7.0 * x[0]  # one rate and one output computed on the way

    x, k1 = rk4_step.py_func(rates, keep.py_func, 0.0, (2.0,), None, None, 0.1)
    assert k1 == (-2.0, 14.0)
    assert x[0] == pytest.approx(2.0 * math.exp(-0.1), rel=1e-7)  # RK4: error O(h⁵)


def test_advance_runs_several_steps() -> None:
    @numba.njit
    def run(x0, h, n):  # type: ignore[no-untyped-def]
        x = advance(_oscillator, keep, 0.0, (x0[0], x0[1]), 0.0, 0.0, h, n)
        return np.array([x[0], x[1]])

    x0 = np.array([0.3, -0.7])
    np.testing.assert_array_equal(run(x0, 1e-3, 200), _tuple_steps(x0, 0.0, 1e-3, 200))


def _expm(m: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eig(m)
    return (vectors @ np.diag(np.exp(values)) @ np.linalg.inv(vectors)).real
