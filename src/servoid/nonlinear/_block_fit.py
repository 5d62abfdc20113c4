"""Fitting block-oriented models by output (simulation) error.

The model ``y = g(G(q)·f(u)) + offset + e`` is fitted by minimising
``Σ (y − ŷ)²`` over every parameter at once (static curves, linear
block, offset and the linear block's initial state per record) with
:func:`scipy.optimize.least_squares` (trust-region reflective, box
bounds from the shapes), from the data-driven start of
:mod:`servoid.nonlinear._block_start`.

The covariance is ``σ̂² (JᵀJ)⁻¹`` with ``σ̂² = Σe²/(N − d)`` and J the
Jacobian of the simulated output by central differences at the minimum
(Ljung, *System Identification*, 2nd ed., §9.3); the initial states are
nuisance parameters, projected out of J (a Schur complement), so the
reported covariance accounts for them.  It is right for white output
noise; with coloured noise it is optimistic.

Scale convention
----------------
``k·G`` with ``f/k`` (or g(k·)) gives the same model, so one scale is
fixed.  The library shapes dead zone, saturation, absolute value and
signed power have unit slope (no gain of their own): the linear block
keeps its gain.  A shape with a free scale (polynomial, piecewise
linear, a user function by default) fixes the linear block's static gain
to 1 instead: G(1) = 1 for ``"oe"`` (the last b is computed), G(0) = 1
for ``"tf"`` (b0 = an).  Two free-scale shapes in one Hammerstein–Wiener
model leave a scale no data can fix and are refused.  A Wiener model
with an absolute value is also symmetric under G → −G (centre → −centre):
the fit returns the one with a positive static gain.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_float_list, as_int, as_str, type_error
from .._errors import (
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    ServoidWarning,
    check_option,
)
from .._lazy import optimize
from .._lazy import signal as sps
from .._warn import warn
from ..data import Experiment, ExperimentSet
from ..estimate import Estimate, output_name
from ._block import STRUCTURES, BlockModel, Structure
from ._block_linear import LinearBlock, free_response
from ._block_start import hammerstein_start, wiener_start
from ._block_units import parameter_units
from ._static import StaticNonlinearity, as_nonlinearity, from_data

__all__ = ["LINEARS", "fit_block", "fit_hammerstein", "fit_hammerstein_wiener", "fit_wiener"]

Linear = Literal["oe", "tf"]
LINEARS: tuple[Linear, ...] = ("oe", "tf")
Shape = StaticNonlinearity | str
#: Fewest samples that must reach each side of a breakpoint for it to be determined.
MIN_REGION_SAMPLES = 5
#: Cost reduction per parameter [σ̂²] below which a fit is chance (derived in _estimate).
_CHANCE_PER_PARAMETER = 10.0


def fit_block(
    data: Experiment | ExperimentSet,
    structure: Structure,
    *,
    input_nonlinearity: Shape | None = None,
    output_nonlinearity: Shape | None = None,
    linear: Linear = "oe",
    nb: int | None = None,
    nf: int | None = None,
    nk: int | None = None,
    n_poles: int | None = None,
    n_zeros: int | None = None,
    degree: int | None = None,
    breakpoints: Sequence[float] | None = None,
    offset: bool = False,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    initial: Literal["estimate", "zero"] = "estimate",
    max_iter: int = 200,
    tol: float = 1e-10,
) -> Estimate:
    """Fit a Hammerstein, Wiener or Hammerstein–Wiener model.

    ``y = g(G(q)·f(u)) + offset + e`` by output error (see the module
    notes for the method and the scale convention: unit-slope shapes
    leave the gain to the linear block, free-scale shapes fix the linear
    block's static gain to 1).

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with one input of role `input` and the output.
    structure : {"hammerstein", "wiener", "hammerstein-wiener"}
        Which static blocks there are.
    input_nonlinearity, output_nonlinearity : StaticNonlinearity or str
        f and g: a shape object (its parameters are the start) or a
        library name (``"deadzone"``, ``"saturation"``, ``"abs"``,
        ``"power"``, ``"piecewise-linear"``, ``"polynomial"``; started
        from the data).  Hammerstein takes f only, Wiener g only.
    linear : {"oe", "tf"}
        The linear block: discrete B/F with orders `nb`, `nf`, `nk`, or a
        continuous transfer function with `n_poles`, `n_zeros` (ZOH).
    nb, nf, nk : int, optional
        For ``linear = "oe"``: B coefficients (>= 1, default 2), F order
        (>= 0, default 2) and delay [samples] (>= 0, default 1).  A
        continuous block refuses them.
    n_poles, n_zeros : int, optional
        For ``linear = "tf"``: orders of the continuous transfer function
        (default 2 poles, n_zeros default n_poles − 1).  A discrete block
        refuses them.
    degree : int, optional
        Degree of a ``"polynomial"`` given by name (default 3); refused
        when no shape is a polynomial given by name.
    breakpoints : sequence of float, optional
        Breakpoints of a ``"piecewise-linear"`` given by name (default:
        quantiles of the block's input); refused when no shape is one.
    offset : bool
        Fit a constant output offset.
    input : {"u", "r"}
        Role of the input channel.
    output : str, optional
        Output channel when there are several.
    initial : {"estimate", "zero"}
        The linear block's initial state per record: fitted with the
        model, or rest.
    max_iter : int
        Most iterations (Jacobian evaluations) of the joint search.
    tol : float
        Relative tolerance on the cost and the step.

    Returns
    -------
    Estimate
        Method = `structure`; model a :class:`BlockModel`; parameters the
        static shapes' (``deadzone.lower``, …; prefixed ``input.`` /
        ``output.`` in a Hammerstein–Wiener model), the linear block's
        (``b0…``, ``f1…`` or ``b…``, ``a…``) and ``offset``.

    Raises
    ------
    IdentifiabilityError
        A breakpoint the block's input never crosses, a model that
        explains no more of the output than chance, parameters the
        data cannot separate, or a free-scale shape before or after an
        integrating linear block (G(1) = 1 cannot hold).
    OptionError
        A keyword the chosen linear block or shape does not use.
    """
    check_option("structure", structure, STRUCTURES)
    check_option("linear", linear, LINEARS)
    check_option("input", input, ("u", "r"))
    check_option("initial", initial, ("estimate", "zero"))
    if not isinstance(offset, bool):
        raise type_error("offset", offset, "true or false")
    shapes = _shapes(structure, input_nonlinearity, output_nonlinearity)
    _unused(linear, shapes, nb=nb, nf=nf, nk=nk, n_poles=n_poles, n_zeros=n_zeros,
            degree=degree, breakpoints=breakpoints)
    nb = as_int("nb", 2 if nb is None else nb, minimum=1, maximum=50)
    nf = as_int("nf", 2 if nf is None else nf, minimum=0, maximum=50)
    nk = as_int("nk", 1 if nk is None else nk, minimum=0, maximum=10000)
    n_poles = as_int("n_poles", 2 if n_poles is None else n_poles, minimum=1, maximum=20)
    n_zeros = n_poles - 1 if n_zeros is None else as_int("n_zeros", n_zeros, minimum=0,
                                                         maximum=n_poles)
    degree = as_int("degree", 3 if degree is None else degree, minimum=1, maximum=12)
    if breakpoints is not None:
        breakpoints = as_float_list("breakpoints", breakpoints, min_length=1)
        if any(b <= a for a, b in itertools.pairwise(breakpoints)):
            raise DataError(f"breakpoints must be strictly increasing, got {breakpoints}; "
                            "sort them")
    max_iter = as_int("max_iter", max_iter, minimum=1)
    tol = as_float("tol", tol, positive=True)
    pairs, names = _records(data, input, output)
    dt = _dt(data)
    f_spec, g_spec = shapes
    f_free = f_spec is not None and _free_scale(f_spec)
    g_free = g_spec is not None and _free_scale(g_spec)
    if f_free and g_free:
        raise IdentifiabilityError(
            "a Hammerstein–Wiener model with two free-scale shapes (polynomial, "
            "piecewise-linear, a user function) has a gain no data can fix between them; use a "
            "unit-slope shape (deadzone, saturation, abs, power) for one of them")
    lin = LinearBlock(linear, dt, nb, nf, nk, n_poles, n_zeros, unit_gain=f_free or g_free)
    n_total = sum(y.size for _, y in pairs)
    n_states = lin.order if initial == "estimate" else 0
    problem = _Problem(structure, lin, offset, pairs, n_states)
    f0, g0, theta_lin, d0 = _start(problem, f_spec, g_spec, degree, breakpoints)
    if lin.unit_gain:
        _check_not_integrating(lin, theta_lin, "start")
    problem.set_shapes(f0, g0)
    if problem.n_free + n_states * len(pairs) >= n_total - 1:
        raise DataError(f"{problem.n_free} parameters cannot be fitted to {n_total} samples; "
                        "record more data or lower the orders")
    p0 = problem.pack(f0.parameters if f0 else np.empty(0), theta_lin,
                      g0.parameters if g0 else np.empty(0), d0)
    p_hat, nfev, status = _search(problem, p0, max_iter, tol)
    p_hat = _normalise_sign(problem, p_hat)
    discrete = linear == "oe"
    return _estimate(problem, p_hat, nfev, status, names, {
        "structure": structure, "linear": linear, "nb": nb if discrete else None,
        "nf": nf if discrete else None, "nk": nk if discrete else None,
        "n_poles": None if discrete else n_poles, "n_zeros": None if discrete else n_zeros,
        "degree": degree, "offset": offset, "input": input, "initial": initial,
        "max_iter": max_iter, "tol": tol,
        "input_nonlinearity": f0.kind if f0 else None,
        "output_nonlinearity": g0.kind if g0 else None,
        "unit_gain": lin.unit_gain})


def fit_hammerstein(
    data: Experiment | ExperimentSet,
    nonlinearity: Shape,
    nb: int | None = None,
    nf: int | None = None,
    nk: int | None = None,
    *,
    linear: Linear = "oe",
    n_poles: int | None = None,
    n_zeros: int | None = None,
    degree: int | None = None,
    breakpoints: Sequence[float] | None = None,
    offset: bool = False,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    initial: Literal["estimate", "zero"] = "estimate",
    max_iter: int = 200,
    tol: float = 1e-10,
) -> Estimate:
    """Fit a Hammerstein model y = G(q)·f(u) + e.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s).
    nonlinearity : StaticNonlinearity or str
        f: a shape (its parameters are the start) or a library name.
    nb, nf, nk : int, optional
        Orders of a discrete linear block B/F and its delay [samples]
        (default 2, 2, 1).
    linear, n_poles, n_zeros, degree, breakpoints, offset, input, output, initial, max_iter, tol
        As for :func:`fit_block`.

    Returns
    -------
    Estimate
        See :func:`fit_block`.
    """
    return fit_block(data, "hammerstein", input_nonlinearity=nonlinearity, linear=linear,
                     nb=nb, nf=nf, nk=nk, n_poles=n_poles, n_zeros=n_zeros, degree=degree,
                     breakpoints=breakpoints, offset=offset, input=input, output=output,
                     initial=initial, max_iter=max_iter, tol=tol)


def fit_wiener(
    data: Experiment | ExperimentSet,
    nonlinearity: Shape,
    nb: int | None = None,
    nf: int | None = None,
    nk: int | None = None,
    *,
    linear: Linear = "oe",
    n_poles: int | None = None,
    n_zeros: int | None = None,
    degree: int | None = None,
    breakpoints: Sequence[float] | None = None,
    offset: bool = False,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    initial: Literal["estimate", "zero"] = "estimate",
    max_iter: int = 200,
    tol: float = 1e-10,
) -> Estimate:
    """Fit a Wiener model y = g(G(q)·u) + e.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s).
    nonlinearity : StaticNonlinearity or str
        g: a shape (its parameters are the start) or a library name.
    nb, nf, nk : int, optional
        Orders of a discrete linear block B/F and its delay [samples]
        (default 2, 2, 1).
    linear, n_poles, n_zeros, degree, breakpoints, offset, input, output, initial, max_iter, tol
        As for :func:`fit_block`.

    Returns
    -------
    Estimate
        See :func:`fit_block`.
    """
    return fit_block(data, "wiener", output_nonlinearity=nonlinearity, linear=linear,
                     nb=nb, nf=nf, nk=nk, n_poles=n_poles, n_zeros=n_zeros, degree=degree,
                     breakpoints=breakpoints, offset=offset, input=input, output=output,
                     initial=initial, max_iter=max_iter, tol=tol)


def fit_hammerstein_wiener(
    data: Experiment | ExperimentSet,
    input_nonlinearity: Shape,
    output_nonlinearity: Shape,
    nb: int | None = None,
    nf: int | None = None,
    nk: int | None = None,
    *,
    linear: Linear = "oe",
    n_poles: int | None = None,
    n_zeros: int | None = None,
    degree: int | None = None,
    breakpoints: Sequence[float] | None = None,
    offset: bool = False,
    input: Literal["u", "r"] = "u",
    output: str | None = None,
    initial: Literal["estimate", "zero"] = "estimate",
    max_iter: int = 200,
    tol: float = 1e-10,
) -> Estimate:
    """Fit a Hammerstein–Wiener model y = g(G(q)·f(u)) + e.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s).
    input_nonlinearity, output_nonlinearity : StaticNonlinearity or str
        f and g: shapes or library names.
    nb, nf, nk : int, optional
        Orders of a discrete linear block B/F and its delay [samples]
        (default 2, 2, 1).
    linear, n_poles, n_zeros, degree, breakpoints, offset, input, output, initial, max_iter, tol
        As for :func:`fit_block`.

    Returns
    -------
    Estimate
        See :func:`fit_block`.
    """
    return fit_block(data, "hammerstein-wiener", input_nonlinearity=input_nonlinearity,
                     output_nonlinearity=output_nonlinearity, linear=linear, nb=nb, nf=nf,
                     nk=nk, n_poles=n_poles, n_zeros=n_zeros, degree=degree,
                     breakpoints=breakpoints, offset=offset, input=input, output=output,
                     initial=initial, max_iter=max_iter, tol=tol)


# -- the problem -------------------------------------------------------------------------------


class _Problem:
    """Parameter layout and residuals: [f θ, linear θ, g θ, offset, states per record]."""

    def __init__(self, structure: str, lin: LinearBlock, offset: bool,
                 pairs: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 n_states: int) -> None:
        self.structure, self.lin, self.offset, self.pairs = structure, lin, offset, pairs
        self.n_states = n_states
        self.f: StaticNonlinearity | None = None
        self.g: StaticNonlinearity | None = None
        self.scale = max(float(np.std(np.concatenate([y for _, y in pairs]))), 1e-300)

    def set_shapes(self, f: StaticNonlinearity | None, g: StaticNonlinearity | None) -> None:
        self.f, self.g = f, g
        self.nf_ = f.parameters.size if f else 0
        self.ng_ = g.parameters.size if g else 0
        self.n_free = self.nf_ + self.lin.size + self.ng_ + int(self.offset)

    @property
    def names(self) -> tuple[str, ...]:
        prefix_f = "input." if self.structure == "hammerstein-wiener" else ""
        prefix_g = "output." if self.structure == "hammerstein-wiener" else ""
        return (*(prefix_f + n for n in (self.f.names if self.f else ())), *self.lin.names,
                *(prefix_g + n for n in (self.g.names if self.g else ())),
                *(("offset",) if self.offset else ()))

    def pack(self, tf: NDArray[np.float64], tl: NDArray[np.float64], tg: NDArray[np.float64],
             d: float) -> NDArray[np.float64]:
        states = np.zeros(self.n_states * len(self.pairs))
        return np.concatenate([tf, tl, tg, [d] if self.offset else [], states])

    def unpack(self, p: NDArray[np.float64]) -> tuple[Any, ...]:
        i = 0
        tf = p[i: i + self.nf_]
        i += self.nf_
        tl = p[i: i + self.lin.size]
        i += self.lin.size
        tg = p[i: i + self.ng_]
        i += self.ng_
        d = float(p[i]) if self.offset else 0.0
        i += int(self.offset)
        states = p[i:].reshape(len(self.pairs), self.n_states)
        return tf, tl, tg, d, states

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        lo_f, hi_f = self.f.bounds if self.f else (np.empty(0), np.empty(0))
        lo_g, hi_g = self.g.bounds if self.g else (np.empty(0), np.empty(0))
        rest = self.lin.size
        tail = int(self.offset) + self.n_states * len(self.pairs)
        return (np.concatenate([lo_f, np.full(rest, -np.inf), lo_g, np.full(tail, -np.inf)]),
                np.concatenate([hi_f, np.full(rest, np.inf), hi_g, np.full(tail, np.inf)]))

    def outputs(self, p: NDArray[np.float64]) -> list[tuple[NDArray[np.float64], ...]]:
        """(v, x, ŷ) per record."""
        tf, tl, tg, d, states = self.unpack(p)
        num, den = self.lin.polynomials(tl)
        out = []
        for (u, _), c in zip(self.pairs, states, strict=True):
            v = u if self.f is None else self.f._f(u, tf)
            x = sps.lfilter(num, den, v)
            if c.size:
                x = x + free_response(den, c, u.size)
            y = x if self.g is None else self.g._f(x, tg)
            out.append((v, x, y + d))
        return out

    def residual(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            r = np.concatenate([y - sim[2] for (_, y), sim in
                                zip(self.pairs, self.outputs(p), strict=True)])
        # an unstable trial step: a large, finite residual the search will reject
        limit = 1e6 * self.scale
        return np.clip(np.where(np.isfinite(r), r, limit), -limit, limit)

    def jacobian(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """∂ŷ/∂p by central differences (J of the output, = −∂r/∂p)."""
        cols = []
        for k in range(p.size):
            h = 1e-6 * max(abs(p[k]), 1e-3)
            up, down = p.copy(), p.copy()
            up[k] += h
            down[k] -= h
            cols.append((self.residual(down) - self.residual(up)) / (2 * h))
        return np.column_stack(cols)

    def model(self, p: NDArray[np.float64]) -> BlockModel:
        tf, tl, tg, d, _ = self.unpack(p)
        return BlockModel(self.structure, self.lin.model(tl), self.lin.dt,  # type: ignore[arg-type]
                          self.f._with(tf) if self.f else None,
                          self.g._with(tg) if self.g else None, d)


# -- private ------------------------------------------------------------------------------


def _shapes(structure: str, f: object, g: object) -> tuple[Shape | None, Shape | None]:
    wants = {"hammerstein": (True, False), "wiener": (False, True),
             "hammerstein-wiener": (True, True)}[structure]
    out = []
    for name, value, needed in (("input_nonlinearity", f, wants[0]),
                                ("output_nonlinearity", g, wants[1])):
        if needed and value is None:
            raise OptionError(f"a {structure} model needs {name} (a shape or one of deadzone, "
                              "saturation, abs, power, piecewise-linear, polynomial)")
        if not needed and value is not None:
            raise OptionError(f"a {structure} model has no {name}; leave it out")
        out.append(None if value is None else as_nonlinearity(value, name))
    return out[0], out[1]


def _free_scale(shape: Shape) -> bool:
    if isinstance(shape, str):
        return shape in ("polynomial", "piecewise-linear")
    return bool(shape.free_scale)


def _unused(linear: str, shapes: tuple[Shape | None, Shape | None], **given: Any) -> None:
    """Refuse a keyword the chosen linear block or shapes would silently ignore."""
    other = {"oe": ("n_poles", "n_zeros"), "tf": ("nb", "nf", "nk")}[linear]
    for key in other:
        if given[key] is not None:
            takes = ("n_poles and n_zeros (a continuous block)" if linear == "tf" else
                     "nb, nf and nk (a discrete block)")
            raise OptionError(
                f"{key} = {given[key]!r} is not used by linear = \"{linear}\", which takes "
                f"{takes}; leave {key} out, or choose linear = "
                f"\"{'oe' if linear == 'tf' else 'tf'}\""
                + (" (a discrete block with its delay)" if key == "nk" else ""))
    named = [s for s in shapes if isinstance(s, str)]
    for key, kind in (("degree", "polynomial"), ("breakpoints", "piecewise-linear")):
        if given[key] is not None and kind not in named:
            raise OptionError(
                f"{key} is for a \"{kind}\" shape given by name, and no shape here is one "
                f"(shapes: {', '.join(_shape_name(s) for s in shapes if s is not None)}); "
                f"leave {key} out")


def _shape_name(shape: Shape) -> str:
    return f"\"{shape}\"" if isinstance(shape, str) else type(shape).__name__


def _records(data: object, role: str, output: str | None
             ) -> tuple[list[tuple[NDArray[np.float64], NDArray[np.float64]]], dict[str, Any]]:
    if isinstance(data, Experiment):
        records = [data]
    elif isinstance(data, ExperimentSet):
        records = list(data)
    else:
        raise type_error("data", data, "an Experiment or ExperimentSet")
    if output is not None:
        as_str("output", output)
    pairs = []
    names: dict[str, Any] = {}
    for exp in records:
        y_name = output_name(exp, output)
        u = exp.signal(role)  # type: ignore[arg-type]
        if u.shape[1] != 1:
            raise DataError(f"a block model has one input; the experiment has {u.shape[1]} "
                            f"channels of role {role!r} ({', '.join(exp.names_of(role))}); "
                            "keep one (Experiment.select)")
        y = exp[y_name]
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise DataError("the record has NaN or inf samples; remove or interpolate them")
        if np.ptp(u) == 0:
            raise IdentifiabilityError(f"input {exp.names_of(role)[0]!r} is constant: it excites "
                                       "nothing; excite the system with a PRBS, multisine or "
                                       "chirp")
        if y.size < 20:
            raise DataError(f"a block model needs at least 20 samples per record, got {y.size}")
        pairs.append((np.asarray(u[:, 0], dtype=float), np.asarray(y, dtype=float)))
        names = {"inputs": [exp.names_of(role)[0]], "output": y_name,
                 "output_unit": exp.unit(y_name), "input_unit": exp.unit(exp.names_of(role)[0])}
    return pairs, names


def _dt(data: Experiment | ExperimentSet) -> float:
    return float(data.dt)


def _start(problem: _Problem, f_spec: Shape | None, g_spec: Shape | None, degree: int,
           breakpoints: Sequence[float] | None) -> tuple[Any, Any, NDArray[np.float64], float]:
    lin, pairs = problem.lin, problem.pairs
    u_all = np.concatenate([u for u, _ in pairs])
    f0 = g0 = None
    if f_spec is not None:
        f0 = from_data(f_spec, u_all, degree=degree, breakpoints=breakpoints) \
            if isinstance(f_spec, str) else f_spec
    if problem.structure == "hammerstein":
        assert f0 is not None
        s = hammerstein_start(f0, isinstance(f_spec, str), pairs, lin, problem.offset)
        f0 = f0._with(s.theta)
        b, den, d = s.b, s.f, s.offset
        inputs = [(f0._f(u, f0.parameters), None) for u, _ in pairs]
    else:
        vs = [(u if f0 is None else f0._f(u, f0.parameters), y) for u, y in pairs]
        x_all = np.concatenate([v for v, _ in vs])  # a first guess of the block's input range
        assert g_spec is not None
        g_shape = from_data(g_spec, x_all, degree=degree, breakpoints=breakpoints) \
            if isinstance(g_spec, str) else g_spec
        s = wiener_start(g_shape, isinstance(g_spec, str), vs, lin, problem.offset)
        g0 = g_shape._with(s.theta)
        b, den, d = s.b, s.f, s.offset
        if isinstance(g_spec, str) and g_spec == "piecewise-linear" and breakpoints is None:
            # breakpoints belong where the linear block's output lives, now that it is known
            x = np.concatenate([sps.lfilter(np.concatenate([np.zeros(_nk(lin)), b]), den, v)
                                for v, _ in vs])
            g0 = from_data("piecewise-linear", x)
        if s.scale != 1.0 and f0 is not None and f0._basis(u_all) is not None:
            f0 = f0._with(f0.parameters * s.scale)  # the scale of G·f lives in f
        inputs = [(v, None) for v, _ in vs]
    theta_lin = _linear_theta(lin, b, den, inputs)
    return f0, g0, theta_lin, d


def _nk(lin: LinearBlock) -> int:
    return lin.nk if lin.kind == "oe" else 1


def _linear_theta(lin: LinearBlock, b: NDArray[np.float64], den: NDArray[np.float64],
                  inputs: list[tuple[NDArray[np.float64], Any]]) -> NDArray[np.float64]:
    """The linear block's θ from a discrete start (b, F)."""
    if lin.kind == "oe":
        if lin.unit_gain:
            gain = b.sum() / den.sum()
            if np.isfinite(gain) and abs(gain) > 1e-12:
                b = b / gain
        return lin.theta_of(b, den)
    # continuous: SRIVC on the noise-free output of the discrete start
    from ..estimate import fit_tf

    v = np.concatenate([vi for vi, _ in inputs])
    x = sps.lfilter(np.concatenate([[0.0], b]), den, v)
    exp = Experiment.from_arrays(lin.dt, u=v, y=x)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            tf = fit_tf(exp, lin.n_poles, lin.n_zeros).model
    except (ConvergenceError, IdentifiabilityError, DataError, ModelError) as exc:
        raise ConvergenceError(f"no continuous start for the linear block ({exc}); try "
                               "linear = \"oe\" or other orders") from exc
    num = np.asarray(tf.num, dtype=float)
    num = np.concatenate([np.zeros(lin.n_zeros + 1 - num.size), num])
    dd = np.asarray(tf.den, dtype=float)
    if lin.unit_gain and num[-1] != 0 and dd[-1] != 0:
        num = num * dd[-1] / num[-1]
    return lin.theta_of(num, dd)


def _search(problem: _Problem, p0: NDArray[np.float64], max_iter: int, tol: float
            ) -> tuple[NDArray[np.float64], int, str]:
    lo, hi = problem.bounds()
    finite_lo, finite_hi = np.isfinite(lo), np.isfinite(hi)
    margin_lo = np.where(finite_lo, 1e-9 * (1 + np.abs(np.where(finite_lo, lo, 0.0))), 0.0)
    margin_hi = np.where(finite_hi, 1e-9 * (1 + np.abs(np.where(finite_hi, hi, 0.0))), 0.0)
    p0 = np.clip(p0, lo + margin_lo, hi - margin_hi)
    result = optimize.least_squares(problem.residual, p0, bounds=(lo, hi), method="trf",
                                    x_scale="jac", ftol=tol, xtol=tol, gtol=tol,
                                    max_nfev=max_iter)  # the Jacobian's evaluations not counted
    status = "ok"
    if result.status == 0:
        status = "iteration limit reached"
        warn(f"the block-model search stopped at {max_iter} iterations before "
             "converging; raise max_iter or check the start", ServoidWarning)
    elif result.status < 0:
        raise ConvergenceError(f"the block-model search failed: {result.message}")
    return np.asarray(result.x, dtype=float), int(result.nfev), status


def _normalise_sign(problem: _Problem, p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pick the positive-gain twin of a Wiener model with |·| (G → −G, centre → −centre)."""
    g = problem.g
    if g is None or g.kind != "abs" or problem.lin.unit_gain:
        return p
    tf, tl, tg, d, states = problem.unpack(p)
    if problem.lin.static_gain(tl) >= 0:
        return p
    num, den = problem.lin.coefficients(tl)
    tl = problem.lin.theta_of(-num, den)
    return problem.pack(tf, tl, -tg, d) + np.concatenate(
        [np.zeros(problem.n_free), -states.ravel()])


def _estimate(problem: _Problem, p: NDArray[np.float64], nfev: int, status: str,
              names: dict[str, Any], options: dict[str, Any]) -> Estimate:
    r = problem.residual(p)
    n = r.size
    n_free, n_all = problem.n_free, p.size
    sse = float(r @ r)
    sigma2 = sse / max(n - n_all, 1)
    _check_regions(problem, p)
    y_all = np.concatenate([y for _, y in problem.pairs])
    baseline = float(np.sum((y_all - y_all.mean()) ** 2)) if problem.offset else float(
        y_all @ y_all)
    # Is the fit more than noise? If the output did not respond at all, y = e (white, σ²),
    # and the reduction baseline − sse of a least-squares fit of d parameters entering
    # linearly is σ²·χ²_d. P(χ²_d > 10d) is 1.6e-3 for d = 1, 5e-5 for d = 2 and below
    # 1e-6 from d = 3 (scipy.stats.chi2.sf): a false alarm is rare. Breakpoints and centres
    # enter nonlinearly and are searched like change points, which buys chance more than
    # one χ²_1 each (≈ 3σ² seen on records of noise alone), still inside the 10σ² budget;
    # and a real response explains orders of magnitude more. Initial states count (n_all).
    if baseline - sse < _CHANCE_PER_PARAMETER * n_all * sigma2:
        raise IdentifiabilityError(
            "the fitted model explains no more of the output than chance "
            f"({baseline - sse:.3g} of {baseline:.3g}): the output does not respond to the input "
            "through this structure — the input may never leave a dead zone, or the shape or "
            "the delay nk is wrong")
    jac = problem.jacobian(p)
    j_theta, j_state = jac[:, :n_free], jac[:, n_free:]
    if j_state.shape[1]:  # project the initial states out (Schur complement)
        coef, *_ = np.linalg.lstsq(j_state, j_theta, rcond=None)
        j_theta = j_theta - j_state @ coef
    norms = np.linalg.norm(j_theta, axis=0)
    labels = problem.names
    dead = [labels[k] for k in range(n_free) if norms[k] <= 1e-12 * max(norms.max(), 1e-300)]
    if dead:
        raise IdentifiabilityError(f"the data do not determine {', '.join(dead)}: the output does "
                                   "not change with it; excite the system more widely or fix "
                                   "the structure")
    scaled = j_theta / norms
    _u_s, sv, vt = np.linalg.svd(scaled, full_matrices=False)
    if sv[-1] < 1e-8 * sv[0]:
        weak = np.argsort(-np.abs(vt[-1]))[:2]
        raise IdentifiabilityError(
            f"the data cannot separate {' and '.join(labels[k] for k in sorted(weak))} "
            f"(condition {sv[0] / sv[-1]:.3g}); lower the orders, excite more widely, or fix "
            "the structure")
    inv = (vt.T / sv ** 2) @ vt
    covariance = sigma2 * inv / np.outer(norms, norms)
    if problem.lin.unit_gain:  # the pole near z = 1 judged by its confidence region
        span = slice(problem.nf_, problem.nf_ + problem.lin.size)
        _check_not_integrating(problem.lin, p[span], "fit", covariance[span, span])
    model = problem.model(p)
    stable_den = problem.lin.polynomials(p[problem.nf_: problem.nf_ + problem.lin.size])[1]
    if stable_den.size > 1 and np.any(np.abs(np.roots(stable_den)) >= 1.0):
        warn("the fitted linear block is unstable; its simulation diverges on a long "
             "record", ServoidWarning)
    theta = p[:n_free].copy()
    tail = p[n_free:].copy()

    def model_function(t: NDArray[np.float64]) -> BlockModel:
        return problem.model(np.concatenate([t, tail]))

    units = parameter_units(problem.f, problem.g, problem.lin, problem.offset, names)
    return Estimate(
        model=model, parameters=theta, names=labels, covariance=covariance,
        noise_variance=sigma2, n_samples=n, method=problem.structure, status=status,
        options={**options, **{k: v for k, v in names.items() if not k.endswith("_unit")},
                 "nfev": nfev, "cost": sse, "n_states": problem.n_states},
        units=units, residual_function=lambda: r.copy(), model_function=model_function)


#: Distance of the pole nearest z = 1 below which a start counts as an integrator (no
#: covariance yet): a pole on 1 to rounding.
_ON_ONE = 1e-6
#: Standard deviations of |p − 1| within which the fitted pole nearest z = 1 cannot be told
#: from an integrator (its approximate 99.7 % region contains z = 1; a unit root's estimate
#: is not Gaussian, so a wide region).
INTEGRATOR_SIGMAS = 3.0


def _check_not_integrating(lin: LinearBlock, theta: NDArray[np.float64], when: str,
                           covariance: NDArray[np.float64] | None = None) -> None:
    """Refuse the convention G(1) = 1 on a linear block with a pole at z = 1.

    With a free-scale shape the static gain G(1) = B(1)/F(1) is fixed to 1
    by B(1) = F(1).  A pole p at 1 makes F(1) ∝ (1 − p) vanish, so the
    shape's coefficients carry the block's gain 1/(1 − p): the product is
    right but the coefficients are huge and their intervals meaningless.
    Whether the pole *is* at 1 is a question for its confidence region,
    not for a threshold on |F(1)| (a slow, stable process has poles at
    0.99 that the data place well inside the unit circle): after the fit,
    the distance |p − 1| of the pole nearest 1 and its standard deviation
    by the delta method from the covariance of the linear block's
    parameters; the block integrates when the distance is within
    :data:`INTEGRATOR_SIGMAS` of them.  At the start (no covariance) only a
    pole on 1 to rounding is refused.
    """
    _num, den = lin.polynomials(theta)
    if den.size < 2:
        return
    poles = np.roots(den)
    pole = poles[int(np.argmin(np.abs(poles - 1.0)))]
    distance = float(abs(pole - 1.0))
    if covariance is None:
        if distance >= _ON_ONE:
            return
        region = f"z = {pole.real:.6g} at the {when}"
    else:
        sigma = _distance_spread(lin, theta, pole, covariance)
        if not distance < max(INTEGRATOR_SIGMAS * sigma, _ON_ONE):
            return
        region = (f"z = {_complex_text(pole)}, |z − 1| = {distance:.2g} within "
                  f"{INTEGRATOR_SIGMAS:g}σ = {INTEGRATOR_SIGMAS * sigma:.2g} of its "
                  f"uncertainty, after the {when}")
    raise IdentifiabilityError(
        f"the linear block integrates (its pole nearest 1, {region}, cannot be told from "
        "z = 1), so its static gain is infinite and the scale convention of a free-scale shape "
        "(polynomial, piecewise-linear, a user function), linear static gain G(1) = 1, cannot "
        "hold: the shape's coefficients would carry the integrator's gain. Use a unit-slope "
        "shape (deadzone, saturation, abs, power) so the linear block keeps the gain")


def _distance_spread(lin: LinearBlock, theta: NDArray[np.float64], pole: complex,
                     covariance: NDArray[np.float64]) -> float:
    """σ of |p − 1| for the pole p nearest 1, by central differences of the roots."""
    grad = np.zeros(theta.size)
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    for k in range(theta.size):
        h = max(1e-3 * std[k], 1e-9 * max(abs(theta[k]), 1.0))
        moved = []
        for sign in (1.0, -1.0):
            t = theta.copy()
            t[k] += sign * h
            roots = np.roots(lin.polynomials(t)[1])
            moved.append(abs(roots[int(np.argmin(np.abs(roots - pole)))] - 1.0))
        grad[k] = (moved[0] - moved[1]) / (2 * h)
    var = float(grad @ covariance @ grad)
    return math.sqrt(var) if var > 0 and math.isfinite(var) else 0.0


def _complex_text(z: complex) -> str:
    if abs(z.imag) < 1e-12:
        return f"{z.real:.6g}"
    return f"{z.real:.6g} {'+' if z.imag >= 0 else '−'} {abs(z.imag):.3g}j"


def _check_regions(problem: _Problem, p: NDArray[np.float64]) -> None:
    """Each breakpoint must have samples of its block's input beyond it."""
    tf, _, tg, _, _ = problem.unpack(p)
    sims = problem.outputs(p)
    for shape, theta, signal, block in (
            (problem.f, tf, np.concatenate([u for u, _ in problem.pairs]), "input"),
            (problem.g, tg, np.concatenate([s[1] for s in sims]), "linear block's output")):
        if shape is None:
            continue
        for index, side, where in shape._regions(theta):
            count = int(np.sum(signal < where) if side == "below" else np.sum(signal > where))
            if count < MIN_REGION_SAMPLES:
                name = shape.names[index]
                raise IdentifiabilityError(
                    f"{name} is not determined: the {block} goes {side} {where:.4g} in only "
                    f"{count} samples (range {signal.min():.4g} … {signal.max():.4g}); excite "
                    f"the system so that it crosses the breakpoint (a larger or "
                    f"{'more negative' if side == 'below' else 'more positive'} input)")
        if shape.kind in ("deadzone", "saturation") and theta[0] > theta[1]:
            what = "no dead zone" if shape.kind == "deadzone" else "no linear range"
            raise IdentifiabilityError(
                f"the fitted {shape.kind} closed up ({shape.names[0]} = {theta[0]:.4g} > "
                f"{shape.names[1]} = {theta[1]:.4g}): the data show {what} on the {block}; "
                "drop that block (a simpler structure) or choose another shape")
