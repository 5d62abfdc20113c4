"""First-order departures of the data from a reduced one-step fit, in one regression.

A one-step output-error fit leaves a residual ``e = y − ŷ(θ̂)``.  Any small
departure of the real loop from the model adds ``Σ_j a_j·z_j`` to it,
where ``z_j`` is the departure's direction ``∂ŷ/∂a_j`` at ``a = 0``.  So
regressing e on the fit's own gradient ``∂ŷ/∂θ`` and the directions
estimates each ``a_j`` (a score test of ``a_j = 0``) and how far θ moves
when the departures are modelled to first order.  Two departures are
tested (issue 24):

``gain``   ``z = ŷ``: the data's DC gain is ``(1 + a)·c/F`` — a reference gain c,
           a reference or position channel gain, or F (with K) off by ``a``
           (:mod:`._dc_gain`);
``gamma``  ``z = −G/(1 + F·G)·(|u|·ÿ)``: the valve's flow law to first order in
           the load pressure, ``a = γ = M_t/(2·A_p·(P_s − P_T))`` (:mod:`._flow_check`).

ŷ, ÿ and the flapper error ``u = c·r − F·ŷ`` are simulated from r with
the continuous reduced loop, exact for the reference's hold (staircase or
linear between samples).  The model's own sampled form (with the rig's
filter and decimation) is what the fit used; the regression on the
gradient absorbs the small difference, and the residual is the fit's own.
The covariance is the coloured-residual sandwich of the one-step
intervals (:func:`servoid.closedloop._coloured.sandwich`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._errors import DataError
from ...bench import discretise, realise
from ...closedloop import sandwich
from ...data import Experiment, ExperimentSet, as_segments
from ...models import TransferFunction
from ._result import ClosedLoopResult

__all__ = ["COLUMNS", "FirstOrderFit", "first_order_fit"]

#: The regression's columns: the reduced parameters, the departures, the constant.
COLUMNS = ("K", "omega_hp", "delta_hp", "gain", "gamma", "offset")
#: Relative step of the finite-difference gradient of ŷ.
_STEP = 1e-6


@dataclass(frozen=True)
class FirstOrderFit:
    """The residual of a reduced fit regressed on its gradient and the departures.

    Parameters
    ----------
    reduced, reduced_std : tuple of float
        The reduced fit's K, ω_hp, δ_hp and their standard deviations.
    beta : ndarray, shape (6,)
        Coefficients of :data:`COLUMNS`.
    covariance : ndarray, shape (6, 6)
        Their sandwich covariance.
    gain_sensitivity : tuple of float
        How far the reduced fit moves K, ω_hp, δ_hp per unit relative error
        of the DC gain (the projection of ŷ on the gradient).
    peak_acceleration : float
        Peak |ÿ| of the model on the test [m/s²].
    """

    reduced: tuple[float, float, float]
    reduced_std: tuple[float, float, float]
    beta: NDArray[np.float64]
    covariance: NDArray[np.float64]
    gain_sensitivity: tuple[float, float, float]
    peak_acceleration: float

    def coefficient(self, name: str) -> float:
        """Return one coefficient of :data:`COLUMNS`."""
        return float(self.beta[COLUMNS.index(name)])

    def std(self, name: str) -> float:
        """Return its standard deviation."""
        i = COLUMNS.index(name)
        return float(np.sqrt(max(self.covariance[i, i], 0.0)))

    def corrected(self) -> tuple[float, float, float]:
        """K, ω_hp, δ_hp with both departures modelled to first order."""
        return tuple(float(v + b) for v, b in  # type: ignore[return-value]
                     zip(self.reduced, self.beta[:3], strict=True))

    def corrected_std(self) -> tuple[float, float, float]:
        """Their standard deviations."""
        return tuple(float(np.sqrt(max(v, 0.0)))  # type: ignore[return-value]
                     for v in np.diag(self.covariance)[:3])


def first_order_fit(result: ClosedLoopResult,
                    data: Experiment | ExperimentSet) -> FirstOrderFit | None:
    """Regress a reduced one-step fit's residual on its gradient and the departures.

    Parameters
    ----------
    result : ClosedLoopResult
        A one-step fit of the reduced structure.
    data : Experiment or ExperimentSet
        The estimation record(s) it was fitted to.

    Returns
    -------
    FirstOrderFit or None
        None for another approach or structure, or a dynamic F.

    Raises
    ------
    DataError
        The fit's residuals do not match the records.
    """
    if (result.approach != "one-step" or result.structure != "reduced" or result.loop is None
            or not result.loop.is_static):
        return None
    c, f = float(result.loop.c), float(result.loop.F)  # type: ignore[arg-type]
    e = np.asarray(result.source.residuals, dtype=float)
    segments = as_segments(data)
    lag = result.advance
    sizes = [seg.n_samples - lag for seg in segments]
    skip, rest = divmod(sum(sizes) - e.size, len(sizes))
    if rest or skip < 0:
        raise DataError(f"the fit's {e.size} residuals do not match records of "
                        f"{[seg.n_samples for seg in segments]} samples")
    hold = "zoh" if result.intersample == "zoh" else "foh"
    theta = np.asarray(result.estimate.parameters, dtype=float)
    dt = segments[0].dt
    rows: list[NDArray[np.float64]] = []
    peak = 0.0
    for seg in segments:
        r = seg.signal("r")[:, 0]
        r = r - r[0]  # at rest at its first level (the level and offset are the constant)
        y_hat, acc = _paths(theta, c, f, r, dt, hold)
        g_num, loop = _loop_polys(theta, f)
        z = -_simulate(g_num, loop, np.abs(c * r - f * y_hat) * acc, dt, hold)
        cols = []
        for j in range(3):
            step = theta.copy()
            step[j] += _STEP * abs(theta[j]) if theta[j] else _STEP
            cols.append((_paths(step, c, f, r, dt, hold)[0] - y_hat) / (step[j] - theta[j]))
        block = np.column_stack([*cols, y_hat, z, np.ones(r.size)])
        rows.append(block[skip: seg.n_samples - lag])
        peak = max(peak, float(np.max(np.abs(acc))))
    x = np.vstack(rows)
    beta = _lstsq(x, e)
    cov, _ = sandwich([x], [e - x @ beta])
    # the reduced fit's response to a DC-gain error: ŷ projected on the gradient (and level)
    reduced_cols = [0, 1, 2, 5]
    sens = _lstsq(x[:, reduced_cols], x[:, 3])[:3]
    return FirstOrderFit(
        reduced=tuple(float(v) for v in theta),  # type: ignore[arg-type]
        reduced_std=tuple(float(v) for v in result.estimate.std),  # type: ignore[arg-type]
        beta=beta, covariance=cov,
        gain_sensitivity=tuple(float(v) for v in sens),  # type: ignore[arg-type]
        peak_acceleration=peak,
    )


def _lstsq(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    scale = np.linalg.norm(x, axis=0)
    scale[scale == 0.0] = 1.0
    beta, *_ = np.linalg.lstsq(x / scale, y, rcond=None)
    return np.asarray(beta / scale, dtype=float)


def _loop_polys(theta: Sequence[float], f: float) -> tuple[NDArray[np.float64],
                                                           NDArray[np.float64]]:
    k, w, d = (float(v) for v in theta)
    g_num = np.array([k * w * w])
    g_den = np.array([1.0, 2.0 * d * w, w * w, 0.0])
    return g_num, g_den + np.pad(f * g_num, (g_den.size - 1, 0))


def _paths(theta: Sequence[float], c: float, f: float, r: NDArray[np.float64], dt: float,
           hold: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ŷ and ÿ of the reduced loop driven by r."""
    g_num, loop = _loop_polys(theta, f)
    y = _simulate(c * g_num, loop, r, dt, hold)
    acc = _simulate(np.polymul(c * g_num, [1.0, 0.0, 0.0]), loop, r, dt, hold)
    return y, acc


def _simulate(num: NDArray[np.float64], den: NDArray[np.float64], x: NDArray[np.float64],
              dt: float, hold: str) -> NDArray[np.float64]:
    model = discretise(realise(TransferFunction(num, den)), dt, hold)  # type: ignore[arg-type]
    return np.asarray(model.simulate(x), dtype=float)
