"""The :class:`Estimate`: what every estimator returns."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_float, as_mapping, type_error
from .._errors import ChannelError, DataError, ModelError
from .._lazy import stats
from .._warn import warn

__all__ = ["Deferred", "Estimate", "ParameterRow"]


@dataclass(frozen=True)
class ParameterRow:
    """One estimated parameter with its uncertainty."""

    name: str
    value: float
    std: float
    ci_low: float
    ci_high: float
    unit: str = ""


#: Tuples of str that passed the names/units check, by id; holding them keeps the ids
#: from being reused, and an estimator's cached names (ARX) skip the check after
#: the first fit. Bounded: beyond 1024 entries a tuple is simply checked each time.
_CHECKED: dict[int, tuple[str, ...]] = {}


@functools.lru_cache(maxsize=128)
def _blank_units(n: int) -> tuple[str, ...]:
    return ("",) * n


class Deferred:
    """A model an estimator builds on first read of :attr:`Estimate.model`.

    ``Estimate(model=Deferred(build), ...)`` calls ``build()`` once, when
    ``model`` is first read: a fit whose model is not looked at (an order
    scan, a benchmark) does not pay for building it.  Only for a build
    that cannot fail once the fit has succeeded.
    """

    __slots__ = ("build",)

    def __init__(self, build: Callable[[], Any]) -> None:
        self.build = build


class _ModelSlot:
    """The ``model`` field: stores a model or a :class:`Deferred`, returns a model."""

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:  # class access: tells dataclass the field has no default
            raise AttributeError("model")
        value = obj.__dict__["_model"]
        if isinstance(value, Deferred):
            value = value.build()
            obj.__dict__["_model"] = value
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        # reached only from __init__ (object.__setattr__); the frozen dataclass's
        # __setattr__ refuses assignments from outside first
        obj.__dict__["_model"] = value


@dataclass(frozen=True, eq=False)
class Estimate:
    """A fitted model with covariance, residuals and diagnostics.

    Attributes
    ----------
    model : object
        The identified model (e.g. a :class:`~servoid.models.PolynomialModel`).
    parameters : ndarray, shape (n,)
        Estimated parameter vector θ̂.
    names : tuple of str
        A name per parameter.
    covariance : ndarray, shape (n, n)
        Covariance of θ̂.
    noise_variance : float
        Estimated variance of the equation error / residual σ̂².
    n_samples : int
        Number of equations (residuals) the fit used.
    method : str
        Estimator, e.g. ``"arx"``.
    status : str
        Solver status: ``"ok"`` or a description of what happened.
    options : mapping
        The settings used (orders, solver route, ...), JSON-friendly.
    units : tuple of str
        A unit per parameter ('' when dimensionless or unknown).
    residual_function : callable, optional
        ``() -> residuals``, called once on first access of :attr:`residuals`.
    model_function : callable, optional
        ``theta -> model``: the model at another parameter vector (same order
        as `parameters`).  It carries the covariance to anything computed
        from the model (frequency response bands, poles, gains) by the delta
        method; see :meth:`model_at`.
    """

    model: Any = _ModelSlot()  # type: ignore[assignment]
    parameters: NDArray[np.float64]
    names: tuple[str, ...]
    covariance: NDArray[np.float64]
    noise_variance: float
    n_samples: int
    method: str
    status: str = "ok"
    options: Mapping[str, Any] = field(default_factory=dict)
    units: tuple[str, ...] = ()
    residual_function: Callable[[], NDArray[np.float64]] | None = field(
        default=None, repr=False
    )
    model_function: Callable[[NDArray[np.float64]], Any] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("parameters", "covariance"):
            value = getattr(self, name)
            if type(value) is np.ndarray and value.dtype == np.float64:
                arr = value.copy()  # what as_array + np.array give, without their checks
            else:
                arr = np.array(as_array(name, value, finite=False), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if not self.units:
            object.__setattr__(self, "units", _blank_units(self.parameters.size))
        for name in ("names", "units"):
            value = getattr(self, name)
            if type(value) is tuple and _CHECKED.get(id(value)) is value:
                continue  # a tuple of str seen before (held here, so its id is its own)
            if type(value) is tuple and all(type(v) is str for v in value):
                if len(_CHECKED) < 1024:
                    _CHECKED[id(value)] = value
                continue  # already what the check below makes of it
            if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not all(
                    isinstance(v, str) for v in value):
                raise type_error(name, value, "a sequence of strings")
            object.__setattr__(self, name, tuple(value))
        options = self.options
        if type(options) is not dict:
            as_mapping("options", options)
        object.__setattr__(self, "options", MappingProxyType(dict(options)))

    @classmethod
    def _trusted(cls, *, model: Any, parameters: NDArray[np.float64], names: tuple[str, ...],
                 covariance: NDArray[np.float64], options: dict[str, Any],
                 **fields: Any) -> Estimate:
        """An Estimate from fields already in the form ``__post_init__`` gives them.

        For an estimator's hot path (ARX): ``parameters`` and ``covariance``
        fresh float64 arrays nobody else holds (made read-only here, not
        copied), ``names`` a tuple of str, ``options`` a fresh dict, units
        blank. What ``Estimate(...)`` would store, without its conversions.
        """
        obj = object.__new__(cls)
        parameters.setflags(write=False)
        covariance.setflags(write=False)
        state = obj.__dict__
        state.update(status="ok", units=_blank_units(parameters.size), residual_function=None,
                     model_function=None)
        state.update(fields)
        state.update(_model=model, parameters=parameters, names=names, covariance=covariance,
                     options=MappingProxyType(options))
        return obj

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviation of each parameter."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def dof(self) -> int:
        """Residual degrees of freedom N − n."""
        return max(self.n_samples - self.parameters.size, 1)

    def confidence_intervals(self, level: float = 0.95) -> NDArray[np.float64]:
        """Two-sided intervals θ̂ ± t·σ, shape (n, 2).

        Parameters
        ----------
        level : float
            Coverage probability in (0, 1); Student-t quantile with N − n degrees of freedom.
        """
        level = as_float("level", level)
        if not 0 < level < 1:
            raise DataError(f"level must lie in (0, 1), e.g. 0.95, got {level}")
        half = stats.t.ppf(0.5 + level / 2, self.dof) * self.std
        return np.column_stack([self.parameters - half, self.parameters + half])

    def table(self, level: float = 0.95) -> list[ParameterRow]:
        """Parameters as rows (value, std, confidence interval)."""
        ci = self.confidence_intervals(level)
        return [
            ParameterRow(n, float(v), float(s), float(lo), float(hi), unit)
            for n, v, s, (lo, hi), unit in zip(
                self.names, self.parameters, self.std, ci, self.units, strict=True
            )
        ]

    def model_at(self, theta: NDArray[np.float64]) -> Any:
        """Return the model at parameter vector ``theta``.

        Parameters
        ----------
        theta : ndarray, shape (n,)
            Parameters in the order of :attr:`names`.

        Raises
        ------
        ModelError
            The estimator did not record how the model depends on θ.
        """
        if self.model_function is None:
            raise ModelError(f"this {self.method} estimate does not say how its model depends on "
                             "its parameters, so no uncertainty can be carried to the model")
        theta = as_array("theta", theta, finite=False)
        if theta.shape != self.parameters.shape:
            raise DataError(f"theta must have shape {self.parameters.shape}, got {theta.shape}")
        return self.model_function(theta)

    def __getitem__(self, name: str) -> float:
        try:
            return float(self.parameters[self.names.index(name)])
        except ValueError:
            renamed = self.options.get("former_names", {}).get(name)
            if renamed in self.names:  # a name an older servoid gave, read for one release
                warn(f"{self.method} parameter {name!r} is now {renamed!r}; read it as "
                     f"{renamed!r}", DeprecationWarning)
                return float(self.parameters[self.names.index(renamed)])
            raise ChannelError(f"no parameter {name!r}; parameters are "
                               f"{', '.join(self.names)}") from None

    @cached_property
    def residuals(self) -> NDArray[np.float64]:
        """Residuals of the fit (computed on first access)."""
        values = np.empty(0) if self.residual_function is None else np.array(
            self.residual_function(), dtype=float
        )
        values.setflags(write=False)
        return values

    def to_dict(self, level: float = 0.95) -> dict[str, Any]:
        """Plain-data summary for JSON."""
        return {
            "method": self.method,
            "status": self.status,
            "n_samples": self.n_samples,
            "noise_variance": self.noise_variance,
            "confidence_level": level,
            "parameters": [row.__dict__ for row in self.table(level)],
            "options": dict(self.options),
        }

    def __repr__(self) -> str:
        return (f"<Estimate {self.method}: {len(self.names)} parameters, {self.n_samples} "
                f"samples, σ̂² = {self.noise_variance:.4g}>")

    def _repr_html_(self) -> str:
        from .._display import html_block, number

        rows = [(r.name, number(r.value), number(r.std, 3),
                 f"[{number(r.ci_low)}, {number(r.ci_high)}]", r.unit) for r in self.table()]
        return html_block(f"{self.method} estimate",
                          [("samples", str(self.n_samples)),
                           ("σ̂²", number(self.noise_variance, 4)), ("status", self.status)],
                          ("parameter", "estimate", "std", "95 % CI", "unit"), rows)

    def __str__(self) -> str:
        lines = [f"{self.method} estimate, {self.n_samples} samples, σ̂² = {self.noise_variance:.4g}"]
        width = max(len(n) for n in self.names)
        for row in self.table():
            lines.append(
                f"  {row.name:<{width}}  {row.value: .6g} ± {row.std:.2g}"
                f"  [{row.ci_low:.6g}, {row.ci_high:.6g}] {row.unit}".rstrip()
            )
        return "\n".join(lines)
