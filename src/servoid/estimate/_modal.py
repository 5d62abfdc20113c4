"""Static gain, time constants, natural frequencies and damping with uncertainty.

The numbers a servo is specified in are not the coefficients of its
transfer function but its static gain, the time constants of its real
poles and the natural frequency ω_n and damping ζ of each complex pair:
for a pair s, s̄ = −ζω_n ± jω_n√(1 − ζ²), ``ω_n² = s·s̄`` and
``ζ = −(s + s̄)/(2ω_n)``; for a real pole p, ``T = −1/p``.

A discrete model's poles are mapped to continuous ones by s = ln(z)/dt
(principal logarithm; the inverse of the ZOH pole map z = e^{s·dt}); poles
at z = 0 are a pure delay and give no row, and a pole on the negative real
axis maps to one pole at the Nyquist frequency π/dt, reported as a
"pair" with ω_n = |s| and ζ = −Re s/|s|.

**Uncertainty** by the delta method: ``cov(q) = J·cov(θ)·Jᵀ`` with the
Jacobian J = ∂q/∂θ of these quantities by central differences through
:meth:`~servoid.estimate.Estimate.model_at`, steps ``max(1e-4·σ_i,
1e-6·|θ_i|)``: small against the scale on which the model is linearised,
large against rounding.  At a perturbed θ each pole is matched to its
nominal partner (assignment by distance) and a pair is evaluated through
its sum and product, which stay smooth when a lightly damped pair turns
real or the other way round.  The intervals are Student-t intervals with
the estimate's degrees of freedom, as in
:meth:`~servoid.estimate.Estimate.confidence_intervals`.

The result is a :class:`ModalParameters`: a sequence of
:class:`~servoid.estimate.ParameterRow` that prints as a table and looks rows
up by name (``modal["wn1"]``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_instance, as_str
from .._errors import DataError, ModelError, OptionTypeError
from .._lazy import optimize, stats
from ..models import PolynomialModel, StateSpace, TransferFunction
from ._estimate import Estimate, ParameterRow

__all__ = ["ModalParameters", "modal_parameters"]

_IMAG_TOL = 1e-9  # |Im s| <= this·|s|: a real pole
# the unit of a continuous numerator coefficient over a monic denominator: gain/s^k
_PER_S = re.compile(r"/s(\^\d+)?$")


@dataclass(frozen=True)
class ModalParameters(Sequence[ParameterRow]):
    """Gain, time constants, ω_n and ζ of a model, with uncertainty.

    A sequence of :class:`~servoid.estimate.ParameterRow` (``dc_gain``,
    ``T1 …`` [s], ``wn1``, ``zeta1 …``); indexing by a row's name returns
    that row.  ``print`` shows them as a table.

    Attributes
    ----------
    rows : tuple of ParameterRow
        The quantities, in the order :func:`modal_parameters` documents.
    level : float
        Confidence level of the intervals ``ci_low``, ``ci_high``.
    """

    rows: tuple[ParameterRow, ...]
    level: float = 0.95

    @overload
    def __getitem__(self, key: int | str) -> ParameterRow: ...

    @overload
    def __getitem__(self, key: slice) -> Sequence[ParameterRow]: ...

    def __getitem__(self, key: int | slice | str) -> ParameterRow | Sequence[ParameterRow]:
        if isinstance(key, str):
            for row in self.rows:
                if row.name == key:
                    return row
            raise KeyError(f"no quantity {key!r}; there are {', '.join(self.names)}")
        return self.rows[key]

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self) -> Iterator[ParameterRow]:
        return iter(self.rows)

    @property
    def names(self) -> tuple[str, ...]:
        """The quantities' names, in order."""
        return tuple(row.name for row in self.rows)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON: the level and one mapping per row."""
        return {"confidence_level": self.level, "rows": [dict(row.__dict__) for row in self.rows]}

    def __str__(self) -> str:
        lines = [f"modal parameters (± std, {100 * self.level:g} % intervals)"]
        width = max((len(r.name) for r in self.rows), default=0)
        for row in self.rows:
            lines.append(f"  {row.name:<{width}}  {row.value: .6g} ± {row.std:.2g}"
                         f"  [{row.ci_low:.6g}, {row.ci_high:.6g}] {row.unit}".rstrip())
        return "\n".join(lines)

    def __repr__(self) -> str:
        shown = ", ".join(f"{r.name} = {r.value:.4g}" for r in self.rows)
        return f"<ModalParameters: {shown}>"

    def _repr_html_(self) -> str:
        from .._display import html_block, number

        rows = [(r.name, number(r.value), number(r.std, 3),
                 f"[{number(r.ci_low)}, {number(r.ci_high)}]", r.unit) for r in self.rows]
        return html_block("modal parameters", [],
                          ("quantity", "value", "std", f"{100 * self.level:g} % CI", "unit"),
                          rows)


def modal_parameters(
    estimate: Estimate,
    level: float = 0.95,
    *,
    output_unit: str | None = None,
    input_unit: str | None = None,
) -> ModalParameters:
    """Static gain, time constants, ω_n and ζ of an estimate's model.

    Parameters
    ----------
    estimate : Estimate
        An estimate whose model is a :class:`~servoid.models.TransferFunction`
        (continuous or discrete), a :class:`~servoid.models.PolynomialModel`
        (its first input, ``transfer_function(0)``) or a SISO
        :class:`~servoid.models.StateSpace`, and which records its
        ``model_function``.
    level : float
        Confidence level of the intervals, in (0, 1).
    output_unit, input_unit : str, optional
        Units of the output and input; the gain's unit is their ratio.
        Without them the gain takes the unit the estimate's coefficients
        carry (a continuous fit's ``b0`` is in gain/s^n), and none when
        they carry none (a discrete fit).

    Returns
    -------
    ModalParameters
        A sequence of rows: ``"dc_gain"``; ``"T1", "T2", …`` [s] for the real poles, slowest
        first (negative for an unstable pole, inf for an integrator); and
        ``"wn1", "zeta1", …`` [rad/s] for the complex pairs, by increasing
        ω_n.  A quantity that is not finite (the gain of an integrator)
        has NaN standard deviation and interval.

    Raises
    ------
    ModelError
        The estimate has no ``model_function``, or the model is a state
        space with several inputs or outputs.
    TypeError
        The model is of another kind.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.estimate import Estimate
    >>> from servoid.models import TransferFunction
    >>> def model(th):
    ...     return TransferFunction([th[0]], [1.0, th[1], th[2]])
    >>> est = Estimate(model([100.0, 4.0, 100.0]), np.array([100.0, 4.0, 100.0]),
    ...                ("b0", "a1", "a2"), np.diag([1.0, 0.01, 1.0]), 1.0, 1000, "demo",
    ...                model_function=model)
    >>> modal = modal_parameters(est)
    >>> [(r.name, round(r.value, 3)) for r in modal]
    [('dc_gain', 1.0), ('wn1', 10.0), ('zeta1', 0.2)]
    >>> round(modal["zeta1"].std, 4)
    0.0051
    """
    as_instance("estimate", estimate, Estimate, "an Estimate (from a fit_* function)")
    level = as_float("level", level)
    if not 0.0 < level < 1.0:
        raise DataError(f"level must lie in (0, 1), e.g. 0.95, got {level}")
    if output_unit is not None:
        as_str("output_unit", output_unit, empty=True)
    if input_unit is not None:
        as_str("input_unit", input_unit, empty=True)
    theta = np.asarray(estimate.parameters, dtype=float)
    nominal = _poles_and_gain(estimate.model)
    groups = _groups(nominal[0])
    quantities = _quantities(groups)

    def evaluate(th: NDArray[np.float64]) -> NDArray[np.float64]:
        poles, gain = _poles_and_gain(estimate.model_at(th))
        return np.concatenate([[gain], quantities(_matched(poles, nominal[0]))])

    values = evaluate(theta)  # model_at raises a ModelError without a model_function
    cov = _delta_method(evaluate, theta, estimate.covariance, values)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    std[~np.isfinite(values)] = np.nan
    half = stats.t.ppf(0.5 + level / 2, estimate.dof) * std
    if output_unit is None and input_unit is None:
        gain_unit = _gain_unit(estimate)
    else:
        output_unit, input_unit = output_unit or "", input_unit or ""
        gain_unit = (f"{output_unit or '1'}/{input_unit or '1'}" if (output_unit or input_unit)
                     else "")
    names, units = ["dc_gain"], [gain_unit]
    n_real = sum(1 for g in groups if g[0] == "real")
    names += [f"T{i}" for i in range(1, n_real + 1)]
    units += ["s"] * n_real
    for i in range(1, len(groups) - n_real + 1):
        names += [f"wn{i}", f"zeta{i}"]
        units += ["rad/s", ""]
    return ModalParameters(tuple(
        ParameterRow(name, float(v), float(s), float(v - h), float(v + h), unit)
        for name, v, s, h, unit in zip(names, values, std, half, units, strict=True)
    ), level)


def _gain_unit(estimate: Estimate) -> str:
    """The static gain's unit from the estimate's own: ``b0`` over a monic denominator.

    A continuous fit (``fit_tf``, ``fit_frf``) gives b0 in gain/s^n (a_n is in 1/s^n, and
    the gain is b0/a_n); a discrete one carries no units, and neither does its gain.
    """
    if "b0" not in estimate.names:
        return ""
    unit = estimate.units[estimate.names.index("b0")]
    gain = _PER_S.sub("", unit)
    return "" if gain in ("1", "") else gain


def _transfer(model: object) -> TransferFunction:
    if isinstance(model, TransferFunction):
        return model
    if isinstance(model, PolynomialModel):
        return model.transfer_function(0)
    if isinstance(model, StateSpace):
        if not model.is_siso:
            raise ModelError(
                f"modal_parameters needs a SISO model; this state space has {model.n_inputs} "
                f"input(s) and {model.n_outputs} output(s). Take one channel with to_tf(i, o)"
            )
        return model.to_tf()
    raise OptionTypeError(
        "modal_parameters needs an estimate whose model is a TransferFunction, "
        f"PolynomialModel or StateSpace, got {type(model).__name__}"
    )


def _poles_and_gain(model: object) -> tuple[NDArray[np.complex128], float]:
    """Continuous-time poles (delay poles at z = 0 dropped) and the static gain."""
    tf = _transfer(model)
    poles = tf.poles()
    if tf.dt is not None:
        poles = poles[poles != 0.0]
        poles = np.log(poles.astype(complex)) / tf.dt
    return poles, tf.dc_gain()


def _groups(poles: NDArray[np.complex128]) -> list[tuple[str, list[int]]]:
    """Real poles (slowest first), then complex pairs by increasing |s|."""
    scale = np.maximum(np.abs(poles), 1e-300)
    is_real = np.abs(poles.imag) <= _IMAG_TOL * scale
    used: set[int] = set()
    real, pairs = [], []
    for i in np.argsort(np.abs(poles), kind="stable"):
        i = int(i)
        if i in used:
            continue
        used.add(i)
        if is_real[i]:
            real.append(("real", [i]))
            continue
        partners = [j for j in range(poles.size) if j not in used and not is_real[j]]
        if partners:
            j = min(partners, key=lambda k: abs(poles[k] - np.conj(poles[i])))
            if abs(poles[j] - np.conj(poles[i])) <= 1e-6 * scale[i]:
                used.add(j)
                pairs.append(("pair", [i, j]))
                continue
        pairs.append(("pair", [i]))  # a Nyquist pole: no conjugate partner
    return real + pairs


def _quantities(
    groups: list[tuple[str, list[int]]],
) -> Callable[[NDArray[np.complex128]], NDArray[np.float64]]:
    def quantities(poles: NDArray[np.complex128]) -> NDArray[np.float64]:
        out: list[float] = []
        with np.errstate(divide="ignore", invalid="ignore"):
            for kind, idx in groups:
                if kind == "real":
                    p = float(poles[idx[0]].real)
                    out.append(-1.0 / p if p != 0.0 else math.inf)
                elif len(idx) == 2:
                    prod = float((poles[idx[0]] * poles[idx[1]]).real)
                    wn = math.sqrt(prod) if prod >= 0.0 else math.nan
                    out += [wn, -float((poles[idx[0]] + poles[idx[1]]).real) / (2.0 * wn)]
                else:
                    s = poles[idx[0]]
                    out += [float(abs(s)), -float(s.real) / float(abs(s))]
        return np.array(out)

    return quantities


def _matched(poles: NDArray[np.complex128], nominal: NDArray[np.complex128]) -> NDArray[Any]:
    """Reorder ``poles`` so that entry i is the partner of nominal pole i (NaN if none)."""
    out = np.full(nominal.size, np.nan + 0j)
    if poles.size == 0 or nominal.size == 0:
        return out
    cost = np.abs(nominal[:, None] - poles[None, :])
    rows, cols = optimize.linear_sum_assignment(cost)
    out[rows] = poles[cols]
    return out


def _delta_method(
    evaluate: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    theta: NDArray[np.float64],
    covariance: NDArray[np.float64],
    values: NDArray[np.float64],
) -> NDArray[np.float64]:
    """J·cov·Jᵀ with J by central differences; zero covariance skips the differences."""
    sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    if not np.any(sigma > 0):
        return np.zeros((values.size, values.size))
    jac = np.zeros((values.size, theta.size))
    for i in range(theta.size):
        if sigma[i] == 0.0:
            continue
        h = max(1e-4 * sigma[i], 1e-6 * abs(theta[i]), 1e-300)
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        with np.errstate(invalid="ignore"):
            jac[:, i] = (evaluate(up) - evaluate(down)) / (2.0 * h)
    jac[~np.isfinite(values)] = 0.0
    return jac @ covariance @ jac.T
