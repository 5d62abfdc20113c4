"""to_polynomial (state space → output-error form) and the InnovationModel of fit_n4sid."""

import numpy as np
import pytest

from servoid import Experiment, ModelError, ServoidWarning
from servoid.estimate import InnovationModel, fit_n4sid, to_polynomial
from servoid.models import PolynomialModel, StateSpace

DT = 0.01
OMEGA = np.linspace(0.5, 0.95 * np.pi / DT, 50)  # up to 95 % of Nyquist [rad/s]
# MISO, order 3, no feed-through; one complex pair and a real pole, non-diagonal basis
A = np.array([[0.9, 0.25, 0.0], [-0.25, 0.9, 0.1], [0.0, 0.0, 0.5]])
B = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, -0.3]])
C = np.array([[1.0, 0.0, 2.0]])
MISO = StateSpace(A, B, C, np.zeros((1, 2)), dt=DT)


def poly_response(pm, i):
    """Frequency response of input i of a polynomial model, via its transfer function."""
    return pm.transfer_function(i).freqresp(OMEGA)


@pytest.mark.parametrize("structure", ["oe", "arx"])
def test_round_trip_miso(structure):
    pm = to_polynomial(MISO, structure)
    assert isinstance(pm, PolynomialModel)
    assert pm.structure == structure and pm.nk == (1, 1) and pm.nb == (3, 3)
    for i in range(2):
        g = MISO.freqresp(OMEGA)[:, 0, i]
        # the same rational function, coefficients from Markov parameters: rounding only
        assert np.max(np.abs(poly_response(pm, i) - g)) < 1e-12 * np.max(np.abs(g))
    # the denominator is the characteristic polynomial of A, from the same eigenvalues
    np.testing.assert_allclose(  # rounding of np.poly on |λ| < 1: a few ε
        pm.f[0] if structure == "oe" else pm.a, np.poly(np.linalg.eigvals(A)).real, atol=1e-14
    )


def test_feedthrough_and_delays():
    d = StateSpace(A, B, C, [[0.3, 0.0]], dt=DT)
    pm = to_polynomial(d)
    assert pm.nk == (0, 1)  # input 0 has D ≠ 0; input 1 starts one sample later
    assert pm.nb == (4, 3) and pm.b[0][0] == pytest.approx(0.3, rel=1e-15)  # b0 = D


def test_explicit_delay_drops_leading_coefficients():
    # input 1's first Markov parameter C·B[:, 1] = 1·1 + 2·(−0.3) = 0.4 is dropped: warn
    with pytest.warns(ServoidWarning, match=r"nk\[1\] = 2 drops"):
        pm = to_polynomial(MISO, nk=[1, 2])
    assert pm.nk == (1, 2) and pm.nb == (3, 2)


def test_state_space_similarity_invariant():
    t = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, -1.0], [0.5, 0.0, 2.0]])  # det 1
    a, b = to_polynomial(MISO), to_polynomial(MISO.similarity(t))
    for x, y in zip(a.b + a.f, b.b + b.f, strict=True):
        np.testing.assert_allclose(x, y, atol=1e-12)  # ε·cond(T) ≈ 1e-15·10


def test_n4sid_parameters_are_the_polynomial_coefficients():
    """est.parameters = to_polynomial(est.model): (b, then f), the layout fit_oe uses."""
    u = np.random.default_rng(0).standard_normal((3000, 2))
    exp = Experiment.from_arrays(DT, u=u, y=MISO.simulate(u))
    est = fit_n4sid(exp, 3)
    pm = to_polynomial(est.model)
    # the same numerators() computation on the same model: identical up to rounding
    np.testing.assert_allclose(est.parameters, np.concatenate([*pm.b, pm.f[0][1:]]), atol=1e-12)
    assert est.names == ("u0:b0", "u0:b1", "u0:b2", "u1:b0", "u1:b1", "u1:b2", "f1", "f2", "f3")
    for i in range(2):  # noise-free data inside the structure: recovered to rounding
        g = MISO.freqresp(OMEGA)[:, 0, i]
        assert np.max(np.abs(poly_response(pm, i) - g)) < 1e-8 * np.max(np.abs(g))


def test_bad_models():
    with pytest.raises(ModelError, match="one output"):
        to_polynomial(StateSpace(A, B, np.eye(3)[:2], np.zeros((2, 2)), dt=DT))
    with pytest.raises(ModelError, match="discrete-time.*c2d"):
        to_polynomial(StateSpace(-np.eye(2), np.ones((2, 1)), np.ones((1, 2)), 0.0))
    with pytest.raises(TypeError, match="StateSpace"):
        to_polynomial("model")


# -- innovation form -----------------------------------------------------------------------------

K_TRUE = np.array([[0.5], [0.3], [-0.2]])
A1 = np.array([[0.9, 0.2, 0.0], [0.0, 0.7, 0.1], [0.0, 0.0, 0.3]])
B1, C1 = np.array([[0.0], [1.0], [0.5]]), np.array([[1.0, 0.0, 0.5]])


def innovation_record(n, sigma, seed):
    """x(t+1) = A x + B u + K e, y = C x + e: an innovation-form (ARMAX-like) record."""
    rng = np.random.default_rng(seed)
    u, e = rng.standard_normal(n), sigma * rng.standard_normal(n)
    gen = StateSpace(A1, np.hstack([B1, K_TRUE]), C1, [[0.0, 1.0]], dt=DT)
    return Experiment.from_arrays(DT, u=u, y=gen.simulate(np.column_stack([u, e]))), e


def test_kalman_gain_recovers_the_noise_model():
    exp, e = innovation_record(40000, 0.2, 7)
    est = fit_n4sid(exp, 3)
    im = InnovationModel.from_estimate(est)
    # the noise model H = C(zI − A)⁻¹K + 1 is basis-free; compare away from DC, where H is
    # small: its error is statistical, ~1/√N = 0.5 %, and 0.02 is 4× that
    z = np.exp(1j * OMEGA[10:] * DT)
    def noise_tf(a, k, c):
        return np.array([(c @ np.linalg.solve(zi * np.eye(3) - a, k))[0, 0] + 1 for zi in z])
    h_true, h_est = noise_tf(A1, K_TRUE, C1), noise_tf(est.model.A, im.gain, est.model.C)
    assert np.max(np.abs(h_est - h_true) / np.abs(h_true)) < 0.02
    # innovation variance: relative sd √(2/N) = 0.7 %; 4σ plus the finite-horizon state error
    assert im.noise_covariance[0, 0] == pytest.approx(0.04, rel=0.04)
    # the one-step predictor's errors are the innovations (after its transient)
    pred = im.predict(exp["y"], exp["u"])
    err = exp["y"][200:] - pred[200:]
    assert np.std(err - e[200:]) < 0.1 * np.std(e)  # estimation error of H, a few % of e


def test_predictor_shapes_and_errors():
    model = StateSpace([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=DT)
    im = InnovationModel(model, np.array([[0.5]]), np.array([[0.01]]))
    p = im.predictor()
    assert p.n_inputs == 2 and p.A[0, 0] == pytest.approx(0.4, rel=1e-15)  # 0.9 − 0.5: exact
    assert im.predict(np.zeros(5), np.zeros(5)).shape == (5,)
    with pytest.raises(ModelError, match=r"gain must have shape \(1, 1\)"):
        InnovationModel(model, np.ones((2, 1)), np.eye(1))
    with pytest.raises(ModelError, match="discrete StateSpace"):
        InnovationModel(StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), np.eye(1), np.eye(1))


def test_no_kalman_gain_from_noise_free_data():
    u = np.random.default_rng(1).standard_normal(2000)
    est = fit_n4sid(Experiment.from_arrays(DT, u=u, y=MISO.simulate(np.column_stack([u, u]))), 3)
    with pytest.raises(ModelError, match="no Kalman gain.*noise-free"):
        InnovationModel.from_estimate(est)
