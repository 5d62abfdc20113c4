"""The linear block of a block-oriented model: its parameters and its filter.

Two structures:

- ``"oe"``: discrete ``G(q) = q^(−nk)·B(q)/F(q)``, parameters ``b0 …``
  and ``f1 … f_nf`` as in :func:`servoid.estimate.fit_oe`;
- ``"tf"``: continuous ``G(s) = (b_m s^m + … + b0)/(s^n + a1 s^(n−1) + … + an)``,
  discretised with a zero-order hold at the record's ``dt`` for every
  simulation (parameters ``b_m … b0``, ``a1 … an``).

With ``unit_gain`` the static gain G(1) (discrete) or G(0) (continuous) is
fixed to 1 by computing one numerator coefficient from the others: the
last b of ``"oe"`` (``b_{nb−1} = F(1) − Σ_{j<nb−1} b_j``), ``b0 = an`` of
``"tf"``; that coefficient is then not a parameter.

Every simulation runs as one ``lfilter`` in q⁻¹; the free responses of
the denominator (``lfilter([1], den, 0, zi=c)``, linear in c) carry the
initial state, as :mod:`servoid.validate` does for linear models.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._lazy import signal as sps

__all__ = ["LinearBlock", "arx_fit", "free_response"]


@dataclass(frozen=True)
class LinearBlock:
    """Parametrisation of the linear block (private to the block models)."""

    kind: str
    dt: float
    nb: int = 2
    nf: int = 2
    nk: int = 1
    n_poles: int = 2
    n_zeros: int = 1
    unit_gain: bool = False

    @property
    def names(self) -> tuple[str, ...]:
        """The free parameters' names."""
        if self.kind == "oe":
            bs = [f"b{j}" for j in range(self.nb)]
            if self.unit_gain:
                bs = bs[:-1]
            return (*bs, *(f"f{j}" for j in range(1, self.nf + 1)))
        bs = [f"b{j}" for j in range(self.n_zeros, -1, -1)]
        if self.unit_gain:
            bs = bs[:-1]
        return (*bs, *(f"a{j}" for j in range(1, self.n_poles + 1)))

    @property
    def size(self) -> int:
        """Number of free parameters."""
        return len(self.names)

    @property
    def order(self) -> int:
        """Order of the denominator (number of initial states)."""
        return self.nf if self.kind == "oe" else self.n_poles

    def coefficients(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                 NDArray[np.float64]]:
        """Numerator and denominator: (b, f) in q⁻¹ or (num, den) in s."""
        if self.kind == "oe":
            nfree = self.nb - 1 if self.unit_gain else self.nb
            b, f = theta[:nfree], theta[nfree:]
            den = np.concatenate([[1.0], f])
            if self.unit_gain:
                b = np.concatenate([b, [den.sum() - b.sum()]])
            return np.asarray(b, dtype=float), den
        nfree = self.n_zeros if self.unit_gain else self.n_zeros + 1
        b, a = theta[:nfree], theta[nfree:]
        den = np.concatenate([[1.0], a])
        if self.unit_gain:
            b = np.concatenate([b, [den[-1]]])
        return np.asarray(b, dtype=float), den

    def polynomials(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                NDArray[np.float64]]:
        """Numerator and denominator in q⁻¹ at ``dt`` (lfilter's form)."""
        num, den = self.coefficients(theta)
        if self.kind == "oe":
            return np.concatenate([np.zeros(self.nk), num]), den
        numd, dend, _ = sps.cont2discrete((num, den), self.dt, method="zoh")
        numd = np.atleast_1d(np.squeeze(numd))
        dend = np.atleast_1d(np.squeeze(dend))
        pad = dend.size - numd.size
        return np.concatenate([np.zeros(max(pad, 0)), numd]), dend

    def model(self, theta: NDArray[np.float64]) -> Any:
        """The servoid model of the block at θ."""
        from ..models import PolynomialModel, TransferFunction

        num, den = self.coefficients(theta)
        if self.kind == "oe":
            return PolynomialModel(np.ones(1), (num,), (self.nk,), self.dt, f=(den,))
        return TransferFunction(num, den)

    def theta_of(self, num: NDArray[np.float64], den: NDArray[np.float64]) -> NDArray[np.float64]:
        """θ from coefficients (b, f) or (num, den), dropping the constrained one."""
        b = np.asarray(num, dtype=float)
        if self.unit_gain:
            b = b[:-1]
        return np.concatenate([b, np.asarray(den, dtype=float)[1:]])

    def static_gain(self, theta: NDArray[np.float64]) -> float:
        """G(1) (discrete) or G(0) (continuous)."""
        num, den = self.coefficients(theta)
        if self.kind == "oe":
            return float(num.sum() / den.sum()) if den.sum() != 0 else np.inf
        return float(num[-1] / den[-1]) if den[-1] != 0 else np.inf


def free_response(den: NDArray[np.float64], c: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Free response of 1/den from state ``c`` over ``n`` samples (linear in c)."""
    if den.size <= 1:
        return np.zeros(n)
    return sps.lfilter([1.0], den, np.zeros(n), zi=c)[0]


def free_responses(den: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """(n, order) independent free responses of 1/den."""
    order = den.size - 1
    return np.column_stack([free_response(den, np.eye(order)[j], n) for j in range(order)]) \
        if order else np.empty((n, 0))


def arx_fit(pairs: list[tuple[NDArray[np.float64], NDArray[np.float64]]], na: int, nb: int,
            nk: int, offset: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                     float]:
    """ARX ``A y = B q^(−nk) v (+ d)`` by least squares over records of (v, y).

    Returns a (monic A), b and the offset d (0 without one).
    """
    rows, rhs = [], []
    for v, y in pairs:
        lag = max(na, nk + nb - 1)
        n = y.size
        cols = [-y[lag - i: n - i] for i in range(1, na + 1)]
        cols += [v[lag - nk - j: n - nk - j] for j in range(nb)]
        if offset:
            cols.append(np.ones(n - lag))
        rows.append(np.column_stack(cols))
        rhs.append(y[lag:])
    phi, target = np.vstack(rows), np.concatenate(rhs)
    theta, *_ = np.linalg.lstsq(phi, target, rcond=None)
    a = np.concatenate([[1.0], theta[:na]])
    b = theta[na: na + nb]
    d = float(theta[-1]) if offset else 0.0
    return a, b, d


def stable(den: NDArray[np.float64]) -> NDArray[np.float64]:
    """The denominator with roots outside the unit circle reflected inside."""
    if den.size <= 1:
        return den
    roots = np.roots(den)
    big = np.abs(roots) >= 1.0
    if not big.any():
        return den
    roots[big] = 0.98 / np.conj(roots[big])
    return np.real(np.poly(roots))
