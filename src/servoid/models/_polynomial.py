"""Discrete polynomial (ARX, ARMAX, OE, BJ) models in the shift operator q⁻¹."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array
from .._errors import DataError, ModelError, OptionTypeError, ServoidWarning
from .._lazy import signal
from .._warn import warn
from ._common import as_coefficients, as_input_matrix, check_dt, readonly

if TYPE_CHECKING:
    from ._transfer import TransferFunction

__all__ = ["PolynomialModel"]

_OWNER = "PolynomialModel"
Structure = Literal["arx", "armax", "oe", "bj", "general"]


@dataclass(frozen=True, eq=False)
class PolynomialModel:
    """General discrete polynomial model in the shift operator q⁻¹.

    ``A(q) y(t) = Σ_i B_i(q)/F_i(q) u_i(t − nk_i) + C(q)/D(q) e(t)``,
    with ``e`` white noise of variance `noise_variance`.  A, C, D and the
    F_i are monic: ``X(q) = 1 + x_1 q⁻¹ + … + x_n q⁻ⁿ``.  Use
    :meth:`arx` for the common single-input ARX case.  The arrays are
    stored read-only.

    Parameters
    ----------
    a : array_like
        Coefficients of A for q⁰, q⁻¹, …; ``a[0] == 1``.
    b : sequence of array_like
        One 1-D array per input; ``b[i][j]`` multiplies u_i(t − nk_i − j).
    nk : sequence of int
        Input delays [samples], >= 0, one per input (an int for one input).
    dt : float
        Sample period [s], > 0.
    c : array_like
        Coefficients of C; ``c[0] == 1``; default ``[1.]``.
    d : array_like
        Coefficients of D; ``d[0] == 1``; default ``[1.]``.
    f : sequence of array_like or None
        One monic F_i per input; None (default) means ``[1.]`` for each.
    noise_variance : float
        Variance of e, >= 0 (output units squared).
    input_names : sequence of str or None
        Optional labels, one per input.
    output_name : str or None
        Optional label of the output.

    Examples
    --------
    >>> m = PolynomialModel.arx([1.0, -0.5], [0.0, 1.0], 0, dt=0.01)
    >>> m.structure, m.na, m.nb
    ('arx', 1, (2,))
    >>> [float(v) for v in m.simulate([1.0, 0.0, 0.0])]
    [0.0, 1.0, 0.5]
    """

    a: NDArray[np.float64]
    b: tuple[NDArray[np.float64], ...]
    nk: tuple[int, ...]
    dt: float
    c: NDArray[np.float64] = field(default_factory=lambda: np.ones(1))
    d: NDArray[np.float64] = field(default_factory=lambda: np.ones(1))
    f: tuple[NDArray[np.float64], ...] | None = None
    noise_variance: float = 0.0
    input_names: tuple[str, ...] | None = None
    output_name: str | None = None

    def __post_init__(self) -> None:
        dt = check_dt(self.dt, owner=_OWNER, allow_none=False)
        a = _monic("a", self.a)
        c = _monic("c", self.c)
        d = _monic("d", self.d)
        if isinstance(self.b, np.ndarray) or not isinstance(self.b, Sequence) or not self.b:
            raise OptionTypeError(
                f"{_OWNER}: b must be a non-empty sequence of 1-D arrays, one per input "
                f"(for one input pass (b,) or use PolynomialModel.arx), got {self.b!r}"
            )
        b = tuple(as_coefficients(f"b[{i}]", bi, owner=_OWNER) for i, bi in enumerate(self.b))
        m = len(b)
        if any(np.ndim(bi) == 0 for bi in self.b):
            raise OptionTypeError(f"{_OWNER}: each b[i] must be a 1-D array, got {self.b!r}")
        nk = self.nk
        if isinstance(nk, (int, np.integer)) and not isinstance(nk, bool):
            nk = (int(nk),) * m if m == 1 else nk
        if not isinstance(nk, Sequence) or len(nk) != m:
            raise ModelError(f"{_OWNER}: nk must give one delay per input ({m}), got {self.nk!r}")
        for k in nk:
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
                raise ModelError(f"{_OWNER}: nk must be integers >= 0 [samples], got {self.nk!r}")
        f = (np.ones(1),) * m if self.f is None else self.f
        if isinstance(f, np.ndarray) or not isinstance(f, Sequence) or len(f) != m:
            raise ModelError(f"{_OWNER}: f must give one polynomial per input ({m}), got {f!r}")
        f = tuple(_monic(f"f[{i}]", fi) for i, fi in enumerate(f))
        var = self.noise_variance
        if isinstance(var, bool) or not isinstance(var, (int, float, np.integer, np.floating)):
            raise OptionTypeError(f"{_OWNER}: noise_variance must be a float, got {var!r}")
        if not (math.isfinite(var) and var >= 0.0):
            raise ModelError(f"{_OWNER}: noise_variance must be finite and >= 0, got {var!r}")
        names = self.input_names
        if names is not None:
            names = tuple(names)
            if len(names) != m or not all(isinstance(s, str) for s in names):
                raise ModelError(
                    f"{_OWNER}: input_names must be {m} string(s), got {self.input_names!r}"
                )
        if self.output_name is not None and not isinstance(self.output_name, str):
            raise OptionTypeError(f"{_OWNER}: output_name must be a string, "
                                  f"got {self.output_name!r}")
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "a", readonly(a))
        object.__setattr__(self, "b", tuple(readonly(x) for x in b))
        object.__setattr__(self, "nk", tuple(int(k) for k in nk))
        object.__setattr__(self, "c", readonly(c))
        object.__setattr__(self, "d", readonly(d))
        object.__setattr__(self, "f", tuple(readonly(x) for x in f))
        object.__setattr__(self, "noise_variance", float(var))
        object.__setattr__(self, "input_names", names)

    @classmethod
    def arx(
        cls,
        a: ArrayLike,
        b: ArrayLike | Sequence[ArrayLike],
        nk: int | Sequence[int],
        dt: float,
        noise_variance: float = 0.0,
    ) -> PolynomialModel:
        """Build an ARX model ``A(q) y = Σ B_i(q) u_i(t − nk_i) + e``.

        Parameters
        ----------
        a : array_like
            Coefficients of A, ``a[0] == 1``.
        b : array_like or sequence of array_like
            A 1-D array (one input) or one 1-D array per input.
        nk : int or sequence of int
            Delay(s) [samples]; an int applies to every input.
        dt : float
            Sample period [s].
        noise_variance : float
            Variance of e.

        Returns
        -------
        PolynomialModel
            The ARX model.
        """
        if (
            isinstance(b, np.ndarray)
            and b.ndim == 1
            or (isinstance(b, Sequence) and all(np.ndim(x) == 0 for x in b))
        ):
            bs: tuple[ArrayLike, ...] = (b,)
        elif isinstance(b, np.ndarray) and b.ndim == 2 or isinstance(b, Sequence):
            bs = tuple(b)
        else:
            raise OptionTypeError(f"b must be a 1-D array or a sequence of 1-D arrays, got {b!r}")
        if isinstance(nk, (int, np.integer)) and not isinstance(nk, bool):
            nks: tuple[int, ...] | Sequence[int] = (int(nk),) * len(bs)
        elif isinstance(nk, (Sequence, np.ndarray)) and not isinstance(nk, (str, bytes)):
            nks = tuple(nk)
        else:
            raise OptionTypeError(f"nk must be an integer delay [samples] or one per input, "
                                  f"got {nk!r}")
        return cls(a, bs, nks, dt, noise_variance=noise_variance)

    # -- orders and structure ---------------------------------------------
    def __repr__(self) -> str:
        return (f"<PolynomialModel {self.structure}: na={self.na}, nb={list(self.nb)}, "
                f"nk={list(self.nk)}, nc={self.nc}, nd={self.nd}, nf={list(self.nf)}, "
                f"dt={self.dt:g} s>")

    def _repr_html_(self) -> str:
        from .._display import model_html

        def coeffs(x: NDArray[np.float64]) -> str:
            return ", ".join(f"{v:.6g}" for v in x)

        rows = [("A", coeffs(self.a))]
        for k, b in enumerate(self.b):
            rows.append((f"B{k if self.n_inputs > 1 else ''} (nk = {self.nk[k]})", coeffs(b)))
        if self.nc:
            rows.append(("C", coeffs(self.c)))
        if self.nd:
            rows.append(("D", coeffs(self.d)))
        for k, f in enumerate(self.f or ()):
            if f.size > 1:
                rows.append((f"F{k if self.n_inputs > 1 else ''}", coeffs(f)))
        return model_html(f"PolynomialModel ({self.structure})", self.dt,
                          np.roots(self.a) if self.na else np.array([]),
                          ("polynomial", "coefficients in q⁻¹"), rows,
                          [("noise variance", f"{self.noise_variance:.4g}")])

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return len(self.b)

    @property
    def na(self) -> int:
        """Order of A."""
        return self.a.size - 1

    @property
    def nb(self) -> tuple[int, ...]:
        """Number of B coefficients per input."""
        return tuple(x.size for x in self.b)

    @property
    def nc(self) -> int:
        """Order of C."""
        return self.c.size - 1

    @property
    def nd(self) -> int:
        """Order of D."""
        return self.d.size - 1

    @property
    def nf(self) -> tuple[int, ...]:
        """Order of F per input."""
        return tuple(x.size - 1 for x in self.f or ())

    @property
    def structure(self) -> Structure:
        """Name of the structure by which polynomials are trivial (= 1).

        ``"arx"`` (only A, B), ``"armax"`` (A, B, C), ``"oe"`` (B, F),
        ``"bj"`` (B, F and C and/or D), else ``"general"``.
        """
        has_a, has_c, has_d = self.na > 0, self.nc > 0, self.nd > 0
        has_f = any(n > 0 for n in self.nf)
        if not (has_c or has_d or has_f):
            return "arx"
        if has_c and not (has_d or has_f):
            return "armax"
        if has_f and not (has_a or has_c or has_d):
            return "oe"
        if has_f and not has_a:
            return "bj"
        return "general"

    # -- simulation and prediction ----------------------------------------
    def simulate(
        self,
        u: ArrayLike,
        *,
        y_init: ArrayLike | None = None,
        u_init: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Return the noise-free output of the model for input ``u``.

        ``y = Σ_i B_i/(A F_i) u_i(t − nk_i)``, run as the single difference
        equation below.

        The difference equation is
        ``A·ΠF_j y(t) = Σ_i B_i·Π_{j≠i}F_j u_i(t − nk_i)``, so the initial
        conditions are past values of y and u.  Both are given most
        recent first: ``y_init = [y(−1), y(−2), …]`` and ``u_init[j] =
        u(−1 − j)``; missing values are zero, values beyond the equation's
        lags are ignored.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_inputs)
            Input samples.
        y_init : array_like, shape (L,), optional
            Past outputs, most recent first.
        u_init : array_like, shape (L,) or (L, n_inputs), optional
            Past inputs, most recent first.

        Returns
        -------
        ndarray, shape (N,)
            Noise-free output.
        """
        uu = as_input_matrix(u, self.n_inputs, owner=f"{_OWNER}.simulate")
        den, nums = self._common_denominator()
        if y_init is None and u_init is None:
            # from rest: one compiled pass per input into one array (no lfilter buffers)
            from ._kernels import filter_into

            y = np.zeros(uu.shape[0])
            for i, num in enumerate(nums):
                filter_into(num, den, uu[:, i], y, i > 0)
            return y
        lag = max(den.size, *(x.size for x in nums)) - 1
        yi = _past("y_init", y_init, 1, lag)[:, 0]
        ui = _past("u_init", u_init, self.n_inputs, lag)
        y = np.zeros(uu.shape[0])
        for i, num in enumerate(nums):
            if max(num.size, den.size) == 1:  # static gain: no state
                y += num[0] * uu[:, i]
                continue
            # by linearity the past outputs enter once, through the first input's filter
            past_y = yi[: den.size - 1] if i == 0 else np.zeros(den.size - 1)
            zi = signal.lfiltic(num, den, past_y, ui[: num.size - 1, i])
            y += signal.lfilter(num, den, uu[:, i], zi=zi)[0]
        return y

    def predict(self, y: ArrayLike, u: ArrayLike, horizon: float | None = 1) -> NDArray[np.float64]:
        """Return the k-step-ahead prediction ŷ(t | t − k).

        Uses the exact predictor ``ŷ = W_k G u + (1 − W_k) y`` with
        ``W_k = F_k H⁻¹``, ``H = C/(A D)`` and F_k the first k terms of the
        impulse response of H (Ljung, *System Identification*, 2nd ed.,
        §3.2).  horizon = 1 of an ARX model is the regression φᵀθ;
        horizon = None (or ``math.inf``) is the simulation.  Signals before
        t = 0 are taken as zero.  The predictor is stable only if C has
        its roots inside the unit circle; otherwise a warning is issued.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output.
        u : array_like, shape (N,) or (N, n_inputs)
            Input samples.
        horizon : int or None
            Prediction horizon k >= 1 [samples]; None or ``math.inf`` for
            pure simulation.

        Returns
        -------
        ndarray, shape (N,)
            The predictions.
        """
        uu = as_input_matrix(u, self.n_inputs, owner=f"{_OWNER}.predict")
        yy = as_array("y", y, finite=False)
        if yy.shape != (uu.shape[0],):
            raise DataError(f"y must have shape ({uu.shape[0]},) like u, got {yy.shape}")
        from ._kernels import all_finite, filter_into

        if not all_finite(np.ascontiguousarray(yy, dtype=np.float64).ravel()):
            raise DataError("y must be finite")
        if horizon is None or horizon == math.inf:
            return self.simulate(uu)
        if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or horizon < 1:
            raise ModelError(f"horizon must be an int >= 1, None or math.inf, got {horizon!r}")
        if self.nc and np.any(np.abs(np.roots(self.c)) >= 1.0):
            warn(
                "C has roots on or outside the unit circle: the predictor is unstable",
                ServoidWarning,
            )
        rest, terms = self._predictor_filters(int(horizon))
        # one compiled pass per filter, each adding into ŷ (lfilter allocated per term)
        yhat = np.empty(yy.size)
        filter_into(rest, self.c, yy, yhat, False)
        for i, (num, den) in enumerate(terms):
            filter_into(num, den, uu[:, i], yhat, True)
        return yhat

    def _predictor_filters(
        self, k: int
    ) -> tuple[NDArray[np.float64], list[tuple[NDArray[np.float64], NDArray[np.float64]]]]:
        """The k-step predictor's filters: ``rest/C`` on y, ``num_i/den_i`` per input.

        ``ŷ = (rest/C) y + Σ_i (num_i/den_i) u_i`` with ``rest = C − F_k A D``
        (its first k terms set to zero), ``num_i = F_k D B_i q^{−nk_i}`` and
        ``den_i = C F_i`` (see :meth:`predict`).
        """
        ad = np.convolve(self.a, self.d)
        pulse = np.zeros(k)
        pulse[0] = 1.0
        fk = signal.lfilter(self.c, ad, pulse)  # first k impulse-response terms of H
        rest = _padd(self.c, -np.convolve(fk, ad))
        rest[: min(k, rest.size)] = 0.0  # zero by construction of F_k; drop the rounding
        fkd = np.convolve(fk, self.d)
        terms = [
            (np.convolve(fkd, np.concatenate([np.zeros(self.nk[i]), self.b[i]])),
             np.convolve(self.c, self.f[i]))  # type: ignore[index]
            for i in range(self.n_inputs)
        ]
        return rest, terms

    def residuals(self, y: ArrayLike, u: ArrayLike) -> NDArray[np.float64]:
        """Return the one-step prediction errors ``y − ŷ(t | t − 1)``.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output.
        u : array_like, shape (N,) or (N, n_inputs)
            Input samples.

        Returns
        -------
        ndarray, shape (N,)
            The residuals ε(t).
        """
        yy = as_array("y", y, finite=False)
        out = self.predict(yy, u, 1)
        return np.subtract(yy, out, out=out)  # in place: no second N-sample array

    # -- conversion -------------------------------------------------------
    def transfer_function(self, input: int = 0) -> TransferFunction:
        """Return the discrete transfer function from one input.

        ``G_i = B_i q^{−nk_i}/(A F_i)``.

        Parameters
        ----------
        input : int
            Input index.

        Returns
        -------
        TransferFunction
            In descending powers of z, with this model's dt.
        """
        if not 0 <= input < self.n_inputs:
            raise ModelError(f"input must be in [0, {self.n_inputs}), got {input}")
        num = np.concatenate([np.zeros(self.nk[input]), self.b[input]])
        return _q_tf(num, np.convolve(self.a, self.f[input]), self.dt)  # type: ignore[index]

    def noise_transfer_function(self) -> TransferFunction:
        """Return the noise model ``H = C/(A D)`` as a transfer function."""
        return _q_tf(self.c, np.convolve(self.a, self.d), self.dt)

    # -- private ----------------------------------------------------------
    def _common_denominator(self) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
        """Return A·ΠF_j and the numerators B_i·Π_{j≠i}F_j·q^{−nk_i}."""
        f = self.f or ()
        den = self.a
        for fj in f:
            den = np.convolve(den, fj)
        nums = []
        for i, bi in enumerate(self.b):
            num = np.concatenate([np.zeros(self.nk[i]), bi])
            for j, fj in enumerate(f):
                if j != i:
                    num = np.convolve(num, fj)
            nums.append(num)
        return den, nums


def _monic(name: str, values: ArrayLike) -> NDArray[np.float64]:
    arr = as_coefficients(name, values, owner=_OWNER)
    if arr[0] != 1.0:
        raise ModelError(
            f"{_OWNER}: {name} must be monic ({name}[0] == 1, the q⁰ coefficient), got "
            f"{name}[0] = {arr[0]!r}; divide the polynomial by its first coefficient"
        )
    return arr


def _past(name: str, values: ArrayLike | None, width: int, lag: int) -> NDArray[np.float64]:
    """Return past samples as (lag, width), most recent first, zero-padded."""
    out = np.zeros((lag, width))
    if values is None:
        return out
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim == 1 and width == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != width:
        want = "(L,)" if width == 1 else f"(L, {width})"
        raise DataError(f"{name} must have shape {want}, most recent first, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} must be finite")
    n = min(lag, arr.shape[0])
    out[:n] = arr[:n]
    return out


def _padd(p: NDArray, q: NDArray) -> NDArray[np.float64]:
    """Add two q⁻¹ polynomials (ascending powers of q⁻¹, different lengths)."""
    out = np.zeros(max(p.size, q.size))
    out[: p.size] += p
    out[: q.size] += q
    return out


def _q_tf(num: NDArray, den: NDArray, dt: float) -> TransferFunction:
    """Return a q⁻¹ ratio as a TransferFunction in descending powers of z."""
    from ._transfer import TransferFunction

    size = max(num.size, den.size)
    # multiplying by z^(size − 1) turns q⁻ʲ into z^(size − 1 − j)
    num_z = np.concatenate([num, np.zeros(size - num.size)])
    den_z = np.concatenate([den, np.zeros(size - den.size)])
    return TransferFunction(num_z, den_z, dt)
