"""A discrete state-space model as common-denominator output-error polynomials.

An order-n model ``x(t+1) = A x + B u, y = C x + D u`` has the transfer
matrix ``G(q) = N(q⁻¹)/F(q⁻¹)``: F is the characteristic polynomial of A
(monic, degree n) and each entry N_oi(q⁻¹) = b_oi,0 + … + b_oi,n q⁻ⁿ
follows from the Markov parameters h_0 = D, h_k = C A^{k−1} B as the first
n + 1 terms of F·G.  For one output (SISO, MISO) this is exactly the
output-error model ``y = Σ_i B_i/F u_i + e`` a prediction-error fit starts
from; :func:`to_polynomial` returns it as a :class:`PolynomialModel`.

The same polynomials are the parameters of :func:`fit_n4sid`'s estimate,
in the convention of the prediction-error fits: θ = (b_0 … b_{nb−1} for each
output o and input i, where b_j multiplies u_i(t − nk − j), then the shared
f_1 … f_n), with the asymptotic prediction-error covariance computed here
from the exact output-error gradient.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import ModelError, OptionTypeError, ServoidWarning, check_option
from .._lazy import linalg
from .._lazy import signal as sps
from .._warn import warn
from ..models import PolynomialModel, StateSpace
from ._gram import lagged_gram

__all__ = ["oe_covariance", "oe_parameters", "oe_statespace", "to_polynomial"]

#: Largest relative size of a numerator coefficient that `nk` may drop without a warning.
_DROP_RTOL = 1e-6


def to_polynomial(
    model: StateSpace,
    structure: Literal["oe", "arx"] = "oe",
    *,
    nk: int | Sequence[int] | None = None,
    noise_variance: float = 0.0,
) -> PolynomialModel:
    """Return a SISO or MISO state-space model as polynomials in q⁻¹.

    The denominator is the characteristic polynomial of A (degree n, no
    cancellation); input i gets the numerator ``B_i(q⁻¹)`` with its delay
    ``nk_i``.  Use it to start a prediction-error fit from a subspace
    estimate, e.g. ``fit_oe(data, ..., init=to_polynomial(est.model))``.

    Parameters
    ----------
    model : StateSpace
        Discrete, one output, any number of inputs.
    structure : {"oe", "arx"}
        ``"oe"``: ``y = Σ B_i/F_i u_i(t − nk_i) + e`` with every F_i = F;
        ``"arx"``: ``F y = Σ B_i u_i(t − nk_i) + e``.
    nk : int or sequence of int, optional
        Delay per input [samples].  Default: the number of leading
        numerator coefficients that are exactly zero (1 when D = 0).  A
        larger delay drops the leading coefficients (a warning is issued if
        one exceeds 1e-6 of the largest).
    noise_variance : float
        Variance of the white noise e.

    Returns
    -------
    PolynomialModel
        ``b[i]`` has n + 1 − nk_i coefficients (trailing zeros kept, so the
        orders are those of the state-space model) and ``f[i]`` (or ``a``) n + 1.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.models import StateSpace
    >>> ss = StateSpace([[0.5]], [[1.0]], [[2.0]], [[0.0]], dt=0.1)
    >>> pm = to_polynomial(ss)
    >>> pm.structure, pm.nk, [float(v) for v in pm.b[0]], [float(v) for v in pm.f[0]]
    ('oe', (1,), [2.0], [1.0, -0.5])
    """
    check_option("structure", structure, ("oe", "arx"))
    if not isinstance(model, StateSpace):
        raise OptionTypeError(f"model must be a StateSpace, got {type(model).__name__}")
    if model.dt is None:
        raise ModelError("to_polynomial needs a discrete-time model; use c2d first")
    if model.n_outputs != 1:
        raise ModelError(
            f"to_polynomial needs one output (SISO or MISO), the model has {model.n_outputs}; "
            "convert each output row separately (model rows C[o], D[o])"
        )
    f, num = numerators(model)
    m = model.n_inputs
    if nk is None:
        delays = [_leading_zeros(num[0, i]) for i in range(m)]
    elif isinstance(nk, (list, tuple)):
        if len(nk) != m:
            raise ModelError(f"nk needs one delay per input ({m}), got {list(nk)}")
        delays = [as_int(f"nk[{i}]", v, minimum=0) for i, v in enumerate(nk)]
    else:
        delays = [as_int("nk", nk, minimum=0)] * m
    b = []
    for i, k in enumerate(delays):
        coeffs = num[0, i]
        if k > model.n_states:
            raise ModelError(f"nk[{i}] = {k} leaves no numerator coefficient for order "
                             f"{model.n_states}; use nk <= {model.n_states}")
        dropped = np.max(np.abs(coeffs[:k]), initial=0.0)
        if dropped > _DROP_RTOL * np.max(np.abs(coeffs)):
            warn(
                f"nk[{i}] = {k} drops numerator coefficient(s) up to {dropped:.3g} "
                f"(largest {np.max(np.abs(coeffs)):.3g}): the polynomial model differs from "
                "the state-space model",
                ServoidWarning,
            )
        b.append(coeffs[k:])
    if structure == "oe":
        return PolynomialModel([1.0], tuple(b), tuple(delays), model.dt, f=(f,) * m,
                               noise_variance=noise_variance)
    return PolynomialModel(f, tuple(b), tuple(delays), model.dt, noise_variance=noise_variance)


def numerators(model: StateSpace) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return F (n + 1,) and the numerators N (ny, m, n + 1), ascending in q⁻¹."""
    n = model.n_states
    f = np.poly(linalg.eigvals(model.A)).real if n else np.ones(1)
    markov = np.empty((n + 1, model.n_outputs, model.n_inputs))
    markov[0] = model.D
    ca = model.C.copy()
    for k in range(1, n + 1):
        markov[k] = ca @ model.B
        ca = ca @ model.A
    num = np.einsum("kl,lom->omk", _convolution_rows(f, n + 1), markov)
    return f, num


def oe_parameters(
    model: StateSpace, nk: int, inputs: Sequence[str], outputs: Sequence[str]
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """Return θ = (b_0…b_{n−nk} per output and input, then f_1…f_n) and the names."""
    f, num = numerators(model)
    n = model.n_states
    names: list[str] = []
    values = []
    for o, out in enumerate(outputs):
        for i, inp in enumerate(inputs):
            prefix = _prefix(inp, out, len(inputs), len(outputs))
            names += [f"{prefix}b{j}" for j in range(n + 1 - nk)]
            values.append(num[o, i, nk:])
    names += [f"f{k}" for k in range(1, n + 1)]
    values.append(f[1:])
    return np.concatenate(values), tuple(names)


def oe_statespace(
    theta: NDArray[np.float64], n: int, n_inputs: int, n_outputs: int, nk: int, dt: float
) -> StateSpace:
    """Realise the common-denominator model of θ as a StateSpace.

    One output: observer canonical form, order n.  One input: controller
    canonical form, order n.  Several of both: observer blocks per output,
    order n·ny (not minimal: every block carries the same poles).
    """
    f = np.concatenate([[1.0], theta[theta.size - n :]])
    nb = n + 1 - nk
    full = np.zeros((n_outputs, n_inputs, n + 1))
    full[:, :, nk:] = theta[: theta.size - n].reshape(n_outputs, n_inputs, nb)
    d = full[:, :, 0]
    resid = full[:, :, 1:] - d[:, :, None] * f[1:]  # (ny, m, n): strictly proper part
    comp = np.zeros((n, n))
    comp[:, 0] = -f[1:]
    comp[np.arange(n - 1), np.arange(1, n)] = 1.0
    if n_outputs == 1 or n_inputs > 1:
        blocks = n_outputs
        a = linalg.block_diag(*([comp] * blocks)) if n else np.zeros((0, 0))
        b = resid.transpose(0, 2, 1).reshape(n * blocks, n_inputs)
        c = np.kron(np.eye(n_outputs), np.eye(1, n)) if n else np.zeros((n_outputs, 0))
    else:  # one input: the dual (controller) form
        a = comp.T
        b = np.eye(n, 1)
        c = resid[:, 0, :]
    return StateSpace(a, b, c, d, dt)


def oe_covariance(
    model: StateSpace,
    nk: int,
    segments: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    noise_covariance: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Asymptotic PEM covariance of θ for white output errors.

    ``P = [Σ_t Ψ(t) Λ⁻¹ Ψ(t)ᵀ]⁻¹`` with ψ the exact output-error gradient
    (Ljung, *System Identification*, 2nd ed., 1999, eq. 9.29):
    ∂ŷ_o/∂f_k = −q⁻ᵏ ŷ_o/F and ∂ŷ_o/∂b_oi,k = q⁻ᵏ u_i/F.  For one output it
    is σ̂²(ΨᵀΨ)⁻¹.  The gradient Gram is built by
    :func:`~servoid.estimate._gram.lagged_gram` on the filtered signals (Ψ
    is never formed); the first n samples of each segment are skipped.

    Returns
    -------
    ndarray
        The covariance; NaN where the information matrix is singular.
    """
    f, num = numerators(model)
    n, ny, m = model.n_states, model.n_outputs, model.n_inputs
    nb = n + 1 - nk
    n_par = n + ny * m * nb
    lam = np.atleast_2d(noise_covariance)
    if not np.any(np.diag(lam) > 0):
        return np.zeros((n_par, n_par))  # noise-free data: nothing to spread
    # an output without residual would get infinite weight: floor it far below the others
    lam_inv = linalg.pinvh(lam + 1e-12 * np.trace(lam) / ny * np.eye(ny))
    sig = np.array([o for o in range(ny) for _ in range(n)]
                   + [ny + i for i in range(m) for _ in range(nb)], dtype=np.int64)
    lag = np.array(list(range(1, n + 1)) * ny + list(range(nk, n + 1)) * m, dtype=np.int64)
    gram = np.zeros((sig.size, sig.size))
    for u, _ in segments:
        if u.shape[0] <= n:
            continue
        w = sps.lfilter([1.0], f, u, axis=0)  # u_i/F
        # ŷ_o/F = Σ_i N_oi/F · (u_i/F): one more filter per output and input
        yf = [sum(sps.lfilter(num[o, i], f, w[:, i]) for i in range(m)) for o in range(ny)]
        gram += lagged_gram((*yf, *w.T), sig, lag, n)
    if not np.all(np.isfinite(gram)):
        return np.full((n_par, n_par), np.nan)
    fi = np.arange(ny * n).reshape(ny, n)  # f-gradient columns per output
    bi = ny * n + np.arange(m * nb).reshape(m, nb)
    info = np.zeros((n_par, n_par))
    info[:n, :n] = np.einsum("oq,okql->kl", lam_inv, gram[fi[:, :, None, None], fi[None, None]])
    for o in range(ny):
        cols = n + o * m * nb + np.arange(m * nb)
        cross = -np.einsum("q,qkc->kc", lam_inv[:, o], gram[fi[:, :, None], bi.ravel()[None]])
        info[:n, cols] = cross
        info[cols, :n] = cross.T
        for o2 in range(ny):
            cols2 = n + o2 * m * nb + np.arange(m * nb)
            info[np.ix_(cols, cols2)] = lam_inv[o, o2] * gram[np.ix_(bi.ravel(), bi.ravel())]
    # built with f first; θ has the b coefficients first
    order = np.concatenate([np.arange(n, n_par), np.arange(n)])
    info = info[np.ix_(order, order)]
    scale = np.sqrt(np.diag(info))
    if not np.all(scale > 0):
        return np.full((n_par, n_par), np.nan)
    scaled = info / np.outer(scale, scale)
    eig = np.linalg.eigvalsh(scaled)
    if eig[0] <= 1e-14 * eig[-1]:  # singular: a pole–zero cancellation, or order too high
        return np.full((n_par, n_par), np.nan)
    cov = linalg.inv(scaled) / np.outer(scale, scale)
    return (cov + cov.T) / 2


def _convolution_rows(f: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """T[k, l] = f_{k−l}: (F·h)_k = Σ_l T[k, l] h_l for k < size."""
    t = np.zeros((size, size))
    for k in range(size):
        for l_ in range(k + 1):
            if k - l_ < f.size:
                t[k, l_] = f[k - l_]
    return t


def _leading_zeros(coeffs: NDArray[np.float64]) -> int:
    nz = np.flatnonzero(coeffs)
    return int(nz[0]) if nz.size else 0


def _prefix(inp: str, out: str, m: int, ny: int) -> str:
    if ny > 1:
        return f"{inp}->{out}:"
    return f"{inp}:" if m > 1 else ""
