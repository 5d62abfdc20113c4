"""The one-step predictor of the general polynomial model and its exact gradient.

For ``A y = Σ B_i/F_i u_i + C/D e`` the prediction error is
``ε = (D/C)(A y − Σ_i w_i)`` with ``w_i = B_i/F_i u_i(t − nk_i)``, and the
gradient ψ = −∂ε/∂θ (Ljung, *System Identification*, 2nd ed., §10.3) is made
of a handful of filtered signals, each used at several lags:

====================  =====================================
parameter             ψ column
====================  =====================================
a_k                   −(D/C) y            at lag k
b_ij                  +(D/(C F_i)) u_i    at lag nk_i + j
f_ij                  −(D/(C F_i)) w_i    at lag j
c_k                   +(1/C) ε            at lag k
d_k                   −(1/C) v            at lag k, v = A y − Σ w_i
====================  =====================================

So the Gauss–Newton matrix ΨᵀΨ and the gradient Ψᵀε are lagged products
of those signals, which the one-pass kernels of
:mod:`servoid.estimate._gram` form without building Ψ.

Initial conditions
------------------
With ``initial="zero"`` every signal is zero before t = 0.  With
``initial="estimate"`` the unknown past enters ε as a free response
``Γ x``; its columns are again lags of two kinds of impulse responses,
``(1/C) δ`` (the past of y, v and ε) and ``−(D/(C F_i)) δ`` (the past of
u_i and w_i), so the same kernel gives ΓᵀΓ and ΨᵀΓ.  For each θ the
initial values x are eliminated by linear least squares (variable
projection; Golub & Pereyra 1973); the predictor then runs with x
entered as pulses at the filter inputs, its derivative at fixed x is the
same table above, and the Gauss–Newton matrix is the Schur complement
``ΨᵀΨ − ΨᵀΓ (ΓᵀΓ)⁺ ΓᵀΨ`` (the projected Jacobian of Kaufman 1975).

Filtered Gram matrix
--------------------
The robust covariance (:mod:`servoid.estimate._covariance`) needs
``Ψ̃ᵀΨ̃`` with every column of Ψ filtered by ``1/A_v(q)``.  A causal filter
from rest commutes with the delays that make the columns, so filtering
the few base signals once and handing them to the same lagged-Gram plan
gives it (exactly when the sum starts at t = 0 and the signals start at
rest); with estimated initial values the projected columns
``Ψ − Γ (ΓᵀΓ)⁺ΓᵀΨ`` are filtered, which is a quadratic form of the
filtered Gram matrix of [Ψ, Γ].  Either way the result is a Gram matrix,
so it is positive semidefinite by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._gram import _assemble, _full_sums
from ._pem_kernels import EMPTY, ar_filter, filt, sum_squares
from ._pem_orders import PemOrders, Polys, SignalData

__all__ = ["GramPlan", "Problem"]

_ONE = np.ones(1)
#: Relative eigenvalue floor of the scaled ΓᵀΓ: directions below it are
#: dependent initial values (an over-parameterised free response).
_IC_RANK_TOL = 1e-11


class GramPlan:
    """Lagged Gram matrix of fixed (signal, lag) columns, reused across calls."""

    def __init__(self, signal: NDArray[np.int64], lag: NDArray[np.int64]) -> None:
        self.signal = np.asarray(signal, dtype=np.int64)
        self.lag = np.asarray(lag, dtype=np.int64)
        n = self.signal.size
        keys: dict[tuple[int, int, int], int] = {}
        self.pair_key = np.empty((n, n), dtype=np.int64)
        for p in range(n):
            for q in range(p, n):
                a, b, d = int(self.signal[p]), int(self.signal[q]), int(self.lag[p] - self.lag[q])
                if d < 0:
                    a, b, d = b, a, -d
                self.pair_key[p, q] = keys.setdefault((a, b, d), len(keys))
        self.keys = np.array(list(keys), dtype=np.int64).reshape(-1, 3)

    def __call__(self, z: tuple[NDArray[np.float64], ...], start: int) -> NDArray[np.float64]:
        """Σ_{t>=start} z_{s_p}(t − l_p) z_{s_q}(t − l_q) for every column pair."""
        full = np.zeros(self.keys.shape[0])
        _full_sums(z, self.keys, full)
        gram = np.empty((self.signal.size, self.signal.size))
        _assemble(z, self.signal, self.lag, start, self.pair_key, full, gram)
        return gram


@dataclass(frozen=True, eq=False)
class _Coefs:
    """Filter coefficients of one θ."""

    polys: Polys
    cf: tuple[NDArray[np.float64], ...]  # C·F_i

    @classmethod
    def of(cls, orders: PemOrders, theta: NDArray[np.float64]) -> _Coefs:
        p = orders.split(theta)
        return cls(p, tuple(np.convolve(p.c, f) for f in p.f))


class _Segment:
    """Padded signal buffers of one segment and the filters that fill them."""

    def __init__(self, orders: PemOrders, y: NDArray[np.float64],
                 us: tuple[NDArray[np.float64], ...], pad: int, estimate: bool) -> None:
        self.orders = orders
        self.pad = pad
        self.n = y.size
        length = pad + y.size
        self.y = self._padded(y, length)
        self.u = [self._padded(u, length) for u in us]
        trivial = orders.noise_free
        self.uf = [u if nf == 0 else np.zeros(length) for u, nf in zip(self.u, orders.nf,
                                                                      strict=True)]
        self.w = [np.zeros(length) for _ in us]
        self.v = np.zeros(length)
        n0, ni = initial_sizes(orders) if estimate else (0, [0] * len(us))
        self.eps = self.v if trivial and n0 == 0 else np.zeros(length)
        self.ya = self.y if trivial else np.zeros(length)
        self.ub = list(self.uf) if trivial else [np.zeros(length) for _ in us]
        self.wf = [np.zeros(length) for _ in us]
        self.ec = np.zeros(length)
        self.vc = np.zeros(length)
        self.delta = np.zeros(length)
        self.delta[pad] = 1.0
        self.g0 = np.zeros(length)
        self.gi = [np.zeros(length) for _ in us]
        self.n0, self.ni = n0, ni
        self.pulses: tuple[NDArray[np.float64], tuple[NDArray[np.float64], ...]] | None = None
        # the order of signals in the Gram kernels' z tuple (see Problem._columns)
        self.z = (self.eps, self.ya, *self.ub, *self.wf, self.ec, self.vc, self.g0, *self.gi)

    @staticmethod
    def _padded(x: NDArray[np.float64], length: int) -> NDArray[np.float64]:
        out = np.zeros(length)
        out[length - x.size:] = x
        return out

    def errors(self, co: _Coefs, pulses: tuple[NDArray[np.float64],
                                               tuple[NDArray[np.float64], ...]] | None) -> None:
        """Fill uf, w, v and ε; ``pulses`` = (p0, (p_i)) set the initial conditions."""
        o, p, pad = self.orders, co.polys, self.pad
        p0 = EMPTY if pulses is None else pulses[0]
        for i in range(o.n_inputs):
            if o.nf[i]:
                filt(_ONE, p.f[i], self.u[i], self.uf[i], pad, 0, EMPTY)
            pi = EMPTY if pulses is None else pulses[1][i]
            if pi.size:  # a free response: w_i = (B_i u_i + p_i)/F_i in one pass
                filt(p.b[i], p.f[i], self.u[i], self.w[i], pad, o.nk[i], pi)
            else:
                filt(p.b[i], _ONE, self.uf[i], self.w[i], pad, o.nk[i], EMPTY)
        if o.na:
            filt(p.a, _ONE, self.y, self.v, pad, 0, EMPTY)
        else:
            self.v[:] = self.y
        for w in self.w:
            self.v -= w
        if self.eps is not self.v:
            filt(p.d, p.c, self.v, self.eps, pad, 0, p0)
        self.pulses = pulses

    def gradients(self, co: _Coefs) -> None:
        """Fill the ψ signals from the signals :meth:`errors` left."""
        o, p, pad = self.orders, co.polys, self.pad
        trivial = o.noise_free
        if o.na and not trivial:
            filt(p.d, p.c, self.y, self.ya, pad, 0, EMPTY)
        for i in range(o.n_inputs):
            if not trivial:
                filt(p.d, co.cf[i], self.u[i], self.ub[i], pad, 0, EMPTY)
            if o.nf[i]:
                filt(p.d, co.cf[i], self.w[i], self.wf[i], pad, 0, EMPTY)
        if o.nc:
            filt(_ONE, p.c, self.eps, self.ec, pad, 0, EMPTY)
        if o.nd:
            filt(_ONE, p.c, self.v, self.vc, pad, 0, EMPTY)

    def impulses(self, co: _Coefs) -> None:
        """Fill the impulse responses whose lags span the free response Γ."""
        p, pad = co.polys, self.pad
        if self.n0:
            filt(_ONE, p.c, self.delta, self.g0, pad, 0, EMPTY)
        for i, n in enumerate(self.ni):
            if n:
                filt(p.d, co.cf[i], self.delta, self.gi[i], pad, 0, EMPTY)

    def error_view(self, start: int) -> NDArray[np.float64]:
        """ε(t) for t >= start (a view into the buffer)."""
        return self.eps[self.pad + start:]


def initial_sizes(orders: PemOrders) -> tuple[int, list[int]]:
    """Sizes of the free-response bases: (1/C)δ lags and (D/(C F_i))δ lags per input."""
    n0 = max(orders.na + orders.nd, orders.nc, orders.nd)
    ni = [max(nf, nk + nb - 1) for nf, nk, nb in zip(orders.nf, orders.nk, orders.nb, strict=True)]
    return n0, ni


def _pinv_psd(g: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """Pseudo-inverse of a small positive semidefinite matrix, and its rank."""
    s = np.sqrt(np.clip(np.diag(g), 0.0, None))
    s[s == 0] = 1.0
    lam, vec = np.linalg.eigh(g / np.outer(s, s))
    keep = lam > _IC_RANK_TOL * max(float(lam[-1]), 1e-300)
    inv = (vec[:, keep] / lam[keep]) @ vec[:, keep].T
    return inv / np.outer(s, s), int(keep.sum())


class Problem:
    """Prediction errors and Gauss–Newton normal equations over all segments."""

    def __init__(self, orders: PemOrders, data: SignalData, start: int, estimate: bool) -> None:
        self.orders = orders
        self.start = start
        self.estimate = estimate
        self.pad = orders.max_lag + max(orders.nf) + orders.nc + orders.nd + orders.na + 2
        # a segment with no sample past `start` gives no equation (and the Gram kernel's end
        # corrections assume at least one)
        self.segments = [_Segment(orders, y, us, self.pad, estimate)
                         for y, us in zip(data.y, data.u, strict=True) if y.size > start]
        sig, lag, sign, n_ic = self._columns()
        self.n_theta = orders.n_parameters
        self.sign = sign
        n = self.n_theta
        self.full_plan = GramPlan(sig, lag)
        # Γ columns and ε only: for eliminating x at a trial point
        self.ic_plan = GramPlan(sig[n:], lag[n:]) if n_ic else None
        self.n_ic = n_ic
        self.ic_rank = 0
        self._at: NDArray[np.float64] | None = None  # θ whose signals the buffers hold
        self._meat_plan: GramPlan | None = None  # [Ψ, Γ] without ε, built on first use

    def _columns(self) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], int]:
        o = self.orders
        m = o.n_inputs
        # z = (eps, ya, ub_1..ub_m, wf_1..wf_m, ec, vc, g0, gi_1..gi_m)
        eps, ya, ub, wf, ec, vc, g0, gi = 0, 1, 2, 2 + m, 2 + 2 * m, 3 + 2 * m, 4 + 2 * m, 5 + 2 * m
        sig, lag, sign = [], [], []

        def add(s: int, lags: range, sg: float) -> None:
            sig.extend([s] * len(lags))
            lag.extend(lags)
            sign.extend([sg] * len(lags))

        add(ya, range(1, o.na + 1), -1.0)
        for i in range(m):
            add(ub + i, range(o.nk[i], o.nk[i] + o.nb[i]), 1.0)
            add(wf + i, range(1, o.nf[i] + 1), -1.0)
        add(ec, range(1, o.nc + 1), 1.0)
        add(vc, range(1, o.nd + 1), -1.0)
        n_ic = 0
        if self.estimate:
            n0, ni = initial_sizes(o)
            add(g0, range(n0), 1.0)
            for i in range(m):
                add(gi + i, range(ni[i]), -1.0)
            n_ic = n0 + sum(ni)
        add(eps, range(1), 1.0)
        return (np.array(sig, dtype=np.int64), np.array(lag, dtype=np.int64),
                np.array(sign), n_ic)

    @property
    def start_index(self) -> int:
        """First summed index in the padded buffers."""
        return self.pad + self.start

    def cost(self, theta: NDArray[np.float64]) -> float:
        """Σ ε(t)² over t >= start of every segment (x eliminated when estimated)."""
        co = _Coefs.of(self.orders, theta)
        self._at = np.array(theta, dtype=float)
        total = 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            for seg in self.segments:
                seg.errors(co, None)
                if self.ic_plan is not None:
                    seg.errors(co, self._initial_values(seg, co))
                total += float(sum_squares(seg.eps, self.start_index))
        return total

    def _initial_values(self, seg: _Segment, co: _Coefs) -> tuple[NDArray[np.float64],
                                                                    tuple[NDArray[np.float64], ...]]:
        seg.impulses(co)
        assert self.ic_plan is not None
        s = self.sign[self.n_theta:]
        g = self.ic_plan(seg.z, self.start_index) * np.outer(s, s)
        inv, _ = _pinv_psd(g[:-1, :-1])
        x = -inv @ g[:-1, -1]
        p0, o = x[: seg.n0], seg.n0
        pis = []
        for n in seg.ni:
            pis.append(x[o: o + n])
            o += n
        return p0, tuple(pis)

    def normal_equations(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                     NDArray[np.float64]]:
        """ΨᵀΨ and Ψᵀε at θ (the prediction errors are recomputed unless current)."""
        if self._at is None or not np.array_equal(self._at, theta):
            self.cost(theta)
        co = _Coefs.of(self.orders, theta)
        n = self.n_theta
        h = np.zeros((n, n))
        g = np.zeros(n)
        rank = 0
        for seg in self.segments:
            seg.gradients(co)
            gram = self.full_plan(seg.z, self.start_index) * np.outer(self.sign, self.sign)
            if self.n_ic:
                # Schur complement: the initial values are eliminated at every θ
                inv, r = _pinv_psd(gram[n:-1, n:-1])
                cross = gram[:n, n:-1]
                h += gram[:n, :n] - cross @ inv @ cross.T
                g += gram[:n, -1] - cross @ inv @ gram[n:-1, -1]
                rank += r
            else:
                h += gram[:n, :n]
                g += gram[:n, -1]
        self.ic_rank = rank
        return h, g

    def residuals(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """ε(t), t >= start, of every segment, concatenated (a copy)."""
        self.cost(theta)
        return np.concatenate([seg.error_view(self.start).copy() for seg in self.segments]
                              or [np.zeros(0)])

    def errors_at(self, theta: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """ε(t), t >= start, per segment at θ (views, valid until the next call)."""
        self._ensure(theta)
        return [seg.error_view(self.start) for seg in self.segments]

    def filtered_gram(self, theta: NDArray[np.float64],
                      ar: NDArray[np.float64]) -> NDArray[np.float64]:
        """Σ_segments Ψ̃ᵀΨ̃ at θ, Ψ̃ = Ψ/ar(q) (projected when x is estimated)."""
        self._ensure(theta)
        co = _Coefs.of(self.orders, theta)
        n = self.n_theta
        if self._meat_plan is None:
            self._meat_plan = GramPlan(self.full_plan.signal[:-1], self.full_plan.lag[:-1])
        plan = self._meat_plan
        sign = self.sign[:-1]
        used = sorted(set(plan.signal.tolist()))
        out = np.zeros((n, n))
        for seg in self.segments:
            seg.gradients(co)
            z = list(seg.z)
            done: dict[int, NDArray[np.float64]] = {}
            for k in used:  # several z entries can share a buffer (the OE aliases)
                if id(seg.z[k]) not in done:
                    filtered = np.empty_like(seg.z[k])
                    ar_filter(ar, seg.z[k], filtered)
                    done[id(seg.z[k])] = filtered
                z[k] = done[id(seg.z[k])]
            gram = plan(tuple(z), self.start_index) * np.outer(sign, sign)
            if self.n_ic:
                # the projection Ψ − Γ K uses K from the unfiltered Gram matrix
                raw = plan(seg.z, self.start_index) * np.outer(sign, sign)
                inv, _ = _pinv_psd(raw[n:, n:])
                k_mat = inv @ raw[n:, :n]
                t = np.vstack([np.eye(n), -k_mat])
                out += t.T @ gram @ t
            else:
                out += gram
        return 0.5 * (out + out.T)

    def _ensure(self, theta: NDArray[np.float64]) -> None:
        """Make the buffers hold the prediction errors of θ."""
        if self._at is None or not np.array_equal(self._at, theta):
            self.cost(theta)
