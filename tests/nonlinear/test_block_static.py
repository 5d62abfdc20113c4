"""The static shapes: values, parameter Jacobians, names, bounds and bad input."""

import numpy as np
import pytest

from servoid import DataError, ModelError, OptionTypeError
from servoid.nonlinear import (
    SHAPES,
    AbsoluteValue,
    DeadZone,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    SignedPower,
    StaticFunction,
    StaticNonlinearity,
)

X = np.array([-3.0, -1.0, -0.2, 0.0, 0.3, 1.0, 2.5])


@pytest.mark.parametrize(("shape", "expected"), [
    (DeadZone(-0.5, 1.0), [-2.5, -0.5, 0.0, 0.0, 0.0, 0.0, 1.5]),
    (Saturation(-1.0, 2.0), [-1.0, -1.0, -0.2, 0.0, 0.3, 1.0, 2.0]),
    (AbsoluteValue(0.5), [3.5, 1.5, 0.7, 0.5, 0.2, 0.5, 2.0]),
    (SignedPower(2.0), [-9.0, -1.0, -0.04, 0.0, 0.09, 1.0, 6.25]),
    (Polynomial([1.0, 0.0, 1.0]), [-30.0, -2.0, -0.208, 0.0, 0.327, 2.0, 18.125]),
    # slope 0.5 below −1, 2 between −1 and 1, 1 above 1; through the origin
    (PiecewiseLinear([-1.0, 1.0], [0.5, 2.0, 1.0]), [-3.0, -2.0, -0.4, 0.0, 0.6, 2.0, 3.5]),
])
def test_values(shape, expected):
    np.testing.assert_allclose(shape(X), expected, rtol=1e-12, atol=1e-15)  # exact arithmetic


@pytest.mark.parametrize("shape", [
    DeadZone(-0.5, 1.0), Saturation(-1.0, 2.0), AbsoluteValue(0.5), SignedPower(1.7),
    Polynomial([1.0, -0.3, 0.2]), PiecewiseLinear([-1.0, 1.0], [0.5, 2.0, 1.0]),
    StaticFunction(lambda x, th: th[0] * np.tanh(th[1] * x), [1.5, 0.8]),
])
def test_jacobian_matches_central_differences(shape):
    x = np.linspace(-2.9, 2.9, 41) + 0.013  # off every breakpoint: the curves are smooth there
    theta = shape.parameters
    jac = shape.jacobian(x)
    assert jac.shape == (x.size, theta.size)
    for k in range(theta.size):
        h = np.zeros(theta.size)
        h[k] = 1e-6
        fd = (shape.evaluate(x, theta + h) - shape.evaluate(x, theta - h)) / 2e-6
        np.testing.assert_allclose(jac[:, k], fd, atol=1e-6)  # central difference: O(h²) + ε/h


def test_names_bounds_and_scale_flags():
    assert DeadZone(0, 1).names == ("deadzone.lower", "deadzone.upper")
    assert Saturation(0, 1).names == ("saturation.lower", "saturation.upper")
    assert AbsoluteValue().names == ("abs.center",)
    assert SignedPower().names == ("power.exponent",)
    assert Polynomial([1, 2]).names == ("poly.c1", "poly.c2")
    assert PiecewiseLinear([0.0]).names == ("pwl.s0", "pwl.s1")
    assert SignedPower().bounds[0][0] > 0  # the exponent stays positive in a fit
    assert not DeadZone(0, 1).free_scale and Polynomial([1]).free_scale
    assert StaticFunction(lambda x, th: th[0] * x, [1.0], has_free_scale=False).free_scale is False
    assert set(SHAPES) == {"abs", "deadzone", "piecewise-linear", "polynomial", "power",
                           "saturation"}
    assert all(isinstance(s, StaticNonlinearity) for s in (DeadZone(0, 1), Polynomial([1])))


def test_with_parameters_returns_a_new_frozen_shape():
    dz = DeadZone(-1.0, 1.0)
    moved = dz.with_parameters([-0.5, 0.5])
    assert (moved.lower, moved.upper) == (-0.5, 0.5) and (dz.lower, dz.upper) == (-1.0, 1.0)
    with pytest.raises(DataError, match="2 values"):
        dz.with_parameters([1.0])
    with pytest.raises(AttributeError):
        dz.lower = 3.0  # frozen


@pytest.mark.parametrize(("make", "error", "match"), [
    (lambda: DeadZone(1.0, -1.0), DataError, "wrong order"),
    (lambda: Saturation(2.0, 1.0), DataError, "wrong order"),
    (lambda: DeadZone("a", 1.0), OptionTypeError, "lower"),
    (lambda: SignedPower(-1.0), DataError, "exponent"),
    (lambda: PiecewiseLinear([1.0, 0.0]), DataError, "increasing"),
    (lambda: PiecewiseLinear([0.0], [1.0]), DataError, "slopes"),
    (lambda: Polynomial([]), DataError, "coefficients"),
    (lambda: StaticFunction(3, [1.0]), OptionTypeError, "function"),
    (lambda: StaticFunction(lambda x, th: x[:2], [1.0]), ModelError, "shaped like x"),
    (lambda: StaticFunction(lambda x, th: 1 / 0, [1.0]), ModelError, "ZeroDivisionError"),
    (lambda: StaticFunction(lambda x, th: x, [1.0], lower=[2.0]), DataError, "bounds"),
    (lambda: Polynomial.of_degree(0), DataError, "degree"),
])
def test_bad_shapes(make, error, match):
    with pytest.raises(error, match=match):
        make()
