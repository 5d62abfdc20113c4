"""ARX by linear least squares: A(q) y(t) = Σ_i B_i(q) u_i(t − nk_i) + e(t)."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import DataError, ServoidWarning, check_option
from .._lazy import signal as sps
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..models import PolynomialModel
from ._channels import LARGEST_VALUE, SMALLEST_VALUE, check_magnitude, check_not_constant
from ._channels import output_name as _channel_output
from ._estimate import Deferred, Estimate
from ._gram import (  # lagged_gram_ranges: the reference the tests compare the screen with
    _lagged_gram_ranges,
    _pair_keys,
    lagged_gram,
    lagged_gram_ranges,  # noqa: F401
    value_range,
)
from ._ls import LsMethod, _gram_core, lstsq

__all__ = ["ArxOrders", "fit_arx"]

InputRole = Literal["u", "r"]


class ArxOrders:
    """Validated ARX orders: na, nb and nk per input."""

    __slots__ = ("_max_lag", "_n_parameters", "na", "nb", "nk")

    def __init__(self, na: int, nb: int | Sequence[int], nk: int | Sequence[int], n_inputs: int):
        self.na = _count("na", na, minimum=0)
        self.nb = _per_input("nb", nb, n_inputs, minimum=1)
        self.nk = _per_input("nk", nk, n_inputs, minimum=0)
        # derived once: the instance is never changed after construction
        self._n_parameters = self.na + sum(self.nb)
        self._max_lag = max(self.na, *(k + b - 1 for k, b in zip(self.nk, self.nb, strict=True)))

    @property
    def n_parameters(self) -> int:
        """Number of ARX coefficients na + Σ nb."""
        return self._n_parameters

    @property
    def max_lag(self) -> int:
        """Longest delay in the regressor [samples]."""
        return self._max_lag

    def columns(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Signal index (0 = y, 1.. = inputs) and lag of each regressor column."""
        sig = [0] * self.na
        lag = list(range(1, self.na + 1))
        for i, (nb, nk) in enumerate(zip(self.nb, self.nk, strict=True)):
            sig += [i + 1] * nb
            lag += list(range(nk, nk + nb))
        return np.array(sig, dtype=np.int64), np.array(lag, dtype=np.int64)

    def __repr__(self) -> str:
        nb = self.nb[0] if len(self.nb) == 1 else list(self.nb)
        nk = self.nk[0] if len(self.nk) == 1 else list(self.nk)
        return f"ARX(na={self.na}, nb={nb}, nk={nk})"


def fit_arx(
    data: Experiment | ExperimentSet,
    na: int,
    nb: int | Sequence[int],
    nk: int | Sequence[int] = 1,
    *,
    input: InputRole = "u",
    output: str | None = None,
    method: LsMethod = "auto",
    start: int | None = None,
) -> Estimate:
    """Fit an ARX model by least squares, with parameter covariance.

    The model is ``y(t) + a_1 y(t−1) + … + a_na y(t−na) = Σ_i Σ_j b_ij u_i(t − nk_i − j) + e(t)``.
    Regressors are built within each segment of an :class:`ExperimentSet`,
    never across a boundary.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s); one output channel, one or more input channels.
    na : int
        Number of poles (A coefficients after the leading 1).
    nb : int or sequence of int
        Number of B coefficients per input; Tustin images of strictly proper
        n-th order systems need ``nb = n + 1`` with ``nk = 0``.
    nk : int or sequence of int
        Input delay per input [samples].
    input : {"u", "r"}
        Which role supplies the input: the plant input ``u`` (open loop, direct
        approach) or the reference ``r`` (closed loop from r to y).
    output : str, optional
        Output channel name when the experiment has several.
    method : {"auto", "qr", "gram"}
        ``"qr"`` factorises the regressor matrix; ``"gram"`` solves the
        normal equations from a one-pass lagged Gram matrix (refused when the
        scaled condition number exceeds 1e3); ``"auto"`` tries the Gram route
        and falls back to QR.
    start : int, optional
        First sample of each segment used as an equation (default: the longest lag).
        A common start makes fits of different orders comparable.

    Returns
    -------
    Estimate
        ``model`` is a :class:`~servoid.models.PolynomialModel`; parameters are
        ``a1…a_na, b0…`` (``name:b0…`` per input when there are several).

    Raises
    ------
    IdentifiabilityError
        An input is constant, or the regressor is rank deficient.
    DataError
        Too few samples for the orders, or a missing channel.

    Notes
    -----
    Memory: about 0 N × 8 bytes beyond the record on the Gram route (the
    channel checks and the Gram sums read the channels in place, in one
    compiled call; the residuals are computed on first access, 8·N bytes,
    and the model is built on first read of ``model``); the QR route,
    taken when the Gram matrix is ill-conditioned, adds the
    N × (na + Σnb) regressor matrix.
    Checked by ``benchmarks/bench_scaling.py``.
    """
    check_option("input", input, ("u", "r"))
    check_option("method", method, ("auto", "qr", "gram"))
    segments = as_segments(data)
    first = segments[0]
    input_names = first.names_of(input)
    if not input_names:
        first.signal(input)  # raises a DataError naming what exists
    output_name = _channel_output(first, output)
    orders = _orders(na, nb, nk, len(input_names))
    max_lag = orders.max_lag
    start = max_lag if start is None else as_int("start", start, minimum=0)
    if start < max_lag:
        raise DataError(f"start must be >= the longest lag {max_lag}, got {start}")
    n_par = orders.n_parameters
    n_rows = sum(max(seg.n_samples - start, 0) for seg in segments)
    if n_rows <= n_par:
        need = start + n_par + 1
        raise DataError(
            f"{orders!r} has {n_par} parameters and needs at least {need} samples "
            f"({start} initial + {n_par + 1} equations); got {first.n_samples if len(segments) == 1 else n_rows}"
            ". Use a longer record or lower orders"
        )
    names, sig, lag, target_sig, target_lag, key_arr, pair_key = _structure_keys(
        orders.na, orders.nb, orders.nk, tuple(input_names))
    signals = [_signals(seg, output_name, input_names) for seg in segments]
    gram = None
    if method in ("auto", "gram") and all(z[0].size > start for z in signals):
        # the Gram sums and each channel's range in one compiled call per segment
        parts = [_lagged_gram_ranges(z, target_sig, target_lag, start, key_arr, pair_key)
                 for z in signals]
        if len(parts) == 1 and _ranges_ok(parts[0][1], LARGEST_VALUE, SMALLEST_VALUE):
            gram = parts[0][0]  # no channel check can fail: decided in one compiled call
        else:
            _check_channels(signals, input_names, [r for _, r in parts])
            gram = parts[0][0] if len(parts) == 1 else sum(g for g, _ in parts)
    else:
        _check_channels(signals, input_names)

    na_ = orders.na
    core = None
    if method in ("auto", "gram"):
        # A segment with no more than `start` samples gives no equation; the kernel's
        # end corrections assume at least one (they would index past its end).
        if gram is None:
            gram = sum(
                lagged_gram(z, target_sig, target_lag, start) for z in signals if z[0].size > start
            )
        core = _gram_core(gram, n_rows, names)
        if core is None and method == "gram":
            warn(
                "the regressor is too ill-conditioned for the normal equations "
                "(scaled condition number > 1e3); solved by QR instead",
                ServoidWarning,
            )
    stable: bool | None
    if core is not None:
        # θ = θ_s/scale, a = [1, −θ_a], the covariance with the a–b blocks' signs flipped
        # (the regression used −y lags) and the stability test in one compiled call
        # (the same float operations as the numpy expressions, so the same bits).
        theta_s, cov_s, scale, rss, sigma2, condition = core
        theta, a, parameters, cov, stable = _finish(theta_s, cov_s, scale, sigma2, na_,
                                                     _powers(na_ + 1))
        noise_variance = rss / (n_rows - n_par)
        solver = "gram"
    else:
        phi = _regressor(signals, sig, lag, start, n_rows)
        target = np.concatenate([z[0][start:] for z in signals])
        result = lstsq(phi, target, names)
        theta = result.theta
        a = np.concatenate([[1.0], -theta[:na_]])
        parameters = np.concatenate([a[1:], theta[na_:]])
        # The regression used −y lags; flip the sign of the a-part of the covariance.
        # (exact sign flips of the off-diagonal a–b blocks, in place: result is ours)
        cov = result.covariance
        cov[:na_, na_:] *= -1.0
        cov[na_:, :na_] *= -1.0
        noise_variance = result.noise_variance
        condition, solver, stable = result.condition, result.method, None
    _warn_if_unstable(a, stable)

    def b_list() -> list[NDArray[np.float64]]:
        out, offset = [], na_
        for nb_i in orders.nb:
            out.append(theta[offset : offset + nb_i])
            offset += nb_i
        return out

    # built on first read of estimate.model: θ is finite here, so the build cannot fail
    model = Deferred(lambda: PolynomialModel.arx(a, b_list(), list(orders.nk), first.dt,
                                                 noise_variance=noise_variance))

    def residuals() -> NDArray[np.float64]:
        bs = b_list()
        return np.concatenate([_equation_error(z, a, bs, orders.nk)[start:] for z in signals])

    def model_at(theta: NDArray[np.float64]) -> PolynomialModel:
        bounds = np.cumsum([orders.na, *orders.nb])
        return PolynomialModel.arx(np.concatenate([[1.0], theta[: orders.na]]),
                                   np.split(theta[orders.na :], bounds[1:-1] - orders.na),
                                   list(orders.nk), first.dt,
                                   noise_variance=noise_variance)

    # _trusted: the arrays are fresh and ours, names a cached tuple of str, options a new dict
    return Estimate._trusted(
        model=model,
        parameters=parameters,
        names=names,
        covariance=cov,
        noise_variance=noise_variance,
        n_samples=n_rows,
        method="arx",
        options={
            "na": orders.na,
            "nb": list(orders.nb),
            "nk": list(orders.nk),
            "input": input,
            "inputs": list(input_names),
            "output": output_name,
            "solver": solver,
            "condition": condition,
            "start": start,
            "segments": len(segments),
        },
        residual_function=residuals,
        model_function=model_at,
    )


def _signals(
    seg: Experiment, output: str, inputs: Sequence[str]
) -> tuple[NDArray[np.float64], ...]:
    # The channels themselves (read-only views), not a stacked copy: ARX reads them once.
    return (seg[output], *(seg[name] for name in inputs))


def _regressor(
    signals: Sequence[tuple[NDArray[np.float64], ...]],
    sig: NDArray[np.int64],
    lag: NDArray[np.int64],
    start: int,
    n_rows: int,
) -> NDArray[np.float64]:
    # Column-major, so the QR factorisation works on it without another copy.
    phi = np.empty((n_rows, sig.size), order="F")
    row = 0
    for z in signals:
        n = z[0].size
        if n <= start:
            continue
        for col, (s, l_) in enumerate(zip(sig, lag, strict=True)):
            phi[row : row + n - start, col] = z[s][start - l_ : n - l_]
        row += n - start
    return phi


def _equation_error(
    z: tuple[NDArray[np.float64], ...], a: NDArray[np.float64], b_list: list[NDArray[np.float64]],
    nk: Sequence[int],
) -> NDArray[np.float64]:
    e = sps.lfilter(a, [1.0], z[0])
    for i, (b, k) in enumerate(zip(b_list, nk, strict=True)):
        e -= sps.lfilter(np.concatenate([np.zeros(k), b]), [1.0], z[i + 1])
    return e


def _parameter_names(orders: ArxOrders, inputs: Sequence[str]) -> tuple[str, ...]:
    names = [f"a{i}" for i in range(1, orders.na + 1)]
    for name, nb in zip(inputs, orders.nb, strict=True):
        prefix = "" if len(inputs) == 1 else f"{name}:"
        names += [f"{prefix}b{j}" for j in range(nb)]
    return tuple(names)


def _orders(na: object, nb: object, nk: object, n_inputs: int) -> ArxOrders:
    """ArxOrders(na, nb, nk, n_inputs), validated once per distinct set of plain ints."""
    plain = type(na) is int and all(
        type(v) is int or (type(v) is tuple and all(type(x) is int for x in v)) for v in (nb, nk)
    )
    if plain:  # ints and tuples of ints hash by value; their check cannot change
        return _cached_orders(na, nb, nk, n_inputs)
    return ArxOrders(na, nb, nk, n_inputs)  # type: ignore[arg-type]


@functools.lru_cache(maxsize=256)
def _cached_orders(na: int, nb: object, nk: object, n_inputs: int) -> ArxOrders:
    # a failed check raises and is not cached; ArxOrders is never mutated by fit_arx
    return ArxOrders(na, nb, nk, n_inputs)  # type: ignore[arg-type]


@functools.lru_cache(maxsize=256)
def _structure(
    na: int, nb: tuple[int, ...], nk: tuple[int, ...], inputs: tuple[str, ...]
) -> tuple[tuple[str, ...], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64],
           NDArray[np.int64]]:
    """Names, regressor columns and the Gram's columns (with y) of validated orders.

    Cached: they depend on the orders only, and rebuilding them cost as much as
    the sums of a 1e4-sample fit. The arrays are read-only (shared).
    """
    orders = ArxOrders(na, nb, nk, len(nb))
    sig, lag = orders.columns()
    target_sig, target_lag = np.append(sig, 0), np.append(lag, 0)
    for arr in (sig, lag, target_sig, target_lag):
        arr.setflags(write=False)
    return _parameter_names(orders, inputs), sig, lag, target_sig, target_lag


@functools.lru_cache(maxsize=256)
def _structure_keys(
    na: int, nb: tuple[int, ...], nk: tuple[int, ...], inputs: tuple[str, ...]
) -> tuple[tuple[str, ...], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64],
           NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """:func:`_structure` and the Gram's lagged-product keys (:func:`_pair_keys`), cached."""
    names, sig, lag, target_sig, target_lag = _structure(na, nb, nk, inputs)
    key_arr, pair_key = _pair_keys(tuple(target_sig.tolist()), tuple(target_lag.tolist()))
    return names, sig, lag, target_sig, target_lag, key_arr, pair_key


@functools.lru_cache(maxsize=64)
def _powers(n: int) -> NDArray[np.float64]:
    """radius**i, i < n, for the stability test's radius (Python's pow, as before)."""
    out = np.array([_STABLE_RADIUS**i for i in range(n)], dtype=np.float64)
    out.setflags(write=False)
    return out


_STABLE_RADIUS = 1.0 + 1e-9


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _finish(theta_s, cov_s, scale, sigma2, na, powers):  # type: ignore[no-untyped-def]  # pragma: no cover
    # θ = θ_s / scale; a = [1, −θ[:na]]; parameters = [a[1:], θ[na:]];
    # cov = σ̂²·cov_s/(scale scaleᵀ) with the a–b blocks negated; a strictly stable?
    n = scale.size
    theta = np.empty(n)
    for i in range(n):
        theta[i] = theta_s[i] / scale[i]
    a = np.empty(na + 1)
    a[0] = 1.0
    for i in range(na):
        a[i + 1] = -theta[i]
    parameters = np.empty(n)
    for i in range(n):
        parameters[i] = a[i + 1] if i < na else theta[i]
    cov = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            v = sigma2 * cov_s[i, j] / (scale[i] * scale[j])
            cov[i, j] = -v if (i < na) != (j < na) else v
    return theta, a, parameters, cov, _schur_cohn(a, powers)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _schur_cohn(a, powers):  # type: ignore[no-untyped-def]  # pragma: no cover
    # _strictly_stable(a, radius) with powers[i] = radius**i, same operations
    if a.size < 2:
        return True
    c = np.empty(a.size)
    for i in range(a.size):
        c[i] = a[i] / powers[i]
    m = a.size
    nxt = np.empty(a.size)
    while m > 1:
        k = c[m - 1] / c[0]
        if not abs(k) < 1.0:  # also NaN
            return False
        scale = 1.0 - k * k
        for i in range(m - 1):
            nxt[i] = (c[i] - k * c[m - 1 - i]) / scale
        m -= 1
        for i in range(m):
            c[i] = nxt[i]
    return True


@numba.njit(cache=True, nogil=True)
def _ranges_ok(ranges, largest, smallest):  # type: ignore[no-untyped-def]  # pragma: no cover
    # _check_channels' screen for one segment (channel 0 the output): True when no check
    # can fail; the same comparisons in the same order
    for k in range(ranges.shape[0]):
        lo = ranges[k, 0]
        hi = ranges[k, 1]
        peak = max(abs(lo), abs(hi))
        if not (peak <= largest and not 0 < peak < smallest):
            return False
        if k and hi - lo <= 1e-12 * max(abs(lo), abs(hi), 1e-300):
            return False
    return True


def _check_channels(signals: Sequence[tuple[NDArray[np.float64], ...]],
                    input_names: Sequence[str],
                    ranges: Sequence[NDArray[np.float64]] | None = None) -> None:
    """check_magnitude of every channel and check_not_constant of the inputs.

    One compiled pass per channel gives min and max (or ``ranges``, per
    segment a (channel, (min, max)) array from :func:`lagged_gram_ranges`,
    channels in the order of ``signals``); only when those show a
    problem (or a segment is empty) do the checks themselves run, raising
    their usual errors, so the behaviour is theirs. With NaN in a channel
    the checks pass whatever the other values (NaN compares false), so the
    unspecified min/max of such a channel can only send it to the checks.
    """
    ok = True
    for k in range(len(input_names) + 1):
        pieces = [z[k] for z in signals]
        if any(p.size == 0 for p in pieces):
            ok = False
            break
        rk = ([value_range(p) for p in pieces] if ranges is None
              else [(float(r[k, 0]), float(r[k, 1])) for r in ranges])
        lo = min(r[0] for r in rk)
        hi = max(r[1] for r in rk)
        peak = max(abs(lo), abs(hi))
        if not (peak <= LARGEST_VALUE and not 0 < peak < SMALLEST_VALUE):
            ok = False
            break
        if k and hi - lo <= 1e-12 * max(abs(lo), abs(hi), 1e-300):
            ok = False
            break
    if ok:
        return
    check_magnitude("output", [z[0] for z in signals])
    for k, name in enumerate(input_names, start=1):
        check_magnitude(f"input {name!r}", [z[k] for z in signals])
        check_not_constant(name, [z[k] for z in signals])


def _strictly_stable(a: NDArray[np.float64], radius: float) -> bool:
    """All roots of the monic a strictly inside |z| < radius (Schur–Cohn step-down).

    a(z)'s roots scaled by 1/radius are the roots of c_k = a_k/radius^k; they lie
    inside the unit circle iff every reflection coefficient k_m = c_m/c_0 of the
    step-down recursion c ← (c − k_m·reverse(c))/(1 − k_m²) has |k_m| < 1
    (Jury's test; Åström & Wittenmark, *Computer-Controlled Systems*, §3.3).
    A few flops instead of the eigenvalues of the companion matrix.
    """
    c = [float(v) / radius**i for i, v in enumerate(a.tolist())]
    while len(c) > 1:
        k = c[-1] / c[0]
        if not abs(k) < 1.0:  # also NaN
            return False
        scale = 1.0 - k * k
        c = [(c[i] - k * c[-1 - i]) / scale for i in range(len(c) - 1)]
    return True


def _warn_if_unstable(a: NDArray[np.float64], stable: bool | None = None) -> None:
    if stable is None:
        stable = a.size < 2 or _strictly_stable(a, _STABLE_RADIUS)
    if stable:
        return
    radius = float(np.abs(np.roots(a)).max())
    if radius > 1.0 + 1e-9:
        warn(
            f"the estimated model is unstable: largest pole magnitude {radius:.6g} > 1. "
            "Simulation will diverge; check for drift or an integrating plant in open loop",
            ServoidWarning,
        )


def _count(name: str, value: object, minimum: int) -> int:
    return as_int(name, value, minimum=minimum)


def _per_input(name: str, value: object, n_inputs: int, minimum: int) -> tuple[int, ...]:
    if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim):
        values = list(value)
    else:  # a scalar, or anything else: as_int names the wrong type
        values = [value] * n_inputs
    if len(values) != n_inputs:
        raise DataError(f"{name} needs one value per input ({n_inputs}), got {values}")
    return tuple(_count(name, v, minimum) for v in values)
