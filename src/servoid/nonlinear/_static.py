"""Static nonlinearities: the memoryless blocks of block-oriented models.

Each shape is a frozen object holding its parameters; ``evaluate`` maps a
signal through it, ``jacobian`` gives the derivative of the output with
respect to the parameters (analytic, one column per parameter).  A shape
knows its parameter names (``deadzone.lower``), box bounds, and whether
its output has a free scale:

- **unit slope** (no free scale): :class:`DeadZone`, :class:`Saturation`,
  :class:`AbsoluteValue`, :class:`SignedPower`.  The gain of the model is
  carried by the linear block.
- **free scale**: :class:`PiecewiseLinear`, :class:`Polynomial`,
  :class:`StaticFunction` (unless told otherwise).  Multiplying the shape
  by k and the linear block by 1/k gives the same model, so the block
  models fix the linear block's static gain to 1.

Shapes never check their parameters inside a fit (an optimiser may cross
two breakpoints on the way); the constructors do.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_float_list, as_str, as_str_list, type_error
from .._errors import DataError, ModelError, check_option

__all__ = ["SHAPES", "AbsoluteValue", "DeadZone", "PiecewiseLinear", "Polynomial", "Saturation",
           "SignedPower", "StaticFunction", "StaticNonlinearity", "as_nonlinearity", "from_data"]

#: The library shapes by the name the API and the experiment file use.
SHAPES = ("abs", "deadzone", "piecewise-linear", "polynomial", "power", "saturation")


class StaticNonlinearity:
    """Base of the static (memoryless) shapes.

    Subclasses are frozen dataclasses; they define ``kind``,
    ``free_scale``, ``parameters``, ``names``, ``bounds`` and the private
    ``_f(x, theta)`` / ``_df(x, theta)``.
    """

    kind: ClassVar[str] = ""
    free_scale: ClassVar[bool] = False

    @property
    def parameters(self) -> NDArray[np.float64]:
        """The parameter vector θ."""
        raise NotImplementedError

    @property
    def names(self) -> tuple[str, ...]:
        """A name per parameter, e.g. ``("deadzone.lower", "deadzone.upper")``."""
        raise NotImplementedError

    @property
    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper box bounds of θ (±inf when free)."""
        n = self.parameters.size
        return np.full(n, -np.inf), np.full(n, np.inf)

    def evaluate(self, x: ArrayLike, theta: ArrayLike | None = None) -> NDArray[np.float64]:
        """Return f(x; θ) (θ: this shape's parameters by default).

        Parameters
        ----------
        x : array_like, shape (N,)
            Input of the static block.
        theta : array_like, optional
            Parameters in the order of :attr:`names`.
        """
        return self._f(self._x(x), self._theta(theta))

    def jacobian(self, x: ArrayLike, theta: ArrayLike | None = None) -> NDArray[np.float64]:
        """Return ∂f(x; θ)/∂θ, shape (N, n_parameters).

        Parameters
        ----------
        x : array_like, shape (N,)
            Input of the static block.
        theta : array_like, optional
            Parameters in the order of :attr:`names`.
        """
        return self._df(self._x(x), self._theta(theta))

    def with_parameters(self, theta: ArrayLike) -> StaticNonlinearity:
        """Return the same shape with parameters ``theta`` (checked).

        Parameters
        ----------
        theta : array_like, shape (n_parameters,)
            New parameters in the order of :attr:`names`.
        """
        return self._with(self._theta(theta))

    def to_record(self) -> dict[str, Any]:
        """The shape as plain data for a model file.

        ``{"kind": ..., "parameters": {name: value}}``; a piecewise-linear
        shape adds its ``breakpoints``.  Floats are Python floats, so JSON
        writes their ``repr`` and :meth:`from_record` gets them back bit
        for bit.
        """
        return {"kind": self.kind,
                "parameters": dict(zip(self.names, self.parameters.tolist(), strict=True))}

    @staticmethod
    def from_record(data: object) -> StaticNonlinearity:
        """Rebuild a library shape from :meth:`to_record`'s data.

        Parameters
        ----------
        data : mapping
            ``{"kind": ..., "parameters": {name: value}}`` (and
            ``breakpoints`` for ``"piecewise-linear"``).

        Raises
        ------
        DataError
            For a record that makes no shape (unknown kind, parameters
            missing, misnamed or out of their range).
        """
        if not isinstance(data, Mapping) or not isinstance(data.get("parameters"), Mapping):
            raise DataError(f"a static block must be a table with \"kind\" and \"parameters\" "
                            f"(name → value), got {data!r}")
        kind = data.get("kind")
        if kind == StaticFunction.kind:
            raise ModelError(StaticFunction.unstorable)
        check_option("kind", kind, SHAPES)
        params = data["parameters"]
        values = list(params.values())
        arity = _ARITY.get(str(kind))
        if arity is not None and len(values) != arity:
            raise DataError(f"a {kind} has {arity} parameter(s), got {len(values)}: {dict(params)}")
        if kind == "piecewise-linear":
            if "breakpoints" not in data:
                raise DataError("a piecewise-linear shape needs its \"breakpoints\"")
            shape: StaticNonlinearity = PiecewiseLinear(data["breakpoints"], values)
        elif kind == "polynomial":
            shape = Polynomial(values)
        else:
            shape = _BY_KIND[str(kind)](*values)
        if shape.names != tuple(params):
            raise DataError(f"the {kind}'s parameters must be named {list(shape.names)}, got "
                            f"{list(params)}")
        return shape

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        return self.evaluate(x)

    # -- private: overridden by the shapes -------------------------------------------------
    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def _with(self, theta: NDArray[np.float64]) -> StaticNonlinearity:
        """The same shape at θ, unchecked (for the optimiser's end point)."""
        raise NotImplementedError

    def _basis(self, x: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """(N, p) with f = basis·θ when f is linear in θ, else None."""
        return None

    def _starts(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Candidate θ for a grid start, given the block's input ``x``."""
        return [self.parameters]

    def _regions(self, theta: NDArray[np.float64]) -> list[tuple[int, str, float]]:
        """(index, side, breakpoint): a parameter seen only by inputs on one side of it."""
        return []

    def _x(self, x: ArrayLike) -> NDArray[np.float64]:
        return as_array("x", x, ndim=1, finite=False)

    def _theta(self, theta: ArrayLike | None) -> NDArray[np.float64]:
        if theta is None:
            return self.parameters
        arr = as_array("theta", theta, ndim=1)
        if arr.size != self.parameters.size:
            raise DataError(f"theta must hold {self.parameters.size} values ({', '.join(self.names)})"
                            f" for this {self.kind}, got {arr.size}")
        return arr


@dataclass(frozen=True)
class _TwoBreakpoints(StaticNonlinearity):
    """A unit-slope shape set by two breakpoints, ``lower <= upper``."""

    lower: float
    upper: float
    _what: ClassVar[str] = ""

    def __post_init__(self) -> None:
        _breakpoints(self, self._what)

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ = (lower, upper)."""
        return np.array([self.lower, self.upper])

    @property
    def names(self) -> tuple[str, ...]:
        """``<kind>.lower``, ``<kind>.upper``."""
        return (f"{self.kind}.lower", f"{self.kind}.upper")

    def _with(self, theta: NDArray[np.float64]) -> Any:
        return _unchecked(self, lower=float(theta[0]), upper=float(theta[1]))

    def _regions(self, theta: NDArray[np.float64]) -> list[tuple[int, str, float]]:
        return [(0, "below", float(theta[0])), (1, "above", float(theta[1]))]


@dataclass(frozen=True)
class DeadZone(_TwoBreakpoints):
    """Dead zone with unit slope: no output between two breakpoints.

    ``f(x) = x − upper`` above ``upper``, ``x − lower`` below ``lower``
    and 0 between them.

    Parameters
    ----------
    lower : float
        Lower breakpoint [input unit].
    upper : float
        Upper breakpoint [input unit], >= ``lower``.

    Examples
    --------
    >>> DeadZone(-0.5, 1.0)([-1.0, 0.0, 2.0]).tolist()
    [-0.5, 0.0, 1.0]
    """

    kind: ClassVar[str] = "deadzone"
    _what: ClassVar[str] = "dead zone"

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.minimum(x - theta[0], 0.0) + np.maximum(x - theta[1], 0.0)

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.column_stack([-(x < theta[0]).astype(float), -(x > theta[1]).astype(float)])

    def _starts(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        return _quantile_pairs(x)


@dataclass(frozen=True)
class Saturation(_TwoBreakpoints):
    """Saturation with unit slope: x clipped to [lower, upper].

    Parameters
    ----------
    lower : float
        Lower limit [input unit].
    upper : float
        Upper limit [input unit], >= ``lower``.

    Examples
    --------
    >>> Saturation(-1.0, 0.5)([-2.0, 0.2, 2.0]).tolist()
    [-1.0, 0.2, 0.5]
    """

    kind: ClassVar[str] = "saturation"
    _what: ClassVar[str] = "saturation"

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        # written as a sum so that crossed limits inside a search stay a continuous function
        return x + np.maximum(theta[0] - x, 0.0) - np.maximum(x - theta[1], 0.0)

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.column_stack([(x < theta[0]).astype(float), (x > theta[1]).astype(float)])

    def _starts(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        lo, hi = np.quantile(x, [0.0, 1.0])
        return [np.array([np.quantile(x, p), np.quantile(x, 1 - p)])
                for p in (0.02, 0.1, 0.25)] + [np.array([lo - 1.0, hi + 1.0])]


@dataclass(frozen=True)
class AbsoluteValue(StaticNonlinearity):
    """Absolute value about a centre: ``f(x) = |x − center|``.

    Parameters
    ----------
    center : float
        The breakpoint [input unit].

    Examples
    --------
    >>> AbsoluteValue(1.0)([-1.0, 1.0, 3.0]).tolist()
    [2.0, 0.0, 2.0]
    """

    center: float = 0.0
    kind: ClassVar[str] = "abs"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", as_float("center", self.center))

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ = (center,)."""
        return np.array([self.center])

    @property
    def names(self) -> tuple[str, ...]:
        """``abs.center``."""
        return ("abs.center",)

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.abs(x - theta[0])

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return -np.sign(x - theta[0])[:, None]

    def _with(self, theta: NDArray[np.float64]) -> AbsoluteValue:
        return _unchecked(self, center=float(theta[0]))

    def _starts(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        return [np.array([c]) for c in np.quantile(x, [0.2, 0.35, 0.5, 0.65, 0.8])]


@dataclass(frozen=True)
class SignedPower(StaticNonlinearity):
    """Sign-preserving power: ``f(x) = sign(x)·|x|^exponent``.

    A valve's flow against its opening, a square-root law (0.5).

    Parameters
    ----------
    exponent : float
        The power p, > 0.

    Examples
    --------
    >>> SignedPower(2.0)([-2.0, 3.0]).tolist()
    [-4.0, 9.0]
    """

    exponent: float = 1.0
    kind: ClassVar[str] = "power"

    def __post_init__(self) -> None:
        object.__setattr__(self, "exponent", as_float("exponent", self.exponent, positive=True))

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ = (exponent,)."""
        return np.array([self.exponent])

    @property
    def names(self) -> tuple[str, ...]:
        """``power.exponent``."""
        return ("power.exponent",)

    @property
    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The exponent stays in [0.05, 20]."""
        return np.array([0.05]), np.array([20.0])

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.sign(x) * np.abs(x) ** theta[0]

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        ax = np.abs(x)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(ax > 0, np.sign(x) * ax ** theta[0] * np.log(np.where(ax > 0, ax, 1.0)),
                         0.0)
        return d[:, None]

    def _with(self, theta: NDArray[np.float64]) -> SignedPower:
        return _unchecked(self, exponent=float(theta[0]))

    def _starts(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        return [np.array([p]) for p in (0.5, 1.0, 1.5, 2.0, 3.0)]


@dataclass(frozen=True)
class PiecewiseLinear(StaticNonlinearity):
    """Continuous piecewise-linear curve through the origin.

    Given breakpoints β₁ < … < βₘ, the m + 1 segments have fitted slopes
    s₀ … sₘ and ``f(0) = 0``: ``f(x) = Σ_k s_k·ℓ_k(x)`` with ℓ_k the signed
    length of [0, x] inside segment k.  Linear in the slopes.

    Parameters
    ----------
    breakpoints : sequence of float
        Increasing breakpoints [input unit], at least one.
    slopes : sequence of float, optional
        One slope per segment (len(breakpoints) + 1); default all 1.

    Examples
    --------
    >>> PiecewiseLinear([0.0], [0.5, 2.0])([-2.0, 1.0]).tolist()
    [-1.0, 2.0]
    """

    breakpoints: tuple[float, ...]
    slopes: tuple[float, ...] | None = None
    kind: ClassVar[str] = "piecewise-linear"
    free_scale: ClassVar[bool] = True

    def __post_init__(self) -> None:
        bp = as_float_list("breakpoints", self.breakpoints, min_length=1)
        if any(nxt <= prev for prev, nxt in itertools.pairwise(bp)):
            raise DataError(f"breakpoints must be strictly increasing, got {bp}; sort them")
        slopes = [1.0] * (len(bp) + 1) if self.slopes is None else as_float_list(
            "slopes", self.slopes, length=len(bp) + 1)
        object.__setattr__(self, "breakpoints", tuple(bp))
        object.__setattr__(self, "slopes", tuple(slopes))

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ = the slopes s₀ … sₘ."""
        return np.array(self.slopes, dtype=float)

    @property
    def names(self) -> tuple[str, ...]:
        """``pwl.s0`` … ``pwl.sm``."""
        return tuple(f"pwl.s{k}" for k in range(len(self.breakpoints) + 1))

    def _basis(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        edges = np.concatenate([[-np.inf], self.breakpoints, [np.inf]])
        cols = []
        for lo, hi in itertools.pairwise(edges):
            # signed length of [0, x] within [lo, hi]
            top = np.clip(np.maximum(x, 0.0), max(lo, 0.0), max(hi, 0.0)) - max(lo, 0.0)
            bottom = np.clip(np.minimum(x, 0.0), min(lo, 0.0), min(hi, 0.0)) - min(hi, 0.0)
            cols.append(top + bottom)
        return np.column_stack(cols)

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._basis(x) @ theta

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._basis(x)

    def to_record(self) -> dict[str, Any]:
        """The shape as plain data, its breakpoints included."""
        return {**super().to_record(), "breakpoints": [float(b) for b in self.breakpoints]}

    def _with(self, theta: NDArray[np.float64]) -> PiecewiseLinear:
        return _unchecked(self, slopes=tuple(float(v) for v in theta))


@dataclass(frozen=True)
class Polynomial(StaticNonlinearity):
    """Polynomial without constant: ``f(x) = Σ c_k·x^k``, k = 1 … d.

    A constant would be an output offset (remove it with ``detrend`` or
    fit one with ``offset=True``).

    Parameters
    ----------
    coefficients : sequence of float
        c₁ … c_d, at least one.

    Examples
    --------
    >>> Polynomial([1.0, 0.0, 0.5])([2.0]).tolist()
    [6.0]
    """

    coefficients: tuple[float, ...]
    kind: ClassVar[str] = "polynomial"
    free_scale: ClassVar[bool] = True

    def __post_init__(self) -> None:
        c = as_float_list("coefficients", self.coefficients, min_length=1)
        object.__setattr__(self, "coefficients", tuple(c))

    @classmethod
    def of_degree(cls, degree: int) -> Polynomial:
        """The identity x as a polynomial of ``degree`` (a start).

        Parameters
        ----------
        degree : int
            Highest power, >= 1.
        """
        from .._checks import as_int

        degree = as_int("degree", degree, minimum=1, maximum=12)
        return cls((1.0,) + (0.0,) * (degree - 1))

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ = c₁ … c_d."""
        return np.array(self.coefficients, dtype=float)

    @property
    def names(self) -> tuple[str, ...]:
        """``poly.c1`` … ``poly.cd``."""
        return tuple(f"poly.c{k}" for k in range(1, len(self.coefficients) + 1))

    def _basis(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.column_stack([x ** k for k in range(1, len(self.coefficients) + 1)])

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._basis(x) @ theta

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._basis(x)

    def _with(self, theta: NDArray[np.float64]) -> Polynomial:
        return _unchecked(self, coefficients=tuple(float(v) for v in theta))


@dataclass(frozen=True)
class StaticFunction(StaticNonlinearity):
    """A user function ``f(x, theta)`` with initial parameters.

    The Jacobian is taken by central differences.

    Parameters
    ----------
    function : callable
        ``function(x, theta) -> ndarray`` of the same shape as ``x`` (N,).
    parameters0 : sequence of float
        Initial θ, at least one value.
    labels : sequence of str, optional
        A name per parameter (default ``f.theta0`` …); given names are
        prefixed ``f.``.
    lower, upper : sequence of float, optional
        Box bounds of θ (default unbounded).
    has_free_scale : bool
        True (default) when the parameters can absorb a gain of the
        linear block: ``k·f(x, θ) = f(x, θ')`` for an input block,
        ``f(k·x, θ) = f(x, θ')`` for an output block.  The linear block's
        static gain is then fixed to 1.  Declared wrongly, the fit stops
        with an IdentifiabilityError naming the inseparable parameters.

    Examples
    --------
    >>> f = StaticFunction(lambda x, th: th[0] * np.tanh(x), [2.0])
    >>> f.names
    ('f.theta0',)
    """

    function: Callable[[NDArray[np.float64], NDArray[np.float64]], Any]
    parameters0: tuple[float, ...]
    labels: tuple[str, ...] | None = None
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None
    has_free_scale: bool = True
    kind: ClassVar[str] = "function"

    def __post_init__(self) -> None:
        if not callable(self.function):
            raise type_error("function", self.function, "a callable f(x, theta)")
        theta = as_float_list("parameters0", self.parameters0, min_length=1)
        n = len(theta)
        labels = [f"theta{k}" for k in range(n)] if self.labels is None else as_str_list(
            "labels", self.labels, length=n)
        for label in labels:
            as_str("labels", label)
        lo = [-np.inf] * n if self.lower is None else as_float_list("lower", self.lower, length=n,
                                                                    finite=False)
        hi = [np.inf] * n if self.upper is None else as_float_list("upper", self.upper, length=n,
                                                                   finite=False)
        if any(a >= b for a, b in zip(lo, hi, strict=True)) or any(
                not a <= t <= b for a, t, b in zip(lo, theta, hi, strict=True)):
            raise DataError(f"the bounds must satisfy lower < upper with parameters0 between "
                            f"them, got lower {lo}, parameters0 {theta}, upper {hi}")
        if not isinstance(self.has_free_scale, bool):
            raise type_error("has_free_scale", self.has_free_scale, "true or false")
        object.__setattr__(self, "parameters0", tuple(theta))
        object.__setattr__(self, "labels", tuple(labels))
        object.__setattr__(self, "lower", tuple(lo))
        object.__setattr__(self, "upper", tuple(hi))
        self._f(np.linspace(-1.0, 1.0, 5), np.array(theta))  # fails early on a bad function

    @property
    def free_scale(self) -> bool:  # type: ignore[override]
        """Whether the output has a free scale (``has_free_scale``)."""
        return self.has_free_scale

    @property
    def parameters(self) -> NDArray[np.float64]:
        """θ (``parameters0`` at construction)."""
        return np.array(self.parameters0, dtype=float)

    @property
    def names(self) -> tuple[str, ...]:
        """``f.<label>`` per parameter."""
        return tuple(f"f.{label}" for label in self.labels or ())

    @property
    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The box bounds given."""
        return np.array(self.lower, dtype=float), np.array(self.upper, dtype=float)

    def _f(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        try:
            out = np.asarray(self.function(x, theta), dtype=float)
        except Exception as exc:
            raise ModelError(f"the static function raised {type(exc).__name__}: {exc}") from exc
        if out.shape != x.shape:
            raise ModelError(f"the static function must return an array shaped like x "
                             f"{x.shape}, got {out.shape}")
        return out

    def _df(self, x: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        cols = []
        for k in range(theta.size):
            h = 1e-6 * max(abs(theta[k]), 1.0)
            up, down = theta.copy(), theta.copy()
            up[k] += h
            down[k] -= h
            cols.append((self._f(x, up) - self._f(x, down)) / (2 * h))
        return np.column_stack(cols)

    #: Why a user function cannot go into a model file, and what to do instead.
    unstorable: ClassVar[str] = (
        "a model with a user StaticFunction cannot be written to a model file: the file holds "
        "numbers, not Python code. Keep the function in your own module and save the rest: "
        "save_model(model.linear, path) for the linear block and the function's parameters "
        "(model.input_nonlinearity.parameters / output_nonlinearity.parameters) beside it, "
        "then rebuild the BlockModel with the same StaticFunction; or fit a library shape "
        "(\"piecewise-linear\" or \"polynomial\" can follow most curves), which a model file "
        "holds")

    def to_record(self) -> dict[str, Any]:
        """Refused: a user function is code, not data.

        Raises
        ------
        ModelError
            Always, with what to do instead.
        """
        raise ModelError(self.unstorable)

    def _with(self, theta: NDArray[np.float64]) -> StaticFunction:
        return _unchecked(self, parameters0=tuple(float(v) for v in theta))


def as_nonlinearity(value: object, name: str = "nonlinearity") -> StaticNonlinearity | str:
    """A shape object as is, or a library shape name (checked).

    Parameters
    ----------
    value : StaticNonlinearity or str
        The shape, or one of ``SHAPES`` (then initialised from the data).
    name : str
        The argument's name for messages.
    """
    if isinstance(value, StaticNonlinearity):
        return value
    if isinstance(value, str):
        check_option(name, value, SHAPES)
        return value
    raise type_error(name, value, "a static nonlinearity (DeadZone, Saturation, …) or one of "
                     + ", ".join(repr(s) for s in SHAPES))


def from_data(kind: str, x: NDArray[np.float64], *, degree: int = 3,
              breakpoints: Sequence[float] | None = None) -> StaticNonlinearity:
    """A library shape with a start read off the block's input ``x``."""
    if kind == "deadzone":
        lo, hi = np.quantile(x, [0.3, 0.7])
        return DeadZone(float(lo), float(hi))
    if kind == "saturation":
        lo, hi = np.quantile(x, [0.05, 0.95])
        return Saturation(float(lo), float(hi))
    if kind == "abs":
        return AbsoluteValue(float(np.median(x)))
    if kind == "power":
        return SignedPower(1.0)
    if kind == "polynomial":
        return Polynomial.of_degree(degree)
    if breakpoints is None:
        inner = np.quantile(x, [0.2, 0.4, 0.6, 0.8])
        breakpoints = [float(v) for v in np.unique(np.round(inner, 12))]
    return PiecewiseLinear(tuple(breakpoints))


# -- private ---------------------------------------------------------------------------------

#: The library shapes by kind, and how many parameters the fixed-size ones take.
_BY_KIND: dict[str, Any] = {"deadzone": DeadZone, "saturation": Saturation, "abs": AbsoluteValue,
                            "power": SignedPower}
_ARITY = {"deadzone": 2, "saturation": 2, "abs": 1, "power": 1}



def _breakpoints(obj: Any, what: str) -> None:
    lower = as_float("lower", obj.lower)
    upper = as_float("upper", obj.upper)
    if lower > upper:
        raise DataError(f"the {what}'s breakpoints are in the wrong order: lower = {lower:g} > "
                        f"upper = {upper:g}; swap them")
    object.__setattr__(obj, "lower", lower)
    object.__setattr__(obj, "upper", upper)


def _unchecked(obj: Any, **values: Any) -> Any:
    """A copy of a frozen shape with new field values, skipping the constructor's checks."""
    new = object.__new__(type(obj))
    for f in getattr(type(obj), "__dataclass_fields__", {}):
        if f in values:
            object.__setattr__(new, f, values[f])
        elif hasattr(obj, f):
            object.__setattr__(new, f, getattr(obj, f))
    return new


def _quantile_pairs(x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    qs = np.quantile(x, [0.1, 0.25, 0.4, 0.5, 0.6, 0.75, 0.9])
    out = []
    for i, lo in enumerate(qs):
        for hi in qs[i:]:
            out.append(np.array([lo, hi]))
    return out

