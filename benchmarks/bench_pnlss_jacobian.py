"""The PNLSS Jacobian at the Wiener–Hammerstein benchmark's size: blocked against whole.

6 states, 1 input, the state monomials of degree 2–3 with the constant (78), 601 parameters
with the initial state, 1e5 samples — the shape of ``examples/wiener_hammerstein/wh.toml``.
Times (median of 3 after a warm-up) and peak numpy memory (tracemalloc) of JᵀJ, Jᵀe formed

* by servoid's search (``_Search.normal_equations``: the exact Jacobian in blocks of 4096
  samples, summed), and
* from the whole Jacobian (the kernel fills N × parameters, then JᵀJ and Jᵀe),

and checks that the two agree::

    PYTHONPATH=src python benchmarks/bench_pnlss_jacobian.py
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from servoid.nonlinear import PnlssModel
from servoid.nonlinear._pnlss import exponents
from servoid.nonlinear._pnlss_fit import _Search
from servoid.nonlinear._pnlss_kernel import jacobian


def _model(nx: int = 6) -> PnlssModel:
    rng = np.random.default_rng(0)
    powers = exponents(nx, 1, 3, "state")
    nm = powers.shape[0]
    a = np.diag(np.full(nx, 0.5)) + 0.05 * rng.standard_normal((nx, nx))
    return PnlssModel(a, rng.standard_normal((nx, 1)), rng.standard_normal(nx), np.zeros(1),
                      1e-3 * rng.standard_normal((nx, nm)), 1e-3 * rng.standard_normal(nm),
                      powers, 1.0)


def _measure(fn, repeats: int) -> tuple[float, float, object]:
    fn()  # warm-up (compilation)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return float(np.median(times)), peak, out


def main(n: int = 100_000, repeats: int = 3) -> None:
    model = _model()
    rng = np.random.default_rng(1)
    u = rng.standard_normal((n, 1))
    y = rng.standard_normal(n)
    search = _Search(model, [(u, y)], 0.0)
    theta, x0 = model.parameters, np.zeros(model.n_states)
    npar = model.n_parameters + model.n_states

    def blocked():
        return search.normal_equations(theta, [x0])

    def whole():
        ys, J = np.empty(n), np.empty((n, npar))
        jacobian(*model._kernel_args(), np.ascontiguousarray(u), x0, 0, ys, J)
        r = ys - y
        return J.T @ J, J.T @ r, r

    t_b, m_b, (h_b, g_b, _) = _measure(blocked, repeats)
    t_w, m_w, (h_w, g_w, _) = _measure(whole, repeats)
    diff = max(float(np.max(np.abs(h_b - h_w)) / np.max(np.abs(h_w))),
               float(np.max(np.abs(g_b - g_w)) / np.max(np.abs(g_w))))
    print(f"PNLSS JᵀJ and Jᵀe, {n:.0e} samples × {npar} parameters (6 states, degree 3, state "
          f"monomials):\n  blocked (servoid): {t_b:.2f} s, peak {m_b / 1e6:.0f} MB\n"
          f"  whole Jacobian:    {t_w:.2f} s, peak {m_w / 1e6:.0f} MB\n"
          f"  largest relative difference {diff:.1e} (summation order)")


if __name__ == "__main__":
    main()
