"""Start values of the prediction-error search.

The default start is consistent, so Gauss–Newton starts inside the basin
of the global minimum for long enough records (Ljung, *System
Identification*, 2nd ed., §10.4):

1. **A** (when na > 0): IV estimate of the ARX part (:func:`iv_core`).
2. **B_i, F_i** (when some nf_i > 0): an IV estimate with a common
   denominator ``Σ nf_i`` on ``Â y`` — exact for one input; with several,
   each input's simulated contribution ``ŵ_i`` is then reduced to
   ``B_i/F_i`` by least squares on the noise-free ŵ_i.  If the common
   denominator is not identifiable (inputs sharing poles), each input gets
   its own IV with the other inputs counted as noise.
3. **C, D**: Hannan–Rissanen on the residual ``v̂ = Â y − Σ B̂_i/F̂_i u_i``:
   a long AR model estimates the innovations ê, then ``D v̂ = C ê`` is a
   linear regression (Hannan & Rissanen, *Biometrika* 69, 1982).

Roots of F, C and D outside the unit circle are reflected into it.
For output error with one input, :func:`sm_starts` adds
Steiglitz–McBride iterates as competing candidates (scored in ``_pem``).
Random starts (multistart) draw stable F, C, D and solve the linear
parameters A, B exactly for them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .._errors import DataError, IdentifiabilityError
from .._lazy import signal as sps
from ._gram import lagged_gram
from ._iv import ar_fit, arx_ls, iv_core, readonly, solve_normal, split_arx
from ._pem_kernels import reflect
from ._pem_orders import PemOrders, Polys, SignalData
from ._pem_predictor import Problem

__all__ = ["iv_start", "random_start", "sm_starts", "stabilize"]

_ONE = np.ones(1)


def iv_start(orders: PemOrders, sd: SignalData, start: int) -> tuple[NDArray[np.float64], str]:
    """A consistent start θ and a word on how it was made."""
    m = orders.n_inputs
    ys, us = sd.y, sd.u
    a = _ONE
    bs: list[NDArray[np.float64]] = [np.zeros(n) for n in orders.nb]
    fs: list[NDArray[np.float64]] = [_ONE] * m
    how = []
    if orders.na:
        first = max(start, orders.na, *(k + b - 1 for k, b in zip(orders.nk, orders.nb,
                                                                   strict=True)))
        fit = iv_core(ys, us, us, orders.na, orders.nb, orders.nk, first, 0)
        a, bs = split_arx(fit.theta, orders.na, orders.nb)
        how.append("IV ARX for A")
    if any(orders.nf):
        y_tilde = tuple(sps.lfilter(a, [1.0], y) for y in ys) if orders.na else ys
        try:
            bs, fs = _common_denominator(orders, y_tilde, us, start)
            how.append("IV with a common denominator for B/F" if m > 1 else "IV for B/F")
        except (IdentifiabilityError, DataError):
            bs, fs = _per_input(orders, y_tilde, us, start)
            how.append("IV per input for B/F")
    elif not orders.na:
        first = max(start, *(k + b - 1 for k, b in zip(orders.nk, orders.nb, strict=True)))
        theta = arx_ls(ys, us, 0, orders.nb, orders.nk, first)
        bs = split_arx(theta, 0, orders.nb)[1]
        how.append("LS for B")
    c, d = _ONE, _ONE
    if orders.nc or orders.nd:
        v = [_plant_residual(y, u, a, bs, fs, orders.nk) for y, u in zip(ys, us, strict=True)]
        try:
            c, d = arma_start(v, orders.nc, orders.nd, max(start, orders.max_lag))
            how.append("Hannan-Rissanen for C/D")
        except (IdentifiabilityError, DataError):
            how.append("C = D = 1 (no noise to model)")
    polys = Polys(a, tuple(bs), tuple(fs), _pad(c, orders.nc), _pad(d, orders.nd))
    return orders.join(polys), ", ".join(how)


def sm_starts(orders: PemOrders, sd: SignalData, start: int, iterations: int,
              samples: int) -> list[NDArray[np.float64]]:
    """Steiglitz–McBride iterates for an output-error structure with one input.

    From F₀ = 1 (the first iterate is the ARX fit), each iterate filters y
    and u by 1/F_k and solves the ARX least-squares problem for
    (F_{k+1}, B_{k+1}) (K. Steiglitz and L. E. McBride, "A technique for
    the identification of linear systems", IEEE Trans. Automatic Control
    10(4), 1965, 461–464; on such starts for the non-convex output-error
    criterion: Ljung, *System Identification*, 2nd ed., 1999, §10.4, and
    Söderström & Stoica, *System Identification*, 1989).  With coloured
    noise the iterates are biased and need not converge, so every one is
    returned as a candidate start; F is reflected into the unit circle.
    Only the first ``samples`` samples of each segment are used (a start,
    not an estimate: its cost stays bounded at any N).
    """
    if orders.na or orders.nc or orders.nd or orders.n_inputs != 1 or not orders.nf[0]:
        return []
    nf, nb, nk = orders.nf[0], orders.nb[0], orders.nk[0]
    first = max(start, nf, nk + nb - 1)
    ys = [y[:samples] for y in sd.y if min(y.size, samples) > first + nf + nb]
    us = [u[0][:samples] for y, u in zip(sd.y, sd.u, strict=True)
          if min(y.size, samples) > first + nf + nb]
    if not ys:
        return []
    f = _ONE
    out: list[NDArray[np.float64]] = []
    for _ in range(iterations):
        yf = [sps.lfilter(_ONE, f, y) for y in ys]
        uf = [(sps.lfilter(_ONE, f, u),) for u in us]
        try:
            theta = arx_ls(yf, uf, nf, [nb], [nk], first)
        except (IdentifiabilityError, DataError):
            break
        if not np.all(np.isfinite(theta)):
            break
        f, b = split_arx(theta, nf, [nb])
        f = reflect(f)[0]
        out.append(np.concatenate([b[0], f[1:]]))
    return out


def arma_start(vs: Sequence[NDArray[np.float64]], nc: int, nd: int,
               start: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(C, D) of ``D v = C e`` by Hannan–Rissanen (AR when nc = 0)."""
    if nc == 0:
        return _ONE, ar_fit(vs, nd, start)
    rows = sum(max(v.size - start, 0) for v in vs)
    n_long = int(min(max(20, 3 * (nc + nd)), max(rows // 10, nc + nd + 1)))
    long_ar = ar_fit(vs, n_long, start)
    es = [sps.lfilter(long_ar, [1.0], v) for v in vs]
    first = start + n_long + max(nc, nd)
    sig = np.array([0] * nd + [1] * nc + [0], dtype=np.int64)
    lag = np.array([*range(1, nd + 1), *range(1, nc + 1), 0], dtype=np.int64)
    sign = np.array([-1.0] * nd + [1.0] * nc + [1.0])
    gram = sum(lagged_gram(readonly((v, e)), sig, lag, first) for v, e in zip(vs, es, strict=True)
               if v.size > first)
    gram = np.asarray(gram) * np.outer(sign, sign)
    theta = solve_normal(gram[:-1, :-1], gram[:-1, -1])
    return np.concatenate([[1.0], theta[nd:]]), np.concatenate([[1.0], theta[:nd]])


def stabilize(orders: PemOrders, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """θ with the roots of F_i, C, D outside the unit circle reflected; the count."""
    p = orders.split(theta)
    count = 0
    fs = []
    for f in p.f:
        f, n = reflect(f)
        fs.append(f)
        count += n
    c, nc = reflect(p.c)
    d, nd = reflect(p.d)
    count += nc + nd
    if count == 0:
        return theta, 0
    return orders.join(Polys(p.a, p.b, tuple(fs), c, d)), count


def random_start(orders: PemOrders, problem: Problem,
                 rng: np.random.Generator) -> NDArray[np.float64]:
    """Random stable F_i, C, D; A and B solved exactly (ε is linear in them)."""
    fs = tuple(_random_stable(n, rng) for n in orders.nf)
    polys = Polys(np.concatenate([_ONE, np.zeros(orders.na)]),
                  tuple(np.zeros(n) for n in orders.nb), fs,
                  _random_stable(orders.nc, rng), _random_stable(orders.nd, rng))
    theta = orders.join(polys)
    a, bs, _, _, _ = orders.blocks()
    linear = np.concatenate([np.arange(a.start, a.stop),
                             *(np.arange(s.start, s.stop) for s in bs)])
    problem.cost(theta)
    h, g = problem.normal_equations(theta)
    try:
        theta[linear] += solve_normal(h[np.ix_(linear, linear)], g[linear])
    except IdentifiabilityError:
        pass  # leave B = 0: the search still starts from a stable point
    return theta


def _random_stable(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """A monic polynomial of degree n with random roots of radius 0.2–0.95."""
    roots: list[complex] = []
    for _ in range(n // 2):
        r = rng.uniform(0.2, 0.95)
        w = rng.uniform(0.0, np.pi)
        roots += [r * np.exp(1j * w), r * np.exp(-1j * w)]
    if n % 2:
        roots.append(rng.uniform(-0.95, 0.95))
    return np.real(np.poly(roots)) if roots else _ONE.copy()


def _common_denominator(orders: PemOrders, ys: Sequence[NDArray[np.float64]],
                        us: Sequence[tuple[NDArray[np.float64], ...]],
                        start: int) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    m = orders.n_inputs
    na2 = sum(orders.nf)
    nb2 = [nb + na2 - nf for nb, nf in zip(orders.nb, orders.nf, strict=True)]
    first = max(start, na2, *(k + b - 1 for k, b in zip(orders.nk, nb2, strict=True)))
    fit = iv_core(ys, us, us, na2, nb2, orders.nk, first, 0)
    a2, b2 = split_arx(fit.theta, na2, nb2)
    if m == 1:
        f, _ = reflect(a2)
        return [b2[0]], [f]
    a2 = reflect(a2)[0]
    bs, fs = [], []
    for i in range(m):
        num = np.concatenate([np.zeros(orders.nk[i]), b2[i]])
        w = [sps.lfilter(num, a2, u[i]) for u in us]
        b, f = _reduce(w, [(u[i],) for u in us], orders, i, start)
        bs.append(b)
        fs.append(f)
    return bs, fs


def _per_input(orders: PemOrders, ys: Sequence[NDArray[np.float64]],
               us: Sequence[tuple[NDArray[np.float64], ...]],
               start: int) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    bs, fs = [], []
    for i in range(orders.n_inputs):
        nf, nb, nk = orders.nf[i], orders.nb[i], orders.nk[i]
        first = max(start, nf, nk + nb - 1)
        ui = [(u[i],) for u in us]
        fit = iv_core(ys, ui, ui, nf, [nb], [nk], first, 0)
        f, b = split_arx(fit.theta, nf, [nb])
        bs.append(b[0])
        fs.append(reflect(f)[0])
    return bs, fs


def _reduce(w: Sequence[NDArray[np.float64]], ui: Sequence[tuple[NDArray[np.float64], ...]],
            orders: PemOrders, i: int, start: int) -> tuple[NDArray[np.float64],
                                                            NDArray[np.float64]]:
    nf, nb, nk = orders.nf[i], orders.nb[i], orders.nk[i]
    first = max(start, nf, nk + nb - 1)
    theta = arx_ls(w, ui, nf, [nb], [nk], first)
    f, b = split_arx(theta, nf, [nb])
    return b[0], reflect(f)[0]


def _plant_residual(y: NDArray[np.float64], us: tuple[NDArray[np.float64], ...],
                    a: NDArray[np.float64], bs: Sequence[NDArray[np.float64]],
                    fs: Sequence[NDArray[np.float64]], nk: Sequence[int]) -> NDArray[np.float64]:
    v = sps.lfilter(a, [1.0], y) if a.size > 1 else np.array(y, dtype=float)
    for u, b, f, k in zip(us, bs, fs, nk, strict=True):
        v -= sps.lfilter(np.concatenate([np.zeros(k), b]), f, u)
    return np.asarray(v, dtype=float)


def _pad(p: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    out = np.zeros(n + 1)
    out[0] = 1.0
    k = min(n + 1, p.size)
    out[:k] = p[:k]
    return out

