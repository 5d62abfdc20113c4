"""The fitted block-oriented model: Hammerstein, Wiener, Hammerstein–Wiener.

``u → f (static) → v → G (linear) → x → g (static) → y (+ offset)``;
a Hammerstein model has no g, a Wiener model no f.  The model replays
itself on a new record (:class:`servoid.validate.Replayable`):

- Hammerstein: the output is linear in the linear block's initial state,
  which :func:`servoid.validate.simulate_model` fits by least squares on
  the static block's output, as for any linear model.
- Wiener and Hammerstein–Wiener: the state passes through g, so it is
  fitted by a short nonlinear least-squares search (the model held fixed,
  from rest as the start).

No noise model: every predictor is the simulation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, type_error
from .._errors import DataError, ModelError, check_option
from .._lazy import optimize
from .._lazy import signal as sps
from ._block_linear import free_response, free_responses
from ._static import StaticNonlinearity

__all__ = ["STRUCTURES", "BlockModel", "Structure"]

Structure = Literal["hammerstein", "wiener", "hammerstein-wiener"]
STRUCTURES: tuple[Structure, ...] = ("hammerstein", "wiener", "hammerstein-wiener")


@dataclass(frozen=True, eq=False)
class BlockModel:
    """A block-oriented model: static f, linear G, static g.

    ``y = g(G(q)·f(u)) + offset``; f is absent (identity) in a Wiener
    model, g in a Hammerstein model.

    Parameters
    ----------
    structure : {"hammerstein", "wiener", "hammerstein-wiener"}
        Which static blocks there are.
    linear : PolynomialModel or TransferFunction
        The linear block: discrete at ``dt`` (single input, B/F), or a
        continuous transfer function (zero-order hold at ``dt``).
    dt : float
        Sample period [s] of the records the model runs on.
    input_nonlinearity : StaticNonlinearity, optional
        f (Hammerstein, Hammerstein–Wiener).
    output_nonlinearity : StaticNonlinearity, optional
        g (Wiener, Hammerstein–Wiener).
    offset : float
        Constant added to the output [output unit].

    Examples
    --------
    >>> from servoid.models import PolynomialModel
    >>> from servoid.nonlinear import DeadZone
    >>> g = PolynomialModel([1.0], ([1.0],), (1,), 0.1, f=([1.0, -0.5],))
    >>> m = BlockModel("hammerstein", g, 0.1, input_nonlinearity=DeadZone(-1.0, 1.0))
    >>> m.simulate([2.0, 2.0, 0.0]).tolist()
    [0.0, 1.0, 1.5]
    """

    structure: Structure
    linear: Any
    dt: float
    input_nonlinearity: StaticNonlinearity | None = None
    output_nonlinearity: StaticNonlinearity | None = None
    offset: float = 0.0
    has_noise_model: ClassVar[bool] = False

    def __post_init__(self) -> None:
        from ..models import PolynomialModel, TransferFunction

        check_option("structure", self.structure, STRUCTURES)
        object.__setattr__(self, "dt", as_float("dt", self.dt, positive=True, unit="s"))
        object.__setattr__(self, "offset", as_float("offset", self.offset))
        lin = self.linear
        if isinstance(lin, PolynomialModel):
            if lin.n_inputs != 1 or lin.a.size > 1 or lin.c.size > 1 or lin.d.size > 1:
                raise ModelError("the linear block must be a single-input output-error model "
                                 "B/F (no A, C or D)")
            if not np.isclose(lin.dt, self.dt, rtol=1e-9, atol=0.0):
                raise DataError(f"the linear block has dt = {lin.dt} s, the model {self.dt} s")
        elif isinstance(lin, TransferFunction):
            if lin.dt is not None and not np.isclose(lin.dt, self.dt, rtol=1e-9, atol=0.0):
                raise DataError(f"the linear block has dt = {lin.dt} s, the model {self.dt} s")
        else:
            raise type_error("linear", lin, "a PolynomialModel (B/F) or a TransferFunction")
        wants = {"hammerstein": (True, False), "wiener": (False, True),
                 "hammerstein-wiener": (True, True)}[self.structure]
        for name, value, needed in (("input_nonlinearity", self.input_nonlinearity, wants[0]),
                                    ("output_nonlinearity", self.output_nonlinearity, wants[1])):
            if needed and not isinstance(value, StaticNonlinearity):
                raise type_error(name, value, f"a static nonlinearity for a {self.structure} "
                                 "model")
            if not needed and value is not None:
                raise ModelError(f"a {self.structure} model has no {name}; pass None")

    # -- simulation ------------------------------------------------------------------------
    def polynomials(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The linear block's numerator and denominator in q⁻¹ at ``dt``."""
        from ..models import PolynomialModel, c2d

        lin = self.linear
        if isinstance(lin, PolynomialModel):
            return np.concatenate([np.zeros(lin.nk[0]), lin.b[0]]), np.asarray(lin.f[0])
        if lin.dt is None:
            lin = c2d(lin, self.dt, "zoh")
        num, den = np.asarray(lin.num, dtype=float), np.asarray(lin.den, dtype=float)
        return np.concatenate([np.zeros(den.size - num.size), num]), den

    def signals(self, u: ArrayLike, state: ArrayLike | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The inner signals v = f(u), x = G v and the output y.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, 1)
            Input.
        state : array_like, optional
            Initial state of the linear block (its denominator's order
            values; the coefficients of its free responses); default rest.

        Returns
        -------
        v, x, y : ndarray, shape (N,)
            Static block output, linear block output, model output.
        """
        uu = _input(u)
        num, den = self.polynomials()
        c = np.zeros(den.size - 1) if state is None else as_array(
            "state", state, ndim=1)
        if c.size != den.size - 1:
            raise DataError(f"state must hold {den.size - 1} values (the linear block's order), "
                            f"got {c.size}")
        return _run(self, num, den, uu, c)

    def simulate(self, u: ArrayLike, state: ArrayLike | None = None) -> NDArray[np.float64]:
        """Return the output for input ``u``, from rest by default.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, 1)
            Input.
        state : array_like, optional
            Initial state of the linear block (see :meth:`signals`).
        """
        return self.signals(u, state)[2]

    def predict(self, y: ArrayLike, u: ArrayLike, horizon: int | None = 1) -> NDArray[np.float64]:
        """Return the k-step prediction: the simulation (no noise model).

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output (unused: an output-error model ignores it).
        u : array_like, shape (N,) or (N, 1)
            Input.
        horizon : int or None
            Ignored for the same reason.
        """
        as_array("y", y, ndim=1)
        return self.simulate(u)

    def replay(self, y: ArrayLike, u: ArrayLike, *,
               initial: Literal["auto", "estimate", "zero", "measured"] = "auto"
               ) -> tuple[NDArray[np.float64], int, str]:
        """Free-run simulation on a record, initial state fitted.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output (used only for the initial state).
        u : array_like, shape (N,) or (N, 1)
            Input.
        initial : {"auto", "estimate", "zero", "measured"}
            ``"auto"`` and ``"estimate"`` fit the linear block's initial
            state (linear least squares for Hammerstein, a short nonlinear
            search otherwise); ``"zero"`` starts from rest; ``"measured"``
            (ARX only) is refused.

        Returns
        -------
        y_sim : ndarray, shape (N,)
            Simulated output.
        first : int
            First sample the metrics use (0).
        initial : str
            The rule applied (``"estimate"`` or ``"zero"``).
        """
        check_option("initial", initial, ("auto", "estimate", "zero", "measured"))
        yy = as_array("y", y, ndim=1, min_size=2)
        uu = _input(u)
        if uu.size != yy.size:
            raise DataError(f"u has {uu.size} samples but y has {yy.size}; pass the same record")
        if initial == "measured":
            raise ModelError('initial="measured" sets the state from past samples, which only an '
                             'ARX model allows; use initial="estimate" for a block model')
        num, den = self.polynomials()
        order = den.size - 1
        if initial == "zero" or order == 0:
            return _run(self, num, den, uu, np.zeros(order))[2], 0, "zero" if initial == "zero" \
                else "estimate"
        if self.output_nonlinearity is None:
            # linear in the state: the linear block on v = f(u), its initial state fitted by
            # least squares exactly as validate does for a linear model
            from ..models import c2d
            from ..validate import simulate_model

            f = self.input_nonlinearity
            assert f is not None
            lin = self.linear if self.linear.dt is not None else c2d(self.linear, self.dt, "zoh")
            x, _, _ = simulate_model(lin, yy - self.offset, f._f(uu, f.parameters),
                                     initial="estimate")
            return x + self.offset, 0, "estimate"
        c = fit_state(self, num, den, uu, yy)
        return _run(self, num, den, uu, c)[2], 0, "estimate"

    # -- model file ------------------------------------------------------------------------
    def to_record(self) -> dict[str, Any]:
        """The model as the plain data of a model file.

        Everything but the file's header (format version, type, ``dt``):
        the structure, the offset, each static block
        (:meth:`StaticNonlinearity.to_record`) and the linear block as a
        nested model record.  Floats are written with ``repr``, so the
        model reads back bit for bit.

        Raises
        ------
        ModelError
            When a static block is a user :class:`StaticFunction`: a model
            file holds numbers, not code (the message says what to do).
        """
        from ..models import model_record

        return {
            "structure": self.structure, "offset": self.offset,
            "input_nonlinearity": _shape_record(self.input_nonlinearity),
            "output_nonlinearity": _shape_record(self.output_nonlinearity),
            "linear": model_record(self.linear),
        }

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> BlockModel:
        """Rebuild the model from a model file's data (:meth:`to_record`).

        Parameters
        ----------
        data : mapping
            The file's content: ``dt`` and the keys :meth:`to_record` writes.

        Raises
        ------
        KeyError
            A required key is missing (the model file reader names it).
        DataError, ModelError, FileFormatError
            Values that make no model.
        """
        from ..models import model_from_record

        shapes = []
        for key in ("input_nonlinearity", "output_nonlinearity"):
            value = data.get(key)
            shapes.append(None if value is None else StaticNonlinearity.from_record(value))
        linear = model_from_record(data["linear"], where="the linear block")
        return cls(data["structure"], linear, data["dt"], input_nonlinearity=shapes[0],
                   output_nonlinearity=shapes[1], offset=data.get("offset", 0.0))


def fit_state(model: BlockModel, num: NDArray[np.float64], den: NDArray[np.float64],
              u: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """The initial state that fits ``y`` best through g (the model held fixed)."""
    order = den.size - 1
    # the free responses die out: only the start of the record sees the state
    n = min(y.size, max(200, 50 * order))
    forced = _run(model, num, den, u[:n], np.zeros(order))
    g = model.output_nonlinearity
    assert g is not None

    def residual(c: NDArray[np.float64]) -> NDArray[np.float64]:
        x = forced[1] + free_response(den, c, n)
        return y[:n] - g._f(x, g.parameters) - model.offset

    # a Gauss–Newton step from rest ignoring g, and its mirror: an even g (|x|) has a twin
    # minimum for every sign pattern of the start, so a few starts are cheap insurance
    free = free_responses(den, n)
    step, *_ = np.linalg.lstsq(free, y[:n] - forced[2], rcond=None)
    best, best_cost = np.zeros(order), np.inf
    for start in (np.zeros(order), step, -step):
        result = optimize.least_squares(residual, start, method="lm", max_nfev=100 * (order + 1))
        cost = float(np.sum(result.fun ** 2))
        if cost < best_cost:
            best, best_cost = np.asarray(result.x, dtype=float), cost
    return best


def _run(model: BlockModel, num: NDArray[np.float64], den: NDArray[np.float64],
         u: NDArray[np.float64], c: NDArray[np.float64]
         ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    f, g = model.input_nonlinearity, model.output_nonlinearity
    v = u if f is None else f._f(u, f.parameters)
    x = sps.lfilter(num, den, v)
    if c.size:
        x = x + free_response(den, c, u.size)
    y = x if g is None else g._f(x, g.parameters)
    return v, x, y + model.offset


def _shape_record(shape: StaticNonlinearity | None) -> dict[str, Any] | None:
    return None if shape is None else shape.to_record()


def _input(u: ArrayLike) -> NDArray[np.float64]:
    arr = as_array("u", u)
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.ndim != 1:
        raise DataError(f"a block model has one input: u must have shape (N,) or (N, 1), got "
                        f"{arr.shape}")
    return arr
