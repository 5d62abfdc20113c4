"""Pole–zero pairs an output-error fit cannot tell apart: the order is too high.

An output-error model ``B_i/F_i`` of higher order than the system places
its extra poles on top of extra zeros: each pair cancels and leaves the
frequency response unchanged, so the data hold nothing about where the
pair sits, yet the covariance (a pseudo-inverse when the information
matrix is singular) can print narrow intervals for its coefficients.

For each input the poles p (roots of F) and zeros z (roots of B, in z)
are paired greedily, nearest first.  A pair is *cancelling* when its
difference is inside its own confidence region: with
``v = (Re(p − z), Im(p − z))`` and its covariance ``C = J·P·Jᵀ`` from the
parameter covariance P and the root sensitivities (for a polynomial
``c₀zᵐ + … + c_m`` with a simple root r, ``∂r/∂c_k = −r^{m−k}/c'(r)``),
the statistic ``m² = vᵀC⁺v`` lies below the χ² quantile at ``1 − level``
with rank(C) degrees of freedom (1 for a real pair, 2 for a complex one).
That is a test of the distance against its σ, not a fixed threshold: a
well-determined pole and zero that lie close but apart are not flagged,
and a pair that cancels within the noise is, however far it sits from
the others.  The note names the pairs and suggests the orders with them
removed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._lazy import stats

__all__ = ["cancellation_note", "cancellation_notes", "cancelling_pairs"]

#: Level of the test "p and z differ": a pair whose difference lies inside the (1 − level)
#: confidence region of its estimate is taken as cancelling.
LEVEL = 0.01


def cancelling_pairs(theta: NDArray[np.float64], cov: NDArray[np.float64],
                     b_slice: slice, f_slice: slice,
                     level: float = LEVEL) -> list[dict[str, Any]]:
    """Return the pole–zero pairs of one input's B/F that cancel within their σ.

    Parameters
    ----------
    theta : ndarray
        The parameter vector.
    cov : ndarray
        Its covariance.
    b_slice, f_slice : slice
        Where B's coefficients (b0, b1, …) and F's (f1, …) sit in θ.
    level : float
        Level of the test that a pair differs.

    Returns
    -------
    list of dict
        One dict per cancelling pair (``pole``, ``zero`` as complex,
        ``distance``, ``m2``, ``dof``), the conjugate of a complex pair
        included.
    """
    b = np.asarray(theta[b_slice], dtype=float)
    f = np.concatenate([[1.0], np.asarray(theta[f_slice], dtype=float)])
    b_idx = np.arange(theta.size)[b_slice]
    f_idx = np.arange(theta.size)[f_slice]
    nz = np.flatnonzero(b)
    if f.size < 2 or nz.size == 0:
        return []
    b_lead = int(nz[0])  # leading zero coefficients (a delay) carry no zeros
    b_poly, b_idx = b[b_lead:], b_idx[b_lead:]
    if b_poly.size < 2 or not (np.all(np.isfinite(b_poly)) and np.all(np.isfinite(f))):
        return []
    poles = np.roots(f)
    zeros = np.roots(b_poly)
    pairs = _greedy(poles, zeros)
    cov = np.asarray(cov, dtype=float)
    out = []
    for p, z in pairs:
        jac = np.zeros((2, theta.size))
        gp = _root_gradient(f, p)[1:]  # the leading 1 of F is not a parameter
        gz = _root_gradient(b_poly, z)
        if gp is None or gz is None:
            continue
        diff = np.zeros(theta.size, dtype=complex)
        diff[f_idx] += gp
        diff[b_idx] -= gz
        jac[0], jac[1] = diff.real, diff.imag
        v = np.array([(p - z).real, (p - z).imag])
        c = jac @ cov @ jac.T
        if not np.all(np.isfinite(c)):
            continue
        dof = int(np.linalg.matrix_rank(c, tol=1e-12 * max(float(np.trace(c)), 1e-300)))
        if dof == 0:
            continue
        m2 = float(v @ np.linalg.pinv(c, rcond=1e-12) @ v)
        if m2 < float(stats.chi2.ppf(1.0 - level, dof)):
            out.append({"pole": complex(p), "zero": complex(z), "distance": float(abs(p - z)),
                        "m2": m2, "dof": dof})
    return out


def cancellation_note(pairs: list[dict[str, Any]], nb: int, nf: int, prefix: str = "",
                      level: float = LEVEL) -> str:
    """One note naming the cancelling pairs and the lower orders to try.

    Parameters
    ----------
    pairs : list of dict
        From :func:`cancelling_pairs`.
    nb, nf : int
        The fitted orders of this input.
    prefix : str
        The input's name and a colon when there are several inputs.
    level : float
        The test's level (for the text).

    Returns
    -------
    str
        Empty when no pair cancels.
    """
    if not pairs:
        return ""
    shown = [p for p in pairs if p["pole"].imag >= 0.0]
    words = "; ".join(
        f"pole {_c(p['pole'])} and zero {_c(p['zero'])} (distance {p['distance']:.2g}, "
        f"{np.sqrt(p['m2']):.2g} of its σ)" for p in shown)
    k = len(pairs)
    return (f"{prefix}{k} pole–zero pair{'s' if k > 1 else ''} cancel within their uncertainty "
            f"(level {100 * level:.3g} %): {words}. The data cannot place "
            f"{'these pairs' if k > 1 else 'this pair'}, so the order is higher than the data "
            f"support and the intervals of the coefficients involved mean nothing; fit nb = "
            f"{max(nb - k, 1)}, nf = {max(nf - k, 0)}")


def cancellation_notes(orders: Any, theta: NDArray[np.float64], cov: NDArray[np.float64],
                       inputs: Any) -> list[str]:
    """The cancellation notes of an output-error fit, one per input with a pair.

    Parameters
    ----------
    orders : PemOrders
        The fitted orders (where each B and F sits in θ).
    theta : ndarray
        The parameter vector.
    cov : ndarray
        Its covariance.
    inputs : sequence of str
        The input names.

    Returns
    -------
    list of str
        Empty when no pair cancels.
    """
    _, bs, fs, _, _ = orders.blocks()
    several = len(inputs) > 1
    notes = []
    for name, b, f, nb, nf in zip(inputs, bs, fs, orders.nb, orders.nf, strict=True):
        pairs = cancelling_pairs(theta, cov, b, f)
        note = cancellation_note(pairs, nb, nf, f"input {name!r}: " if several else "")
        if note:
            notes.append(note)
    return notes


def _greedy(poles: NDArray[np.complex128],
            zeros: NDArray[np.complex128]) -> list[tuple[complex, complex]]:
    """Pair poles and zeros nearest first, each used once."""
    if poles.size == 0 or zeros.size == 0:
        return []
    dist = np.abs(poles[:, None] - zeros[None, :])
    pairs = []
    used_p: set[int] = set()
    used_z: set[int] = set()
    for flat in np.argsort(dist, axis=None):
        i, j = np.unravel_index(flat, dist.shape)
        if i in used_p or j in used_z:
            continue
        used_p.add(int(i))
        used_z.add(int(j))
        pairs.append((complex(poles[i]), complex(zeros[j])))
        if len(used_p) == poles.size or len(used_z) == zeros.size:
            break
    return pairs


def _root_gradient(c: NDArray[np.float64], r: complex) -> NDArray[np.complex128] | None:
    """∂r/∂c_k for a simple root r of c₀zᵐ + … + c_m (None for a repeated root)."""
    m = c.size - 1
    deriv = np.polyval(np.polyder(c), r)
    if not abs(deriv) > 1e-12 * max(float(np.max(np.abs(c))), 1e-300):
        return None
    return -np.power(r, np.arange(m, -1, -1)) / deriv


def _c(x: complex) -> str:
    if abs(x.imag) < 1e-12:
        return f"{x.real:.4g}"
    return f"{x.real:.4g}{x.imag:+.4g}j"
