"""Pruning a fitted PNLSS model: the monomials the data cannot tell from zero are removed."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ._pnlss_fit import _Search

__all__ = ["prune_monomials"]


def prune_monomials(search: _Search, theta: NDArray[np.float64],
                    x0s: list[NDArray[np.float64]], alpha: float, info: dict[str, Any],
                    max_iter: int, tol: float
                    ) -> tuple[NDArray[np.float64], list[NDArray[np.float64]],
                               NDArray[np.int64], list[str]]:
    """Remove the monomials the data cannot tell from zero, refit, until none is removed.

    A monomial's group is its column of E and its entry of F; the Wald
    statistic θ_gᵀ C_g⁺ θ_g of the group (C_g its block of the
    covariance) is χ² with rank(C_g) degrees of freedom when the
    coefficients are zero.  Whether a column of E is zero does not depend
    on the states' basis, so the test means the same in any realisation.
    """
    from scipy.stats import chi2

    model = search.model
    nx, nm, n_model = model.n_states, model.n_monomials, search.n_model
    o_e, o_f = n_model - nx * nm - nm, n_model - nm
    groups = [np.r_[o_e + np.arange(nx) * nm + j, o_f + j] for j in range(nm)]
    gone: set[int] = set()
    n_all = n_model + nx * len(search.records)
    n_free = n_all
    for _ in range(10):
        fixed = np.array(sorted(k for j in gone for k in groups[j]), dtype=np.int64)
        cov, _, _ = search.covariance(theta, x0s, fixed, n_free - fixed.size)
        drop = []
        for j, g in enumerate(groups):
            if j in gone:
                continue
            c = cov[np.ix_(g, g)]
            w, V = np.linalg.eigh(0.5 * (c + c.T))
            keep = w > 1e-12 * max(float(w.max()), 1e-300)
            if not keep.any():
                continue
            z = V[:, keep].T @ theta[g]
            stat = float(np.sum(z**2 / w[keep]))
            if chi2.sf(stat, int(keep.sum())) > alpha:
                drop.append(j)
        if not drop:
            break
        fixed = np.array(sorted(k for j in gone | set(drop) for k in groups[j]),
                         dtype=np.int64)
        trial = theta.copy()
        trial[fixed] = 0.0
        if not np.isfinite(search.cost(trial, x0s)):
            break  # the model without them diverges: they are needed after all
        gone.update(drop)
        free = np.setdiff1d(np.arange(n_all), fixed)
        theta, x0s, again = search._lm(trial, x0s, max_iter, tol, free)
        info.update(status=again["status"], cost=again["cost"])
        for key in ("iterations", "rejected", "diverged"):
            info[key] += again[key]
    fixed = np.array(sorted(k for j in gone for k in groups[j]), dtype=np.int64)
    names = model.monomial_names
    return theta, x0s, fixed, [names[j] for j in sorted(gone)]
