"""RLS passes: known answers against a plain numpy recursion, the Gram pass, memory, guards."""

import tracemalloc
import warnings

import numpy as np
import pytest
from scipy import linalg

from servoid import ServoidWarning
from servoid.estimate import _rls_kernel as kernel
from servoid.estimate import fit_rls, lstsq

TRUE = np.array([2e-3, 4e2, 1.0])


def regressors(seed, n_rows=3000, n=3):
    # columns a million apart in size, as in test_rls: the normalisation has work to do
    rng = np.random.default_rng(seed)
    cols = [1e3 * rng.normal(size=n_rows), 1e-3 * (rng.normal(size=n_rows) + 0.5)]
    cols += [np.full(n_rows, 5.0)] + [rng.normal(size=n_rows) for _ in range(n - 3)]
    return np.column_stack(cols[:n])


def numpy_rls(phi, y, lam, p0, cap, guard):
    """The textbook recursion of the previous fit_rls, in scaled units, with plain numpy."""
    scale = np.sqrt(np.sum(phi**2, axis=0))
    phi_s = phi / scale
    n_rows, n = phi.shape
    theta = np.zeros(n)
    p = np.eye(n) * p0
    prior, post, hist, traces, events = [], [], [], [], 0
    for t in range(n_rows):
        f = phi_s[t]
        q = p @ f
        denom = lam + f @ q
        alpha = y[t] - f @ theta
        theta = theta + q / denom * alpha
        p = (p - np.outer(q, q) / denom) / lam
        p = 0.5 * (p + p.T)
        if guard != "none" and np.trace(p) > cap:
            events += 1
            p = p * (cap / np.trace(p)) if guard == "bound" else np.eye(n) * p0
        prior.append(alpha)
        post.append(y[t] - f @ theta)
        hist.append(theta / scale)
        traces.append(np.trace(p))
    w = lam ** np.arange(n_rows - 1, -1, -1.0)
    resid = y - phi_s @ theta
    sigma2 = float(w @ resid**2) / (w.sum() - n)
    r = linalg.qr(phi_s * np.sqrt(w)[:, None], mode="r")[0][:n]
    hinv = linalg.inv(r.T @ r)
    g = (phi_s * w[:, None]).T @ (phi_s * w[:, None])
    cov = sigma2 * hinv @ g @ hinv / np.outer(scale, scale)
    return {
        "theta": theta / scale,
        "p": p / np.outer(scale, scale),
        "prior": np.array(prior),
        "post": np.array(post),
        "hist": np.array(hist),
        "traces": np.array(traces),
        "events": events,
        "sigma2": sigma2,
        "cov": cov,
    }


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 9])
@pytest.mark.parametrize(("lam", "guard"), [(1.0, "bound"), (0.99, "bound"), (0.95, "reset")])
def test_known_answer_against_the_numpy_recursion(n, lam, guard):
    rng = np.random.default_rng(n)
    phi = regressors(n, n_rows=1500, n=max(n, 3))[:, :n]
    phi[900:, -1] = 0.0  # the last column falls silent: forgetting winds P up, the guard acts
    y = phi @ rng.normal(size=n) + 0.01 * rng.normal(size=phi.shape[0])
    cap = 1e8 * n / 3 if lam < 1 else 1e8 * n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        got = fit_rls(phi, y, forgetting=lam, guard=guard, max_trace=cap, history=True)
    ref = numpy_rls(phi, y, lam, 1e8, cap, guard)
    assert got.guard_events == ref["events"]
    # the same recursion in other coordinates and order of operations: rounding, amplified
    # by cond(P) — far below any statistical scale
    np.testing.assert_allclose(
        got.theta, ref["theta"], rtol=1e-9, atol=1e-12 * np.abs(ref["theta"]).max()
    )
    np.testing.assert_allclose(
        got.history, ref["hist"], rtol=1e-7, atol=1e-9 * np.abs(ref["hist"]).max()
    )
    np.testing.assert_allclose(got.trace_history, ref["traces"], rtol=1e-7)
    scale_y = np.abs(y).max()
    np.testing.assert_allclose(got.prior_residuals, ref["prior"], atol=1e-8 * scale_y)
    np.testing.assert_allclose(got.posterior_residuals, ref["post"], atol=1e-8 * scale_y)
    assert got.estimate.noise_variance == pytest.approx(ref["sigma2"], rel=1e-8)
    if lam == 1.0:  # with forgetting the silent column's variance rests on λ^600-weighted data
        np.testing.assert_allclose(got.covariance, ref["cov"], rtol=1e-8, atol=0)


@pytest.mark.parametrize("n", [1, 2, 4, 6, 8])
def test_generated_kernel_returns_the_loops_bits(n):
    rng = np.random.default_rng(10 + n)
    phi = rng.normal(size=(800, n)) * np.logspace(-2, 2, n)
    phi[500:, 0] = 0.0
    y = phi @ np.arange(1.0, n + 1) + 0.1 * rng.normal(size=800)
    sc2 = np.sum(phi**2, axis=0)
    for lam, guard in [(1.0, 0), (0.97, 0), (0.97, 1), (0.97, 2)]:
        args = (phi, y, np.zeros(n), 1e6 / sc2, sc2, lam, 1e6 * n, guard)
        outs = []
        for run in (kernel._generated("rls", n, True, True, True), kernel._rls_loop):
            series = (np.empty(800), np.empty(800), np.empty((800, n)), np.empty(800))
            outs.append((run(*args, *series), series))
        (res_a, ser_a), (res_b, ser_b) = outs
        for a, b in zip((*res_a[:2], *ser_a), (*res_b[:2], *ser_b), strict=True):
            np.testing.assert_array_equal(a, b)  # same operations, same order: same bits
        assert res_a[2:] == res_b[2:]


def test_pipelined_recursion_equals_the_textbook_one():
    # q_{t+1} and d_{t+1} from P_t (module notes) against q = P_{t+1}φ computed afresh
    rng = np.random.default_rng(3)
    phi = rng.normal(size=(400, 3))
    y = phi @ [1.0, -2.0, 0.5] + 0.1 * rng.normal(size=400)
    run = kernel.rls_pass(
        phi,
        y,
        np.zeros(3),
        np.full(3, 1e4),
        np.ones(3),
        0.98,
        1e300,
        2,
        np.empty(0),
        np.empty(0),
        np.empty((0, 3)),
        np.empty(0),
    )
    theta, p = np.zeros(3), np.eye(3) * 1e4
    for t in range(400):
        q = p @ phi[t]
        d = 0.98 + phi[t] @ q
        theta = theta + q * (y[t] - phi[t] @ theta) / d
        p = (p - np.outer(q, q) / d) / 0.98
    np.testing.assert_allclose(run.theta, theta, rtol=1e-12)  # rounding over 400 steps
    np.testing.assert_allclose(run.p, p, rtol=1e-10, atol=1e-14 * np.abs(p).max())


def test_tracks_a_parameter_step_with_the_forgetting_time_constant():
    rng = np.random.default_rng(4)
    n_rows, lam, half = 20000, 0.995, 10000
    phi = rng.normal(size=(n_rows, 2))
    before, after = np.array([1.0, 2.0]), np.array([1.5, 2.0])
    y = np.where(np.arange(n_rows) < half, phi @ before, phi @ after)
    res = fit_rls(phi, y, forgetting=lam, history=True)
    err = np.abs(res.history[:, 0] - after[0]) / (after[0] - before[0])
    # white regressors: the step's share of the estimate decays like λ^k; a factor 2 for the
    # sample fluctuation of the weighted Gram matrix (as in test_rls)
    for k in (200, 600, 1200):
        assert 0.5 * lam**k < err[half + k] < 2 * lam**k
    # noise-free after the step: once λ^k is below rounding the estimate is exact
    np.testing.assert_allclose(res.theta, after, rtol=1e-9)


@pytest.mark.filterwarnings("ignore:rls. the final memory window")
def test_reset_restores_p0_and_the_trace_history_shows_it():
    rng = np.random.default_rng(5)
    phi = rng.normal(size=(3000, 2))
    phi[400:, 1] = 0.0
    y = phi @ [1.0, -2.0]
    with pytest.warns(ServoidWarning, match="'reset'"):
        res = fit_rls(phi, y, forgetting=0.95, p0=1e4, guard="reset", history=True)
    # the samples where the guard acted record P₀'s trace, 2·p₀ (to the unit-norm scaling's
    # rounding); between them the trace stays below the cap
    at_p0 = np.isclose(res.trace_history, 2e4, rtol=1e-12, atol=0)
    assert res.guard_events == np.count_nonzero(at_p0) > 0
    assert np.all(res.trace_history <= 2e4 * (1 + 1e-12))
    np.testing.assert_allclose(res.theta, [1.0, -2.0], rtol=1e-9)  # noise-free: still exact


def test_guard_cannot_act_at_lambda_one_unless_the_cap_is_below_p0():
    phi = regressors(6)
    y = phi @ TRUE
    assert fit_rls(phi, y).guard_events == 0
    with pytest.warns(ServoidWarning, match="covariance guard"):
        low = fit_rls(phi, y, max_trace=1e7, history=True)
    # λ = 1 only shrinks P: the cap is met once, at the first sample, and never again
    assert low.guard_events == 1 and low.trace_history[0] == pytest.approx(1e7, rel=1e-12)


def test_noise_variance_from_the_recursion_equals_the_direct_sum():
    rng = np.random.default_rng(7)
    phi = regressors(7)
    y = phi @ TRUE + 0.3 * rng.normal(size=phi.shape[0])
    for lam in (1.0, 0.998):
        res = fit_rls(phi, y, forgetting=lam)
        w = lam ** np.arange(y.size - 1, -1, -1.0)
        direct = float(w @ (y - phi @ res.theta) ** 2) / (w.sum() - 3)
        # J_N minus the prior's share: no cancellation, ε·(prior share / RSS) at most
        assert res.estimate.noise_variance == pytest.approx(direct, rel=1e-10)


def test_residuals_are_kept_only_when_asked_and_recomputed_identically():
    rng = np.random.default_rng(8)
    phi = regressors(8, n_rows=2000)
    y = phi @ TRUE + 0.01 * rng.normal(size=2000)
    lazy = fit_rls(phi, y, forgetting=0.99)
    kept = fit_rls(phi, y, forgetting=0.99, residuals=True)
    assert lazy.history is None and lazy.trace_history is None
    np.testing.assert_array_equal(lazy.prior_residuals, kept.prior_residuals)  # same pass
    np.testing.assert_array_equal(lazy.posterior_residuals, kept.posterior_residuals)
    np.testing.assert_array_equal(lazy.theta, kept.theta)
    np.testing.assert_allclose(lazy.estimate.residuals, y - phi @ lazy.theta, rtol=0, atol=0)


def test_no_allocation_of_the_record_size_and_no_qr():
    rng = np.random.default_rng(9)
    phi = rng.normal(size=(200_000, 4))
    y = phi @ [1.0, 2.0, 3.0, 4.0] + rng.normal(size=200_000)
    fit_rls(phi, y)  # compile / load the kernels outside the measurement
    tracemalloc.start()
    try:
        res = fit_rls(phi, y)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # numpy reports its buffers to tracemalloc: one float64 series would be 1.6 MB
    assert peak < 0.2 * 8 * y.size
    np.testing.assert_allclose(res.theta, lstsq(phi, y).theta, rtol=1e-8)  # prior 1/p₀


def test_no_qr_of_the_regressor(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("QR of the regressor")

    monkeypatch.setattr(linalg, "qr", refuse)
    monkeypatch.setattr(np.linalg, "qr", refuse)
    phi = regressors(10)
    res = fit_rls(phi, phi @ TRUE, forgetting=0.999)
    np.testing.assert_allclose(res.theta, TRUE, rtol=1e-7)


@pytest.mark.parametrize("n", [1, 3, 6, 7])
@pytest.mark.parametrize("lam", [1.0, 0.999])
def test_gram_pass_against_numpy(n, lam):
    rng = np.random.default_rng(n)
    phi = rng.normal(size=(3 * kernel.BLOCK + 17, n)) * np.logspace(-3, 3, n)
    gram, h, g = kernel.gram_pass(phi, lam)
    scale = np.sqrt(np.outer(np.diag(gram), np.diag(gram)))
    np.testing.assert_allclose(gram, phi.T @ phi, rtol=0, atol=1e-13 * scale.max())
    if lam == 1.0:
        assert h is None and g is None
        return
    w = lam ** np.arange(phi.shape[0] - 1, -1, -1.0)
    for got, weights in ((h, w), (g, w**2)):
        want = (phi * weights[:, None]).T @ phi
        tol = 1e-13 * np.sqrt(np.outer(np.diag(want), np.diag(want)))  # summation rounding
        assert np.all(np.abs(got - want) <= tol)


def test_non_finite_regressor_is_found_by_the_gram_diagonal():
    phi = regressors(11, n_rows=100)
    phi[7, 2] = np.inf
    with pytest.raises(ValueError, match="finite"):
        fit_rls(phi, np.zeros(100))
    phi[7, 2] = 1e200  # finite, but its square is not
    with pytest.raises(ValueError, match="overflow"):
        fit_rls(phi, np.zeros(100))


def test_rank_test_from_the_gram_matrix_matches_qr():
    phi = regressors(12)
    res = fit_rls(phi, phi @ TRUE)
    r = linalg.qr(phi / np.linalg.norm(phi, axis=0), mode="r")[0][:3]
    s = np.linalg.svd(r, compute_uv=False)
    # cond from the Gram eigenvalues is the square root of cond²: ε·cond² relative
    assert res.estimate.options["condition"] == pytest.approx(s[0] / s[-1], rel=1e-10)
