"""SISO transfer functions in s (continuous) or z (discrete)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import ModelError, OptionTypeError, check_option
from .._lazy import linalg as la
from .._lazy import signal
from ._common import (
    Method,
    as_coefficients,
    as_input_matrix,
    at_sample_time,
    check_delay,
    check_dt,
    check_method,
    common_dt,
    readonly,
)
from ._response import TimeResponse, response_grid

if TYPE_CHECKING:
    from ._polynomial import PolynomialModel
    from ._statespace import StateSpace

__all__ = ["TransferFunction"]

_OWNER = "TransferFunction"


@dataclass(frozen=True, eq=False)
class TransferFunction:
    """Proper SISO transfer function ``num/den`` in s or z.

    The coefficients are in descending powers of s (``dt=None``) or z, as
    in :mod:`scipy.signal`.  The constructor strips leading zeros and
    scales so that ``den[0] == 1``; the arrays are stored read-only.
    Only single-input single-output models; use :class:`StateSpace` for
    several channels.

    A continuous model may carry a delay τ: ``G(s)·e^{−sτ}``.  Its
    frequency response, simulation, step and impulse responses and
    :func:`~servoid.models.c2d` include it; poles, zeros and the static
    gain are those of the rational part.  Series connection adds delays;
    a sum needs equal delays and a feedback loop none (neither would be
    rational).  A discrete model has ``delay=0``: its delay is poles at
    z = 0.  To drop a delay on purpose, use
    ``dataclasses.replace(g, delay=0.0)``.

    Parameters
    ----------
    num : array_like
        Numerator coefficients, descending powers; degree <= that of `den`.
    den : array_like
        Denominator coefficients, descending powers; not all zero.
    dt : float or None
        Sample period [s] of a discrete model, None for continuous time.
    method : {"zoh", "tustin", "foh"} or None
        How the model was discretised, or None (continuous models: None).
    prewarp : float or None
        Tustin prewarp frequency [rad/s] used, or None.
    delay : float
        Input/output delay τ [s] of a continuous model, finite and >= 0;
        0 for a discrete one.

    Examples
    --------
    >>> g = TransferFunction([2.0], [1.0, 1.0])
    >>> float(g.dc_gain())
    2.0
    >>> late = TransferFunction([2.0], [1.0, 1.0], delay=0.5)
    >>> complex(late.freqresp([0.0])[0])
    (2+0j)
    """

    num: NDArray[np.float64]
    den: NDArray[np.float64]
    dt: float | None = None
    method: Method | None = None
    prewarp: float | None = None
    delay: float = 0.0

    def __post_init__(self) -> None:
        num = np.trim_zeros(as_coefficients("num", self.num, owner=_OWNER), "f")
        den = np.trim_zeros(as_coefficients("den", self.den, owner=_OWNER), "f")
        if den.size == 0:
            raise ModelError(f"{_OWNER}: den must not be all zero")
        if num.size == 0:
            num = np.zeros(1)
        if num.size > den.size:
            raise ModelError(
                f"{_OWNER}: the model must be proper (deg num <= deg den), got deg num = "
                f"{num.size - 1} > deg den = {den.size - 1}"
            )
        dt = check_dt(self.dt, owner=_OWNER)
        method, prewarp = check_method(self.method, self.prewarp, dt, owner=_OWNER)
        delay = check_delay(self.delay, dt, owner=_OWNER)
        object.__setattr__(self, "num", readonly(num / den[0]))
        object.__setattr__(self, "den", readonly(den / den[0]))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "prewarp", prewarp)
        object.__setattr__(self, "delay", delay)

    # -- construction ---------------------------------------------------
    @classmethod
    def from_zpk(
        cls, z: ArrayLike, p: ArrayLike, k: float, dt: float | None = None, delay: float = 0.0
    ) -> TransferFunction:
        """Build a transfer function from zeros, poles and gain.

        Parameters
        ----------
        z : array_like
            Zeros (complex ones in conjugate pairs).
        p : array_like
            Poles (complex ones in conjugate pairs).
        k : float
            Gain: the leading coefficient of the numerator.
        dt : float or None
            Sample period [s], None for continuous time.
        delay : float
            Delay τ [s] of a continuous model.

        Returns
        -------
        TransferFunction
            ``k·Π(x − z)/Π(x − p)`` with x = s or z.
        """
        num = k * _real_poly(z, "zeros")
        den = _real_poly(p, "poles")
        return cls(num, den, dt, delay=delay)

    # -- properties -----------------------------------------------------
    @property
    def is_discrete(self) -> bool:
        """True for a discrete-time model."""
        return self.dt is not None

    @property
    def order(self) -> int:
        """Degree of the denominator."""
        return self.den.size - 1

    def __repr__(self) -> str:
        where = "continuous" if self.dt is None else f"dt={self.dt:g} s"
        delay = f", delay={self.delay:g} s" if getattr(self, "delay", 0.0) else ""
        return (f"<TransferFunction {where}{delay}: num={np.round(self.num, 6).tolist()}, "
                f"den={np.round(self.den, 6).tolist()}>")

    def _repr_html_(self) -> str:
        from .._display import model_html

        n = max(self.num.size, self.den.size)
        num = np.concatenate([np.zeros(n - self.num.size), self.num])
        den = np.concatenate([np.zeros(n - self.den.size), self.den])
        var = "s" if self.dt is None else "z"
        rows = [(f"{var}^{n - 1 - k}", f"{num[k]:.6g}", f"{den[k]:.6g}") for k in range(n)]
        extra = [("delay", f"{self.delay:g} s")] if getattr(self, "delay", 0.0) else []
        return model_html("TransferFunction", self.dt, self.poles(), ("power", "num", "den"),
                          rows, extra)

    # -- analysis -------------------------------------------------------
    def poles(self) -> NDArray[np.complex128]:
        """Return the poles (roots of den)."""
        return np.roots(self.den).astype(np.complex128)

    def zeros(self) -> NDArray[np.complex128]:
        """Return the finite zeros (roots of num)."""
        if not np.any(self.num):
            return np.zeros(0, dtype=np.complex128)
        return np.roots(self.num).astype(np.complex128)

    def is_stable(self) -> bool:
        """Return True if every pole is strictly stable.

        Continuous: Re p < 0; discrete: |p| < 1.  An integrator is not stable.
        """
        p = self.poles()
        if self.dt is None:
            return bool(np.all(p.real < 0.0))
        return bool(np.all(np.abs(p) < 1.0))

    def dc_gain(self) -> float:
        """Return the static gain G(0) (continuous) or G(1) (discrete).

        A pole at s = 0 (z = 1) that is not cancelled by a zero gives
        ``inf`` (the gain of an integrator is unbounded) rather than an
        error.  Within rounding (``|den(x0)| <= 100·eps·Σ|den_i|``) a pole
        counts as lying at the DC point.
        """
        num, den = self.num, self.den
        x0 = 0.0 if self.dt is None else 1.0
        for _ in range(den.size):
            n0, d0 = np.polyval(num, x0), np.polyval(den, x0)
            d_small = abs(d0) <= 100 * np.finfo(float).eps * np.sum(np.abs(den))
            n_small = abs(n0) <= 100 * np.finfo(float).eps * max(np.sum(np.abs(num)), 1e-300)
            if not d_small:
                return float(n0 / d0)
            if not n_small:
                return math.inf
            num = np.polydiv(num, [1.0, -x0])[0]  # cancel the common root at the DC point
            den = np.polydiv(den, [1.0, -x0])[0]
        return 0.0

    def freqresp(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """Return G(jω)·e^{−jωτ} (continuous) or G(e^{jω·dt}).

        Parameters
        ----------
        omega : array_like
            Angular frequencies [rad/s].

        Returns
        -------
        ndarray of complex
            The response, same shape as `omega`.
        """
        w = as_array("omega", omega, finite=False)
        x = 1j * w if self.dt is None else np.exp(1j * w * self.dt)
        g = np.polyval(self.num, x) / np.polyval(self.den, x)
        if self.delay:
            g = g * np.exp(-1j * w * self.delay)
        return g

    def bode(self, omega: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return magnitude [dB] and unwrapped phase [deg].

        Parameters
        ----------
        omega : array_like
            Increasing angular frequencies [rad/s], 1-D.

        Returns
        -------
        mag_db, phase_deg : ndarray
            ``20·log10|G|`` [dB] and the phase [deg], unwrapped along omega.
        """
        g = self.freqresp(omega)
        return 20.0 * np.log10(np.abs(g)), np.degrees(np.unwrap(np.angle(g)))

    # -- time responses ---------------------------------------------------
    def simulate(self, u: ArrayLike, dt: float | None = None) -> NDArray[np.float64]:
        """Return the output for input ``u`` from rest.

        Parameters
        ----------
        u : array_like, shape (N,)
            Input samples.
        dt : float, optional
            Sample period [s].  Required for a continuous model, which is
            ZOH-discretised at `dt` first (exact for piecewise-constant u,
            a fractional delay included); for a discrete model it must be
            None or equal to ``self.dt``.

        Returns
        -------
        ndarray, shape (N,)
            Output samples.
        """
        uu = as_input_matrix(u, 1, owner=f"{_OWNER}.simulate")[:, 0]
        model = self._at_dt(dt)
        num, den = _z_to_q(model.num, model.den)
        return signal.lfilter(num, den, uu)

    def predict(self, y: ArrayLike, u: ArrayLike, horizon: int | None = 1) -> NDArray[np.float64]:
        """Return the k-step prediction of a discrete output-error model.

        The noise model of a bare transfer function is H = 1, so every
        horizon's predictor equals :meth:`simulate`; `y` is only checked.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output (unused by an output-error predictor).
        u : array_like, shape (N,)
            Input samples.
        horizon : int or None
            Prediction horizon k >= 1 [samples]; None means infinity.

        Returns
        -------
        ndarray, shape (N,)
            Predicted output.
        """
        if self.dt is None:
            raise ModelError(f"{_OWNER}.predict needs a discrete-time model; use c2d first")
        _check_horizon(horizon)
        yy = as_array("y", y, finite=False)
        yhat = self.simulate(u)
        if yy.shape != yhat.shape:
            raise ModelError(f"y must have shape {yhat.shape} like u, got {yy.shape}")
        return yhat

    def step(self, t: int | ArrayLike) -> TimeResponse:
        """Return the unit-step response.

        Parameters
        ----------
        t : int or array_like
            Number of samples (discrete models) or a uniform time grid [s]
            from 0.  Continuous responses are exact at the grid points.

        Returns
        -------
        TimeResponse
            Times [s] and output.
        """
        grid, step = response_grid(t, self.dt)
        return TimeResponse(grid, self.simulate(np.ones(grid.size), dt=step), "step")

    def impulse(self, t: int | ArrayLike) -> TimeResponse:
        """Return the impulse response.

        Discrete: the response to a unit pulse at k = 0.  Continuous: the
        samples of g(t) = C·e^{At}·B (a direct feed-through's Dirac term
        is omitted, as in :func:`scipy.signal.impulse`), shifted by the
        delay: g(t − τ), zero before τ.

        Parameters
        ----------
        t : int or array_like
            Number of samples (discrete models) or a uniform time grid [s]
            from 0.

        Returns
        -------
        TimeResponse
            Times [s] and output.
        """
        grid, step = response_grid(t, self.dt)
        if self.dt is not None:
            pulse = np.zeros(grid.size)
            pulse[0] = 1.0
            return TimeResponse(grid, self.simulate(pulse), "impulse")
        from ._discretize import c2d
        from ._statespace import StateSpace

        ss = self._rational().to_ss()
        ssd = c2d(ss, step, "zoh")
        # y(k·step) = C·e^{A·(k·step − τ)}·B for k·step >= τ: the free response of the
        # sampled model from the state the impulse has reached at the first grid point
        first = min(math.ceil(self.delay / step - 1e-9), grid.size)  # 1e-9: τ on the grid
        x0 = la.expm(ss.A * (first * step - self.delay)) @ ss.B[:, 0] if ss.n_states else ss.B[:, 0]
        free = StateSpace(ssd.A, np.zeros_like(ssd.B), ssd.C, np.zeros_like(ssd.D), dt=step)
        y = np.zeros(grid.size)
        if first < grid.size:
            y[first:] = free.simulate(np.zeros(grid.size - first), x0=x0)
        return TimeResponse(grid, y, "impulse")

    # -- algebra --------------------------------------------------------
    def __mul__(self, other: TransferFunction | float) -> TransferFunction:
        """Series connection ``self·other``."""
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        dt = common_dt(self.dt, o.dt, what="multiply")
        return _with_memory(
            np.polymul(self.num, o.num), np.polymul(self.den, o.den), dt, self, o,
            self.delay + o.delay,
        )

    __rmul__ = __mul__

    def __add__(self, other: TransferFunction | float) -> TransferFunction:
        """Parallel connection ``self + other``."""
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        dt = common_dt(self.dt, o.dt, what="add")
        if not math.isclose(self.delay, o.delay, rel_tol=1e-12, abs_tol=0.0):
            raise ModelError(
                f"cannot add models with different delays ({self.delay} s and {o.delay} s): "
                "the sum is not a rational function times one delay; discretise both with "
                "c2d first (a whole-sample delay becomes z^-k) or approximate the difference"
            )
        num = np.polyadd(np.polymul(self.num, o.den), np.polymul(o.num, self.den))
        return _with_memory(num, np.polymul(self.den, o.den), dt, self, o, self.delay)

    __radd__ = __add__

    def __neg__(self) -> TransferFunction:
        """Negate the transfer function."""
        return TransferFunction(
            -self.num, self.den, self.dt, self.method, self.prewarp, self.delay
        )

    def __sub__(self, other: TransferFunction | float) -> TransferFunction:
        """Difference ``self − other``."""
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return self + (-o)

    def __rsub__(self, other: float) -> TransferFunction:
        """Difference ``other − self``."""
        return (-self) + other

    def feedback(self, other: TransferFunction | float = 1.0, sign: int = -1) -> TransferFunction:
        """Close a loop around this model.

        Parameters
        ----------
        other : TransferFunction or float
            Feedback path F.
        sign : {-1, 1}
            -1 for negative feedback ``G/(1 + F·G)``, +1 for ``G/(1 − F·G)``.

        Returns
        -------
        TransferFunction
            The closed loop from reference to output.
        """
        check_option("sign", sign, (-1, 1))
        o = self._coerce(other)
        if o is None:
            raise OptionTypeError(f"other must be a TransferFunction or a number, got {other!r}")
        dt = common_dt(self.dt, o.dt, what="connect")
        if self.delay or o.delay:
            raise ModelError(
                f"cannot close a loop around a delay (delays {self.delay} s and {o.delay} s): "
                "the loop is not rational; discretise with c2d first (the delay becomes "
                "poles at z = 0)"
            )
        num = np.polymul(self.num, o.den)
        den = np.polysub(np.polymul(self.den, o.den), sign * np.polymul(self.num, o.num))
        return _with_memory(num, den, dt, self, o)

    def minreal(self, tol: float = 1e-8) -> TransferFunction:
        """Cancel pole-zero pairs closer than ``tol·max(1, |p|)``.

        Parameters
        ----------
        tol : float
            Relative distance below which a zero cancels a pole.

        Returns
        -------
        TransferFunction
            The reduced model, same dt, method and delay.
        """
        zeros = list(self.zeros())
        poles = list(self.poles())
        kept_p = []
        for p in poles:
            if zeros:
                dist = np.abs(np.asarray(zeros) - p)
                j = int(np.argmin(dist))
                if dist[j] <= tol * max(1.0, abs(p)):
                    zeros.pop(j)
                    continue
            kept_p.append(p)
        gain = self.num[0] if np.any(self.num) else 0.0
        num = gain * _real_poly(zeros, "zeros")
        return TransferFunction(
            num, _real_poly(kept_p, "poles"), self.dt, self.method, self.prewarp, self.delay
        )

    # -- conversion -----------------------------------------------------
    def to_ss(self) -> StateSpace:
        """Return a state-space realisation (controller canonical form).

        Raises
        ------
        ModelError
            For a model with a delay, which a state-space model cannot hold.
        """
        from ._statespace import StateSpace

        if self.delay:
            raise ModelError(
                f"{_OWNER}.to_ss: a StateSpace model has no delay and this model has "
                f"delay = {self.delay} s; discretise with c2d (the delay becomes states), or "
                "drop it on purpose with dataclasses.replace(g, delay=0.0)"
            )
        n = self.order
        if n == 0:  # a static gain: no state (tf2ss would return a dummy 1×1 one)
            gain = float(self.num[-1] / self.den[-1])
            return StateSpace(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)),
                              np.array([[gain]]), self.dt, self.method, self.prewarp)
        a, b, c, d = signal.tf2ss(self.num, self.den)
        return StateSpace(
            np.reshape(a, (n, n)),
            np.reshape(b, (n, 1)),
            np.reshape(c, (1, n)),
            np.reshape(d, (1, 1)),
            self.dt,
            self.method,
            self.prewarp,
        )

    def to_polynomial(
        self, structure: Literal["arx", "oe"] = "arx", noise_variance: float = 0.0
    ) -> PolynomialModel:
        """Return the discrete model as a polynomial model in q⁻¹.

        The delay ``nk`` is the number of leading zeros of the numerator
        in q⁻¹ form (the relative degree).

        Parameters
        ----------
        structure : {"arx", "oe"}
            Put the denominator in A (ARX, noise model 1/A) or in F (OE).
        noise_variance : float
            Variance of the white noise e.

        Returns
        -------
        PolynomialModel
            ``A y = B u(t − nk) + e`` or ``y = B/F u(t − nk) + e``.
        """
        from ._polynomial import PolynomialModel

        check_option("structure", structure, ("arx", "oe"))
        if self.dt is None:
            raise ModelError(f"{_OWNER}.to_polynomial needs a discrete-time model; use c2d first")
        numq, denq = _z_to_q(self.num, self.den)
        nz = np.flatnonzero(numq)
        nk = int(nz[0]) if nz.size else 0
        # trailing zeros in q⁻¹ form only pad the orders (poles/zeros at the origin)
        b = np.trim_zeros(numq[nk:], "b") if nz.size else np.zeros(1)
        denq = np.trim_zeros(denq, "b")
        if structure == "arx":
            return PolynomialModel(denq, (b,), (nk,), self.dt, noise_variance=noise_variance)
        return PolynomialModel(
            [1.0], (b,), (nk,), self.dt, f=(denq,), noise_variance=noise_variance
        )

    # -- private ----------------------------------------------------------
    def _rational(self) -> TransferFunction:
        """Return the model without its delay."""
        if not self.delay:
            return self
        return TransferFunction(self.num, self.den, self.dt, self.method, self.prewarp)

    def _coerce(self, other: object) -> TransferFunction | None:
        if isinstance(other, TransferFunction):
            return other
        if isinstance(other, (int, float, np.integer, np.floating)) and not isinstance(other, bool):
            return TransferFunction([float(other)], [1.0], self.dt, self.method, self.prewarp)
        return None

    def _at_dt(self, dt: float | None) -> TransferFunction:
        return at_sample_time(self, dt, _OWNER)  # type: ignore[no-any-return]


def _with_memory(
    num: NDArray,
    den: NDArray,
    dt: float | None,
    g1: TransferFunction,
    g2: TransferFunction,
    delay: float = 0.0,
) -> TransferFunction:
    """Build a result that keeps the method only if both operands agree."""
    static = g2.den.size == 1 and g2.num.size == 1
    if static or (g1.method == g2.method and g1.prewarp == g2.prewarp):
        return TransferFunction(num, den, dt, g1.method, g1.prewarp, delay)
    return TransferFunction(num, den, dt, delay=delay)


def _real_poly(roots: ArrayLike, what: str) -> NDArray[np.float64]:
    """Return the real monic polynomial with the given roots."""
    r = np.asarray(roots, dtype=np.complex128).ravel()
    if r.size == 0:
        return np.ones(1)
    coeffs = np.poly(r)
    scale = np.sum(np.abs(coeffs))
    if np.max(np.abs(coeffs.imag)) > 1e-9 * scale:
        raise ModelError(f"complex {what} must come in conjugate pairs, got {r}")
    return coeffs.real.astype(np.float64)


def _z_to_q(num: NDArray, den: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return descending-z coefficients as equal-length q⁻¹ polynomials."""
    numq = np.concatenate([np.zeros(den.size - num.size), num])
    return numq, np.array(den, dtype=np.float64)


def _check_horizon(horizon: object) -> None:
    if horizon is None or horizon == math.inf:
        return
    if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or horizon < 1:
        raise ModelError(f"horizon must be an int >= 1, None or math.inf, got {horizon!r}")
