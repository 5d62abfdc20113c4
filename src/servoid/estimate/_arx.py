"""ARX by linear least squares: A(q) y(t) = Σ_i B_i(q) u_i(t − nk_i) + e(t)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import DataError, ServoidWarning, check_option
from .._lazy import signal as sps
from ..data import Experiment, ExperimentSet, as_segments
from ..models import PolynomialModel
from ._channels import check_magnitude, check_not_constant
from ._channels import output_name as _channel_output
from ._estimate import Estimate
from ._gram import lagged_gram
from ._ls import LeastSquaresResult, LsMethod, lstsq, solve_gram

__all__ = ["ArxOrders", "fit_arx"]

InputRole = Literal["u", "r"]


class ArxOrders:
    """Validated ARX orders: na, nb and nk per input."""

    __slots__ = ("na", "nb", "nk")

    def __init__(self, na: int, nb: int | Sequence[int], nk: int | Sequence[int], n_inputs: int):
        self.na = _count("na", na, minimum=0)
        self.nb = _per_input("nb", nb, n_inputs, minimum=1)
        self.nk = _per_input("nk", nk, n_inputs, minimum=0)

    @property
    def n_parameters(self) -> int:
        """Number of ARX coefficients na + Σ nb."""
        return self.na + sum(self.nb)

    @property
    def max_lag(self) -> int:
        """Longest delay in the regressor [samples]."""
        return max(self.na, *(k + b - 1 for k, b in zip(self.nk, self.nb, strict=True)))

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
    Memory: about 1 N × 8 bytes beyond the record on the Gram route (one
    float copy of a channel in the checks; the residuals are computed on
    first access, 8·N bytes more); the QR route, taken when the Gram
    matrix is ill-conditioned, adds the N × (na + Σnb) regressor matrix.
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
    orders = ArxOrders(na, nb, nk, len(input_names))
    start = orders.max_lag if start is None else as_int("start", start, minimum=0)
    if start < orders.max_lag:
        raise DataError(f"start must be >= the longest lag {orders.max_lag}, got {start}")
    n_par = orders.n_parameters
    n_rows = sum(max(seg.n_samples - start, 0) for seg in segments)
    if n_rows <= n_par:
        need = start + n_par + 1
        raise DataError(
            f"{orders!r} has {n_par} parameters and needs at least {need} samples "
            f"({start} initial + {n_par + 1} equations); got {first.n_samples if len(segments) == 1 else n_rows}"
            ". Use a longer record or lower orders"
        )
    signals = [_signals(seg, output_name, input_names) for seg in segments]
    check_magnitude("output", [z[0] for z in signals])
    for k, name in enumerate(input_names, start=1):
        check_magnitude(f"input {name!r}", [z[k] for z in signals])
        check_not_constant(name, [z[k] for z in signals])
    names = _parameter_names(orders, input_names)
    sig, lag = orders.columns()

    result: LeastSquaresResult | None = None
    if method in ("auto", "gram"):
        target_sig = np.append(sig, 0)
        target_lag = np.append(lag, 0)
        # A segment with no more than `start` samples gives no equation; the kernel's
        # end corrections assume at least one (they would index past its end).
        gram = sum(
            lagged_gram(z, target_sig, target_lag, start) for z in signals if z[0].size > start
        )
        result = solve_gram(gram, n_rows, names)
        if result is None and method == "gram":
            warnings.warn(
                "the regressor is too ill-conditioned for the normal equations "
                "(scaled condition number > 1e3); solved by QR instead",
                ServoidWarning,
                stacklevel=2,
            )
    if result is None:
        phi = _regressor(signals, sig, lag, start, n_rows)
        target = np.concatenate([z[0][start:] for z in signals])
        result = lstsq(phi, target, names)

    theta = result.theta
    a = np.concatenate([[1.0], -theta[: orders.na]])
    b_list, offset = [], orders.na
    for nb_i in orders.nb:
        b_list.append(theta[offset : offset + nb_i])
        offset += nb_i
    # The regression used −y lags; flip the sign of the a-part of the covariance.
    sign = np.concatenate([-np.ones(orders.na), np.ones(n_par - orders.na)])
    cov = result.covariance * np.outer(sign, sign)
    model = PolynomialModel.arx(
        a, b_list, list(orders.nk), first.dt, noise_variance=result.noise_variance
    )
    _warn_if_unstable(a)

    def residuals() -> NDArray[np.float64]:
        return np.concatenate([_equation_error(z, a, b_list, orders.nk)[start:] for z in signals])

    def model_at(theta: NDArray[np.float64]) -> PolynomialModel:
        bounds = np.cumsum([orders.na, *orders.nb])
        return PolynomialModel.arx(np.concatenate([[1.0], theta[: orders.na]]),
                                   np.split(theta[orders.na :], bounds[1:-1] - orders.na),
                                   list(orders.nk), first.dt,
                                   noise_variance=result.noise_variance)

    return Estimate(
        model=model,
        parameters=np.concatenate([a[1:], *b_list]),
        names=names,
        covariance=cov,
        noise_variance=result.noise_variance,
        n_samples=n_rows,
        method="arx",
        options={
            "na": orders.na,
            "nb": list(orders.nb),
            "nk": list(orders.nk),
            "input": input,
            "inputs": list(input_names),
            "output": output_name,
            "solver": result.method,
            "condition": result.condition,
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


def _warn_if_unstable(a: NDArray[np.float64]) -> None:
    if a.size < 2:
        return
    radius = float(np.abs(np.roots(a)).max())
    if radius > 1.0 + 1e-9:
        warnings.warn(
            f"the estimated model is unstable: largest pole magnitude {radius:.6g} > 1. "
            "Simulation will diverge; check for drift or an integrating plant in open loop",
            ServoidWarning,
            stacklevel=3,
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
