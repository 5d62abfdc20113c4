"""ARX(3, 4, 0) by least squares: servoid's routes against plain numpy baselines.

Cases
-----
well-conditioned
    White-noise input through a stable 3rd-order ARX system (poles 0.9, 0.7,
    0.5) with equation-error noise, fixed seed; N = 1e4, 1e5, 1e6.
ill-conditioned
    A heavily oversampled slow system (poles 0.995, 0.99, 0.985: continuous
    poles near −5, −10, −15 rad/s sampled at 1 kHz): the scaled condition
    number is ~5e4 > GRAM_COND_LIMIT, so the auto route must fall back to QR.
    With unit DC gain the b coefficients are ~4e-7, far below what N = 1e5
    noisy samples determine statistically: this case tests the numerics
    (agreement with QR), not parameter recovery.

Methods
-------
fit_arx auto / gram / qr
    ``servoid.estimate.fit_arx(exp, 3, 4, 0, method=...)`` with the
    Experiment built outside the timed region. Residuals are computed lazily
    (``Estimate.residuals`` is a cached property), so this is the solve plus
    model/covariance bookkeeping, not a simulation.
kernel lagged_gram+solve_gram
    The Gram route's numerical core on the (y, u) channel views that
    ``_signals`` returns: the one-pass numba Gram kernel and the 7×7 scaled
    Cholesky solve. No Experiment access, no constant-input check, no
    model/covariance bookkeeping.
breakdown: ...
    Pieces of ``fit_arx``'s Gram route timed alone, to show where the time goes.
numpy column-slice Φ + lstsq
    Φ = column_stack of lagged slices, ``numpy.linalg.lstsq`` (SVD-based).
lagged np.dot normal equations
    One ``np.dot`` of two lagged slices per Gram entry (36 for the augmented
    8×8), then ``numpy.linalg.solve`` of the unscaled normal equations.

Accuracy: ``rel_diff`` = max_i |θ_i − θ_QR,i| / |θ_QR,i| against
``fit_arx(..., method="qr")`` on the same data; target ≤ 1e-8.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from _harness import Result, measure_memory, rel_diff, time_call
from scipy import signal as sps

SUITE = "arx"
_QUICK = False  # set by run(): --quick skips the memory pass and the breakdown rows
NA, NB, NK = 3, 4, 0
DT = 1e-3
SEED = 20261121
WELL_POLES = (0.9, 0.7, 0.5)
ILL_POLES = (0.995, 0.99, 0.985)
B_SHAPE = np.array([0.5, 0.3, 0.2, 0.1])
NOISE_STD = 0.05


def make_record(n: int, poles: tuple[float, ...], seed: int = SEED):  # type: ignore[no-untyped-def]
    """White-noise u through A(q) y = B(q) u + e; returns (u, y, a, b)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    e = NOISE_STD * rng.standard_normal(n)
    a = np.real(np.poly(poles))
    b = B_SHAPE * (a.sum() / B_SHAPE.sum())  # unit DC gain
    y = sps.lfilter(b, a, u) + sps.lfilter([1.0], a, e)
    return u, y, a, b


def _ls_to_params(theta: np.ndarray) -> np.ndarray:
    """Regression θ with +y lags → servoid's parameters (a1…a_na, b0…)."""
    out = np.array(theta, dtype=float)
    out[:NA] = -out[:NA]
    return out


def _columns() -> list[tuple[int, int]]:
    """(signal, lag) of each regressor column; signal 0 = y, 1 = u."""
    return [(0, k) for k in range(1, NA + 1)] + [(1, NK + j) for j in range(NB)]


def numpy_lstsq(y: np.ndarray, u: np.ndarray):  # type: ignore[no-untyped-def]
    """Baseline: build Φ by column slicing, solve with numpy.linalg.lstsq."""
    z = (y, u)
    n, start = y.size, max(NA, NK + NB - 1)
    phi = np.column_stack([z[s][start - lag : n - lag] for s, lag in _columns()])
    theta, _, _, sv = np.linalg.lstsq(phi, y[start:], rcond=None)
    return _ls_to_params(theta), float(sv[0] / sv[-1])


def lagged_dot_normal_equations(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Baseline: one np.dot per entry of the augmented Gram matrix, unscaled solve."""
    z = (y, u)
    n, start = y.size, max(NA, NK + NB - 1)
    cols = [*_columns(), (0, 0)]
    m = len(cols)
    views = [z[s][start - lag : n - lag] for s, lag in cols]
    g = np.empty((m, m))
    for p in range(m):
        for q in range(p, m):
            g[p, q] = g[q, p] = np.dot(views[p], views[q])
    theta = np.linalg.solve(g[:-1, :-1], g[:-1, -1])
    return _ls_to_params(theta)


def _internals():  # type: ignore[no-untyped-def]
    """servoid's private Gram-route pieces, or None if they moved."""
    try:
        from servoid.estimate._arx import ArxOrders, _check_not_constant, _signals
        from servoid.estimate._gram import lagged_gram
        from servoid.estimate._ls import solve_gram
    except ImportError:
        return None
    return ArxOrders, _check_not_constant, _signals, lagged_gram, solve_gram


def _repeats(n: int, quick: bool, slow: bool = False) -> int:
    if quick:
        return 3
    if n <= 10**4:
        return 20
    if n <= 10**5:
        return 15 if not slow else 9
    return 10 if not slow else 7


def _bench(
    case: str,
    n: int,
    method: str,
    fn: Callable[[], object],
    repeats: int,
    theta_of: Callable[[object], np.ndarray] | None,
    ref: np.ndarray | None,
    memory: bool = True,
) -> tuple[Result, object]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the forced-gram fallback warns on purpose
        out = fn()  # warm-up (numba compile / cache load) and the value for accuracy
        timing = time_call(fn, repeats, warmup=0)
        mem = measure_memory(fn) if memory and not _QUICK else None
    res = Result(
        suite=SUITE,
        case=case,
        n=n,
        method=method,
        median_ms=timing.median * 1e3,
        best_ms=timing.best * 1e3,
        repeats=repeats,
        peak_mb=None if mem is None else mem.tracemalloc_peak / 2**20,
        rss_mb=None if mem is None or mem.rss_peak_delta is None else mem.rss_peak_delta / 2**20,
    )
    res.minflt = timing.minor_faults_per_call
    res.extra["times_ms"] = [round(t * 1e3, 4) for t in timing.times]
    if timing.sys_s_per_call is not None:
        res.extra["sys_ms_per_call"] = round(timing.sys_s_per_call * 1e3, 3)
    if theta_of is not None and ref is not None:
        res.rel_diff = rel_diff(theta_of(out), ref)
    return res, out


def _fit_rows(case: str, n: int, exp, quick: bool, methods: tuple[str, ...]):  # type: ignore[no-untyped-def]
    from servoid.estimate import fit_arx

    rows: list[Result] = []
    # Reference first: QR.
    qr_res, qr_est = _bench(
        case,
        n,
        "fit_arx qr",
        lambda: fit_arx(exp, NA, NB, NK, method="qr"),
        _repeats(n, quick, slow=True),
        None,
        None,
    )
    ref = np.asarray(qr_est.parameters)
    qr_res.rel_diff = 0.0
    qr_res.condition = qr_est.options["condition"]
    qr_res.solver = qr_est.options["solver"]
    qr_res.note = "reference"
    for method in methods:
        slow = case != "well-conditioned"  # ill-conditioned: every route ends in QR
        r, est = _bench(
            case,
            n,
            f"fit_arx {method}",
            lambda m=method: fit_arx(exp, NA, NB, NK, method=m),
            _repeats(n, quick, slow=slow),
            lambda e: e.parameters,
            ref,
        )
        r.condition = est.options["condition"]
        r.solver = est.options["solver"]
        rows.append(r)
    rows.append(qr_res)
    return rows, ref


def _kernel_rows(case: str, n: int, exp, ref, quick: bool, breakdown: bool):  # type: ignore[no-untyped-def]
    internals = _internals()
    if internals is None:
        return [
            Result(
                SUITE,
                case,
                n,
                "kernel (skipped)",
                float("nan"),
                float("nan"),
                0,
                note="servoid.estimate internals moved; update bench_arx.py",
            )
        ]
    ArxOrders, check_not_constant, signals_of, lagged_gram, solve_gram = internals
    orders = ArxOrders(NA, NB, NK, 1)
    sig, lag = orders.columns()
    start = orders.max_lag
    tsig, tlag = np.append(sig, 0), np.append(lag, 0)
    names = tuple(f"a{i}" for i in range(1, NA + 1)) + tuple(f"b{j}" for j in range(NB))
    z = signals_of(exp, "y", ["u"])
    n_rows = n - start

    def kernel():  # type: ignore[no-untyped-def]
        return solve_gram(lagged_gram(z, tsig, tlag, start), n_rows, names)

    rows = []
    r, out = _bench(
        case,
        n,
        "kernel lagged_gram+solve_gram",
        kernel,
        _repeats(n, quick),
        (lambda res: _ls_to_params(res.theta)) if kernel() is not None else None,
        ref,
    )
    if out is None:
        r.solver = "None (refused)"
        r.note = "Gram attempt refused: cond > GRAM_COND_LIMIT; auto then runs QR"
    else:
        r.condition, r.solver = out.condition, out.method
    rows.append(r)
    if breakdown:
        u_values = exp["u"]
        g = lagged_gram(z, tsig, tlag, start)
        for label, fn in (
            ("breakdown: lagged_gram only", lambda: lagged_gram(z, tsig, tlag, start)),
            ("breakdown: solve_gram only (7x7)", lambda: solve_gram(g, n_rows, names)),
            ("breakdown: _signals (channel views)", lambda: signals_of(exp, "y", ["u"])),
            # fit_arx passes the per-segment pieces of the input (one segment here).
            ("breakdown: constant-input check", lambda: check_not_constant("u", [u_values])),
            # Single-threaded numpy reduction: one read of both signals (not BLAS, whose
            # threaded dot stalls when another process holds a core).
            ("floor: y.sum()+u.sum() (one read)", lambda y=exp["y"]: (y.sum(), u_values.sum())),
        ):
            r, _ = _bench(case, n, label, fn, _repeats(n, quick), None, None)
            rows.append(r)
    return rows


def _baseline_rows(case: str, n: int, exp, ref, quick: bool):  # type: ignore[no-untyped-def]
    y, u = exp["y"], exp["u"]
    r1, out1 = _bench(
        case,
        n,
        "numpy column-slice Φ + lstsq",
        lambda: numpy_lstsq(y, u),
        _repeats(n, quick, slow=True),
        lambda o: o[0],
        ref,
    )
    r1.extra["condition_unscaled"] = out1[1]
    r1.solver = "numpy lstsq (SVD)"
    r2, _ = _bench(
        case,
        n,
        "lagged np.dot normal equations",
        lambda: lagged_dot_normal_equations(y, u),
        _repeats(n, quick),
        lambda o: o,
        ref,
    )
    r2.solver = "np.linalg.solve (unscaled)"
    return [r1, r2]


def run(quick: bool = False) -> list[Result]:
    """Run the ARX suite; ``quick`` uses small N and few repeats (CI smoke)."""
    from servoid.data import Experiment

    global _QUICK
    _QUICK = quick
    results: list[Result] = []
    sizes = (10**4, 10**5) if quick else (10**4, 10**5, 10**6)
    u_all, y_all, a, b = make_record(max(sizes), WELL_POLES)
    truth = np.concatenate([a[1:], b])
    for n in sizes:
        exp = Experiment.from_arrays(DT, u=u_all[:n], y=y_all[:n])  # outside every timed region
        case = "well-conditioned"
        rows, ref = _fit_rows(case, n, exp, quick, ("auto", "gram"))
        rows[-1].extra["rel_error_vs_true_parameters"] = rel_diff(ref, truth)
        rows += _kernel_rows(case, n, exp, ref, quick, breakdown=not quick)
        rows += _baseline_rows(case, n, exp, ref, quick)
        results += rows

    n_ill = 10**4 if quick else 10**5
    u, y, _, _ = make_record(n_ill, ILL_POLES)
    exp = Experiment.from_arrays(DT, u=u, y=y)
    case = "ill-conditioned"
    rows, ref = _fit_rows(case, n_ill, exp, quick, ("auto", "gram"))
    rows += _kernel_rows(case, n_ill, exp, ref, quick, breakdown=False)
    rows += _baseline_rows(case, n_ill, exp, ref, quick)
    results += rows
    return results
