"""The innovation form of a subspace estimate: a noise model for prediction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import DataError, ModelError
from ..models import StateSpace

__all__ = ["InnovationModel"]


@dataclass(frozen=True, eq=False)
class InnovationModel:
    """Steady-state Kalman predictor of a discrete state-space model.

    ``x(t+1) = A x + B u + K e``, ``y = C x + D u + e`` with white
    innovations e of covariance `noise_covariance`.  The one-step
    predictor runs ``x̂(t+1) = (A − KC) x̂ + (B − KD) u + K y``.

    Parameters
    ----------
    model : StateSpace
        The deterministic part (A, B, C, D), discrete.
    gain : ndarray, shape (n, ny)
        Kalman gain K.
    noise_covariance : ndarray, shape (ny, ny)
        Covariance of the innovations e.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.models import StateSpace
    >>> m = StateSpace([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=1.0)
    >>> im = InnovationModel(m, np.array([[0.5]]), np.array([[0.01]]))
    >>> im.predictor().A.tolist()
    [[0.4]]
    """

    model: StateSpace
    gain: NDArray[np.float64]
    noise_covariance: NDArray[np.float64]

    def __post_init__(self) -> None:
        if not isinstance(self.model, StateSpace) or self.model.dt is None:
            raise ModelError("InnovationModel needs a discrete StateSpace model")
        n, ny = self.model.n_states, self.model.n_outputs
        k = np.array(self.gain, dtype=float)
        r = np.atleast_2d(np.array(self.noise_covariance, dtype=float))
        if k.shape != (n, ny):
            raise ModelError(f"gain must have shape ({n}, {ny}), got {k.shape}")
        if r.shape != (ny, ny):
            raise ModelError(f"noise_covariance must have shape ({ny}, {ny}), got {r.shape}")
        for name, arr in (("gain", k), ("noise_covariance", r)):
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"{name} must be finite")
            arr.setflags(write=False)
        object.__setattr__(self, "gain", k)
        object.__setattr__(self, "noise_covariance", r)

    @classmethod
    def from_estimate(cls, estimate: Any) -> InnovationModel:
        """Build it from a :func:`fit_n4sid` estimate.

        Parameters
        ----------
        estimate : Estimate
            With ``options["kalman_gain"]`` and ``options["innovation_covariance"]``.

        Raises
        ------
        ModelError
            The estimate has no Kalman gain (see its ``options["kalman_note"]``).
        """
        gain = estimate.options.get("kalman_gain")
        if gain is None:
            note = estimate.options.get("kalman_note", "it was not estimated")
            raise ModelError(f"this {estimate.method} estimate has no Kalman gain: {note}")
        return cls(estimate.model, np.array(gain, dtype=float),
                   np.array(estimate.options["innovation_covariance"], dtype=float))

    def predictor(self) -> StateSpace:
        """Return the one-step predictor with inputs [u, y] and output ŷ."""
        m = self.model
        return StateSpace(
            m.A - self.gain @ m.C,
            np.hstack([m.B - self.gain @ m.D, self.gain]),
            m.C,
            np.hstack([m.D, np.zeros((m.n_outputs, m.n_outputs))]),
            m.dt,
        )

    def predict(self, y: ArrayLike, u: ArrayLike, x0: ArrayLike | None = None
                ) -> NDArray[np.float64]:
        """Return the one-step-ahead predictions ŷ(t | t−1).

        Parameters
        ----------
        y : array_like, shape (N,) or (N, ny)
            Measured outputs.
        u : array_like, shape (N,) or (N, m)
            Inputs.
        x0 : array_like, shape (n,), optional
            Initial predictor state; zero by default.

        Returns
        -------
        ndarray
            Shape (N,) for one output, else (N, ny).
        """
        yy = np.asarray(y, dtype=float)
        uu = np.asarray(u, dtype=float)
        yy = yy[:, None] if yy.ndim == 1 else yy
        uu = uu[:, None] if uu.ndim == 1 else uu
        if yy.ndim != 2 or yy.shape[1] != self.model.n_outputs:
            raise DataError(f"y must have {self.model.n_outputs} column(s), got shape {np.shape(y)}")
        if uu.shape[0] != yy.shape[0]:
            raise DataError(f"u and y must have the same length, got {uu.shape[0]} and {yy.shape[0]}")
        return self.predictor().simulate(np.hstack([uu, yy]), x0=x0)
