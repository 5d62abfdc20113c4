"""The PNLSS linear stage's Jacobian: the linear columns alone against every column.

The first stage of ``fit_pnlss`` refines A, B, C, D and the initial state with E = F = 0.
Its normal equations need only those columns of the Jacobian; the search used to form all
of them (E's and F's too) and then drop the rest.  This times one JᵀJ, Jᵀe of the linear
stage both ways at the same point (E = F = 0; median of 5 after a warm-up) and checks that
the linear block is the same:

* ``bench``: the ``pnlss`` benchmark's model (2 states, 1 input, degree 3, full monomials:
  17 monomials, 60 parameters), 1e4 samples;
* ``wh``: the real Wiener–Hammerstein benchmark's (6 states, degree 3 in the states:
  78 monomials, 595 parameters), 1e5 samples.

Usage::

    PYTHONPATH=src python benchmarks/bench_pnlss_linear_stage.py
"""

from __future__ import annotations

import os
import time
from functools import partial

if __name__ == "__main__":  # before numpy is imported
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from servoid.nonlinear import PnlssModel
from servoid.nonlinear._pnlss import exponents
from servoid.nonlinear._pnlss_fit import _Search


def _case(nx: int, degree: int, monomials: str, n: int) -> _Search:
    rng = np.random.default_rng(0)
    powers = exponents(nx, 1, degree, monomials)  # type: ignore[arg-type]
    nm = powers.shape[0]
    a = np.diag(np.full(nx, 0.5)) + 0.05 * rng.standard_normal((nx, nx))
    model = PnlssModel(a, rng.standard_normal((nx, 1)), rng.standard_normal(nx), np.zeros(1),
                       np.zeros((nx, nm)), np.zeros(nm), powers, 1.0)
    u = rng.standard_normal((n, 1))
    return _Search(model, [(u, rng.standard_normal(n))], 0.0)


def _median(fn, repeats: int = 5) -> tuple[float, object]:
    fn()  # warm-up (compilation)
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main() -> None:
    for name, args in (("bench", (2, 3, "full", 10_000)), ("wh", (6, 3, "state", 100_000))):
        search = _case(*args)
        theta = search.model.parameters
        x0s = [np.zeros(search.model.n_states)]
        keep = np.setdiff1d(np.arange(search.n_model + search.model.n_states), search.ef)
        form = search.normal_equations
        t_all, (H_all, _, _) = _median(partial(form, theta, x0s))
        t_lin, (H_lin, _, _) = _median(partial(form, theta, x0s, linear=True))
        diff = float(np.max(np.abs(H_all[np.ix_(keep, keep)] - H_lin[np.ix_(keep, keep)]))
                     / np.max(np.abs(H_all[np.ix_(keep, keep)])))
        print(f"{name}: {search.model.n_parameters} parameters, {keep.size} linear columns "
              f"(with x0), {args[3]} samples: every column {t_all * 1e3:.1f} ms, linear "
              f"columns {t_lin * 1e3:.1f} ms ({t_all / t_lin:.1f}×); max relative "
              f"difference of the linear block {diff:.1e}")


if __name__ == "__main__":
    main()
