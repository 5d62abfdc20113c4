"""``method = "hammerstein" | "wiener" | "hammerstein-wiener"``: block-oriented models.

A static curve before (Hammerstein), after (Wiener) or on both sides of
(Hammerstein–Wiener) a linear block, fitted jointly by output error
(:func:`servoid.nonlinear.fit_block`), validated on each validation
record by free-run simulation with the initial state fitted, and drawn
with its ±2σ band.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .._checks import as_float_list
from .._errors import DataError, OptionError, ServoidError
from ..data import Experiment, ExperimentSpec
from ..estimate import Estimate
from ..nonlinear import (
    SHAPES,
    AbsoluteValue,
    DeadZone,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    SignedPower,
    StaticNonlinearity,
    fit_block_retrying,
)
from ..report import Figure, Section, new_figure, save_figure
from ._common import keyed, parameter_table, warnings_as_notes
from ._examples import open_loop
from ._lti import IdentificationResult, lti_result, model_dict
from ._options import HORIZON, OUTPUT, ROLE, boolean, choice, integer, number, optional
from ._registry import FigureWriter, Method, Option

__all__ = ["HAMMERSTEIN", "HAMMERSTEIN_WIENER", "WIENER", "BlockResult"]

_TITLES = {"hammerstein": "Hammerstein", "wiener": "Wiener",
           "hammerstein-wiener": "Hammerstein–Wiener"}
#: Parameters each shape takes from ``*_parameters``, in order.
_PARAMETERS = {"deadzone": ("lower", "upper"), "saturation": ("lower", "upper"),
               "abs": ("center",), "power": ("exponent",),
               "polynomial": ("c1", "c2", "…"), "piecewise-linear": ("s0", "s1", "…")}


@dataclass(frozen=True)
class StaticCurve:
    """A fitted static block drawn over its input's range, with a ±2σ band."""

    block: str
    kind: str
    x: np.ndarray
    value: np.ndarray
    std: np.ndarray


@dataclass(frozen=True, eq=False, repr=False)
class BlockResult(IdentificationResult):
    """A block-oriented model identified from an experiment file, validated.

    The fields are those of
    :class:`~servoid.workflows.IdentificationResult` (``method`` is
    ``"hammerstein"``, ``"wiener"`` or ``"hammerstein-wiener"``; the
    estimate's model a :class:`~servoid.nonlinear.BlockModel`), and:

    Attributes
    ----------
    curves : tuple of StaticCurve
        The static blocks over their input's range, with their bands.
    """

    curves: tuple[StaticCurve, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``, the model described by its blocks."""
        out = super().to_dict()
        model = self.estimate.model
        out["model"] = {
            "type": "block", "structure": model.structure, "dt": model.dt,
            "offset": model.offset,
            "input_nonlinearity": _shape_dict(model.input_nonlinearity),
            "output_nonlinearity": _shape_dict(model.output_nonlinearity),
            "linear": model_dict(model.linear),
            # for servoid export --to json: the model file keeps the covariance
            "parameter_names": list(self.estimate.names),
            "covariance": np.asarray(self.estimate.covariance).tolist(),
        }
        return out

    def figures(self) -> dict[str, FigureWriter]:
        """Validation and residual plots per record, the static curves."""
        out = super().figures()
        if self.curves:
            out["static.png"] = partial(_plot_curves, self.curves, self.title)
        return out

    def _model_section(self, files: Mapping[str, Path]) -> Section:
        figures = (Figure.from_file(files["static.png"], "Fitted static curve(s) over the range "
                                    "their input covers, with ±2σ bands from the covariance"),) \
            if "static.png" in files else ()
        return Section("Model", paragraphs=(_model_text(self),),
                       tables=(parameter_table(self.estimate),), figures=figures)


def run(structure: str, spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> BlockResult:
    """Fit the block model and validate it on each validation record."""
    estimation, validations = spec.records()
    first = estimation if isinstance(estimation, Experiment) else estimation[0]
    role = options["input"]
    settings = _settings(options, set(spec.identify))
    with keyed({"nb": "[identify] nb", "nf": "[identify] nf", "nk": "[identify] nk",
                "n_poles": "[identify] n_poles", "n_zeros": "[identify] n_zeros",
                "max_iter": "[identify] max_iter", "tol": "[identify] tol"}), \
            warnings_as_notes() as notes:
        estimate = fit_block_retrying(
            estimation, structure, offset=options["offset"], input=role,
            output=options["output"], initial=options["initial"],
            max_iter=options["max_iter"], tol=options["tol"],
            multistart=options["multistart"], seed=options["seed"], **settings)
    if estimate.status != "ok":
        notes.append(f"the search ended with status: {estimate.status}")
    o = estimate.options
    orders = (f"nb = {o['nb']}, nf = {o['nf']}, nk = {o['nk']}" if o["linear"] == "oe" else
              f"continuous, {o['n_poles']} poles, {o['n_zeros']} zeros"
              + (f", delay {o['nk']} samples" if o["nk"] else ""))
    shapes = " / ".join(s for s in (o["input_nonlinearity"], o["output_nonlinearity"]) if s)
    title = f"{_TITLES[structure]} ({shapes}; {orders})"
    result = lti_result(spec, structure, estimate, title, validations, options,
                        notes=list(dict.fromkeys(notes)), truth=truth, modal=False,
                        result_type=BlockResult, records=estimation,
                        extra={"curves": _curves(estimate, first.signal(role)[:, 0])})
    assert isinstance(result, BlockResult)
    if result.truth:  # known values of the parameters this structure has, only
        kept = {k: v for k, v in result.truth.items() if k in estimate.names} or None
        result = dataclasses.replace(result, truth=kept)
    return result


# -- options -------------------------------------------------------------------------------------


def _settings(options: Mapping[str, Any], given: set[str]) -> dict[str, Any]:
    """fit_block's keywords from the options; a key the choice leaves unused is refused.

    ``given`` holds the keys the experiment file sets (defaults of unused
    keys are simply not passed on).
    """
    linear = options["linear"]
    used = ("nb", "nf", "nk") if linear == "oe" else ("n_poles", "n_zeros")
    for key in {"oe": ("n_poles", "n_zeros"), "tf": ("nb", "nf", "nk")}[linear]:
        if key in given:
            raise OptionError(
                f"[identify] {key} is not used by linear = \"{linear}\", which takes "
                f"{' and '.join(used)}; remove {key}, or choose linear = "
                f"\"{'oe' if linear == 'tf' else 'tf'}\"")
    settings: dict[str, Any] = {"linear": linear, **{k: options[k] for k in used}}
    for side in ("input", "output"):
        key = f"{side}_nonlinearity"
        if key not in options:
            continue  # this structure has no block on that side
        kind = options[key]
        settings[key] = _shape(options, side)
        for option, wants in ((f"{side}_breakpoints", "piecewise-linear"),
                              (f"{side}_degree", "polynomial")):
            if option in given and kind != wants:
                raise OptionError(f"[identify] {option} is for a {wants} shape and "
                                  f"{key} = \"{kind}\"; remove {option}")
        if f"{side}_degree" in given and options[f"{side}_parameters"] is not None:
            raise OptionError(f"[identify] {side}_degree and [identify] {side}_parameters both "
                              "set the polynomial's degree (one coefficient per power); give "
                              "one")
        # one shape per side can be free-scale (two are refused), so the side whose shape
        # is named hands its breakpoints or degree on
        if isinstance(settings[key], str):
            if kind == "piecewise-linear" and options[f"{side}_breakpoints"] is not None:
                settings["breakpoints"] = options[f"{side}_breakpoints"]
            if kind == "polynomial":
                settings["degree"] = options[f"{side}_degree"]
    return settings


def _shape(options: Mapping[str, Any], side: str) -> StaticNonlinearity | str:
    """The shape of one side from its name and optional start parameters."""
    kind = options[f"{side}_nonlinearity"]
    values = options[f"{side}_parameters"]
    if values is None:
        return kind
    key = f"[identify] {side}_parameters"
    expected = _PARAMETERS[kind]
    try:
        if kind in ("deadzone", "saturation", "abs", "power") and len(values) != len(expected):
            raise DataError(f"{key} for \"{kind}\" must hold {len(expected)} value(s) "
                            f"({', '.join(expected)}), got {len(values)}: {values}")
        if kind == "deadzone":
            return DeadZone(*values)
        if kind == "saturation":
            return Saturation(*values)
        if kind == "abs":
            return AbsoluteValue(values[0])
        if kind == "power":
            return SignedPower(values[0])
        if kind == "polynomial":
            return Polynomial(tuple(values))
        breakpoints = options[f"{side}_breakpoints"]
        if breakpoints is None:
            raise DataError(f"{key} for \"piecewise-linear\" are its slopes: give "
                            f"[identify] {side}_breakpoints too")
        return PiecewiseLinear(tuple(breakpoints), tuple(values))
    except ServoidError as exc:
        text = str(exc)
        if text.startswith(key):
            raise
        raise type(exc)(f"{key}: {text}") from None


def _numbers() -> Any:
    def check(value: Any, where: str, name: str) -> list[float]:
        return as_float_list(name, value, min_length=1, where=where)
    return check


def _side_options(side: str, default: str) -> tuple[Option, ...]:
    return (
        Option(f"{side}_nonlinearity", default, choice(SHAPES),
               f"shape of the {side} static block: " + ", ".join(SHAPES)),
        Option(f"{side}_parameters", None, optional(_numbers()),
               "start values of its parameters (deadzone, saturation: [lower, upper]; abs: "
               "[center]; power: [exponent]; polynomial: [c1, c2, …]; piecewise-linear: "
               "slopes); none: from the data"),
        Option(f"{side}_breakpoints", None, optional(_numbers()),
               "breakpoints of a piecewise-linear shape (increasing; none: quantiles of its "
               "input); refused for other shapes"),
        Option(f"{side}_degree", 3, integer(minimum=1, maximum=12),
               f"degree of a polynomial shape named without {side}_parameters; refused "
               "otherwise"),
    )


def _method(structure: str, summary: str) -> Method:
    sides = {"hammerstein": _side_options("input", "polynomial"),
             "wiener": _side_options("output", "polynomial"),
             "hammerstein-wiener": (*_side_options("input", "deadzone"),
                                    *_side_options("output", "polynomial"))}[structure]
    return Method(
        name=structure,
        summary=summary,
        options=(
            ROLE, OUTPUT, *sides,
            Option("linear", "oe", choice(("oe", "tf")),
                   'linear block: "oe" (discrete B/F: nb, nf, nk) or "tf" (continuous: '
                   "n_poles, n_zeros)"),
            Option("nb", 2, integer(minimum=1, maximum=50),
                   'B coefficients of a discrete linear block (linear = "oe" only)'),
            Option("nf", 2, integer(minimum=0, maximum=50),
                   'F order (poles) of a discrete linear block (linear = "oe" only)'),
            Option("nk", 1, integer(minimum=0),
                   'delay of a discrete linear block [samples] (linear = "oe" only)'),
            Option("n_poles", 2, integer(minimum=1, maximum=20),
                   'poles of a continuous linear block (linear = "tf" only)'),
            Option("n_zeros", None, optional(integer(minimum=0, maximum=20)),
                   'zeros of a continuous linear block (linear = "tf" only; none: n_poles − 1)'),
            Option("offset", False, boolean(), "fit a constant output offset"),
            Option("initial", "estimate", choice(("estimate", "zero")),
                   "initial state of the linear block in the fit: estimated or rest"),
            Option("multistart", 0, integer(minimum=0, maximum=1000),
                   "random starts tried when the others give no stable linear block"),
            Option("seed", 0, integer(minimum=0), "seed of the random starts"),
            Option("max_iter", 200, integer(minimum=1), "most iterations of the joint search"),
            Option("tol", 1e-10, number(positive=True), "relative tolerance of the search"),
            HORIZON,
        ),
        run=partial(run, structure),
        example=partial(open_loop, kind=structure, identify={"method": structure}),
    )


HAMMERSTEIN = _method("hammerstein", "Hammerstein model y = G(q)·f(u) + e: a static curve "
                      "(dead zone, saturation, …) before a linear block, jointly by output error")
WIENER = _method("wiener", "Wiener model y = g(G(q)·u) + e: a linear block before a static "
                 "curve (|x|, saturation, …), jointly by output error")
HAMMERSTEIN_WIENER = _method("hammerstein-wiener", "Hammerstein–Wiener model y = g(G(q)·f(u)) "
                             "+ e: static curves on both sides of a linear block")


# -- private ---------------------------------------------------------------------------------


def _shape_dict(shape: StaticNonlinearity | None) -> dict[str, Any] | None:
    if shape is None:
        return None
    out: dict[str, Any] = {"kind": shape.kind,
                           "parameters": dict(zip(shape.names, shape.parameters.tolist(),
                                                  strict=True))}
    if isinstance(shape, PiecewiseLinear):
        out["breakpoints"] = list(shape.breakpoints)
    return out


def _curves(estimate: Estimate, u: np.ndarray) -> tuple[StaticCurve, ...]:
    """Each static block over its input's range, ±σ by the delta method."""
    model = estimate.model
    try:
        _v, x, _ = model.signals(u)
    except ServoidError:
        return ()
    out = []
    prefixes = ("input.", "output.") if model.structure == "hammerstein-wiener" else ("", "")
    blocks = (("input", model.input_nonlinearity, u, prefixes[0]),
              ("output", model.output_nonlinearity, x, prefixes[1]))
    for block, shape, signal, prefix in blocks:
        if shape is None:
            continue
        index = [estimate.names.index(prefix + name) for name in shape.names]
        grid = np.linspace(float(np.min(signal)), float(np.max(signal)), 400)
        jac = shape.jacobian(grid)
        cov = estimate.covariance[np.ix_(index, index)]
        std = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", jac, cov, jac), 0.0, None))
        out.append(StaticCurve(block, shape.kind, grid, shape(grid), std))
    return tuple(out)


def _model_text(result: BlockResult) -> str:
    est = result.estimate
    o = est.options
    scale = ("the linear block's static gain is fixed to 1 (the static curve carries the gain)"
             if o.get("unit_gain") else "the static curve has unit slope (the linear block "
             "carries the gain)")
    return (f"{result.title} by output error (joint least squares over every parameter, the "
            f"linear block's initial state estimated) on {est.n_samples} samples; residual "
            f"variance {est.noise_variance:.4g}; status {est.status}; {o.get('nfev')} "
            f"evaluations. Scale convention: {scale}. Covariance σ̂²(JᵀJ)⁻¹ at the minimum, "
            "right for white output noise.")


def _plot_curves(curves: Sequence[StaticCurve], title: str, path: Path,
                 overwrite: bool) -> None:
    fig = new_figure((5.0 * len(curves), 3.6))
    for k, curve in enumerate(curves):
        ax = fig.add_subplot(1, len(curves), k + 1)
        ax.plot(curve.x, curve.value, color="C0", lw=1.5, label=f"{curve.kind}")
        ax.fill_between(curve.x, curve.value - 2 * curve.std, curve.value + 2 * curve.std,
                        color="C0", alpha=0.2, lw=0, label="±2σ")
        ax.set_xlabel(f"{curve.block} block input")
        ax.set_ylabel(f"{curve.block} block output")
        ax.set_title(f"{curve.block}: {curve.kind}")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, overwrite)
