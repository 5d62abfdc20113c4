"""Compiled kernel of the local polynomial method: one small solve per line.

For the window of lines ``s … s + 2n`` around a line the regressor is
``K = [diag(X)·P, P]`` with P the powers ``r^j`` (r scaled to [−1, 1]).
Every entry of KᴴK, Kᴴz and zᴴz is a sum over the window of a product of
spectra times a power of r; the transient block ``PᵀP`` is the same for
every window, so it is eliminated through its Schur complement
``S = A − B·C⁻¹·Bᴴ`` (A = Pᵀ·diag|X|²·P, B = Pᵀ·diag(conj X)·P, C = PᵀP),
which leaves an (R + 1) × (R + 1) Hermitian system per window, solved by
its Cholesky factor.  The residual energy follows from the normal
equations: ``Σ res_o·conj(res_p) = z_pᴴz_o − (Kᴴz_p)ᴴ·θ_o``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["lpm_lines"]


@numba.njit(cache=True, nogil=True)
def lpm_lines(x, z, lines, starts, n, degree, c_inv, theta0, h, cov, ok):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Local polynomial fits for each line.

    ``x``: input (or reference) spectrum; ``z``: (n_out, K) output
    spectra; ``lines``/``starts``: each line and the first line of its
    window (nondecreasing).  Writes G at each line per output
    (``theta0``, (n_out, L)), ``h = v·S⁻¹·v`` (``h``), the residual
    covariance divided by the degrees of freedom (``cov``, (L, n_out,
    n_out)) and whether the window's system was positive definite
    (``ok``).
    """
    width = 2 * n + 1
    n_poly = degree + 1
    n_out = z.shape[0]
    q = width - 2 * n_poly
    n_pow = 2 * degree + 1
    powers = np.empty((width, n_pow))
    for w in range(width):
        r = (w - n) / n
        acc = 1.0
        for p in range(n_pow):
            powers[w, p] = acc
            acc *= r
    m1 = np.empty(n_pow)
    m2 = np.empty(n_pow, dtype=np.complex128)
    m3 = np.empty((n_out, n_poly), dtype=np.complex128)
    m4 = np.empty((n_out, n_poly), dtype=np.complex128)
    e = np.empty((n_out, n_out), dtype=np.complex128)
    bmat = np.empty((n_poly, n_poly), dtype=np.complex128)
    bci = np.empty((n_poly, n_poly), dtype=np.complex128)
    low = np.zeros((n_poly, n_poly), dtype=np.complex128)
    theta_g = np.empty((n_poly, n_out), dtype=np.complex128)
    theta_t = np.empty((n_poly, n_out), dtype=np.complex128)
    work = np.empty(n_poly, dtype=np.complex128)
    resid = np.empty((n_out, n_out), dtype=np.complex128)
    vpow = np.empty(n_poly)
    current = -1
    good = False
    for li in range(lines.size):
        s = starts[li]
        if s != current:
            current = s
            # -- moments of the window
            for p in range(n_pow):
                m1[p] = 0.0
                m2[p] = 0.0
            for o in range(n_out):
                for c in range(n_poly):
                    m3[o, c] = 0.0
                    m4[o, c] = 0.0
                for o2 in range(n_out):
                    e[o, o2] = 0.0
            for w in range(width):
                xv = x[s + w]
                xx = xv.real * xv.real + xv.imag * xv.imag
                for p in range(n_pow):
                    m1[p] += xx * powers[w, p]
                    m2[p] += xv * powers[w, p]
                xc = np.conj(xv)
                for o in range(n_out):
                    zv = z[o, s + w]
                    xz = xc * zv
                    for c in range(n_poly):
                        m3[o, c] += xz * powers[w, c]
                        m4[o, c] += zv * powers[w, c]
                    for o2 in range(n_out):
                        e[o, o2] += zv * np.conj(z[o2, s + w])
            # -- Schur complement S = A − B·C⁻¹·Bᴴ, into `low` (lower triangle, then Cholesky)
            for c in range(n_poly):
                for d in range(n_poly):
                    bmat[c, d] = np.conj(m2[c + d])
            for c in range(n_poly):
                for d in range(n_poly):
                    acc = 0.0 + 0.0j
                    for k in range(n_poly):
                        acc += bmat[c, k] * c_inv[k, d]
                    bci[c, d] = acc
            good = True
            for j in range(n_poly):
                for i in range(j, n_poly):
                    acc = m1[i + j] + 0.0j
                    for k in range(n_poly):
                        acc -= bci[i, k] * np.conj(bmat[j, k])
                    for k in range(j):
                        acc -= low[i, k] * np.conj(low[j, k])
                    if i == j:
                        d = acc.real
                        if not d > 1e-13 * max(m1[2 * j], 1e-300):
                            good = False
                            d = 1.0
                        low[j, j] = np.sqrt(d)
                    else:
                        low[i, j] = acc / low[j, j].real
            # -- θ_g = S⁻¹·(Kᴴz reduced); θ_t = C⁻¹·(Pᵀz − Bᴴ·θ_g)
            for o in range(n_out):
                for c in range(n_poly):
                    acc = m3[o, c]
                    for k in range(n_poly):
                        acc -= bci[c, k] * m4[o, k]
                    for k in range(c):
                        acc -= low[c, k] * work[k]
                    work[c] = acc / low[c, c].real
                for c in range(n_poly - 1, -1, -1):
                    acc = work[c]
                    for k in range(c + 1, n_poly):
                        acc -= np.conj(low[k, c]) * theta_g[k, o]
                    theta_g[c, o] = acc / low[c, c].real
                for c in range(n_poly):
                    acc = m4[o, c]
                    for k in range(n_poly):
                        acc -= np.conj(bmat[k, c]) * theta_g[k, o]
                    work[c] = acc
                for c in range(n_poly):
                    acc = 0.0 + 0.0j
                    for k in range(n_poly):
                        acc += c_inv[c, k] * work[k]
                    theta_t[c, o] = acc
            for o in range(n_out):
                for o2 in range(n_out):
                    acc = e[o, o2]
                    for c in range(n_poly):
                        acc -= np.conj(m3[o2, c]) * theta_g[c, o]
                        acc -= np.conj(m4[o2, c]) * theta_t[c, o]
                    resid[o, o2] = acc / q
                if resid[o, o].real < 0.0:  # rounding of a noise-free window
                    resid[o, o] = 0.0
        # -- G and its variance factor at this line's place in the window
        r0 = (lines[li] - (s + n)) / n
        for o in range(n_out):
            acc = 0.0 + 0.0j
            v = 1.0
            for c in range(n_poly):
                acc += v * theta_g[c, o]
                v *= r0
            theta0[o, li] = acc
        total = 0.0
        v = 1.0
        for c in range(n_poly):
            vpow[c] = v
            v *= r0
        for c in range(n_poly):  # L⁻¹·v
            acc = vpow[c] + 0.0j
            for k in range(c):
                acc -= low[c, k] * work[k]
            work[c] = acc / low[c, c].real
            total += work[c].real * work[c].real + work[c].imag * work[c].imag
        h[li] = total
        for o in range(n_out):
            for o2 in range(n_out):
                cov[li, o, o2] = resid[o, o2]
        ok[li] = good
