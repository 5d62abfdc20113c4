"""Residual correlations at the lags used: known answers against plain numpy, linear cost."""

import tracemalloc

import numpy as np
import pytest
from scipy import signal as sps
from scipy import stats

from servoid.signals import prbs
from servoid.validate import _residuals as res_mod
from servoid.validate import fit_percent, nrmse, relative_error, residual_analysis, rmse, vaf

N = 3000
M = 10


def direct(a, b, lags):
    """Σ_t a(t)·b(t + τ) for each τ (zero outside the record), one np.dot per lag."""
    n = a.size
    return np.array(
        [
            a[max(0, -t) : n - max(0, t)] @ b[max(0, t) : n - max(0, -t)] if abs(t) < n else 0.0
            for t in lags
        ]
    )


def centred(x):
    x = x - x.mean()
    return x / np.abs(x).max()


def reference(e, u, max_lag, confidence=0.99, causal=False):
    """residual_analysis written out with plain numpy: shifted copies, no tricks."""
    n = e.size
    e = centred(e)
    lags = np.arange(max_lag + 1)
    auto = direct(e, e, lags) / (e @ e)
    q = n * (n + 2) * np.sum(auto[1:] ** 2 / (n - lags[1:]))
    p_white = stats.chi2.sf(q, max_lag)
    uu = np.asarray(u, dtype=float).reshape(n, -1)
    cols = [centred(c) for c in uu.T]
    two = np.arange(-max_lag, max_lag + 1)
    cross = np.array([direct(c, e, two) / np.sqrt((c @ c) * (e @ e)) for c in cols])
    if p_white > 1 - confidence:
        # Cov(√N r)[(i,τ),(j,τ')] = Σ_s u_i(s − τ)u_j(s − τ')/(‖u_i‖‖u_j‖): shifted copies
        def shifted(c, tau):
            out = np.zeros(n)
            out[max(tau, 0) : n + min(tau, 0)] = c[max(-tau, 0) : n - max(tau, 0)]
            return out

        x = np.column_stack([shifted(c, t) / np.linalg.norm(c) for c in cols for t in two])
        cov = x.T @ x
    else:
        k_max = int(min(4 * max_lag, n // 4))
        ks = np.arange(-k_max, k_max + 1)
        rho = direct(e, e, ks) / (e @ e) * (1 - np.abs(ks) / (k_max + 1))
        blocks = []
        for ci in cols:
            row = []
            for cj in cols:
                reach = np.arange(-(2 * max_lag + k_max), 2 * max_lag + k_max + 1)
                s_ij = direct(ci, cj, reach)
                d = two[:, None] - two[None, :]
                # Σ_k ρ(k)·S_ij(k + d)
                row.append(
                    np.array([[rho @ s_ij[ks + dd + reach[-1]] for dd in dr] for dr in d])
                    / (np.linalg.norm(ci) * np.linalg.norm(cj))
                )
            blocks.append(row)
        cov = np.block(blocks)
    r = cross.ravel()
    if causal:
        keep = np.tile(two >= 0, len(cols))
        r, cov = r[keep], cov[np.ix_(keep, keep)]
    eig, vec = np.linalg.eigh(cov)
    keep = eig > eig[-1] * cov.shape[0] * np.finfo(float).eps
    stat = n * np.sum((vec[:, keep].T @ r) ** 2 / eig[keep])
    return auto, cross, p_white, stats.chi2.sf(stat, keep.sum())


@pytest.mark.parametrize(
    ("n", "first", "last"),
    [(10, 0, 9), (100, 0, 3), (5000, 0, 25), (5000, 26, 100), (4099, 1, 50), (2048, 0, 2047)],
)
def test_lag_products_against_one_dot_per_lag(n, first, last):
    rng = np.random.default_rng(n + first)
    a, b = rng.normal(size=n), rng.normal(size=n)
    got = res_mod._lag_products(a, b, first, last)
    want = direct(a, b, np.arange(first, last + 1))
    # blocked, vectorised sums: rounding only, ε·√N·‖a‖‖b‖ at most
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.sqrt(n) * n)


def test_lagged_sums_are_exact_where_a_padded_fft_would_wrap():
    # 2M + K beyond N − 1: an FFT of length 2^⌈log2 2N⌉ aliases those lags; direct sums are 0
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=60), rng.normal(size=60)
    got = res_mod._lagged_sums(a, b, 73)
    want = direct(a, b, np.arange(-73, 74))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.all(got[np.abs(np.arange(-73, 74)) >= 60] == 0.0)


@pytest.mark.parametrize(
    ("name", "causal"),
    [
        ("white", False),
        ("ar1", False),
        ("ar1", True),
        ("prbs", False),
        ("two inputs", False),
        ("dependent", False),
    ],
)
def test_known_answers_against_plain_numpy(name, causal):
    rng = np.random.default_rng(7)
    w = rng.normal(size=N)
    u = rng.normal(size=N)
    e = w
    if name in ("ar1",):
        e = sps.lfilter([1.0], [1.0, -0.6], w)
    if name == "prbs":
        u = prbs(11, clock=10, periods=2).values[:N]
    if name == "two inputs":
        u = rng.normal(size=(N, 2))
        e = sps.lfilter([1.0], [1.0, -0.6], w)
    if name == "dependent":
        e = w + 0.2 * np.r_[0.0, 0.0, u[:-2]]
    got = residual_analysis(e, u, M, causal=causal)
    auto, cross, p_white, p_indep = reference(e, u, M, causal=causal)
    # the correlations at each lag: rounding of sums of N products of unit-scale values
    np.testing.assert_allclose(got.autocorrelation, auto, rtol=0, atol=1e-13)
    np.testing.assert_allclose(got.cross_correlation, cross, rtol=0, atol=1e-13)
    # p-values: χ² tails of statistics equal to ~1e-12 relative
    assert got.whiteness_pvalue == pytest.approx(p_white, rel=1e-9, abs=1e-300)
    assert got.independence_pvalue == pytest.approx(p_indep, rel=1e-8, abs=1e-300)
    assert got.is_white == (name in ("white", "prbs", "dependent"))


def test_scale_invariance_and_no_overflow_near_1e150():
    rng = np.random.default_rng(3)
    e = sps.lfilter([1.0], [1.0, -0.3], rng.normal(size=N))
    u = rng.normal(size=N)
    unit = residual_analysis(e, u, M)
    big = residual_analysis(1e150 * (1.0 + 1e-3 * e), 1e150 * u, M)
    # the centring subtracts 1e150 exactly enough to keep ~13 digits of the 1e147 signal
    np.testing.assert_allclose(big.autocorrelation, unit.autocorrelation, rtol=0, atol=1e-10)
    np.testing.assert_allclose(big.cross_correlation, unit.cross_correlation, rtol=0, atol=1e-10)
    assert big.whiteness_pvalue == pytest.approx(unit.whiteness_pvalue, rel=1e-6, abs=1e-300)
    assert np.isfinite(big.independence_pvalue)


def test_memory_is_a_few_copies_of_the_record():
    rng = np.random.default_rng(4)
    n = 200_000
    e, u = rng.normal(size=n), rng.normal(size=n)
    residual_analysis(e, u)  # kernels compiled / loaded outside the measurement
    tracemalloc.start()
    try:
        residual_analysis(e, u)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # the centred e and u (and one temporary while centring): an FFT padded to 2N would need
    # ~2^19 complex values per spectrum, several at once
    assert peak < 4 * 8 * n


@pytest.mark.parametrize("shape", [(500,), (500, 3)])
def test_metric_sums_against_numpy(shape):
    rng = np.random.default_rng(6)
    y = np.cumsum(rng.normal(size=shape), axis=0) + 100.0
    y_hat = y + 0.1 * rng.normal(size=shape)
    spread = np.linalg.norm(y - y.mean(axis=0), axis=0)
    err = np.linalg.norm(y - y_hat, axis=0)
    # rounding only: sums of 500 terms in another order
    np.testing.assert_allclose(nrmse(y, y_hat), err / spread, rtol=1e-13)
    np.testing.assert_allclose(fit_percent(y, y_hat), 100 * (1 - err / spread), rtol=1e-13)
    np.testing.assert_allclose(
        rmse(y, y_hat), np.sqrt(np.mean((y - y_hat) ** 2, axis=0)), rtol=1e-13
    )
    np.testing.assert_allclose(
        vaf(y, y_hat), 100 * (1 - np.var(y - y_hat, axis=0) / np.var(y, axis=0)), rtol=1e-13
    )
    np.testing.assert_allclose(
        relative_error(y, y_hat), 100 * err / np.linalg.norm(y, axis=0), rtol=1e-13
    )
    assert np.shape(nrmse(y, y_hat)) == shape[1:]
