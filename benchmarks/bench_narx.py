"""NARX term selection: servoid's fit_narx against sysidentpy's FROLS on the same record.

Target (issue 14): term selection on 1e5 samples with 100 candidate terms,
≥ 10× faster than sysidentpy's FROLS at the same selected terms.

Case
----
select-105
    A polynomial NARX with six true terms (``y(t-1)``, ``y(t-2)``,
    ``u(t-1)``, ``u(t-2)``, ``y(t-1)·u(t-1)``, ``u(t-1)²``), simulated by a
    plain Python loop with white equation error σ = 0.02, input uniform on
    [−1, 1], fixed seed; N = 1e5 (1e4 under ``--quick``). Candidates:
    na = 6 output lags, nb = 7 input lags (nk = 1), degree 2 — every
    monomial of 13 lagged variables up to degree 2 with the constant,
    C(15, 2) = 105 terms (sysidentpy: ``ylag=6, xlag=7,
    Polynomial(degree=2)``, the same 105).

Methods
-------
servoid fit_narx (bic)
    ``fit_narx(exp, na=6, nb=7, criterion="bic")``: the compiled regressor
    kernel and a BLAS Gram pass, forward OLS on the Gram matrix with BIC,
    backward pruning, the QR refit with covariance and the Estimate
    (residuals are lazy). The Experiment is built outside the timed region.
sysidentpy FROLS (bic, n_info_values=15)
    ``FROLS(order_selection=True, info_criteria="bic", n_info_values=15,
    estimator=LeastSquares())``: its own regressor matrix, Householder
    FROLS and its information-criterion loop (what a user writes to have the
    number of terms chosen). Run in a separate interpreter (a venv with
    sysidentpy, never a servoid dependency): ``$SYSIDENTPY_PYTHON`` or
    ``/tmp/sysid/bin/python``; the row is skipped with a note when absent.
    Timed inside that process around ``fit`` alone, on the same samples
    (passed as a .npy file).
sysidentpy FROLS (n_terms=6)
    The same with the number of terms given (``order_selection=False,
    n_terms=6``): selection alone, no criterion loop — the fastest way to
    run the peer, and a number servoid cannot use (it must choose the count).

Columns: ``rel_diff`` = max |θ − θ_servoid| / |θ_servoid| over the selected
terms (the same least-squares fit twice: rounding); ``extra["same_terms"]``
says whether the selected sets are equal; ``extra["speedup"]`` is the
peer's median over servoid's.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
import warnings
from pathlib import Path

import numpy as np
from _harness import Result, measure_memory, time_call

from servoid.data import Experiment
from servoid.nonlinear import fit_narx

SUITE = "narx"
SEED = 20261124
NA, NB, DEGREE = 6, 7, 2
TRUE = {"y(t-1)": 0.6, "y(t-2)": -0.15, "u(t-1)": 0.8, "u(t-2)": 0.3,
        "y(t-1)*u(t-1)": -0.25, "u(t-1)^2": 0.2}
PEER_DEFAULT = "/tmp/sysid/bin/python"

_PEER = r"""
import json, sys, time, warnings
import numpy as np
from sysidentpy.basis_function import Polynomial
from sysidentpy.model_structure_selection import FROLS
from sysidentpy.parameter_estimation import LeastSquares

data = np.load(sys.argv[1])
u, y = data[0].reshape(-1, 1), data[1].reshape(-1, 1)
repeats = int(sys.argv[2])
variant = sys.argv[3]
times = []
for _ in range(repeats):
    if variant == "bic":
        model = FROLS(ylag=6, xlag=7, basis_function=Polynomial(degree=2),
                      estimator=LeastSquares(), order_selection=True, info_criteria="bic",
                      n_info_values=15)
    else:
        model = FROLS(ylag=6, xlag=7, basis_function=Polynomial(degree=2),
                      estimator=LeastSquares(), order_selection=False, n_terms=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        model.fit(X=u, y=y)
        times.append(time.perf_counter() - t0)
import sysidentpy
print(json.dumps({"times": times, "codes": model.final_model.tolist(),
                  "theta": model.theta.ravel().tolist(), "version": sysidentpy.__version__}))
"""


def _record(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    u = rng.uniform(-1.0, 1.0, n)
    e = 0.02 * rng.standard_normal(n)
    y = [0.0, 0.0]
    for t in range(2, n):  # a plain loop: not the estimator's kernel
        y.append(0.6 * y[t - 1] - 0.15 * y[t - 2] + 0.8 * u[t - 1] + 0.3 * u[t - 2]
                 - 0.25 * y[t - 1] * u[t - 1] + 0.2 * u[t - 1] ** 2 + e[t])
    return u, np.array(y)


def _label(code: list[int]) -> str:
    """sysidentpy's regressor code ([1001, 2001] = y(k-1)·x1(k-1)) as servoid's term name."""
    factors = sorted(((0 if c < 2000 else 1), c % 1000) for c in code if c)
    if not factors:
        return "constant"
    counts: dict[tuple[int, int], int] = {}
    for f in factors:
        counts[f] = counts.get(f, 0) + 1
    return "*".join(f"{'y' if s == 0 else 'u'}(t-{lag})" + (f"^{p}" if p > 1 else "")
                    for (s, lag), p in counts.items())


def _peer(u: np.ndarray, y: np.ndarray, repeats: int, variant: str) -> dict | str:
    python = os.environ.get("SYSIDENTPY_PYTHON", PEER_DEFAULT)
    if not Path(python).is_file():
        return (f"skipped: no interpreter with sysidentpy at {python} (python3 -m venv "
                "/tmp/sysid && /tmp/sysid/bin/pip install sysidentpy numpy)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "record.npy"
        np.save(path, np.vstack([u, y]))
        env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
        done = subprocess.run([python, "-c", _PEER, str(path), str(repeats), variant], check=False,
                              capture_output=True, text=True, timeout=3600, env=env)
    if done.returncode != 0:
        return f"skipped: sysidentpy failed: {done.stderr.strip().splitlines()[-1:]}"
    return json.loads(done.stdout.strip().splitlines()[-1])


def run(quick: bool) -> list[Result]:
    n = 10_000 if quick else 100_000
    u, y = _record(n)
    exp = Experiment.from_arrays(0.01, u=u, y=y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = fit_narx(exp, na=NA, nb=NB, degree=DEGREE, criterion="bic")
        timing = time_call(lambda: fit_narx(exp, na=NA, nb=NB, degree=DEGREE),
                           repeats=3 if quick else 7)
        memory = None if quick else measure_memory(lambda: fit_narx(exp, na=NA, nb=NB))
    ours = dict(zip(est.names, est.parameters, strict=True))
    rows = [Result(SUITE, "select-105", n, "servoid fit_narx (bic)", timing.median * 1e3,
                   timing.best * 1e3, len(timing.times),
                   peak_mb=None if memory is None else memory.tracemalloc_peak / 2**20,
                   rss_mb=None if memory is None or memory.rss_peak_delta is None
                   else memory.rss_peak_delta / 2**20,
                   condition=float(est.options["condition"]), solver="gram+ols+qr",
                   note=f"{len(est.names)} terms of {est.options['n_candidates']}; true set: "
                        f"{set(est.names) == set(TRUE)}",
                   extra={"terms": sorted(est.names), "n_candidates": est.options["n_candidates"],
                          "true_terms": set(est.names) == set(TRUE)})]
    for variant, repeats, label in (("bic", 1 if not quick else 2,
                                     "sysidentpy FROLS (bic, n_info_values=15)"),
                                    ("n_terms", 3, "sysidentpy FROLS (n_terms=6)")):
        peer = _peer(u, y, repeats, variant)
        if isinstance(peer, str):
            rows.append(Result(SUITE, "select-105", n, label, float("nan"), float("nan"), 0,
                               note=peer))
            continue
        names = [_label(code) for code in peer["codes"]]
        theirs = dict(zip(names, peer["theta"], strict=True))
        same = set(names) == set(ours)
        rel = (max(abs(theirs[k] - ours[k]) / abs(ours[k]) for k in ours) if same else None)
        median = float(np.median(peer["times"])) * 1e3
        rows.append(Result(
            SUITE, "select-105", n, label, median, min(peer["times"]) * 1e3,
            len(peer["times"]), rel_diff=rel,
            note=f"sysidentpy {peer['version']}; same terms: {same}; "
                 f"{median / (timing.median * 1e3):.0f}x servoid's time",
            extra={"terms": sorted(names), "same_terms": same,
                   "speedup": median / (timing.median * 1e3)}))
    return rows
