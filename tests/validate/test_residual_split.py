"""The residual lag sums of a long record, in two halves on two threads.

From ``_SPLIT`` residuals on, ``_split_sums`` runs the sweep over the two
halves of the record at once (the second on a worker thread) and adds them
in a fixed order, so the numbers must not depend on whether a thread was
used, and must be the lag products themselves (numpy's dot products of the
centred signals; 1e-12 relative is the rounding of two blocked sums).
"""

import multiprocessing as mp
import sys

import numba
import numpy as np
import pytest

from servoid.validate import _residuals as R


def _centred(x):
    return R._Centred.of(x, float(np.mean(x)))


def _signals(n, seed=0):
    rng = np.random.default_rng(seed)
    u = 2.0 + rng.standard_normal(n)
    e = np.convolve(rng.standard_normal(n + 3), [1.0, 0.5, 0.2], "valid")[:n]
    return e, u


N = 2 * R._SPLIT + 4097  # both halves, a partial last block


def test_split_sums_are_the_lag_products():
    e, u = _signals(N)
    ce, cu = _centred(e), _centred(u)
    ee, ue, eu, uu = R._fused_sums(ce, cu, 7)
    ec, uc = (e - ce.mean) * ce.scale, (u - cu.mean) * cu.scale

    def lagged(a, b, k):
        return np.dot(a[: N - k], b[k:])

    np.testing.assert_allclose(ee, [lagged(ec, ec, k) for k in range(8)], rtol=1e-12)
    np.testing.assert_allclose(ue, [lagged(uc, ec, k) for k in range(8)], rtol=1e-12)
    np.testing.assert_allclose(eu, [lagged(ec, uc, k) for k in range(8)], rtol=1e-12)
    np.testing.assert_allclose(uu, [lagged(uc, uc, k) for k in range(15)], rtol=1e-12)
    far = R._centred_lags(cu, cu, 20, 33)  # the pair kernel goes through the same split
    np.testing.assert_allclose(far, [lagged(uc, uc, k) for k in range(20, 34)], rtol=1e-12)


def test_a_thread_changes_no_digit(monkeypatch):
    e, u = _signals(N, 1)
    ce, cu = _centred(e), _centred(u)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    assert R._worker() is not None
    threaded = R._fused_sums(ce, cu, 25), R._centred_lags(ce, cu, 3, 40)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    assert R._worker() is None  # as in a fleet worker: both halves on the calling thread
    serial = R._fused_sums(ce, cu, 25), R._centred_lags(ce, cu, 3, 40)
    for got, want in zip(threaded[0], serial[0], strict=True):
        assert np.array_equal(got, want)
    assert np.array_equal(threaded[1], serial[1])


def test_a_short_record_is_one_sweep(monkeypatch):
    calls = []

    def kernel(*args):
        calls.append(args[-2:])
        return np.zeros(1)

    R._split_sums(kernel, R._SPLIT - 1, "x")
    R._split_sums(kernel, N, "x")
    half = (N // 2 // R.BLOCK) * R.BLOCK
    assert sorted(calls) == [(0, R._SPLIT - 1), (0, half), (half, N)]


def _child(conn):
    e, u = _signals(N, 2)
    conn.send(R._fused_sums(_centred(e), _centred(u), 5))
    conn.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork start method")
def test_a_forked_child_gets_its_own_worker(monkeypatch):
    # the parent's worker thread does not exist in a forked child: it must make its own
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    e, u = _signals(N, 2)
    want = R._fused_sums(_centred(e), _centred(u), 5)  # the parent's pool exists now
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send,), daemon=True)
    proc.start()
    try:
        assert recv.poll(30), "the forked child hung on the parent's worker"
        got = recv.recv()
    finally:
        proc.terminate()
        proc.join(10)
    for g, w in zip(got, want, strict=True):
        assert np.array_equal(g, w)
