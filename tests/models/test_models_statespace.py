"""StateSpace: simulation, invariants and conversion."""

import numpy as np
import pytest
from scipy import signal

from servoid import DataError, ModelError
from servoid.models import StateSpace, TransferFunction, c2d

RNG_SEED = 7


def random_ss(n=4, m=2, p=3, dt=None, seed=RNG_SEED):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n)) - 3 * np.eye(n)
    ss = StateSpace(a, rng.normal(size=(n, m)), rng.normal(size=(p, n)), rng.normal(size=(p, m)))
    return ss if dt is None else c2d(ss, dt)


def test_similarity_leaves_frequency_response_unchanged():
    ss = random_ss(dt=0.05)
    t = np.random.default_rng(1).normal(size=(4, 4)) + 4 * np.eye(4)
    w = np.logspace(-1, 1.8, 40)
    # ε·cond(T) per entry
    assert np.allclose(ss.similarity(t).freqresp(w), ss.freqresp(w), rtol=1e-10, atol=1e-12)
    assert ss.similarity(t).method == "zoh"
    with pytest.raises(ModelError, match="invertible"):
        ss.similarity(np.zeros((4, 4)))


def test_discrete_simulate_matches_dlsim_with_initial_state():
    ss = random_ss(dt=0.05)
    u = np.random.default_rng(2).normal(size=(500, 2))
    x0 = np.array([1.0, -1.0, 0.5, 0.0])
    _, ref, _ = signal.dlsim((ss.A, ss.B, ss.C, ss.D, ss.dt), u, x0=x0)
    # modal form costs ε·cond(V) (< 1e6 by construction)
    assert np.allclose(ss.simulate(u, x0), ref, rtol=0, atol=1e-9)


def test_defective_a_falls_back_to_the_time_loop():
    ss = StateSpace([[0.9, 1.0], [0.0, 0.9]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], 0.1)
    u = np.ones(50)
    _, ref, _ = signal.dlsim((ss.A, ss.B, ss.C, ss.D, 0.1), u)
    assert np.allclose(ss.simulate(u), ref[:, 0], rtol=0, atol=1e-12)  # same recursion


def test_continuous_simulate_is_zoh_exact():
    ss = random_ss(m=1, p=1)
    u = np.random.default_rng(3).normal(size=200)
    y = ss.simulate(u, dt=0.01)
    # lsim with ZOH-held input samples reproduces the sampled output to its accuracy
    _, ref, _ = signal.lsim((ss.A, ss.B, ss.C, ss.D), u, np.arange(200) * 0.01, interp=False)
    assert np.allclose(y, ref, rtol=0, atol=1e-9)
    with pytest.raises(ModelError, match="needs dt"):
        ss.simulate(u)


def test_poles_dc_gain_and_to_tf():
    ss = random_ss()
    g = ss.to_tf(input=1, output=2)
    w = np.array([0.3, 3.0])
    assert np.allclose(g.freqresp(w), ss.freqresp(w)[:, 2, 1], rtol=1e-10)  # ss2tf rounding
    dc = ss.dc_gain()
    assert dc.shape == (3, 2)
    assert dc[2, 1] == pytest.approx(g.dc_gain(), rel=1e-10)
    assert np.allclose(np.sort_complex(ss.poles()), np.sort_complex(g.poles()), rtol=1e-8)
    integ = TransferFunction([1.0], [1.0, 1.0, 0.0]).to_ss()
    assert integ.dc_gain() == np.inf


def test_shapes_and_validation():
    ss = StateSpace([[-1.0]], [1.0], [2.0], 0.0)  # 1-D B/C read as column/row, scalar D
    assert ss.B.shape == (1, 1) and ss.C.shape == (1, 1) and ss.is_siso
    with pytest.raises(ValueError, match="read-only"):
        ss.A[0, 0] = 1.0
    with pytest.raises(ModelError, match="A must be square"):
        StateSpace(np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((1, 3)), [[0.0]])
    with pytest.raises(ModelError, match="B must have 2 rows"):
        StateSpace(np.eye(2), np.zeros((3, 1)), np.zeros((1, 2)), [[0.0]])
    with pytest.raises(ModelError, match="D must have shape"):
        StateSpace(np.eye(2), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((2, 2)))
    with pytest.raises(DataError, match="x0 must have shape"):
        c2d(ss, 0.1).simulate(np.ones(3), x0=[1.0, 2.0])
    with pytest.raises(DataError, match=r"u must have shape \(N, 2\)"):
        random_ss(dt=0.1).simulate(np.ones(5))
    with pytest.raises(ModelError, match="out of range"):
        ss.to_tf(input=1)
