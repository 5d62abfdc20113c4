"""Instrumental variables for the ARX structure, open and closed loop.

The equation ``y(t) = φ(t)ᵀθ + w(t)`` with ``φ = [−y(t−1) … −y(t−na),
u_i(t−nk_i) … ]`` is solved with instruments ζ(t) correlated with φ but not
with the equation error w: ``θ̂ = (Σ ζφᵀ)⁻¹ Σ ζ y`` (Söderström & Stoica,
*Instrumental Variable Methods for System Identification*, 1983;
Ljung, *System Identification*, 2nd ed., §7.6 and §15.3).

Open loop (``instrument="auto"``), in the spirit of IV4 and of Young's
refined IV: (1) least squares; (2) the basic IV estimate with instruments
``ζ = [−x(t−k), u_i(t−nk_i−j)]`` from the noise-free output ``x = B̂/Â u``
of that model; then ``iterations`` refinement passes, each (3) fitting an
AR noise model ``D̂ v̂ ≈ e`` to the output error ``v̂ = y − B̂/Â u`` and (4)
solving the IV equations again with instruments from the latest model and
every signal prefiltered by ``L = D̂/Â``.  The equation error is
``w = A v``, so ``L w ≈ D̂ v ≈ e``: the prefilter whitens it, which makes the
estimate nearly as efficient as the prediction-error estimate (Young,
*Recursive Estimation and Time-Series Analysis*, 2nd ed., 2011, ch. 7;
Ljung §15.3 describes IV4, which whitens with an AR model of w instead —
too short an AR model when A has poles near the unit circle).

Closed loop (``instrument="r"``) replaces the input in the instruments by
its part driven by the reference, ``ū_i``: an auxiliary ARX model from r
to u_i simulated from r.  Anything computed from r alone is uncorrelated
with the noise even though u is not (the controller feeds the noise back),
so the estimate stays consistent with an unknown controller; the same
refinement then uses ``x = B̂/Â ū`` (Gilson & Van den Hof, *Automatica*
41(2), 2005, the "tailor-made" closed-loop IV).

Covariance
----------
With ``M = Z_LᵀΦ_L`` (the prefiltered instruments Z_L and regressors Φ_L)
and w_L the prefiltered equation error ``L(Â y − B̂ u)``, the estimate's
error is ``M⁻¹ Σ ζ_L(t) w_L(t)`` and its covariance the sandwich
``P = M⁻¹ [Σ_τ r_w(τ) Σ_t ζ_L(t) ζ_L(t−τ)ᵀ] M⁻ᵀ`` (Söderström & Stoica
1983, §4.3), computed by :mod:`servoid.estimate._covariance`:

* ``"white"``: ``σ̂² M⁻¹ (Z_LᵀZ_L) M⁻ᵀ``, σ̂² the variance of w_L.  It
  assumes that L whitens the equation error; with ``iterations=0`` (no
  prefilter) it holds only for a white equation error (ARX data).
* ``"robust"`` (what ``"auto"`` means): r_w from an AR model of w_L chosen
  by AIC.  Where the prefilter whitens, AIC mostly picks order 0 and this
  is the white formula exactly; where a fixed-order AR prefilter cannot
  whiten (a noise zero near the unit circle: ``(1 − 0.9q⁻¹)e`` on the
  closed-loop test rig, 40 seeds) the white formula overstated the
  standard deviations 1.4–2.5× (every interval covered) while this one
  covered 96 %; and for the basic IV it replaces a formula that is simply
  wrong for coloured noise (σ of a1, a2 ×1.4 too large on the ARMA rig).
  The prefilter is a whitening device of fixed order, not a noise model
  validated by the fit, so ``"auto"`` does not trust it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import DataError, IdentifiabilityError, OptionError, check_option
from .._lazy import signal as sps
from ..data import Experiment, ExperimentSet
from ..models import PolynomialModel
from ._arx import ArxOrders, _parameter_names
from ._covariance import COVARIANCES, Covariance, resolve, sandwich_covariance
from ._estimate import Estimate
from ._gram import lagged_gram
from ._pem_kernels import reflect
from ._pem_orders import SignalData, check_record, prepare

__all__ = ["IvFit", "ar_fit", "arx_ls", "aux_inputs", "equation_error", "fit_iv", "iv_core",
           "noise_order", "readonly", "solve_normal", "split_arx"]

Instrument = Literal["auto", "r"]
Arrays = tuple[NDArray[np.float64], ...]

#: cond(scaled ζᵀφ) above which the instruments do not determine θ.
_IV_COND_LIMIT = 1e10
#: Most refinement passes: the estimate settles in a handful (Young & Jakeman).
_MAX_ITERATIONS = 100


@dataclass(frozen=True, eq=False)
class IvFit:
    """Result of :func:`iv_core` (parameters in ARX order a1…, b…)."""

    theta: NDArray[np.float64]
    covariance: NDArray[np.float64]
    sigma2: float
    noise: NDArray[np.float64]
    passes: int
    covariance_kind: str  # "white" or "robust"
    ar_order: int | None  # order of the residual AR model (robust only)


def fit_iv(
    data: Experiment | ExperimentSet,
    na: int,
    nb: int | Sequence[int],
    nk: int | Sequence[int] = 1,
    *,
    instrument: Instrument = "auto",
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    iterations: int = 2,
    start: int | None = None,
    covariance: Covariance = "auto",
    auxiliary_order: int | None = None,
) -> Estimate:
    """Fit an ARX-structure model by instrumental variables.

    Consistent where least squares is biased: coloured equation error (the
    data come from an OE, ARMAX or BJ system) and, with ``instrument="r"``,
    closed-loop data with an unknown controller.  See the module notes for
    the algorithm (refined IV / IV4) and the covariance formula.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s); segments are never joined.
    na : int
        Number of A coefficients after the leading 1.
    nb : int or sequence of int
        Number of B coefficients per input.
    nk : int or sequence of int
        Input delay per input [samples].
    instrument : {"auto", "r"}
        ``"auto"``: instruments simulated from the input (open loop).
        ``"r"``: instruments built from the reference channel(s) (closed
        loop); the data must have a channel with role ``r``.
    input : {"u", "r"}
        Role of the input channels the model is driven by.
    output : str, optional
        Output channel when there are several.
    iterations : int
        Refinement passes (noise-model prefilter + instruments from the
        latest model), >= 0; 0 is the basic IV.  The default 2 takes the
        prefilter and instruments from an already refined estimate: on the
        seeded studies of the tests the reported covariance then matches
        the scatter of the estimates, with 1 it overstates it.
    start : int, optional
        First sample of each segment used as an equation (default: the
        longest lag); a common start makes fits of different orders comparable.
    covariance : {"auto", "white", "robust"}
        ``"white"`` trusts the prefilter to whiten the equation error;
        ``"robust"`` (and ``"auto"``) is the sandwich with the residual's
        own autocovariance (module notes).
    auxiliary_order : int, optional
        With ``instrument="r"``: the order n of the auxiliary ARX(n, n + 1)
        model r → u whose simulation from r replaces the input in the
        instruments; 0 uses the reference itself (its plain lags).  Default
        ``min(max(2(na + max nb), 6), 30)``.

    Returns
    -------
    Estimate
        ``model`` is an ARX-form :class:`~servoid.models.PolynomialModel`
        (it carries no noise model); parameters ``a1…, b0…`` as in
        :func:`fit_arx`; ``residuals`` are the equation errors ``Â y − B̂ u``;
        ``options["covariance"]`` is ``"white"`` or ``"robust"`` and
        ``options["covariance_ar_order"]`` the order of the residual AR
        model (None for ``"white"``).

    Raises
    ------
    IdentifiabilityError
        A constant input, or instruments uncorrelated with the regressors.
    DataError
        Too few samples, a missing channel or reference.
    OptionError
        An unknown ``instrument`` or ``input``.
    """
    check_option("instrument", instrument, ("auto", "r"))
    check_option("covariance", covariance, COVARIANCES)
    iterations = as_int("iterations", iterations, minimum=0)
    if iterations > _MAX_ITERATIONS:
        raise DataError(f"iterations must be <= {_MAX_ITERATIONS} refinement passes, got "
                        f"{iterations}; the estimate settles in a handful")
    if instrument == "r" and input == "r":
        raise OptionError("instrument='r' builds instruments from the reference for a model "
                          "driven by u; for a model from r to y use instrument='auto'")
    sd = prepare(data, input, output, with_reference=instrument == "r")
    orders = ArxOrders(na, nb, nk, len(sd.inputs))
    first = orders.max_lag if start is None else as_int("start", start, minimum=orders.max_lag)
    n_par = orders.n_parameters
    n_rows = check_record(repr(orders), n_par, sd, first, orders.max_lag)
    n_noise = noise_order(orders.na, sum(orders.nb), n_rows) if iterations else 0
    check_record(repr(orders) + f" with its order-{n_noise} noise prefilter", n_par + n_noise,
                 sd, first + n_noise, orders.max_lag + n_noise)
    if auxiliary_order is not None:
        auxiliary_order = as_int("auxiliary_order", auxiliary_order, minimum=0, maximum=30)
    ubar, aux = (aux_inputs(sd, first, orders, auxiliary_order) if instrument == "r"
                 else (sd.u, 0))
    fit = iv_core(sd.y, sd.u, ubar, orders.na, orders.nb, orders.nk, first, iterations,
                  resolve(covariance, noise_model=False))
    names = _parameter_names(orders, sd.inputs)

    def model_at(theta: NDArray[np.float64]) -> PolynomialModel:
        a, bs = split_arx(np.asarray(theta, dtype=float), orders.na, orders.nb)
        return PolynomialModel(a, bs, orders.nk, sd.dt, noise_variance=fit.sigma2,
                               input_names=sd.inputs, output_name=sd.output)

    def residuals() -> NDArray[np.float64]:
        a, bs = split_arx(fit.theta, orders.na, orders.nb)
        return np.concatenate([equation_error(y, us, a, bs, orders.nk)[first:]
                               for y, us in zip(sd.y, sd.u, strict=True)])

    return Estimate(
        model=model_at(fit.theta),
        parameters=fit.theta,
        names=names,
        covariance=fit.covariance,
        noise_variance=fit.sigma2,
        n_samples=n_rows,
        method="iv",
        options={
            "na": orders.na,
            "nb": list(orders.nb),
            "nk": list(orders.nk),
            "instrument": instrument,
            "iterations": iterations,
            "noise_order": int(fit.noise.size - 1),
            "auxiliary_order": aux,
            "input": input,
            "inputs": list(sd.inputs),
            "references": list(sd.references),
            "output": sd.output,
            "start": first,
            "segments": len(sd.y),
            "covariance": fit.covariance_kind,
            "covariance_ar_order": fit.ar_order,
        },
        residual_function=residuals,
        model_function=model_at,
    )


def iv_core(
    ys: Sequence[NDArray[np.float64]],
    us: Sequence[Arrays],
    ubars: Sequence[Arrays],
    na: int,
    nb: Sequence[int],
    nk: Sequence[int],
    start: int,
    refine: int,
    covariance: str = "white",
) -> IvFit:
    """IV estimate of ``A y = Σ B_i u_i`` with instruments from ``ubars``.

    ``ubars`` is ``us`` itself for open loop (IV4), or the reference-driven
    parts of the inputs for closed loop.  ``refine`` prefiltered passes
    follow the basic IV; ``covariance`` is ``"white"`` or ``"robust"``
    (see the module notes).
    """
    m = len(nb)
    closed = ubars is not us
    # signals z = (y, u_1..u_m, x[, ū_1..ū_m]); ū_i is u_i itself in open loop
    x_sig = 1 + m
    ubar_sig = [2 + m + i for i in range(m)] if closed else [1 + i for i in range(m)]
    phi = [(0, k, -1.0) for k in range(1, na + 1)]
    zeta = [(x_sig, k, -1.0) for k in range(1, na + 1)]
    for i in range(m):
        phi += [(1 + i, nk[i] + j, 1.0) for j in range(nb[i])]
        zeta += [(ubar_sig[i], nk[i] + j, 1.0) for j in range(nb[i])]
    union = list(dict.fromkeys([*phi, *zeta, (0, 0, 1.0)]))
    where = {c: k for k, c in enumerate(union)}
    ip = np.array([where[c] for c in phi])
    iz = np.array([where[c] for c in zeta])
    it = where[(0, 0, 1.0)]
    sig = np.array([c[0] for c in union], dtype=np.int64)
    lag = np.array([c[1] for c in union], dtype=np.int64)
    sign = np.array([c[2] for c in union])

    theta = arx_ls(ys, us, na, nb, nk, start)
    rows = sum(max(y.size - start, 0) for y in ys)
    n_noise = noise_order(na, sum(nb), rows)
    noise = np.ones(1)
    for p in range(refine + 1):
        a, bs = split_arx(theta, na, nb)
        a_sim = reflect(a)[0]
        if p:  # the noise model of the output error sets the prefilter L = D̂/Â
            v = [y - _simulate(u, a_sim, bs, nk) for y, u in zip(ys, us, strict=True)]
            noise = ar_fit(v, n_noise, start)
        gram = np.zeros((len(union), len(union)))
        first = start + (n_noise if p else 0)
        used = []
        for y, u, ub in zip(ys, us, ubars, strict=True):
            if y.size <= first:
                continue
            x = _simulate(ub, a_sim, bs, nk) if na else np.zeros(y.size)
            z = (y, *u, x, *(ub if closed else ()))
            if p:
                z = tuple(sps.lfilter(noise, a_sim, s) for s in z)
            used.append(readonly(z))
            gram += lagged_gram(used[-1], sig, lag, first)
        gram *= np.outer(sign, sign)
        mat = gram[np.ix_(iz, ip)]
        theta = _solve_square(mat, gram[iz, it], gram[np.ix_(iz, iz)], gram[np.ix_(ip, ip)])
    n_rows = sum(max(y.size - first, 0) for y in ys)
    g_pp, g_py, g_yy = gram[np.ix_(ip, ip)], gram[ip, it], gram[it, it]
    rss = max(float(g_yy - 2 * theta @ g_py + theta @ g_pp @ theta), 0.0)
    dof = max(n_rows - theta.size, 1)
    sigma2 = rss / dof
    a, bs = split_arx(theta, na, nb)

    def residuals() -> list[NDArray[np.float64]]:
        # the prefiltered equation error L(Â y − B̂ u) = Â (L y) − B̂ (L u), the IV residual
        return [equation_error(z[0], z[1:1 + m], a, bs, nk)[first:] for z in used]

    def instrument_gram(ar: NDArray[np.float64]) -> NDArray[np.float64]:
        if ar.size == 1:
            return gram[np.ix_(iz, iz)]
        # the columns are lags of a few signals: filter those once, then lag (from rest)
        out = sum(lagged_gram(readonly(tuple(sps.lfilter([1.0], ar, s) if k in zeta_sig else s
                                             for k, s in enumerate(z))),
                              sig[iz], lag[iz], first) for z in used)
        return np.asarray(out) * np.outer(sign[iz], sign[iz])

    zeta_sig = set(sig[iz].tolist())
    result = sandwich_covariance(covariance, mat, sigma2, dof, residuals, instrument_gram)
    return IvFit(theta, result.covariance, sigma2, noise, refine + 1, result.kind,
                 result.ar_order)


def noise_order(na: int, nb_total: int, rows: int) -> int:
    """Order of the AR noise model behind the prefilter.

    Long enough to whiten a moving-average noise (its inverse decays
    geometrically), short against the record: 2(na + Σnb), 10 to 30, at
    most one per 20 equations.
    """
    return int(max(1, min(max(2 * (na + nb_total), 10), 30, rows // 20)))


def _simulate(us: Arrays, a: NDArray[np.float64], bs: Sequence[NDArray[np.float64]],
              nk: Sequence[int]) -> NDArray[np.float64]:
    """Σ B_i/A u_i(t − nk_i) from rest."""
    x = np.zeros(us[0].size)
    for u, b, k in zip(us, bs, nk, strict=True):
        x += sps.lfilter(np.concatenate([np.zeros(k), b]), a, u)
    return x


def arx_ls(
    ys: Sequence[NDArray[np.float64]],
    us: Sequence[Arrays],
    na: int,
    nb: Sequence[int],
    nk: Sequence[int],
    start: int,
) -> NDArray[np.float64]:
    """Least-squares ARX parameters (a1…, b…) from the lagged Gram matrix."""
    cols = [(0, k, -1.0) for k in range(1, na + 1)]
    for i in range(len(nb)):
        cols += [(1 + i, nk[i] + j, 1.0) for j in range(nb[i])]
    cols.append((0, 0, 1.0))
    sig = np.array([c[0] for c in cols], dtype=np.int64)
    lag = np.array([c[1] for c in cols], dtype=np.int64)
    sign = np.array([c[2] for c in cols])
    gram = sum(lagged_gram(readonly((y, *u)), sig, lag, start)
               for y, u in zip(ys, us, strict=True) if y.size > start)
    gram = np.asarray(gram) * np.outer(sign, sign)
    return solve_normal(gram[:-1, :-1], gram[:-1, -1])


def ar_fit(signals: Sequence[NDArray[np.float64]], order: int, start: int) -> NDArray[np.float64]:
    """Monic AR polynomial L with L(q) s ≈ white, by least squares on t >= start + order."""
    if order == 0:
        return np.ones(1)
    sig = np.zeros(order + 1, dtype=np.int64)
    lag = np.arange(order + 1, dtype=np.int64)
    lag = np.append(lag[1:], 0)
    gram = sum(lagged_gram((s,), sig, lag, start + order)
               for s in signals if s.size > start + order)
    gram = np.asarray(gram)
    # columns are +s(t−k); the AR model s(t) = −Σ l_k s(t−k) + e
    coef = solve_normal(gram[:-1, :-1], gram[:-1, -1])
    return np.concatenate([[1.0], -coef])


def aux_inputs(sd: SignalData, start: int, orders: ArxOrders,
               order: int | None = None) -> tuple[tuple[Arrays, ...], int]:
    """The parts of the inputs driven by the reference, and the auxiliary order.

    Each input is fitted by an ARX model from all reference channels (orders
    n, n + 1, delay 0 — a controller may pass r through directly) and
    simulated from r alone; ``order`` sets n (default from the model's orders).
    """
    n_aux = (int(min(max(2 * (orders.na + max(orders.nb)), 6), 30)) if order is None
             else order)
    n_r = len(sd.references)
    first = max(start, n_aux)
    ubars = [[] for _ in sd.y]  # type: list[list[NDArray[np.float64]]]
    for i in range(len(sd.inputs)):
        ui = [u[i] for u in sd.u]
        try:
            theta = arx_ls(ui, sd.r, n_aux, [n_aux + 1] * n_r, [0] * n_r, first)
        except IdentifiabilityError:
            raise IdentifiabilityError(
                f"input {sd.inputs[i]!r} is not correlated with the reference "
                f"{', '.join(sd.references)}: the reference does not excite it, so it cannot "
                "serve as an instrument. Excite the loop through the reference"
            ) from None
        a, bs = split_arx(theta, n_aux, [n_aux + 1] * n_r)
        a = reflect(a)[0]
        for k, rs in enumerate(sd.r):
            ubars[k].append(sum(sps.lfilter(b, a, r) for b, r in zip(bs, rs, strict=True)))
    return tuple(tuple(u) for u in ubars), n_aux


def equation_error(
    y: NDArray[np.float64], us: Arrays, a: NDArray[np.float64],
    bs: Sequence[NDArray[np.float64]], nk: Sequence[int],
) -> NDArray[np.float64]:
    """``A y − Σ B_i u_i(t − nk_i)`` from rest."""
    e = sps.lfilter(a, [1.0], y) if a.size > 1 else np.array(y, dtype=float)
    for u, b, k in zip(us, bs, nk, strict=True):
        e -= sps.lfilter(np.concatenate([np.zeros(k), b]), [1.0], u)
    return np.asarray(e, dtype=float)


def readonly(z: Sequence[NDArray[np.float64]]) -> Arrays:
    """Read-only views of the signals: the Gram kernel wants one array type for all."""
    out = []
    for s in z:
        v = np.ascontiguousarray(s, dtype=np.float64).view()
        v.setflags(write=False)
        out.append(v)
    return tuple(out)


def solve_normal(g: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve the symmetric normal equations ``g θ = rhs`` after equilibration.

    Raises
    ------
    IdentifiabilityError
        When ``g`` is singular in double precision (a regressor is zero or
        a combination of the others).
    """
    s = np.sqrt(np.clip(np.diag(g), 0.0, None))
    if np.any(s == 0):
        raise IdentifiabilityError(
            "a regressor is identically zero: the signal does not excite the model; "
            "check the channels and the excitation")
    gs = g / np.outer(s, s)
    lam = np.linalg.eigvalsh(gs)
    if not lam[0] > 1e-14 * lam[-1]:
        raise IdentifiabilityError(
            f"the normal equations are singular (scaled condition number "
            f"{lam[-1] / max(lam[0], 1e-300):.3g}): the input is not persistently exciting for "
            "these orders. Use a richer input (PRBS, multisine) or lower orders")
    return np.linalg.solve(gs, rhs / s) / s


def _solve_square(mat: NDArray[np.float64], rhs: NDArray[np.float64],
                  g_zz: NDArray[np.float64], g_pp: NDArray[np.float64]) -> NDArray[np.float64]:
    sz = np.sqrt(np.clip(np.diag(g_zz), 0.0, None))
    sp = np.sqrt(np.clip(np.diag(g_pp), 0.0, None))
    if np.any(sz == 0) or np.any(sp == 0):
        raise IdentifiabilityError(
            "an instrument or regressor is identically zero: the input does not excite the "
            "model; check the channels and the excitation")
    ms = mat / np.outer(sz, sp)
    cond = np.linalg.cond(ms)
    if not cond < _IV_COND_LIMIT:
        raise IdentifiabilityError(
            f"the instruments are (nearly) uncorrelated with the regressors (scaled condition "
            f"number {cond:.3g}): the input does not excite these orders. Use lower orders or "
            "a richer input")
    return np.linalg.solve(ms, rhs / sz) / sp


def split_arx(theta: NDArray[np.float64], na: int,
              nb: Sequence[int]) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    """A (monic) and the B_i of ARX parameters (a1…, b…)."""
    a = np.concatenate([[1.0], theta[:na]])
    bs, o = [], na
    for n in nb:
        bs.append(np.array(theta[o:o + n]))
        o += n
    return a, bs

