"""The polynomial NARX model: y(t) = Σ_j θ_j·Π(lagged y and u) + e(t).

Each term is a product of lagged outputs and inputs (a monomial); the
model is linear in its coefficients θ. It is *one-step* by construction:
fitted by least squares on the measured past, it predicts y(t) from
y(t−1), …; run from its own output (the free run) it is the simulation a
validation compares with a record.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_float, as_int, as_str, type_error
from .._errors import DataError, ModelError, ServoidWarning, check_option
from .._warn import warn
from ..validate import INITIALS, Initial, check_signals
from ._narx_kernel import predict_k, simulate_free

__all__ = ["NarxModel", "Term", "term_label"]

#: A term: its factors as (signal, lag) pairs, signal 0 = the output, i ≥ 1 = input i.
Term = tuple[tuple[int, int], ...]


@dataclass(frozen=True, eq=False)
class NarxModel:
    """A polynomial NARX model that replays itself on records.

    ``y(t) = Σ_j θ_j · Π_{(s, l) ∈ term_j} z_s(t − l) + e(t)`` where
    ``z_0 = y`` and ``z_i`` is input i; the empty term is the constant.

    Attributes
    ----------
    terms : tuple of tuple of (int, int)
        Each term's factors as ``(signal, lag)`` pairs: signal 0 is the
        output (lag >= 1 [samples]), signal i >= 1 is input i (lag >= 0).
        ``()`` is the constant term; a repeated factor is a power.
    coefficients : ndarray, shape (n_terms,)
        θ, one per term [output unit per unit of the term].
    dt : float
        Sample period [s].
    covariance : ndarray, shape (n_terms, n_terms), optional
        Covariance of the coefficients (σ̂²(ΦᵀΦ)⁻¹ from :func:`fit_narx`).
    noise_variance : float
        Variance of the one-step prediction error e(t).
    input_names : tuple of str
        A name per input, in signal order (default ``("u",)``).
    output_name : str
        The output's name.
    output_unit : str
        Unit of the output ('' when unknown).
    input_units : tuple of str
        A unit per input (empty when unknown).

    Notes
    -----
    ``has_noise_model`` is True: the one-step predictor (measured past
    outputs) is not the free run (its own past outputs), so
    :func:`servoid.validate.validate` scores :meth:`predict` and
    :meth:`residuals` apart from the simulation.
    """

    terms: tuple[Term, ...]
    coefficients: NDArray[np.float64]
    dt: float
    covariance: NDArray[np.float64] | None = None
    noise_variance: float = 0.0
    input_names: tuple[str, ...] = ("u",)
    output_name: str = "y"
    output_unit: str = ""
    input_units: tuple[str, ...] = ()
    _sig: NDArray[np.int64] = field(init=False, repr=False, compare=False)
    _lag: NDArray[np.int64] = field(init=False, repr=False, compare=False)

    has_noise_model: ClassVar[bool] = True

    def __post_init__(self) -> None:
        names = _str_tuple("input_names", self.input_names)
        if not names:
            raise DataError("input_names needs at least one input name, e.g. ('u',)")
        object.__setattr__(self, "input_names", names)
        object.__setattr__(self, "output_name", as_str("output_name", self.output_name))
        object.__setattr__(self, "output_unit",
                           as_str("output_unit", self.output_unit, empty=True))
        units = _str_tuple("input_units", self.input_units)
        if units and len(units) != len(names):
            raise DataError(f"input_units needs one unit per input ({len(names)}), got "
                            f"{len(units)}")
        object.__setattr__(self, "input_units", units)
        terms = _check_terms(self.terms, len(names))
        object.__setattr__(self, "terms", terms)
        theta = np.array(as_array("coefficients", self.coefficients, ndim=1), dtype=float)
        if theta.size != len(terms):
            raise DataError(f"coefficients needs one value per term ({len(terms)}), got "
                            f"{theta.size}")
        theta.setflags(write=False)
        object.__setattr__(self, "coefficients", theta)
        object.__setattr__(self, "dt", as_float("dt", self.dt, positive=True, unit="s"))
        if self.covariance is not None:
            cov = np.array(as_array("covariance", self.covariance, ndim=2), dtype=float)
            if cov.shape != (len(terms), len(terms)):
                raise DataError(f"covariance must have shape ({len(terms)}, {len(terms)}), got "
                                f"{cov.shape}")
            cov.setflags(write=False)
            object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "noise_variance",
                           as_float("noise_variance", self.noise_variance, nonneg=True))
        sig, lag = encode_terms(terms)
        object.__setattr__(self, "_sig", sig)
        object.__setattr__(self, "_lag", lag)

    # -- structure ------------------------------------------------------------------------
    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return len(self.input_names)

    @property
    def max_lag(self) -> int:
        """Longest lag of any term [samples]: the measured samples a free run starts from."""
        return max((lag for term in self.terms for _, lag in term), default=0)

    @property
    def degree(self) -> int:
        """Largest number of factors in a term (0 for a constant alone)."""
        return max((len(term) for term in self.terms), default=0)

    @property
    def names(self) -> tuple[str, ...]:
        """A readable label per term, e.g. ``"y(t-1)*u(t-2)"``."""
        return tuple(term_label(t, self.output_name, self.input_names) for t in self.terms)

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviation of each coefficient (NaN without covariance)."""
        if self.covariance is None:
            return np.full(len(self.terms), np.nan)
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def with_coefficients(self, coefficients: NDArray[np.float64]) -> NarxModel:
        """Return the same terms with other coefficients.

        Parameters
        ----------
        coefficients : ndarray, shape (n_terms,)
            The new θ, in the order of :attr:`terms`.
        """
        return replace(self, coefficients=coefficients)

    # -- running --------------------------------------------------------------------------
    def simulate(self, u: NDArray[np.float64],
                 y0: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Free-run simulation from the input alone.

        Parameters
        ----------
        u : ndarray, shape (N,) or (N, n_inputs)
            Input.
        y0 : ndarray, shape (max_lag,), optional
            The outputs y(0), …, y(max_lag − 1) the recursion starts from
            (default zeros); inputs before t = 0 are not used.

        Returns
        -------
        ndarray, shape (N,)
            y0 followed by the simulated output (NaN from the sample where
            the run diverges, with a :class:`~servoid.ServoidWarning`).
        """
        u2 = self._inputs(as_array("u", u), None)
        m = self.max_lag
        if u2.shape[0] <= m:
            raise DataError(f"u needs more than max_lag = {m} samples to simulate, got "
                            f"{u2.shape[0]}")
        start = np.zeros(m) if y0 is None else as_array("y0", y0, ndim=1)
        if start.size != m:
            raise DataError(f"y0 must hold the first max_lag = {m} outputs, got {start.size}")
        z = np.empty((1 + self.n_inputs, u2.shape[0]))
        z[1:] = u2.T
        z[0, :m] = start
        z[0, m:] = 0.0
        self._free_run(z, m)
        return z[0].copy()

    def replay(self, y: NDArray[np.float64], u: NDArray[np.float64], *,
               initial: Initial = "auto") -> tuple[NDArray[np.float64], int, str]:
        """Free-run on a record from its first max_lag measured samples.

        Parameters
        ----------
        y : ndarray, shape (N,)
            Measured output; only y(0 … max_lag − 1) are used.
        u : ndarray, shape (N,) or (N, n_inputs)
            Input.
        initial : {"auto", "measured"}
            How the run starts: from the measured samples (both values).
            ``"estimate"`` and ``"zero"`` are refused: a NARX model has no
            state to fit, and from zero its first samples are not the
            record's.

        Returns
        -------
        y_sim : ndarray, shape (N,)
            The measured samples before ``first``, then the free run.
        first : int
            ``max_lag``: the first sample the metrics use.
        initial : str
            ``"measured"``.
        """
        check_option("initial", initial, INITIALS)
        if initial not in ("auto", "measured"):
            raise ModelError(
                f'initial="{initial}" is not available for a NARX model: its free run starts '
                'from the first max_lag measured samples; use initial="measured" (or "auto") '
                '(from an experiment file: [validation] initial = "measured")')
        z = self._record(y, u)
        self._free_run(z, self.max_lag)
        return z[0].copy(), self.max_lag, "measured"

    def predict(self, y: NDArray[np.float64], u: NDArray[np.float64],
                horizon: int = 1) -> NDArray[np.float64]:
        """k-step-ahead prediction ŷ(t | t − k) on a record.

        Parameters
        ----------
        y : ndarray, shape (N,)
            Measured output.
        u : ndarray, shape (N,) or (N, n_inputs)
            Input.
        horizon : int
            k [samples]: outputs up to t − k are measured, later ones predicted.

        Returns
        -------
        ndarray, shape (N,)
            The prediction from sample max_lag on; the measurement before it.
        """
        horizon = as_int("horizon", horizon, minimum=1)
        z = self._record(y, u)
        out = z[0].copy()
        predict_k(z, self._sig, self._lag, self.coefficients, self.max_lag, horizon, out)
        return out

    def residuals(self, y: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """One-step prediction errors y(t) − ŷ(t | t − 1) on a record.

        Parameters
        ----------
        y : ndarray, shape (N,)
            Measured output.
        u : ndarray, shape (N,) or (N, n_inputs)
            Input.

        Returns
        -------
        ndarray, shape (N,)
            Zero before sample max_lag (those samples start the predictor).
        """
        z = self._record(y, u)
        pred = z[0].copy()
        predict_k(z, self._sig, self._lag, self.coefficients, self.max_lag, 1, pred)
        return z[0] - pred

    # -- display --------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Terms, coefficients and their std as plain data."""
        return {
            "type": "narx", "dt": self.dt, "output": self.output_name,
            "inputs": list(self.input_names),
            "terms": [[list(f) for f in t] for t in self.terms],
            "names": list(self.names), "coefficients": self.coefficients.tolist(),
            "std": [None if np.isnan(s) else float(s) for s in self.std],
            "noise_variance": self.noise_variance, "max_lag": self.max_lag,
            "output_unit": self.output_unit, "input_units": list(self.input_units),
            "covariance": None if self.covariance is None else self.covariance.tolist(),
        }

    def to_record(self) -> dict[str, Any]:
        """The model as the plain data of a model file.

        Everything but the file's header (format version, type, ``dt``):
        terms, coefficients, covariance, noise variance, names, units, and
        the readable term labels (for other tools; not read back).  Floats
        are Python floats, so JSON writes their ``repr`` and
        :meth:`from_record` gets the model back bit for bit.
        """
        return {
            "terms": [[list(f) for f in t] for t in self.terms],
            "term_names": list(self.names),
            "coefficients": self.coefficients.tolist(),
            "noise_variance": self.noise_variance,
            "input_names": list(self.input_names), "output_name": self.output_name,
            "input_units": list(self.input_units), "output_unit": self.output_unit,
            "covariance": None if self.covariance is None else self.covariance.tolist(),
        }

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> NarxModel:
        """Rebuild the model from a model file's data (:meth:`to_record`).

        Parameters
        ----------
        data : mapping
            The file's content: ``dt`` and the keys :meth:`to_record` writes.

        Raises
        ------
        KeyError
            A required key is missing (the model file reader names it).
        DataError
            Values that make no model.
        """
        terms = data["terms"]
        if not isinstance(terms, list):
            raise DataError(f"terms must be a list of terms, got {terms!r}")
        return cls(terms, data["coefficients"], data["dt"], covariance=data.get("covariance"),
                   noise_variance=data.get("noise_variance", 0.0),
                   input_names=_listed(data, "input_names", ("u",)),
                   output_name=data.get("output_name", "y"),
                   output_unit=data.get("output_unit", ""),
                   input_units=_listed(data, "input_units", ()))

    def __str__(self) -> str:
        parts = [f"{c:+.6g}" + ("" if not t else f"·{n}")
                 for c, t, n in zip(self.coefficients, self.terms, self.names, strict=True)]
        body = " ".join(parts) if parts else "0"
        return f"{self.output_name}(t) = {body} + e(t)"

    def __repr__(self) -> str:
        return (f"<NarxModel: {len(self.terms)} terms, degree {self.degree}, max lag "
                f"{self.max_lag}, dt = {self.dt:g} s>")

    # -- private --------------------------------------------------------------------------
    def _inputs(self, u: NDArray[np.float64], n: int | None) -> NDArray[np.float64]:
        u2 = u.reshape(-1, 1) if u.ndim == 1 else u
        if u2.ndim != 2 or u2.shape[1] != self.n_inputs or (n is not None and u2.shape[0] != n):
            want = f"({n if n is not None else 'N'},)" if self.n_inputs == 1 else ""
            want += f" or ({n if n is not None else 'N'}, {self.n_inputs})"
            raise DataError(f"u must have shape {want.strip(' or')} for this model's "
                            f"{self.n_inputs} input(s), got {u.shape}")
        if not np.all(np.isfinite(u2)):
            raise DataError("u has non-finite values; remove or interpolate them first")
        return u2

    def _record(self, y: object, u: object) -> NDArray[np.float64]:
        y_arr, u_arr = check_signals(y, u)
        u2 = self._inputs(u_arr, y_arr.size)
        m = self.max_lag
        if y_arr.size <= m + 2:
            raise DataError(f"the record has {y_arr.size} samples; this NARX model needs more "
                            f"than max_lag + 2 = {m + 2} (max_lag of them start it)")
        if not np.all(np.isfinite(y_arr)):
            raise DataError("y has non-finite values; remove or interpolate them first")
        z = np.empty((1 + self.n_inputs, y_arr.size))
        z[0] = y_arr
        z[1:] = u2.T
        return z

    def _free_run(self, z: NDArray[np.float64], start: int) -> None:
        where = simulate_free(z, self._sig, self._lag, self.coefficients, start)
        if where >= 0:
            warn(
                f"the free run of the NARX model diverges at sample {where} (t = "
                f"{where * self.dt:.6g} s): its output leaves ±1e150, and the samples from "
                "there on are NaN. The one-step predictor can be good while the simulation is "
                "unstable; try a lower degree or fewer terms (max_terms, criterion = \"bic\")",
                ServoidWarning)


def term_label(term: Term, output: str = "y", inputs: Sequence[str] = ("u",)) -> str:
    """A readable label for a term, e.g. ``"y(t-1)^2*u(t-2)"``."""
    if not term:
        return "constant"
    pieces: list[str] = []
    counts: dict[tuple[int, int], int] = {}
    for factor in term:
        counts[factor] = counts.get(factor, 0) + 1
    for (s, lag), power in counts.items():
        name = output if s == 0 else inputs[s - 1]
        base = f"{name}(t)" if lag == 0 else f"{name}(t-{lag})"
        pieces.append(base + (f"^{power}" if power > 1 else ""))
    return "*".join(pieces)


def encode_terms(terms: Sequence[Term]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The kernels' (T, D) signal and lag tables, signal −1 padding."""
    depth = max((len(t) for t in terms), default=0)
    sig = np.full((len(terms), max(depth, 1)), -1, dtype=np.int64)
    lag = np.zeros((len(terms), max(depth, 1)), dtype=np.int64)
    for j, term in enumerate(terms):
        for f, (s, l_) in enumerate(term):
            sig[j, f] = s
            lag[j, f] = l_
    return sig, lag


def _check_terms(terms: object, n_inputs: int) -> tuple[Term, ...]:
    if isinstance(terms, (str, bytes)) or not isinstance(terms, Sequence):
        raise type_error("terms", terms, "a sequence of terms, each a sequence of (signal, lag) "
                         "pairs")
    out: list[Term] = []
    for k, term in enumerate(terms):
        if isinstance(term, (str, bytes)) or not isinstance(term, Sequence):
            raise type_error(f"terms[{k}]", term, "a sequence of (signal, lag) pairs")
        factors = []
        for factor in term:
            if isinstance(factor, (str, bytes)) or not isinstance(factor, Sequence) or \
                    len(factor) != 2:
                raise type_error(f"terms[{k}]", term, "a sequence of (signal, lag) pairs")
            s = as_int(f"terms[{k}] signal", factor[0], minimum=0, maximum=n_inputs)
            lag = as_int(f"terms[{k}] lag", factor[1], minimum=1 if s == 0 else 0)
            factors.append((s, lag))
        out.append(tuple(sorted(factors)))
    if len(set(out)) != len(out):
        raise ModelError("terms holds the same term twice; list each term once")
    return tuple(out)


def _listed(data: Mapping[str, Any], key: str, default: tuple[str, ...]) -> tuple[str, ...]:
    value = data.get(key)
    if value is None:
        return default
    return _str_tuple(key, value)


def _str_tuple(name: str, value: object) -> tuple[str, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not all(
            isinstance(v, str) for v in value):
        raise type_error(name, value, "a sequence of strings")
    return tuple(value)
