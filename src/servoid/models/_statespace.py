"""State-space models ``x' = Ax + Bu, y = Cx + Du`` in continuous or discrete time."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ModelError, OptionTypeError
from .._lazy import linalg as la
from .._lazy import signal
from ._common import Method, as_input_matrix, at_sample_time, check_dt, check_method, readonly

if TYPE_CHECKING:
    from ._transfer import TransferFunction

__all__ = ["StateSpace"]

_OWNER = "StateSpace"
# modal simulation loses about eps·cond(V); above this the time loop is used instead
_MAX_MODAL_COND = 1e6


@dataclass(frozen=True, eq=False)
class StateSpace:
    """Linear time-invariant model in state-space form.

    Continuous (``dt=None``): ``dx/dt = A x + B u``, ``y = C x + D u``.
    Discrete: ``x(t+1) = A x(t) + B u(t)``, ``y(t) = C x(t) + D u(t)``.
    Several inputs and outputs are allowed.  A 1-D `B` is read as one
    column (one input), a 1-D `C` as one row (one output) and a scalar
    `D` as 1×1; matrices are never transposed.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    C : array_like, shape (p, n)
        Output matrix.
    D : array_like, shape (p, m)
        Feed-through matrix.
    dt : float or None
        Sample period [s] of a discrete model, None for continuous time.
    method : {"zoh", "tustin"} or None
        How the model was discretised, or None.
    prewarp : float or None
        Tustin prewarp frequency [rad/s] used, or None.
    """

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    dt: float | None = None
    method: Method | None = None
    prewarp: float | None = None

    def __post_init__(self) -> None:
        a = _matrix("A", self.A)
        b = _matrix("B", self.B, column=True)
        c = _matrix("C", self.C, row=True)
        d = _matrix("D", self.D)
        n = a.shape[0]
        if a.shape != (n, n):
            raise ModelError(f"{_OWNER}: A must be square, got shape {a.shape}")
        if b.shape[0] != n:
            raise ModelError(f"{_OWNER}: B must have {n} rows like A, got shape {b.shape}")
        if c.shape[1] != n:
            raise ModelError(f"{_OWNER}: C must have {n} columns like A, got shape {c.shape}")
        if d.shape != (c.shape[0], b.shape[1]):
            raise ModelError(
                f"{_OWNER}: D must have shape {(c.shape[0], b.shape[1])} (outputs, inputs), "
                f"got {d.shape}"
            )
        dt = check_dt(self.dt, owner=_OWNER)
        method, prewarp = check_method(self.method, self.prewarp, dt, owner=_OWNER)
        for name, value in (("A", a), ("B", b), ("C", c), ("D", d)):
            object.__setattr__(self, name, readonly(value))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "prewarp", prewarp)

    # -- properties -----------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of states n."""
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        """Number of inputs m."""
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of outputs p."""
        return self.C.shape[0]

    @property
    def is_siso(self) -> bool:
        """True for one input and one output."""
        return self.n_inputs == 1 and self.n_outputs == 1

    def __repr__(self) -> str:
        where = "continuous" if self.dt is None else f"dt={self.dt:g} s"
        return (f"<StateSpace {where}: {self.A.shape[0]} states, {self.B.shape[1]} inputs, "
                f"{self.C.shape[0]} outputs>")

    def _repr_html_(self) -> str:
        from .._display import model_html

        return model_html("StateSpace", self.dt, self.poles(),
                          extra=[("states", str(self.A.shape[0])),
                                 ("inputs", str(self.B.shape[1])),
                                 ("outputs", str(self.C.shape[0]))])

    # -- analysis -------------------------------------------------------
    def poles(self) -> NDArray[np.complex128]:
        """Return the poles (eigenvalues of A)."""
        return la.eigvals(self.A).astype(np.complex128)

    def is_stable(self) -> bool:
        """Return True if every pole is strictly stable.

        Continuous: Re p < 0; discrete: |p| < 1.  An integrator is not stable.
        """
        p = self.poles()
        return bool(np.all(p.real < 0.0) if self.dt is None else np.all(np.abs(p) < 1.0))

    def freqresp(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """Return C(xI − A)⁻¹B + D at x = jω or e^{jω·dt}.

        Parameters
        ----------
        omega : array_like, shape (N,)
            Angular frequencies [rad/s].

        Returns
        -------
        ndarray of complex
            Shape (N,) for a SISO model, else (N, p, m).
        """
        w = np.atleast_1d(as_array("omega", omega, finite=False))
        if w.ndim != 1:
            raise DataError(f"omega must be 1-D, got shape {w.shape}")
        x = 1j * w if self.dt is None else np.exp(1j * w * self.dt)
        n = self.n_states
        pencil = x[:, None, None] * np.eye(n) - self.A  # (N, n, n)
        g = self.C @ np.linalg.solve(pencil, np.broadcast_to(self.B, (w.size, *self.B.shape)))
        g = g + self.D
        return g[:, 0, 0] if self.is_siso else g

    def dc_gain(self) -> float | NDArray[np.float64]:
        """Return the static gain G(0) (continuous) or G(1) (discrete).

        Returns ``inf`` for a channel whose transfer function has an
        uncancelled pole at the DC point (an integrator); a float for a
        SISO model, else a (p, m) array.
        """
        n = self.n_states
        shift = np.zeros((n, n)) if self.dt is None else np.eye(n)
        p = self.poles()
        x0 = 0.0 if self.dt is None else 1.0
        scale = max(1.0, float(np.max(np.abs(p)))) if n else 1.0
        if n == 0 or np.min(np.abs(p - x0)) > 1e-9 * scale:
            g = self.D + self.C @ np.linalg.solve(shift - self.A, self.B)
        else:
            # a pole at the DC point may be cancelled in some channels: decide per channel
            g = np.array(
                [
                    [self.to_tf(i, o).dc_gain() for i in range(self.n_inputs)]
                    for o in range(self.n_outputs)
                ]
            )
        return float(g[0, 0]) if self.is_siso else g

    # -- time responses ---------------------------------------------------
    def simulate(
        self, u: ArrayLike, x0: ArrayLike | None = None, dt: float | None = None
    ) -> NDArray[np.float64]:
        """Return the output for input ``u`` from initial state ``x0``.

        A discrete model is simulated mode by mode with
        :func:`scipy.signal.lfilter` (no Python loop over time) when A is
        diagonalisable with well-conditioned eigenvectors, otherwise by a
        time loop.  A continuous model is ZOH-discretised at `dt` first
        (exact for piecewise-constant u).

        Parameters
        ----------
        u : array_like, shape (N,) or (N, m)
            Input samples.
        x0 : array_like, shape (n,), optional
            Initial state; zero by default.
        dt : float, optional
            Sample period [s]: required for continuous models, must be None
            or equal to ``self.dt`` for discrete ones.

        Returns
        -------
        ndarray
            Shape (N,) for one output, else (N, p).
        """
        model = self._at_dt(dt)
        uu = as_input_matrix(u, self.n_inputs, owner=f"{_OWNER}.simulate")
        n = self.n_states
        xi = np.zeros(n) if x0 is None else np.asarray(x0, dtype=np.float64)
        if xi.shape != (n,):
            raise DataError(f"x0 must have shape ({n},), got {xi.shape}")
        y = uu @ model.D.T
        if n:
            y = y + _state_output(model.A, model.B, model.C, uu, xi)
        return y[:, 0] if self.n_outputs == 1 else y

    def predict(self, y: ArrayLike, u: ArrayLike, horizon: int | None = 1) -> NDArray[np.float64]:
        """Return the k-step prediction of a discrete output-error model.

        Without a noise model (H = 1) every horizon's predictor is the
        simulation from rest; `y` is only checked for shape.

        Parameters
        ----------
        y : array_like
            Measured output, shape like the simulated output.
        u : array_like, shape (N,) or (N, m)
            Input samples.
        horizon : int or None
            Prediction horizon k >= 1 [samples]; None means infinity.

        Returns
        -------
        ndarray
            Predicted output, shape (N,) or (N, p).
        """
        from ._transfer import _check_horizon

        if self.dt is None:
            raise ModelError(f"{_OWNER}.predict needs a discrete-time model; use c2d first")
        _check_horizon(horizon)
        yhat = self.simulate(u)
        if np.shape(y) != yhat.shape:
            raise DataError(f"y must have shape {yhat.shape}, got {np.shape(y)}")
        return yhat

    # -- conversion -----------------------------------------------------
    def to_tf(self, input: int = 0, output: int = 0) -> TransferFunction:
        """Return the transfer function of one channel.

        Parameters
        ----------
        input : int
            Input index.
        output : int
            Output index.

        Returns
        -------
        TransferFunction
            Same dt and method; denominator of degree n (no cancellation).
        """
        from ._transfer import TransferFunction

        if not (0 <= input < self.n_inputs and 0 <= output < self.n_outputs):
            raise ModelError(
                f"channel (input={input}, output={output}) out of range for a model with "
                f"{self.n_inputs} input(s) and {self.n_outputs} output(s)"
            )
        b = self.B[:, input : input + 1]
        c = self.C[output : output + 1, :]
        d = self.D[output : output + 1, input : input + 1]
        if self.n_states == 0:
            return TransferFunction([d[0, 0]], [1.0], self.dt, self.method, self.prewarp)
        # den from eigenvalues (backward-stable); num by scipy's poly(A − BC) identity
        den = np.poly(la.eigvals(self.A)).real
        num, _ = signal.ss2tf(self.A, b, c, d)
        return TransferFunction(np.ravel(num), den, self.dt, self.method, self.prewarp)

    def similarity(self, T: ArrayLike) -> StateSpace:
        """Return the model in new coordinates ``z = T x``.

        Parameters
        ----------
        T : array_like, shape (n, n)
            Invertible transformation.

        Returns
        -------
        StateSpace
            ``(T A T⁻¹, T B, C T⁻¹, D)``, same dt and method.
        """
        t = np.asarray(T, dtype=np.float64)
        n = self.n_states
        if t.shape != (n, n):
            raise ModelError(f"T must have shape ({n}, {n}), got {t.shape}")
        if not np.all(np.isfinite(t)) or np.linalg.cond(t) > 1.0 / np.finfo(float).eps:
            raise ModelError(
                "T must be finite and invertible (it is singular to working precision)"
            )
        t_inv = np.linalg.inv(t)
        return StateSpace(
            t @ self.A @ t_inv,
            t @ self.B,
            self.C @ t_inv,
            self.D,
            self.dt,
            self.method,
            self.prewarp,
        )

    # -- private ----------------------------------------------------------
    def _at_dt(self, dt: float | None) -> StateSpace:
        return at_sample_time(self, dt, _OWNER)  # type: ignore[no-any-return]


def _matrix(name: str, value: ArrayLike, column: bool = False, row: bool = False) -> NDArray:
    """Return a finite 2-D float matrix, reading 1-D B as a column and 1-D C as a row."""
    try:
        m = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(f"{_OWNER}: {name} must be a real matrix, got {value!r}") from exc
    if m.ndim == 0:
        m = m.reshape(1, 1)
    elif m.ndim == 1:
        m = m[:, None] if column else m[None, :]
        if not (column or row):
            raise ModelError(f"{_OWNER}: {name} must be 2-D, got shape {np.shape(value)}")
    if m.ndim != 2:
        raise ModelError(f"{_OWNER}: {name} must be 2-D, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ModelError(f"{_OWNER}: {name} must be finite")
    return m


def _state_output(
    a: NDArray, b: NDArray, c: NDArray, u: NDArray, x0: NDArray
) -> NDArray[np.float64]:
    """Return C·x(t) of ``x(t+1) = A x(t) + B u(t)`` for all t, shape (N, p)."""
    lam, v = la.eig(a)
    if np.linalg.cond(v) < _MAX_MODAL_COND:
        # modal form: n first-order complex recursions, each one lfilter call
        w = u @ la.solve(v, b.astype(complex)).T  # (N, n) modal inputs
        xi0 = la.solve(v, x0.astype(complex))
        modes = np.empty_like(w)
        for i, li in enumerate(lam):
            modes[:, i] = signal.lfilter([0.0, 1.0], [1.0, -li], w[:, i], zi=[xi0[i]])[0]
        return (modes @ (c @ v).T).real
    x = x0.copy()
    bu = u @ b.T
    states = np.empty((u.shape[0], a.shape[0]))
    for t in range(u.shape[0]):  # defective or ill-conditioned modes: plain recursion
        states[t] = x
        x = a @ x + bu[t]
    return states @ c.T
