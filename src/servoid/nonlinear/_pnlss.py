"""The polynomial nonlinear state-space model (PNLSS; Paduart et al., Automatica 2010).

``x(t+1) = A x + B u + E ζ(x, u)``, ``y(t) = C x + D u + F η(x, u)``, with
ζ = η the monomials of degree 2 … ``degree`` in the states and inputs
(``"full"``), the states alone (``"state"``) or the inputs alone
(``"input"``).  The model works on normalised signals, ``ũ = (u − ū)/s_u``
and ``y = ȳ + s_y ỹ``, so its coefficients are of order one whatever the
units; the normalisation is part of the model (and of its file).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_int, as_str, type_error
from .._display import html_block, number
from .._errors import DataError, ModelError, ServoidWarning, check_option
from .._warn import warn
from ..validate import INITIALS, Initial, check_signals
from ._pnlss_kernel import jacobian, simulate

__all__ = ["MONOMIALS", "PnlssModel", "exponents"]

Monomials = Literal["full", "state", "input"]
#: Which variables the monomials ζ = η are built from.
MONOMIALS: tuple[Monomials, ...] = ("full", "state", "input")


def exponents(nx: int, nu: int, degree: int, monomials: Monomials = "full"
              ) -> NDArray[np.int64]:
    """The exponent rows of the constant and the monomials of degree 2 … ``degree``.

    Parameters
    ----------
    nx, nu : int
        Numbers of states and inputs.
    degree : int
        Highest total degree (1: no monomial, a linear model).
    monomials : {"full", "state", "input"}
        Products of states and inputs, of states alone, or of inputs alone.

    Returns
    -------
    ndarray, shape (n_monomials, nx + nu)
        One row per monomial: the power of each state, then of each input,
        by degree and then in lexicographic order.  With ``degree >= 2`` the
        first row is the constant (all powers 0): the offsets the nonlinear
        terms need (a mean of x² in the state, in the output) without
        shifting the states away from the origin.  ``degree = 1`` gives no
        row (a linear model).
    """
    check_option("monomials", monomials, MONOMIALS)
    variables = {"full": range(nx + nu), "state": range(nx),
                 "input": range(nx, nx + nu)}[monomials]
    rows = [np.zeros(nx + nu, dtype=np.int64)] if degree >= 2 else []
    for d in range(2, degree + 1):
        for combo in itertools.combinations_with_replacement(variables, d):
            row = np.zeros(nx + nu, dtype=np.int64)
            for k in combo:
                row[k] += 1
            rows.append(row)
    return np.array(rows, dtype=np.int64).reshape(len(rows), nx + nu)


@dataclass(frozen=True, eq=False)
class PnlssModel:
    """A polynomial nonlinear state-space model (PNLSS).

    It replays itself on records (:class:`~servoid.validate.Replayable`).

    On the normalised signals ũ = (u − u_mean)/u_scale and
    ỹ = (y − y_mean)/y_scale::

        x(t+1) = A x(t) + B ũ(t) + E m(x(t), ũ(t))
        ỹ(t)   = C x(t) + D ũ(t) + F m(x(t), ũ(t))

    where m holds the monomials whose exponents are the rows of
    ``powers`` (see :func:`exponents`).

    Attributes
    ----------
    A, B, C, D : ndarray
        The linear part, shapes (nx, nx), (nx, nu), (nx,), (nu,).
    E, F : ndarray
        The nonlinear coefficients, shapes (nx, n_monomials), (n_monomials,).
    powers : ndarray of int, shape (n_monomials, nx + nu)
        Each monomial's power of each state, then of each input.
    dt : float
        Sample period [s].
    u_mean, u_scale : ndarray, shape (nu,)
        Input normalisation (scale > 0).
    y_mean, y_scale : float
        Output normalisation (scale > 0).
    monomials : str
        How the monomial set was built (``"full"``, ``"state"``,
        ``"input"``; ``"custom"`` for any other ``powers``).
    covariance : ndarray, optional
        Covariance of the parameters (A, B, C, D, E, F flattened in that
        order, row-major), in the normalised coordinates.
    noise_variance : float
        Variance of the simulation error of the fit [output unit²].
    input_names, output_name, input_units, output_unit
        Names and units of the channels.
    """

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    E: NDArray[np.float64]
    F: NDArray[np.float64]
    powers: NDArray[np.int64]
    dt: float
    u_mean: NDArray[np.float64] = field(default_factory=lambda: np.zeros(1))
    u_scale: NDArray[np.float64] = field(default_factory=lambda: np.ones(1))
    y_mean: float = 0.0
    y_scale: float = 1.0
    monomials: str = "full"
    covariance: NDArray[np.float64] | None = None
    noise_variance: float = 0.0
    input_names: tuple[str, ...] = ("u",)
    output_name: str = "y"
    input_units: tuple[str, ...] = ()
    output_unit: str = ""

    has_noise_model: ClassVar[bool] = False

    def __post_init__(self) -> None:
        A = _matrix("A", self.A, 2)
        nx = A.shape[0]
        if A.shape != (nx, nx) or nx < 1:
            raise DataError(f"A must be square with at least one state, got shape {A.shape}")
        B = _matrix("B", self.B, 2)
        nu = B.shape[1]
        if B.shape[0] != nx or nu < 1:
            raise DataError(f"B must have shape ({nx}, n_inputs), got {B.shape}")
        powers = np.array(as_array("powers", self.powers, ndim=2, min_size=0),
                          dtype=float).reshape(-1, nx + nu) if np.size(self.powers) else \
            np.zeros((0, nx + nu))
        if np.any(powers < 0) or np.any(powers != np.round(powers)):
            raise DataError("powers must hold non-negative integers")
        powers_i = powers.astype(np.int64)
        nm = powers_i.shape[0]
        shapes = {"C": (nx,), "D": (nu,), "E": (nx, nm), "F": (nm,), "u_mean": (nu,),
                  "u_scale": (nu,)}
        values = {"A": A, "B": B}
        for name, shape in shapes.items():
            arr = np.array(as_array(name, getattr(self, name), min_size=0),
                           dtype=float).reshape(-1)
            if arr.size != int(np.prod(shape)):
                raise DataError(f"{name} must have shape {shape} for {nx} states, {nu} "
                                f"inputs and {nm} monomials, got {arr.size} values")
            values[name] = arr.reshape(shape)
        if np.any(values["u_scale"] <= 0):
            raise DataError("u_scale must be positive")
        for name, arr in values.items():
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        powers_i.setflags(write=False)
        object.__setattr__(self, "powers", powers_i)
        object.__setattr__(self, "dt", as_float("dt", self.dt, positive=True, unit="s"))
        object.__setattr__(self, "y_mean", as_float("y_mean", self.y_mean))
        object.__setattr__(self, "y_scale", as_float("y_scale", self.y_scale, positive=True))
        object.__setattr__(self, "monomials", as_str("monomials", self.monomials))
        object.__setattr__(self, "noise_variance",
                           as_float("noise_variance", self.noise_variance, nonneg=True))
        n = self.n_parameters
        if self.covariance is not None:
            cov = np.array(as_array("covariance", self.covariance, ndim=2), dtype=float)
            if cov.shape != (n, n):
                raise DataError(f"covariance must have shape ({n}, {n}), got {cov.shape}")
            cov.setflags(write=False)
            object.__setattr__(self, "covariance", cov)
        names = _str_tuple("input_names", self.input_names)
        if len(names) != nu:
            raise DataError(f"input_names needs one name per input ({nu}), got {len(names)}")
        object.__setattr__(self, "input_names", names)
        units = _str_tuple("input_units", self.input_units)
        if units and len(units) != nu:
            raise DataError(f"input_units needs one unit per input ({nu}), got {len(units)}")
        object.__setattr__(self, "input_units", units)
        object.__setattr__(self, "output_name", as_str("output_name", self.output_name))
        object.__setattr__(self, "output_unit",
                           as_str("output_unit", self.output_unit, empty=True))

    # -- structure ------------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.A.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return int(self.B.shape[1])

    @property
    def n_monomials(self) -> int:
        """Number of monomials in ζ = η."""
        return int(self.powers.shape[0])

    @property
    def degree(self) -> int:
        """Highest total degree of a monomial (1 without monomials)."""
        return int(self.powers.sum(axis=1).max()) if self.n_monomials else 1

    @property
    def n_parameters(self) -> int:
        """Number of coefficients in A, B, C, D, E, F."""
        nx, nu, nm = self.n_states, self.n_inputs, self.n_monomials
        return nx * nx + nx * nu + nx + nu + nx * nm + nm

    @property
    def parameters(self) -> NDArray[np.float64]:
        """A, B, C, D, E, F flattened (row-major) in that order."""
        return np.concatenate([self.A.ravel(), self.B.ravel(), self.C, self.D,
                               self.E.ravel(), self.F])

    @property
    def names(self) -> tuple[str, ...]:
        """A name per parameter: ``A[1,2]``, …, ``E[1,x1*u]``, ``F[x1^3]`` (1-based)."""
        nx, nu = self.n_states, self.n_inputs
        labels = self.monomial_names
        out = [f"A[{i + 1},{k + 1}]" for i in range(nx) for k in range(nx)]
        out += [f"B[{i + 1},{k + 1}]" for i in range(nx) for k in range(nu)]
        out += [f"C[{i + 1}]" for i in range(nx)] + [f"D[{k + 1}]" for k in range(nu)]
        out += [f"E[{i + 1},{m}]" for i in range(nx) for m in labels]
        out += [f"F[{m}]" for m in labels]
        return tuple(out)

    @property
    def monomial_names(self) -> tuple[str, ...]:
        """Each monomial in words, e.g. ``x1^2*u``."""
        nx = self.n_states
        symbols = [f"x{i + 1}" for i in range(nx)] + (
            ["u"] if self.n_inputs == 1 else [f"u{k + 1}" for k in range(self.n_inputs)])
        out = []
        for row in self.powers:
            parts = [s + (f"^{p}" if p > 1 else "") for s, p in zip(symbols, row, strict=True)
                     if p > 0]
            out.append("*".join(parts) or "1")
        return tuple(out)

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviation of each parameter (NaN without covariance)."""
        if self.covariance is None:
            return np.full(self.n_parameters, np.nan)
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def with_parameters(self, theta: ArrayLike) -> PnlssModel:
        """The same structure with other A, B, C, D, E, F (see :attr:`parameters`)."""
        from dataclasses import replace

        th = np.asarray(theta, dtype=float)
        if th.shape != (self.n_parameters,):
            raise DataError(f"theta must hold {self.n_parameters} values, got {th.shape}")
        parts = _split(th, self.n_states, self.n_inputs, self.n_monomials)
        return replace(self, covariance=None, **parts)

    def poles(self) -> NDArray[np.complex128]:
        """Poles of the linear part: the eigenvalues of A."""
        return np.linalg.eigvals(self.A)

    def linear_part(self) -> Any:
        """The linear part (E = F = 0) as a StateSpace in the data's units.

        Returns
        -------
        StateSpace
            ``x(t+1) = A x + B (u/s_u)``, ``y = s_y (C x + D u/s_u)``: the
            model's response to small deviations around the normalised
            origin (the offsets ū, ȳ are left out).
        """
        from ..models import StateSpace

        B = self.B / self.u_scale[None, :]
        C = self.y_scale * self.C[None, :]
        D = (self.y_scale * self.D / self.u_scale)[None, :]
        return StateSpace(self.A, B, C, D, dt=self.dt)

    # -- running --------------------------------------------------------------------------
    def simulate(self, u: ArrayLike, x0: ArrayLike | None = None, *,
                 linear: bool = False) -> NDArray[np.float64]:
        """Free-run simulation from the input alone.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_inputs)
            Input [input unit].
        x0 : array_like, shape (n_states,), optional
            Initial (normalised) state, default zero.
        linear : bool
            Run the linear part alone (E = F = 0): with the full run, the
            nonlinear terms' contribution over the record.

        Returns
        -------
        ndarray, shape (N,)
            The simulated output [output unit]; NaN from the sample where
            the run diverges, with a :class:`~servoid.ServoidWarning`.
        """
        un = self._normalised(self._inputs(as_array("u", u, min_size=1)))
        x = np.zeros(self.n_states) if x0 is None else as_array("x0", x0, ndim=1)
        if x.size != self.n_states:
            raise DataError(f"x0 must hold {self.n_states} states, got {x.size}")
        y, where = self._run(un, x, linear)
        if where >= 0:
            self._diverged(where)
        return self.y_mean + self.y_scale * y

    def replay(self, y: ArrayLike, u: ArrayLike, *,
               initial: Initial = "auto") -> tuple[NDArray[np.float64], int, str]:
        """Free run on a record, from an estimated (or zero) initial state.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output (used only to estimate the initial state).
        u : array_like, shape (N,) or (N, n_inputs)
            Input.
        initial : {"auto", "estimate", "zero", "measured"}
            ``"auto"`` and ``"estimate"`` fit the initial state to the
            record (Gauss–Newton with the exact sensitivity);
            ``"zero"`` starts from x = 0 (rest at the mean input);
            ``"measured"`` (ARX only) is refused.

        Returns
        -------
        y_sim : ndarray, shape (N,)
        first : int
            0: every sample is scored.
        initial : str
            The rule applied.
        """
        check_option("initial", initial, INITIALS)
        if initial == "measured":
            raise ModelError('initial="measured" sets the state from past samples, which only '
                             'an ARX model allows; use initial="estimate" for a PNLSS model')
        yy, uu = check_signals(y, u)
        un = self._normalised(self._inputs(uu, yy.size))
        if initial == "zero":
            x0 = np.zeros(self.n_states)
            rule = "zero"
        else:
            x0 = self.initial_state(yy, uu)
            rule = "estimate"
        ys, where = self._run(un, x0, False)
        if where >= 0:
            self._diverged(where)
        return self.y_mean + self.y_scale * ys, 0, rule

    def initial_state(self, y: ArrayLike, u: ArrayLike, *, iterations: int = 20,
                      samples: int | None = None) -> NDArray[np.float64]:
        """The (normalised) initial state that best explains a record's start.

        Gauss–Newton on x(0) alone with the model fixed, on the first
        ``samples`` samples (default: all, at most 20 000), the step halved
        while it does not lower the squared simulation error.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output.
        u : array_like, shape (N,) or (N, n_inputs)
            Input.
        iterations : int
            Most Gauss–Newton steps.
        samples : int, optional
            How many samples from the start the fit uses.

        Returns
        -------
        ndarray, shape (n_states,)
        """
        yy, uu = check_signals(y, u)
        iterations = as_int("iterations", iterations, minimum=1)
        n = min(yy.size, 20000) if samples is None else as_int("samples", samples, minimum=2)
        n = min(n, yy.size)
        un = self._normalised(self._inputs(uu, yy.size))[:n]
        yn = (yy[:n] - self.y_mean) / self.y_scale
        first = self.n_parameters
        x0 = np.zeros(self.n_states)
        J = np.empty((n, self.n_states))
        ysim = np.empty(n)
        args = self._kernel_args()
        where = jacobian(*args, un, x0, first, ysim, J)
        if where >= 0:
            return x0
        cost = float(np.sum((ysim - yn) ** 2))
        for _ in range(iterations):
            step = np.linalg.lstsq(J, yn - ysim, rcond=None)[0]
            scale = 1.0
            improved = False
            while scale > 1e-4:
                trial = x0 + scale * step
                yt = np.empty(n)
                Jt = np.empty_like(J)
                if jacobian(*args, un, trial, first, yt, Jt) < 0:
                    c = float(np.sum((yt - yn) ** 2))
                    if c < cost:
                        improved = cost - c > 1e-12 * cost
                        x0, cost, ysim, J = trial, c, yt, Jt
                        break
                scale *= 0.5
            if not improved:
                break
        return x0

    def contribution(self, u: ArrayLike, x0: ArrayLike | None = None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The model's run and the same run with E = F = 0, on an input.

        Returns
        -------
        full, linear : ndarray, shape (N,)
            Both free runs [output unit]; ``full − linear`` is what the
            nonlinear terms add over the record.
        """
        un = self._normalised(self._inputs(as_array("u", u, min_size=1)))
        x = np.zeros(self.n_states) if x0 is None else as_array("x0", x0, ndim=1)
        full, _ = self._run(un, x, False)
        lin, _ = self._run(un, x, True)
        return self.y_mean + self.y_scale * full, self.y_mean + self.y_scale * lin

    # -- files and display ----------------------------------------------------------------
    def to_record(self) -> dict[str, Any]:
        """The model as the plain data of a model file (floats as Python floats: bit-exact)."""
        return {
            "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
            "D": self.D.tolist(), "E": self.E.tolist(), "F": self.F.tolist(),
            "powers": self.powers.tolist(), "monomial_names": list(self.monomial_names),
            "monomials": self.monomials,
            "u_mean": self.u_mean.tolist(), "u_scale": self.u_scale.tolist(),
            "y_mean": self.y_mean, "y_scale": self.y_scale,
            "noise_variance": self.noise_variance,
            "input_names": list(self.input_names), "output_name": self.output_name,
            "input_units": list(self.input_units), "output_unit": self.output_unit,
            "covariance": None if self.covariance is None else self.covariance.tolist(),
        }

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> PnlssModel:
        """Rebuild the model from a model file's data (:meth:`to_record` and ``dt``).

        Raises
        ------
        KeyError
            A required key is missing (the model file reader names it).
        DataError
            Values that make no model.
        """
        nx = len(data["A"]) if isinstance(data["A"], list) else 0
        powers = data["powers"]
        if isinstance(powers, list) and not powers:
            nu = len(data["u_mean"]) if isinstance(data.get("u_mean"), list) else 1
            powers = np.zeros((0, nx + nu), dtype=np.int64)
        E = data["E"]
        if isinstance(E, list) and E and all(isinstance(r, list) and not r for r in E):
            E = np.zeros((len(E), 0))
        return cls(data["A"], data["B"], data["C"], data["D"], E, data["F"], powers,
                   data["dt"], u_mean=data["u_mean"], u_scale=data["u_scale"],
                   y_mean=data["y_mean"], y_scale=data["y_scale"],
                   monomials=data.get("monomials", "custom"),
                   covariance=data.get("covariance"),
                   noise_variance=data.get("noise_variance", 0.0),
                   input_names=tuple(data.get("input_names") or ("u",)),
                   output_name=data.get("output_name", "y"),
                   input_units=tuple(data.get("input_units") or ()),
                   output_unit=data.get("output_unit", ""))

    def to_dict(self) -> dict[str, Any]:
        """Structure, coefficients and their std as plain data (``results.json``)."""
        return {"type": "polynomial_state_space", "dt": self.dt, "n_states": self.n_states,
                "degree": self.degree, "monomials": self.monomials,
                "names": list(self.names), "parameters": self.parameters.tolist(),
                "std": [None if np.isnan(s) else float(s) for s in self.std],
                "poles": [{"re": float(p.real), "im": float(p.imag)}
                          for p in np.linalg.eigvals(self.A)],
                "model_file": {"servoid_model": 1, "type": "PnlssModel", "dt": self.dt,
                               **self.to_record()}}

    def __str__(self) -> str:
        labels = self.monomial_names
        lines = [(f"PNLSS model: {self.n_states} states, {self.n_inputs} input(s), "
                  f"{self.n_monomials} monomials ({self.monomials}, degree ≤ {self.degree}), "
                  f"dt = {self.dt:g} s")]
        for i in range(self.n_states):
            terms = " ".join(f"{c:+.4g}·{m}" for c, m in zip(self.E[i], labels, strict=True)
                             if c != 0.0)
            lines.append(f"  x{i + 1}(t+1) = linear part {terms}".rstrip())
        terms = " ".join(f"{c:+.4g}·{m}" for c, m in zip(self.F, labels, strict=True) if c)
        lines.append(f"  ỹ(t) = linear part {terms}".rstrip())
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<PnlssModel: {self.n_states} states, degree {self.degree} "
                f"({self.monomials}, {self.n_monomials} monomials), dt = {self.dt:g} s>")

    def _repr_html_(self) -> str:
        poles = np.linalg.eigvals(self.A)
        rows = [(m, *(number(e, 4) for e in self.E[:, j]), number(self.F[j], 4))
                for j, m in enumerate(self.monomial_names)]
        cols = ("monomial", *(f"E[x{i + 1}]" for i in range(self.n_states)), "F")
        return html_block(
            "PNLSS model", [("dt", f"{self.dt:g} s"), ("states", str(self.n_states)),
                            ("degree", str(self.degree)), ("monomials", self.monomials),
                            ("linear poles", ", ".join(f"{p:.4g}" for p in poles[:8]))],
            cols if rows else (), rows, note="coefficients on the normalised signals")

    # -- private --------------------------------------------------------------------------
    def _kernel_args(self, linear: bool = False) -> tuple[Any, ...]:
        E = np.zeros_like(self.E) if linear else self.E
        F = np.zeros_like(self.F) if linear else self.F
        return (np.ascontiguousarray(self.A), np.ascontiguousarray(self.B), self.C, self.D,
                np.ascontiguousarray(E), F, np.ascontiguousarray(self.powers))

    def _run(self, un: NDArray[np.float64], x0: NDArray[np.float64], linear: bool
             ) -> tuple[NDArray[np.float64], int]:
        y = np.empty(un.shape[0])
        x = np.empty((un.shape[0] + 1, self.n_states))
        where = simulate(*self._kernel_args(linear), un, np.asarray(x0, dtype=float), y, x)
        return y, int(where)

    def _normalised(self, u2: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.ascontiguousarray((u2 - self.u_mean) / self.u_scale)

    def _inputs(self, u: NDArray[np.float64], n: int | None = None) -> NDArray[np.float64]:
        u2 = u.reshape(-1, 1) if u.ndim == 1 else u
        if u2.ndim != 2 or u2.shape[1] != self.n_inputs or (n is not None and u2.shape[0] != n):
            raise DataError(f"u must have shape (N,{' 1' if self.n_inputs == 1 else ''} "
                            f"{self.n_inputs}) for this model's {self.n_inputs} input(s)"
                            f"{'' if n is None else f' and N = {n}'}, got {u.shape}"
                            .replace("(N, 1 1)", "(N,) or (N, 1)"))
        if not np.all(np.isfinite(u2)):
            raise DataError("u has non-finite values; remove or interpolate them first")
        return np.asarray(u2, dtype=float)

    def _diverged(self, where: int) -> None:
        warn(f"the free run of the PNLSS model diverges at sample {where} (t = "
             f"{where * self.dt:.6g} s): its state leaves ±1e12, and the output from there on is "
             "NaN. The input leaves the range the model was fitted on, or the model is unstable "
             "there; fit on a record that covers this amplitude, or lower the degree",
             ServoidWarning)


def _split(theta: NDArray[np.float64], nx: int, nu: int, nm: int) -> dict[str, Any]:
    """θ → A, B, C, D, E, F (see :attr:`PnlssModel.parameters`)."""
    sizes = (nx * nx, nx * nu, nx, nu, nx * nm, nm)
    parts = np.split(theta, np.cumsum(sizes)[:-1])
    return {"A": parts[0].reshape(nx, nx), "B": parts[1].reshape(nx, nu), "C": parts[2],
            "D": parts[3], "E": parts[4].reshape(nx, nm), "F": parts[5]}


def _matrix(name: str, value: object, ndim: int) -> NDArray[np.float64]:
    arr = np.array(as_array(name, value, min_size=0), dtype=float)
    if arr.ndim != ndim:
        raise DataError(f"{name} must be a {ndim}-D array, got {arr.ndim}-D")
    return arr


def _str_tuple(name: str, value: object) -> tuple[str, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not all(
            isinstance(v, str) for v in value):
        raise type_error(name, value, "a sequence of strings")
    return tuple(value)
