"""Channel selection, excitation checks and nested order search for black-box closed loop."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .._checks import type_error
from .._errors import DataError, IdentifiabilityError
from ..data import Experiment, ExperimentSet, as_segments

__all__ = [
    "aic_order",
    "check_excites",
    "check_name",
    "ls_fit",
    "output_name",
    "reference_name",
    "single_name",
]


def check_name(argument: str, name: object) -> str | None:
    """Return a channel-name argument if it is a string or None."""
    if name is not None and not isinstance(name, str):
        raise type_error(argument, name, "a channel name (a string) or None")
    return name


def single_name(seg: Experiment, role: str, name: str | None, what: str) -> str:
    """Return the one channel of ``role`` (or ``name``), else a DataError naming the fix."""
    if name is not None and name != role:
        seg.channel(name)  # a ChannelError listing the channels
        return name
    names = seg.names_of(role)  # type: ignore[arg-type]
    if not names:
        seg.signal(role)  # type: ignore[arg-type]  # a DataError naming what exists
    if len(names) > 1:
        raise DataError(
            f"the experiment has {len(names)} {what} channels ({', '.join(names)}); this method "
            f"is single-input: pass the channel name, e.g. {names[0]!r}"
        )
    return names[0]


def output_name(seg: Experiment, output: str | None) -> str:
    """Return the output channel name (``output`` or the only role-y channel)."""
    if output is not None:
        seg.channel(check_name("output", output))  # type: ignore[arg-type]
        return output
    return single_name(seg, "y", None, "output (pass output=<name>)")


def reference_name(data: Experiment | ExperimentSet, method: str) -> str:
    """Return the single reference channel, or a DataError saying what to do instead."""
    first = as_segments(data)[0]
    refs = first.names_of("r")
    if not refs:
        listed = ", ".join(f"{c.name} ({c.role})" for c in first.channels)
        raise DataError(
            f"{method} needs the reference r, which is the only signal the loop noise does not "
            f"reach, but the experiment has no reference ('r') channel; it has: {listed}. Map "
            "the set-point/command channel to role 'r', or, without a recorded reference, use "
            "the direct approach fit_bj on (u, y) with a noise model"
        )
    return single_name(first, "r", None, "reference")


def check_excites(name: str, pieces: Sequence[NDArray[np.float64]], role: str) -> None:
    """Raise IdentifiabilityError when a signal is constant over every segment."""
    low = min(float(np.min(p)) for p in pieces)
    high = max(float(np.max(p)) for p in pieces)
    if high - low <= 1e-12 * max(abs(low), abs(high), 1e-300):
        if role == "r":
            fix = ("a constant reference does not excite the loop, so the part of u and y it "
                   "drives is nil. Add a PRBS or multisine to the set-point (servoid excite)")
        else:
            fix = ("a constant signal is not persistently exciting. Excite the system with a "
                   "PRBS, multisine or chirp (servoid excite)")
        raise IdentifiabilityError(
            f"{name!r} is constant ({low:.6g} over all {sum(p.size for p in pieces)} samples): "
            f"{fix}"
        )


def ls_fit(
    x: NDArray[np.float64], y: NDArray[np.float64], rcond: float = 1e-12
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Least squares ``y ≈ x θ`` from the column-scaled Gram matrix.

    Directions whose Gram eigenvalue is below ``rcond`` times the largest
    are dropped (minimum-norm solution).  The normal equations keep these
    tall, modestly conditioned lag regressions fast where a threaded QR or
    SVD is not on a busy machine.

    Returns
    -------
    theta : ndarray
        Coefficients.
    residual : ndarray
        ``y − x θ``.
    rank : int
        Numerical rank of ``x``.
    """
    scale = np.sqrt(np.einsum("ij,ij->j", x, x))
    scale[scale == 0] = 1.0
    xs = x / scale
    eig, vec = np.linalg.eigh(xs.T @ xs)
    keep = eig > rcond * max(float(eig[-1]), 1e-300)
    shape = (-1,) + (1,) * (y.ndim - 1)  # y may hold several right-hand sides as columns
    coef = vec[:, keep] @ ((vec[:, keep].T @ (xs.T @ y)) / eig[keep].reshape(shape))
    resid = y - xs @ coef
    return coef / scale.reshape(shape), resid, int(keep.sum())


def aic_order(
    phi: NDArray[np.float64], target: NDArray[np.float64], sizes: Sequence[int]
) -> int:
    """Return the index into ``sizes`` whose column prefix minimises AIC.

    The candidate models are nested: model k uses the first ``sizes[k]``
    columns of ``phi`` (see :func:`aic_order_gram`).
    """
    aug = np.column_stack([phi, target])
    return aic_order_gram(aug.T @ aug, target.size, sizes)


def aic_order_gram(gram: NDArray[np.float64], n: int, sizes: Sequence[int]) -> int:
    """:func:`aic_order` from the Gram matrix of ``[phi, target]`` over n rows.

    One Cholesky factor R of the column-scaled Gram matrix gives every
    residual sum of squares, ``RSS_k = ‖y‖² − Σ_{i<n_k} R[i, −1]²``, and
    ``AIC_k = N·ln(RSS_k/N) + 2·n_k`` (Akaike 1974; Ljung, *System
    Identification*, 2nd ed., §16.4).
    """
    scale = np.sqrt(np.diag(gram).copy())
    scale[scale == 0] = 1.0
    scaled = gram / np.outer(scale, scale)
    ridge = 1e-12 * np.trace(scaled) / scaled.shape[0]
    scaled[np.diag_indices_from(scaled)] += ridge  # keeps a rank-deficient prefix factorable
    upper = np.linalg.cholesky(scaled).T
    total = float(gram[-1, -1])
    explained = np.concatenate([[0.0], np.cumsum(upper[:-1, -1] ** 2)]) * scale[-1] ** 2
    best, best_crit = 0, np.inf
    floor = total * 1e-300 + 1e-300
    for k, size in enumerate(sizes):
        rss = max(total - explained[size], floor)
        crit = n * np.log(rss / n) + 2.0 * size
        if crit < best_crit:
            best, best_crit = k, crit
    return best
