"""Compiled kernels of the polynomial nonlinear state-space model.

``x(t+1) = A x + B u + E m(x, u)``, ``y(t) = C x + D u + F m(x, u)`` with
``m`` the monomials whose exponents are the rows of ``P`` (one column per
state, then per input).  :func:`simulate` runs the model; :func:`jacobian`
runs it together with the exact forward sensitivity recursion

    S(t+1) = (A + E ∂m/∂x) S(t) + ∂x(t+1)/∂θ|direct,
    ∂y(t)/∂θ = (C + F ∂m/∂x) S(t) + ∂y(t)/∂θ|direct,

so the Levenberg–Marquardt search never differences the simulation.  The
parameters are ordered A (row-major), B, C, D, E, F, then the initial
state; ``first`` skips the leading blocks (``first = n_model`` gives the
initial state's columns alone, for the validation's initial-state fit).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["jacobian", "jacobian_block", "record_start", "simulate"]

#: |x| past which a run counts as diverged (its output is then NaN from there on).
LIMIT = 1e12


@nb.njit(cache=True, nogil=True)
def _values(z, P, m):  # pragma: no cover - compiled
    """m_j = Π_k z_k^P[j,k]: the monomials alone (a free run needs no derivatives)."""
    nm, nz = P.shape
    for j in range(nm):
        v = 1.0
        for k in range(nz):
            p = P[j, k]
            if p > 0:
                v *= z[k] ** p
        m[j] = v


@nb.njit(cache=True, nogil=True)
def _monomials(z, P, m, dm):  # pragma: no cover - compiled
    """m_j = Π_k z_k^P[j,k] and dm[j, i] = ∂m_j/∂x_i for the first dm.shape[1] entries of z."""
    _values(z, P, m)
    nm, nz = P.shape
    nx = dm.shape[1]
    for j in range(nm):
        for i in range(nx):
            p = P[j, i]
            if p == 0:
                dm[j, i] = 0.0
                continue
            d = p * z[i] ** (p - 1)
            for k in range(nz):
                q = P[j, k]
                if k != i and q > 0:
                    d *= z[k] ** q
            dm[j, i] = d


@nb.njit(cache=True, nogil=True)
def simulate(A, B, C, D, E, F, P, u, x0, y, x):  # pragma: no cover - compiled
    """Free run from x0; fills y (N,) and the states x (N+1, nx); returns the first sample
    whose state left ±LIMIT (or became NaN), or -1."""
    N, nu = u.shape
    nx = A.shape[0]
    nm = P.shape[0]
    z = np.empty(nx + nu)
    m = np.empty(nm)
    for i in range(nx):
        x[0, i] = x0[i]
    for t in range(N):
        for i in range(nx):
            z[i] = x[t, i]
        for k in range(nu):
            z[nx + k] = u[t, k]
        _values(z, P, m)
        out = 0.0
        for i in range(nx):
            out += C[i] * z[i]
        for k in range(nu):
            out += D[k] * u[t, k]
        for j in range(nm):
            out += F[j] * m[j]
        y[t] = out
        bad = False
        for i in range(nx):
            s = 0.0
            for k in range(nx):
                s += A[i, k] * z[k]
            for k in range(nu):
                s += B[i, k] * u[t, k]
            for j in range(nm):
                s += E[i, j] * m[j]
            x[t + 1, i] = s
            if not (abs(s) < LIMIT):
                bad = True
        if bad:
            for s_ in range(t + 1, N):
                y[s_] = np.nan
            return t + 1
    return -1


@nb.njit(cache=True, nogil=True)
def jacobian(A, B, C, D, E, F, P, u, x0, first, y, J):  # pragma: no cover - compiled
    """Simulate and fill J (N, n_par − first) with ∂y(t)/∂θ_k for k ≥ first.

    Returns the first diverged sample, or -1 (then J is finite)."""
    nx = A.shape[0]
    npar = J.shape[1]
    z = np.empty(nx)
    S = np.zeros((nx, npar))
    for i in range(nx):
        z[i] = x0[i]
        S[i, npar - nx + i] = 1.0
    return jacobian_block(A, B, C, D, E, F, P, u, z, S, first, y, J)


@nb.njit(cache=True, nogil=True)
def jacobian_block(A, B, C, D, E, F, P, u, x, S, first, y, J):  # pragma: no cover - compiled
    """:func:`jacobian` over one block of a record, from the state x (nx,) and its sensitivity
    S (nx, n_par − first), both updated in place to those after the block's last sample.

    A record cut into consecutive blocks, each started from the previous block's x and S,
    gives the rows of :func:`jacobian` bit for bit, so J need never be held whole.  Returns
    the first diverged sample of the block, or -1."""
    N, nu = u.shape
    nx = A.shape[0]
    nm = P.shape[0]
    nA = nx * nx
    nB = nx * nu
    nE = nx * nm
    oB = nA
    oC = oB + nB
    oD = oC + nx
    oE = oD + nu
    oF = oE + nE
    npar = S.shape[1]
    z = np.empty(nx + nu)
    xn = np.empty(nx)
    m = np.empty(nm)
    dm = np.empty((nm, nx))
    Ax = np.empty((nx, nx))
    Cx = np.empty(nx)
    Sn = np.empty((nx, npar))
    for i in range(nx):
        z[i] = x[i]
    for t in range(N):
        for k in range(nu):
            z[nx + k] = u[t, k]
        _monomials(z, P, m, dm)
        # linearisation of both equations at (x(t), u(t))
        for i in range(nx):
            Cx[i] = C[i]
            for j in range(nm):
                Cx[i] += F[j] * dm[j, i]
            for k in range(nx):
                s = A[i, k]
                for j in range(nm):
                    s += E[i, j] * dm[j, k]
                Ax[i, k] = s
        out = 0.0
        for i in range(nx):
            out += C[i] * z[i]
        for k in range(nu):
            out += D[k] * z[nx + k]
        for j in range(nm):
            out += F[j] * m[j]
        y[t] = out
        # output row: (C + F dm) S + direct terms (rows of S are contiguous: inner loop on c)
        for c in range(npar):
            J[t, c] = 0.0
        for i in range(nx):
            a = Cx[i]
            for c in range(npar):
                J[t, c] += a * S[i, c]
        if oC >= first:
            for i in range(nx):
                J[t, oC + i - first] += z[i]
            for k in range(nu):
                J[t, oD + k - first] += z[nx + k]
            for j in range(nm):
                J[t, oF + j - first] += m[j]
        # next state and its sensitivity
        bad = False
        for i in range(nx):
            s = 0.0
            for k in range(nx):
                s += A[i, k] * z[k]
            for k in range(nu):
                s += B[i, k] * z[nx + k]
            for j in range(nm):
                s += E[i, j] * m[j]
            xn[i] = s
            if not (abs(s) < LIMIT):
                bad = True
        for i in range(nx):
            for c in range(npar):
                Sn[i, c] = 0.0
            for k in range(nx):
                a = Ax[i, k]
                for c in range(npar):
                    Sn[i, c] += a * S[k, c]
        if first == 0:  # the model's own columns (not the initial state's alone)
            for i in range(nx):
                for k in range(nx):
                    Sn[i, i * nx + k - first] += z[k]
                for k in range(nu):
                    Sn[i, oB + i * nu + k - first] += z[nx + k]
                for j in range(nm):
                    Sn[i, oE + i * nm + j - first] += m[j]
        for i in range(nx):
            z[i] = xn[i]
            x[i] = xn[i]
            for c in range(npar):
                S[i, c] = Sn[i, c]
        if bad:
            for s_ in range(t + 1, N):
                y[s_] = np.nan
            return t + 1
    return -1


def record_start(x0: NDArray[np.float64], k: int, nown: int, nmod: int, nx: int
                 ) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64],
                            NDArray[np.float64], NDArray[np.float64]]:
    """What :func:`jacobian_block` carries through record k, at its first sample.

    Returns the record's columns of the whole Jacobian (the model's `nown`
    formed ones and its own `nx` initial states), its state, the state's
    sensitivity (∂x/∂x(0) = I), and its zeroed JᵀJ and Jᵀr blocks.
    """
    cols = np.r_[np.arange(nown), nmod + k * nx + np.arange(nx)]
    sens = np.zeros((nx, nown + nx))
    sens[:, nown:] = np.eye(nx)
    return (cols, np.array(x0, dtype=float), sens, np.zeros((nown + nx, nown + nx)),
            np.zeros(nown + nx))
