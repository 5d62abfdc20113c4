"""Subspace identification of discrete state-space models: :func:`fit_n4sid`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_int, as_str_list
from .._errors import DataError, IdentifiabilityError, ServoidWarning, check_option
from .._lazy import linalg
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..models import StateSpace
from ._channels import check_magnitude, check_not_constant
from ._estimate import Estimate
from ._ss_polynomial import oe_covariance, oe_parameters, oe_statespace
from ._subspace_choice import (
    DEFAULT_MAX_ORDER,
    adaptive_horizon,
    check_order,
    choose_order,
    default_horizon,
    given_horizons,
    largest_order,
)
from ._subspace_core import (
    HankelLayout,
    Weighting,
    hankel_gram,
    innovation_covariances,
    observability,
    state_regression,
    state_rows,
    system_matrices,
)
from ._subspace_output import OutputFit, fit_input_matrices

__all__ = ["WEIGHTINGS", "fit_n4sid"]

#: The weightings :func:`fit_n4sid` offers.
WEIGHTINGS: tuple[Weighting, ...] = ("moesp", "cva", "n4sid")
#: cond(scaled input Gram) above which the input is not persistently exciting (1/√ε).
_PE_COND_LIMIT = 1.0 / math.sqrt(np.finfo(float).eps)


@dataclass(frozen=True, eq=False)
class _Data:
    """The checked signals of a fit, shared by its passes."""

    signals: tuple[tuple[NDArray[np.float64], ...], ...]  # per segment (u_0…, y_0…)
    uy: tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]  # per segment (N, m), (N, ny)
    scale: NDArray[np.float64]  # RMS per signal
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    lengths: tuple[int, ...]
    dt: float

    @property
    def m(self) -> int:
        return len(self.inputs)

    @property
    def ny(self) -> int:
        return len(self.outputs)


@dataclass(frozen=True, eq=False)
class _Pass:
    """One subspace fit at fixed horizons."""

    past: int
    future: int
    n: int
    rule: str
    sv: NDArray[np.float64]
    model: StateSpace
    fit: OutputFit
    unstable: bool
    gain: NDArray[np.float64] | None
    innovation: NDArray[np.float64] | None
    kalman_note: str
    n_columns: int
    cap: int | None
    messages: list[str]


def fit_n4sid(
    data: Experiment | ExperimentSet,
    order: int | None = None,
    *,
    weighting: Weighting = "moesp",
    horizon: int | tuple[int, int] | None = None,
    input: Literal["u", "r"] = "u",
    output: str | Sequence[str] | None = None,
    feedthrough: bool = False,
    max_order: int | None = None,
) -> Estimate:
    """Fit a discrete state-space model by subspace identification.

    The extended observability matrix Γ_f is taken from the weighted
    oblique projection of future outputs on past data along future inputs
    (Van Overschee & De Moor, *Subspace Identification for Linear Systems*,
    1996, thm. 2 and ch. 4; Verhaegen & Verdult, *Filtering and System
    Identification*, 2007, ch. 9).  A and C follow from its shift
    structure; B, D and the initial state of each segment by linear least
    squares on the output (so the model is fitted for simulation); the
    Kalman gain from the residuals of the state sequences and a Riccati
    equation (Van Overschee & De Moor 1996, sec. 4.3.1).

    All projections are computed from the Gram matrix of the block-Hankel
    data, accumulated in one pass over the record: memory does not grow
    with the record length.  Channels are scaled to unit RMS inside (the
    model is returned in the data's units).  Open-loop data are assumed:
    with feedback the estimate is biased.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s).  Segments of a set share the model; each has its
        own initial state and no Hankel column spans two segments.
    order : int, optional
        State dimension n.  None chooses it from the singular values σ_i:
        the largest n ≤ max_order whose drop ``log σ_n − log σ_{n+1}`` is
        at least half the largest drop (the last sharp fall to the noise
        floor, so a weak fast mode after a dominant one still counts).  A
        :class:`~servoid.ServoidWarning` says when the gap is not clear — no
        ratio σ_n/σ_{n+1} above 2, or a higher order whose drop is itself
        clear (above 2 and 3× in log any drop after it: a weak mode standing
        out of the noise floor) — or when the choice sits at max_order.
    weighting : {"moesp", "cva", "n4sid"}
        ``"moesp"`` (PO-MOESP, W₁ = I, W₂ = Π_{U_f}^⊥), ``"cva"``
        (canonical variate analysis: singular values are the canonical
        correlations of future outputs and past data) or ``"n4sid"``
        (unweighted oblique projection).
    horizon : int or (int, int), optional
        Past and future horizons [samples]; an int sets both.  The future
        horizon should span the decay of the slowest mode.  Default
        (adaptive): a first pass with ``max(2·n_ref, 20)`` for both (n_ref
        = `order`, else `max_order`, else 10); if the slowest estimated
        pole |z| needs more samples than that to decay to 25 %, a second
        pass with horizons that long (at most 4× the first).  Both are
        shortened for a short record so that the block-Hankel matrix has at
        least twice as many columns as rows.
    input : {"u", "r"}
        Channels of this role are the inputs.
    output : str or sequence of str, optional
        Output channel(s); default every ``y`` channel.
    feedthrough : bool
        Estimate D (direct feed-through); default D = 0 (one-sample delay,
        as in a sampled-data servo).
    max_order : int, optional
        Largest order the singular-value rule considers (default 10, capped
        by what the horizons allow); ignored when `order` is given.

    Returns
    -------
    Estimate
        ``model`` is a discrete :class:`~servoid.models.StateSpace` in the
        basis of the singular vectors.  ``parameters`` are the coefficients
        of the equivalent common-denominator output-error model
        ``y_o = Σ_i B_oi(q)/F(q) u_i(t − nk)``, ordered as in ``fit_oe``:
        ``b0 … b_{n−nk}`` per output and input (names ``b0``, ``u1:b0`` or
        ``u1->y0:b0``; b_j multiplies u(t − nk − j); nk = 1, or 0 with
        `feedthrough`), then the shared ``f1 … fn``.
        ``model_function(θ)`` realises them (observer form; with several
        inputs and outputs a non-minimal realisation of order n·ny), so
        ``model_at(parameters)`` has the transfer function of ``model``.
        ``covariance`` is the asymptotic prediction-error covariance of
        these coefficients, ``[Σ_t Ψ Λ⁻¹ Ψᵀ]⁻¹`` (σ̂²(ΨᵀΨ)⁻¹ for one output)
        with Ψ the exact output-error gradient evaluated at the subspace
        estimate and Λ the residual covariance.  A subspace estimate has no
        standard covariance of its own: this is the covariance of the PEM
        estimate it starts, accurate for the subspace estimate when it lies
        near the PEM optimum with white output errors (in the tests its
        pole scatter stays within 1.5× of it); NaN when the information
        matrix is singular or the model unstable.  ``noise_variance`` is
        the mean residual variance over outputs.  ``options`` hold,
        JSON-friendly: ``order``, ``order_rule``, ``singular_values`` (of
        the RMS-scaled data: plot them on a log scale with the order
        marked), ``weighting``, ``horizon`` [past, future],
        ``horizon_rule``, ``inputs``, ``outputs``, ``feedthrough``, ``x0``
        per segment, ``kalman_gain`` (n × ny, or None with
        ``kalman_note``), ``innovation_covariance``,
        ``residual_covariance`` and the solver used for B, D; see also
        :class:`InnovationModel` and :func:`to_polynomial`.

    Raises
    ------
    DataError
        The order exceeds what the horizons allow, the record is too short
        for the horizons, or a channel is missing.
    IdentifiabilityError
        An input is constant or not persistently exciting, or an output is
        identically zero.
    OptionError
        An unknown weighting or input role.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid import Experiment
    >>> from servoid.models import StateSpace
    >>> true = StateSpace([[0.9, 0.2], [0.0, 0.5]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=0.01)
    >>> u = np.random.default_rng(0).standard_normal(2000)
    >>> est = fit_n4sid(Experiment.from_arrays(0.01, u=u, y=true.simulate(u)))
    >>> est.options["order"], np.round(np.sort(est.model.poles().real), 6).tolist()
    (2, [0.5, 0.9])
    """
    check_option("weighting", weighting, WEIGHTINGS)
    check_option("input", input, ("u", "r"))
    feedthrough = as_bool("feedthrough", feedthrough)
    n_given = None if order is None else as_int("order", order, minimum=1)
    cap = DEFAULT_MAX_ORDER if max_order is None else as_int("max_order", max_order, minimum=1)
    d = _prepare(as_segments(data), input, output)
    m, ny = d.m, d.ny
    first_pass: int | None = None
    radius: float | None = None
    if horizon is not None:
        past, future = given_horizons(horizon, m, ny, d.lengths)
        if n_given is not None:
            check_order(n_given, past, future, m, ny)
        projection = _project(d, past, future, n_given, cap, weighting)
        rule = "given"
    else:
        n_ref = n_given if n_given is not None else (cap if max_order is not None else None)
        s0 = default_horizon(n_ref, m, ny, d.lengths)
        if n_given is not None:
            check_order(n_given, s0, s0, m, ny)
        projection = _project(d, s0, s0, n_given, cap, weighting)
        radius = float(np.max(np.abs(linalg.eigvals(projection.a))))
        s1 = adaptive_horizon(radius, s0, m, ny, d.lengths)
        rule = "adaptive: the slowest first-pass pole decays to 25 % (at most 4× the first)"
        first_pass = s0
        if s1 > s0:
            projection = _project(d, s1, s1, n_given, cap, weighting)
    result = _identify(d, projection, feedthrough)
    for message in result.messages:
        warn(message, ServoidWarning)
    return _estimate(d, result, weighting, feedthrough, input,
                     {"horizon_rule": rule, "horizon_first_pass": first_pass,
                      "slowest_pole_first_pass": radius})


# -- the passes -------------------------------------------------------------------------------------


def _prepare(segments: tuple[Experiment, ...], input: str, output: str | Sequence[str] | None
             ) -> _Data:
    first = segments[0]
    inputs = first.names_of(input)  # type: ignore[arg-type]
    if not inputs:
        first.signal(input)  # type: ignore[arg-type]  # raises a DataError naming what exists
    outputs = _output_names(first, output)
    m = len(inputs)
    signals = tuple(tuple(seg[name] for name in (*inputs, *outputs)) for seg in segments)
    for k, name in enumerate((*inputs, *outputs)):
        check_magnitude(f"{'input' if k < m else 'output'} {name!r}", [z[k] for z in signals])
    for k, name in enumerate(inputs):
        check_not_constant(name, [z[k] for z in signals])
    scale = _rms(signals, (*inputs, *outputs), m)
    uy = tuple((_columns(z[:m]), _columns(z[m:])) for z in signals)
    return _Data(signals, uy, scale, tuple(inputs), outputs,
                 tuple(seg.n_samples for seg in segments), first.dt)


@dataclass(frozen=True, eq=False)
class _Projection:
    """The subspace step: singular values, order, Γ_f, A and C."""

    layout: HankelLayout
    gram: NDArray[np.float64]
    n_columns: int
    sv: NDArray[np.float64]
    n: int
    rule: str
    cap: int | None
    messages: list[str]
    gamma: NDArray[np.float64]
    a: NDArray[np.float64]
    c_scaled: NDArray[np.float64]


def _project(d: _Data, past: int, future: int, n_given: int | None, cap: int,
             weighting: Weighting) -> _Projection:
    m, ny = d.m, d.ny
    layout = HankelLayout(m, ny, past, future)
    n_max = largest_order(past, future, m, ny)
    gram, n_columns = hankel_gram(d.signals, layout, d.scale)
    _check_excitation(gram, layout, d.inputs)
    left, sv, unweight = observability(gram, layout, weighting)
    messages: list[str] = []
    if n_given is None:
        n, messages = choose_order(sv, min(cap, n_max), cap_is_horizon=cap > n_max)
        rule = "last log singular-value gap >= half the largest"
    else:
        n, rule = n_given, "given"
    gamma, a, c_scaled = system_matrices(left, sv, unweight, n, ny)
    if n_given is None and _is_unstable(a):
        n, rule, gamma, a, c_scaled = _stable_order(left, sv, unweight, ny, n, rule,
                                                    min(cap, n_max), messages,
                                                    (gamma, a, c_scaled))
    return _Projection(layout, gram, n_columns, sv, n, rule,
                       None if n_given is not None else min(cap, n_max), messages, gamma, a,
                       c_scaled)


def _stable_order(left: Any, sv: NDArray[np.float64], unweight: Any, ny: int, n: int,
                  rule: str, cap: int, messages: list[str], chosen: tuple[Any, Any, Any],
                  ) -> tuple[int, str, Any, Any, Any]:
    """The order of the clearest singular-value gap whose model is stable.

    The gap rule chose `n` and its A is unstable: the other orders up to
    `cap` are tried in decreasing size of their log gap, and the first
    with a stable A is taken (a message says so); when none is stable the
    rule's order stays (its instability is reported downstream).
    """
    size = max(sv.size, cap + 1)
    s = np.zeros(size)
    s[: sv.size] = sv
    s = np.maximum(s, sv[0] * np.finfo(float).eps)
    gaps = np.log(s[:-1]) - np.log(s[1:])
    for k in sorted(range(1, cap + 1), key=lambda j: -gaps[j - 1]):
        if k == n:
            continue
        gamma, a, c_scaled = system_matrices(left, sv, unweight, k, ny)
        if not _is_unstable(a):
            messages.append(
                f"the singular-value rule chose order {n}, whose model is unstable; order {k} "
                f"(σ_{k}/σ_{k + 1} = {math.exp(gaps[k - 1]):.3g}), the clearest other gap with "
                "a stable model, was taken instead (pass order= to keep another)")
            return k, rule + "; unstable, so the clearest gap with a stable model", gamma, a, \
                c_scaled
    return (n, rule, *chosen)


def _identify(d: _Data, pr: _Projection, feedthrough: bool) -> _Pass:
    m, n = d.m, pr.n
    a, c_scaled, gram = pr.a, pr.c_scaled, pr.gram
    messages = list(pr.messages)
    su, sy = d.scale[:m], d.scale[m:]
    c = c_scaled * sy[:, None]
    rows = state_rows(gram, pr.layout, pr.gamma)
    unstable = _is_unstable(a)
    if unstable:
        b_scaled, d_scaled = state_regression(gram, rows, a, c_scaled, feedthrough)
        b, dd = b_scaled / su, d_scaled * sy[:, None] / su
        fit = OutputFit(b, dd, tuple(np.zeros(n) for _ in d.uy),
                        _residual_products(a, b, c, dd, d.uy), "state sequences (unstable A)",
                        math.nan)
        radius = float(np.max(np.abs(linalg.eigvals(a))))
        messages.append(
            f"the estimated model is unstable (largest pole magnitude {radius:.6g} > 1): B and D "
            "come from the state sequences instead of a simulation fit, and the covariance is "
            "NaN. Check for drift, an integrating plant or feedback in the data, or lengthen "
            "the horizons"
        )
    else:
        fit = fit_input_matrices(a, c, d.uy, feedthrough)
        b_scaled, d_scaled = fit.b * su, fit.d * su / sy[:, None]
    model = StateSpace(a, fit.b, c, fit.d, d.dt)
    gain, innovation, note = _kalman(gram, rows, a, b_scaled, c_scaled, d_scaled, sy)
    return _Pass(pr.layout.past, pr.layout.future, n, pr.rule, pr.sv, model, fit, unstable,
                 gain, innovation, note, pr.n_columns, pr.cap, messages)


def _estimate(d: _Data, p: _Pass, weighting: Weighting, feedthrough: bool, input: str,
              horizon_options: dict[str, object]) -> Estimate:
    m, ny, n = d.m, d.ny, p.n
    model, fit = p.model, p.fit
    nk = 0 if feedthrough else 1
    theta, names = oe_parameters(model, nk, d.inputs, d.outputs)
    n_total = sum(d.lengths)
    # per output: n + m·(n + 1 − nk) coefficients, so RSS/(N − that) is σ̂² of the OE fit
    resid_cov = _noise_covariance(fit.residual_products, d.scale[m:],
                                  n_total - (n + m * (n + 1 - nk)))
    if p.unstable:  # an output-error predictor with unstable F has no stationary gradient
        covariance = np.full((theta.size, theta.size), np.nan)
    else:
        covariance = oe_covariance(model, nk, d.uy, resid_cov)

    def residual_function() -> NDArray[np.float64]:
        out = np.concatenate(
            [y - model.simulate(u, x0=x0).reshape(y.shape) for (u, y), x0 in zip(d.uy, fit.x0)]
        )
        return out[:, 0] if ny == 1 else out

    options = {
        "order": n,
        "order_rule": p.rule,
        "singular_values": [float(s) for s in p.sv],
        "weighting": weighting,
        "horizon": [p.past, p.future],
        **horizon_options,
        "input": input,
        "inputs": list(d.inputs),
        "outputs": list(d.outputs),
        "feedthrough": feedthrough,
        "nk": nk,
        "max_order": p.cap,
        "hankel_columns": p.n_columns,
        "x0": [x.tolist() for x in fit.x0],
        "kalman_gain": None if p.gain is None else p.gain.tolist(),
        "innovation_covariance": None if p.innovation is None else p.innovation.tolist(),
        "kalman_note": p.kalman_note,
        "residual_covariance": np.atleast_2d(resid_cov).tolist(),
        "covariance_method": "asymptotic output-error PEM covariance at the subspace estimate",
        "solver": fit.solver,
        "condition": fit.condition,
        "segments": len(d.lengths),
    }
    return Estimate(
        model=model,
        parameters=theta,
        names=names,
        covariance=covariance,
        noise_variance=float(np.mean(np.diag(np.atleast_2d(resid_cov)))),
        n_samples=n_total,
        method="n4sid",
        options=options,
        residual_function=residual_function,
        model_function=partial(oe_statespace, n=n, n_inputs=m, n_outputs=ny, nk=nk, dt=d.dt),
    )


# -- private helpers ------------------------------------------------------------------------------


def _output_names(exp: Experiment, output: str | Sequence[str] | None) -> tuple[str, ...]:
    if output is None:
        names = exp.names_of("y")
        if not names:
            exp.signal("y")  # raises a DataError naming what exists
        return names
    if isinstance(output, str):
        chosen: tuple[str, ...] = (output,)
    else:
        chosen = tuple(as_str_list("output", output))
    if not chosen:
        raise DataError("output must name at least one channel, got an empty list")
    for name in chosen:
        exp.channel(name)  # raises a ChannelError listing the channels
    if len(set(chosen)) != len(chosen):
        raise DataError(f"output names a channel twice: {list(chosen)}")
    return chosen


def _columns(channels: Sequence[NDArray[np.float64]]) -> NDArray[np.float64]:
    """(N, k) C-contiguous; one channel is a view, not a copy."""
    return channels[0][:, None] if len(channels) == 1 else np.column_stack(channels)


def _rms(signals: Sequence[tuple[NDArray[np.float64], ...]], names: Sequence[str], m: int
         ) -> NDArray[np.float64]:
    total = sum(z[0].size for z in signals)
    rms = np.sqrt(np.array([sum(float(z[k] @ z[k]) for z in signals) for k in range(len(names))])
                  / total)
    for k in range(m, len(names)):
        if not rms[k] > 0:
            raise IdentifiabilityError(
                f"output {names[k]!r} is identically zero: nothing to identify; check the "
                "channel mapping"
            )
    return rms


def _check_excitation(gram: NDArray[np.float64], layout: HankelLayout,
                      names: Sequence[str]) -> None:
    rows = np.concatenate([layout.rows("uf"), layout.rows("up")])
    g = gram[np.ix_(rows, rows)]
    scale = np.sqrt(np.diag(g))
    eig = np.linalg.eigvalsh(g / np.outer(scale, scale))
    cond = math.sqrt(eig[-1] / eig[0]) if eig[0] > 0 else math.inf
    if cond > _PE_COND_LIMIT:
        order = layout.past + layout.future
        plural = len(names) > 1
        raise IdentifiabilityError(
            f"the input{'s' if plural else ''} {', '.join(map(repr, names))} "
            f"{'are' if plural else 'is'} not persistently exciting of order {order} "
            f"(past + future horizons; condition number {cond:.3g}): a sum of few sinusoids, a "
            "slow staircase or inputs that move together. Use a PRBS or multisine (servoid "
            "excite), or shorter horizons"
        )


def _noise_covariance(products: NDArray[np.float64], y_rms: NDArray[np.float64], dof: int
                      ) -> NDArray[np.float64]:
    """Residual covariance Σ e eᵀ/dof, exactly zero at the rounding level of noise-free data.

    The sums come from the normal equations, where yᵀy − θᵀΦᵀy cancels to about
    ε·yᵀy (and may even come out negative); 1e-12 of the output power is far below any
    real measurement noise (−120 dB) and well above that rounding.
    """
    cov = products / max(dof, 1)
    if not np.all(np.isfinite(cov)):  # an unstable model's simulation overflowed
        return np.full_like(cov, np.nan)
    w, v = np.linalg.eigh(cov)
    w = np.where(w > 1e-12 * float(y_rms @ y_rms), w, 0.0)
    return (v * w) @ v.T


def _kalman(
    gram: NDArray[np.float64],
    rows: tuple[NDArray[np.float64], ...],
    a: NDArray[np.float64],
    b_scaled: NDArray[np.float64],
    c_scaled: NDArray[np.float64],
    d_scaled: NDArray[np.float64],
    sy: NDArray[np.float64],
) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None, str]:
    """Kalman gain and innovation covariance in data units, or None and why not."""
    n = a.shape[0]
    cov = innovation_covariances(gram, rows, a, b_scaled, c_scaled, d_scaled)
    q, s, r = cov[:n, :n], cov[:n, n:], cov[n:, n:]
    # the outputs are scaled to unit power: below 1e-12 (−120 dB) a residual is rounding
    if not np.all(np.linalg.eigvalsh(r) > 1e-12):
        return None, None, "the output residual covariance is singular (noise-free data?)"
    try:
        p = linalg.solve_discrete_are(a.T, c_scaled.T, q, r, s=s)
    except (ValueError, np.linalg.LinAlgError) as exc:
        return None, None, f"the Riccati equation has no stabilising solution ({exc})"
    re = c_scaled @ p @ c_scaled.T + r
    k = linalg.solve(re.T, (a @ p @ c_scaled.T + s).T).T
    if not (np.all(np.isfinite(k)) and np.max(np.abs(np.linalg.eigvals(a - k @ c_scaled))) < 1):
        return None, None, "the Riccati solution does not give a stable predictor"
    return k / sy[None, :], re * np.outer(sy, sy), "ok"


def _is_unstable(a: NDArray[np.float64]) -> bool:
    return bool(a.size) and float(np.max(np.abs(linalg.eigvals(a)))) > 1.0 + 1e-9


def _residual_products(
    a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64],
    d: NDArray[np.float64], uy: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
) -> NDArray[np.float64]:
    """Σ e eᵀ of the simulation from rest (the unstable route has no normal equations)."""
    model = StateSpace(a, b, c, d, 1.0)
    out = np.zeros((c.shape[0], c.shape[0]))
    with np.errstate(over="ignore", invalid="ignore"):
        for u, y in uy:
            e = y - model.simulate(u).reshape(y.shape)
            out += e.T @ e
    return out
