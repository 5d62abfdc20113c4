"""``method = "pnlss"``: polynomial nonlinear state space grown from a linear model."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ConvergenceError, DataError, OptionError, ServoidError, ServoidWarning
from ..data import Experiment, ExperimentSet, ExperimentSpec
from ..report import Figure, Section, Table
from ._common import keyed, parameter_table, warnings_as_notes
from ._examples import open_loop
from ._lti import IdentificationResult, lti_result
from ._options import (
    HORIZON,
    OUTPUT,
    ROLE,
    choice,
    choices,
    integer,
    number,
    optional,
    orders,
    text,
)
from ._pnlss_start import AutoStart, choose_linear
from ._registry import FigureWriter, Method, Option

__all__ = ["METHOD", "PnlssResult"]

_KEYS = {name: f"[identify] {name}" for name in
         ("n_states", "degree", "monomials", "ridge", "prune", "linear", "plan",
          "max_iter", "holdout", "horizon", "weighting")}


@dataclass(frozen=True)
class Candidate:
    """One (n_states, degree) of a grid, scored by its free run on held-out data."""

    n_states: int
    degree: int
    n_parameters: int
    rms: float  # free-run RMS error on the held-out part [output unit]; inf: failed
    status: str
    linear_rms: float = np.nan  # the same for its linear part (E = F = 0) [output unit]
    kept: str = ""  # "nonlinear", "linear" or "the linear start" (see fit_pnlss)
    linear: str = ""  # its linear start (n4sid, oe, bla)


@dataclass(frozen=True, eq=False, repr=False)
class PnlssResult(IdentificationResult):
    """A PNLSS model from an experiment file, validated by free run.

    The fields are those of :class:`~servoid.workflows.IdentificationResult`
    plus ``grid`` (the candidates of a (n_states, degree) search, best
    first) and ``contribution`` (time, the full free run and the linear
    part's on the first validation record).
    """

    grid: tuple[Candidate, ...] = ()
    contribution: tuple[Any, ...] = field(default=(), repr=False)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``, with the model file record and the grid."""
        out = super().to_dict()
        out["model"] = self.estimate.model.to_dict()
        out["grid"] = [c.__dict__ for c in self.grid] or None
        out["linear_choice"] = self.estimate.options.get("linear_choice")
        share = self._share()
        out["nonlinear_share"] = None if share is None else share
        return out

    def _share(self) -> float | None:
        """RMS of the nonlinear terms' contribution over the RMS of the output's variation."""
        if not self.contribution:
            return None
        _, full, lin = self.contribution
        ok = np.isfinite(full) & np.isfinite(lin)
        if not ok.any():
            return None
        spread = float(np.std(full[ok]))
        return float(np.sqrt(np.mean((full[ok] - lin[ok]) ** 2)) / spread) if spread > 0 else 0.0

    def _headline(self) -> str:
        est = self.estimate
        o = est.options
        return (f"{self.title}: output {o['output']} from {', '.join(o['inputs'])} "
                f"({o['input']}); {est.parameters.size} parameters on {est.n_samples} samples, "
                f"simulation-error σ̂² = {est.noise_variance:.4g}")

    def _extra_lines(self) -> list[str]:
        o = self.estimate.options
        lines = [(f"  search: linear start RMS {o['linear_rms']:.4g} → "
                  f"{np.sqrt(o['cost']):.4g} after {o['iterations']} Levenberg–Marquardt "
                  f"iterations ({o['rejected']} steps rejected, {o['diverged_steps']} of them "
                  "diverged)")]
        if o.get("pruned"):
            lines.append(f"  pruned at α = {o['prune']:g}: {len(o['pruned'])} of "
                         f"{o['n_monomials']} monomials ({', '.join(o['pruned'])})")
        share = self._share()
        if share is not None:
            lines.append(f"  nonlinear terms: {100 * share:.3g} % of the output's RMS variation "
                         "on the first validation record")
        held = o.get("held_out")
        if held:
            lines.append(f"  held out ({held['samples']} samples): {held['why']}")
        if len(self.grid) > 1:
            lines.append("  (n_states, degree) by free-run RMS on the held-out data:")
            lines += [f"    {c.n_states}, {c.degree}: {c.rms:.4g} ({c.n_parameters} parameters; "
                      f"{c.linear} start; {c.status})" for c in self.grid]
        return lines

    def figures(self) -> dict[str, FigureWriter]:
        """The validation plots, the linear part's Bode and the nonlinear contribution."""
        out = super().figures()
        out["linear_bode.png"] = partial(_plot_linear, self)
        if self.contribution:
            out["nonlinear.png"] = partial(_plot_contribution, self)
        return out

    def _model_section(self, files: Mapping[str, Path]) -> Section:
        est = self.estimate
        o = est.options
        text = (f"PNLSS model (Paduart et al. 2010) with {o['n_states']} states and "
                f"{o['n_monomials']} monomials ({o['monomials']}, degree ≤ {o['degree']}, with "
                f"the constant) in both equations, on the signals normalised to zero mean and "
                f"unit variance. Started from a linear model ({o['linear']}), refined by output "
                f"error with E = F = 0, then all coefficients and the initial state together, "
                f"by Levenberg–Marquardt on the simulation error with the exact Jacobian "
                f"(sensitivity recursion); {o['iterations']} iterations, {o['rejected']} steps "
                f"rejected ({o['diverged_steps']} because the simulation diverged); "
                f"ridge {o['ridge']:g}{_pruned(o)}. Free-run RMS on the estimation data: linear "
                f"{o['linear_rms']:.4g}, PNLSS {np.sqrt(o['cost']):.4g}. The covariance is "
                "σ̂²(JᵀJ)⁺ with the similarity-transform directions left out.")
        refit = o.get("refit")
        if refit and refit.get("by"):
            text = (f"PNLSS model (Paduart et al. 2010) with {o['n_states']} states, on the "
                    f"signals normalised to zero mean and unit variance: started from a linear "
                    f"model ({o['linear']}), fitted with monomials of degree ≤ "
                    f"{refit['degree']} ({o['monomials']}) on {refit['fitted_samples']} "
                    f"samples, whose held-out part kept that linear start itself (E = F = 0); "
                    f"model choice then picked {refit['by']} among its linear candidates on "
                    f"all {refit['samples']} estimation samples ({refit['choice']['reason']}),"
                    f" and this model is it with E = F = 0 (free-run RMS on the estimation "
                    f"data {refit['rms_before']:.4g} → {refit['rms']:.4g}).")
        elif refit:
            text = (f"PNLSS model (Paduart et al. 2010) with {o['n_states']} states, on the "
                    f"signals normalised to zero mean and unit variance: started from a linear "
                    f"model ({o['linear']}), fitted with monomials of degree ≤ "
                    f"{refit['degree']} ({o['monomials']}) on {refit['fitted_samples']} "
                    f"samples, whose held-out part kept E = F = 0; that linear model was then "
                    f"refitted by output error on all {refit['samples']} estimation samples, "
                    f"from itself, by Levenberg–Marquardt on the simulation error with the "
                    f"exact Jacobian ({refit['iterations']} iterations; free-run RMS on the "
                    f"estimation data {refit['rms_before']:.4g} → {refit['rms']:.4g}). The "
                    "covariance is σ̂²(JᵀJ)⁺ with the similarity-transform directions left out.")
        text += _weighting(o.get("weighting_info"))
        held = o.get("held_out")
        if held:
            text += (f" Every accepted iterate was also run freely on {held['samples']} held-out "
                     f"samples (not fitted) and the one with the lowest RMS error there kept: "
                     f"{held['why']}. The output offset (the model's y_mean): "
                     + (f"{held['offset']}." if not refit else
                        "set so that the refit starts from the kept model's map "
                        "y = k + G(q)·u, its constant k included."))
        figures = []
        if "linear_bode.png" in files:
            figures.append(Figure.from_file(files["linear_bode.png"],
                                            "The PNLSS model's linear part (E = F = 0) against "
                                            "the linear model it started from"))
        # one paragraph per line of the model's equations (a paragraph joins lines)
        return Section("Model", paragraphs=(text, *str(est.model).splitlines()),
                       tables=(parameter_table(est, "A … F on the normalised signals; std from "
                                                    "σ̂²(JᵀJ)⁺"),),
                       figures=tuple(figures))

    def _extra_sections(self, files: Mapping[str, Path]) -> list[Section]:
        out = []
        share = self._share()
        if share is not None and "nonlinear.png" in files:
            out.append(Section(
                "Nonlinear terms",
                paragraphs=((f"Over the first validation record the nonlinear terms (E ζ, F η) "
                             f"change the free run by {100 * share:.3g} % of the output's RMS "
                             "variation: the full model's run against the same model with "
                             "E = F = 0, from the same initial state."),),
                figures=(Figure.from_file(files["nonlinear.png"],
                                          "Free run of the model and of its linear part, and "
                                          "their difference"),)))
        if len(self.grid) > 1:
            rows = tuple((str(c.n_states), str(c.degree), c.linear, str(c.n_parameters),
                          f"{c.linear_rms:.4g}", f"{c.rms:.4g}", c.status) for c in self.grid)
            share = 100 * self.estimate.options.get("holdout", 0.25)
            out.append(Section(
                "States and degree",
                paragraphs=((f"Each candidate fitted on the estimation data but its last "
                             f"{share:g} % and scored by its free-run RMS error on that held-out "
                             "part (initial state estimated); each search keeps its iterate "
                             "with the lowest held-out error, its linear start first, so a "
                             "candidate whose nonlinear terms do not pay there is its linear "
                             "part. With several linear starts, each order's linear model "
                             "(degree 1) from each start is scored there first and the better "
                             "start grows the nonlinear terms. The best candidate is the model; "
                             "it is not refitted (the held-out part stays its guard) unless it "
                             "kept its linear part (E = F = 0): then that linear model is "
                             "refitted by output error on all the estimation data. A candidate "
                             "that diverges on the held-out part is never chosen."),),
                tables=(Table(("n_states", "degree", "linear start", "parameters",
                               "linear part's held-out RMS",
                               "held-out RMS", "status"), rows, "Best first"),)))
        return out

    def _subtitle(self) -> str:
        return f"{self.title}, validated by free-run simulation on data not used for fitting"


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> PnlssResult:
    """Fit a PNLSS model (choosing states and degree from a grid) and validate it."""
    estimation, validations = spec.records()
    fitting = {**options, "_plan": _plan(spec, options)}
    if "auto" in _starts(options["linear"]):
        if options["linear"] == "auto" and "n_states" in (getattr(spec, "identify", None) or {}):
            raise OptionError('[identify] linear = "auto" starts from the linear model that '
                              "model choice picks, and the states are its order; n_states = "
                              f"{options['n_states']} cannot be given with it: remove "
                              'n_states, or give linear = "n4sid" (or "oe") to choose the '
                              "states on the held-out part")
        fitting["_auto"] = _auto_start(spec, estimation, options)
        if options["linear"] == "auto":
            fitting["n_states"] = fitting["_auto"].model.n_states
    states = _grid(fitting["n_states"])
    degrees = _grid(options["degree"])
    grid: tuple[Candidate, ...] = ()
    with keyed(_KEYS), warnings_as_notes() as notes:
        if options["holdout"] > 0:
            grid, estimate = _search(estimation, states, degrees, fitting)
        elif len(states) * len(degrees) > 1:
            raise OptionError("[identify] n_states or degree is a list (a grid), which is "
                              "chosen on held-out data, but holdout = 0 holds none out; give "
                              "holdout > 0 (e.g. 0.25) or single values")
        else:  # nothing held out to choose a start on: the first
            estimate = _fit(estimation, states[0], degrees[0],
                            {**fitting, "linear": _starts(options["linear"])[0]})
        held = estimate.options.get("held_out")
        by_choice = "linear_choice" in estimate.options  # grown from model choice's start
        if held and (held["kept"] == "linear" or (held["kept"] == "the linear start"
                                                  and (by_choice or
                                                       estimate.options["linear"] == "oe"))):
            # an output-error fit, E = F = 0, kept there: refit it on all the data (n4sid's
            # start kept means its refinement by output error did not pay there: no refit)
            estimate = (_refit_chosen(spec, estimation, estimate, fitting)
                        if held["kept"] == "the linear start" and by_choice else
                        _refit(estimation, estimate, fitting))
        estimate = replace(estimate, options={**estimate.options,
                                              "holdout": options["holdout"]})
    if grid and estimate.options.get("refit"):
        by = estimate.options["refit"].get("by")
        grid = (replace(grid[0], status=f"{grid[0].status}; " + (
            f"model choice's linear model on all the estimation data: {by}" if by else
            "refitted on all the estimation data")), *grid[1:])
    model = estimate.model
    contribution: tuple[Any, ...] = ()
    first = validations[0]
    try:
        u = np.asarray(first.signal(options["input"]), dtype=float)
        y = np.asarray(first[estimate.options["output"]], dtype=float)
        x0 = model.initial_state(y, u)
        full, lin = model.contribution(u, x0)
        contribution = (first.time, full, lin)
    except ServoidError:
        pass  # a record the model cannot run: the validation says why
    o = estimate.options
    title = (f"PNLSS (n_states = {o['n_states']}, degree = {o['degree']}, {o['monomials']} "
             f"monomials)")
    refit = o.get("refit")
    if refit:
        title = (f"PNLSS (n_states = {o['n_states']}, degree = {refit['degree']}, "
                 f"{o['monomials']} monomials), E = F = 0 kept on held-out data, that linear "
                 "model refitted on all the estimation data")
        if refit.get("by"):
            title = (f"PNLSS (n_states = {o['n_states']}, degree = {refit['degree']}, "
                     f"{o['monomials']} monomials), E = F = 0 kept on held-out data: the "
                     f"linear model model choice picks on all the estimation data, "
                     f"{refit['by']}")
    elif o.get("held_out") and o["held_out"]["kept"] != "nonlinear":
        title += ", E = F = 0 kept on held-out data"
    result = lti_result(spec, "pnlss", estimate, title, validations, options, notes=notes,
                        truth=truth, modal=False, result_type=PnlssResult, records=estimation,
                        extra={"grid": grid, "contribution": contribution},
                        how="Levenberg–Marquardt on the simulation error")
    assert isinstance(result, PnlssResult)
    return result


# -- private ------------------------------------------------------------------------------


def _fit(data: Experiment | ExperimentSet, n_states: int, degree: int,
         options: Mapping[str, Any], held: Experiment | ExperimentSet | None = None) -> Any:
    from ..nonlinear import fit_pnlss

    bla = options["linear"] == "bla"
    auto = options["linear"] == "auto"
    start = _bla_start(data, n_states, options) if bla else None
    if auto:
        start = options["_auto"].model
    est = fit_pnlss(data, n_states, degree, monomials=options["monomials"],
                    linear="n4sid" if bla or auto else options["linear"], initial=start,
                    ridge=options["ridge"], prune=options["prune"], input=options["input"],
                    output=options["output"], max_iter=options["max_iter"], held_out=held,
                    weighting=options["weighting"], plan=options["_plan"],
                    offset="start" if auto else None)
    if bla:
        est = replace(est, options={**est.options,
                                    "linear": f"BLA, ML fit in z of {n_states} poles"})
    elif auto:
        est = replace(est, options={**est.options, "linear": options["_auto"].text,
                                    "linear_choice": options["_auto"].record()})
    return est


def _refit(data: Experiment | ExperimentSet, kept: Any, options: Mapping[str, Any]) -> Any:
    """The linear model the held-out guard kept (E = F = 0), refitted by output error on
    all the estimation data (the held-out part included), from itself.

    Its held-out score was needed only to decide "linear"; the refit starts from the kept
    model's own input-output map, its offset included (y = k + G(q) u, with
    k = y_mean − G(1)·u_mean held), and no data are left out.  The kept model when the
    refit fails."""
    from ..nonlinear import fit_pnlss

    model = kept.model
    lin = model.linear_part()
    records = [data] if isinstance(data, Experiment) else list(data)
    u_all = np.concatenate([np.asarray(r.signal(options["input"]), dtype=float)
                            .reshape(r.n_samples, -1) for r in records])
    gain = np.asarray(lin.dc_gain(), dtype=float).reshape(-1)
    offset: float | None = float(model.y_mean - gain @ model.u_mean + gain @ u_all.mean(axis=0))
    if not np.isfinite(offset):
        offset = None  # a pure integrator: the output's mean, as fit_pnlss takes it
    o = kept.options
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            est = fit_pnlss(data, model.n_states, 1, monomials=o["monomials"], initial=lin,
                            input=options["input"], output=o["output"],
                            max_iter=options["max_iter"], offset=offset,
                            weighting=options["weighting"], plan=options["_plan"])
    except ServoidError as exc:
        held = {**o["held_out"], "why": f"{o['held_out']['why']}; its refit on all the "
                                        f"estimation data failed ({exc}), so it is as kept"}
        return replace(kept, options={**o, "held_out": held})
    before = _rms(model, records, options["input"], o["output"])
    after = float(np.sqrt(est.options["cost"]))
    held = {**o["held_out"], "why": (
        f"{o['held_out']['why']}; that linear model was then refitted by output error on "
        f"all {est.n_samples} estimation samples (the held-out part included: its score was "
        f"needed only to decide \"linear\"), from itself: free-run RMS on them "
        f"{before:.4g} → {after:.4g}")}
    refit = {"degree": o["degree"], "fitted_samples": kept.n_samples,
             "samples": est.n_samples, "rms_before": before, "rms": after,
             "iterations": est.options["iterations"]}
    return replace(est, options={**est.options, "held_out": held, "refit": refit,
                                 "linear": o["linear"], "linear_start": o["linear_start"],
                                 "offset": offset,
                                 **({"linear_choice": o["linear_choice"]}
                                    if "linear_choice" in o else {})})


def _rms(model: Any, records: Sequence[Experiment], role: str, output: str) -> float:
    """A model's free-run RMS error over records, each from its estimated initial state."""
    total, n = 0.0, 0
    for r in records:
        u = np.asarray(r.signal(role), dtype=float)
        y = np.asarray(r[output], dtype=float)
        ys = model.simulate(u, model.initial_state(y, u))
        total += float(np.sum((ys - y) ** 2))
        n += y.size
    return float(np.sqrt(total / n))


def _plan(spec: ExperimentSpec, options: Mapping[str, Any]) -> Any:
    """The multisine plan of ``linear = "bla"`` or ``weighting = "bla"`` (None otherwise)."""
    need = [f'{k} = "bla"' for k in ("linear", "weighting") if options[k] == "bla"]
    if not need:
        return None
    from ..signals import read_plan

    given = options["plan"]
    if given is not None:
        path = Path(given)
        return read_plan(path if path.is_absolute() else spec.base_dir / path)
    beside = spec.data_path.with_name(spec.data_path.stem + ".plan.json")
    if not beside.is_file():
        other = 'linear = "n4sid"' if need[0].startswith("linear") else 'weighting = "none"'
        raise DataError(f"[identify] {need[0]} needs the multisine plan: none beside the "
                        f"data file ({beside.name}); write the test with servoid excite "
                        "random-multisine (it writes the plan beside the data file), name it "
                        f"with [identify] plan, or use {other}")
    return read_plan(beside)


def _bla_start(data: Experiment | ExperimentSet, n_states: int,
               options: Mapping[str, Any]) -> Any:
    """The best linear approximation of a multisine record, fitted in z (ML) by n_states
    poles and zeros: the linear start, turned into state space by fit_pnlss."""
    from ..frequency import estimate_bla, fit_ml

    first = data if isinstance(data, Experiment) else data[0]
    bla = estimate_bla(first, options["_plan"], input=options["input"],
                       output=options["output"])
    return fit_ml(bla, n_states, n_states, domain="z")


def _weighting(info: Mapping[str, Any] | None) -> str:
    """The weighting, for the model section's text ("" when none)."""
    if not info:
        return ""
    return (f" The simulation error of each of the {info['periods']} whole periods of "
            f"{info['period']} samples was weighted line by line of its DFT by 1/σ² of the "
            f"output's noise, from the spread over the measured periods ({info['variance_dof']} "
            f"degrees of freedom a line after averaging {info['smoothing_lines']} neighbouring "
            f"lines); the weights, the noise's mean variance over the line's, ran from "
            f"{info['weight_min']:.3g} to {info['weight_max']:.3g}.")


def _pruned(o: Mapping[str, Any]) -> str:
    """The pruning, for the model section's text ("" when none)."""
    if not o.get("prune"):
        return ""
    gone = o.get("pruned") or []
    return (f"; pruning at α = {o['prune']:g} removed {len(gone)} of {o['n_monomials']} "
            f"monomials" + (f" ({', '.join(gone)})" if gone else ""))


def _starts(value: str | Sequence[str]) -> list[str]:
    """The linear starts to choose from (one: no choice)."""
    return [value] if isinstance(value, str) else list(value)


def _linear(value: Any, where: str, name: str) -> str | list[str]:
    """The linear option: one start, or a list of n4sid and oe chosen per order, and auto
    (model choice's linear model, its own order) beside them."""
    items = choices(("n4sid", "oe", "bla", "auto"))(value, where, name)
    if len(items) > 1 and "bla" in items:
        raise OptionError(f'{where} {name} = {items}: "bla" starts from the multisine test\'s '
                          'best linear approximation and is given alone; a list chooses '
                          'between "n4sid" and "oe" per order on the held-out part, and '
                          '"auto" beside them')
    return items[0] if len(items) == 1 else items


def _auto_start(spec: ExperimentSpec, estimation: Experiment | ExperimentSet,
                options: Mapping[str, Any]) -> AutoStart:
    """Model choice's linear model on PNLSS's fitted part (the estimation data but its
    held-out part, which stays the PNLSS search's guard), as a discrete state space."""
    if options["holdout"] > 0:
        fit_on, _ = _split(estimation, options["holdout"])
    else:
        fit_on = estimation
    return choose_linear(spec, fit_on, options)


def _refit_chosen(spec: ExperimentSpec, data: Experiment | ExperimentSet, kept: Any,
                  options: Mapping[str, Any]) -> Any:
    """``linear = "auto"`` whose search kept its linear start (E = F = 0): the nonlinear
    terms did not pay on the held-out part, so the model is the linear one model choice
    picks on all the estimation data (as ``method = "auto"`` would return among its linear
    candidates), as a PNLSS model with E = F = 0 and the same response.  The output-error
    refit of the kept start (:func:`_refit`) when that fails."""
    from ..nonlinear import fit_pnlss

    segments = (data,) if isinstance(data, Experiment) else tuple(data)
    o = kept.options
    try:
        whole = choose_linear(spec, data, options)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            est = fit_pnlss(data, whole.model.n_states, 1, monomials=o["monomials"],
                            initial=whole.model, input=options["input"], output=o["output"],
                            max_iter=0, offset="start", weighting=options["weighting"],
                            plan=options["_plan"])
    except ServoidError:
        return _refit(data, kept, options)
    before = _rms(kept.model, list(segments), options["input"], o["output"])
    after = _rms(est.model, list(segments), options["input"], o["output"])
    held = {**o["held_out"], "why": (
        f"{o['held_out']['why']}; the nonlinear terms did not pay there, so the model is "
        f"the linear one model choice picks on all {whole.samples} estimation samples, "
        f"{whole.label} ({whole.reason}): free-run RMS on them {before:.4g} → {after:.4g}")}
    refit = {"degree": o["degree"], "fitted_samples": kept.n_samples,
             "samples": est.n_samples, "rms_before": before, "rms": after,
             "iterations": 0, "by": whole.label, "choice": whole.record()}
    return replace(est, options={**est.options, "held_out": held, "refit": refit,
                                 "linear": o["linear"], "linear_choice": o["linear_choice"],
                                 "linear_start": o["linear_start"]})


def _degree(value: Any, where: str, name: str) -> int | list[int]:
    """The degree option: an order from 1 to 6 (the monomials fit_pnlss forms), or a list."""
    degrees = orders(1)(value, where, name)
    if max(_grid(degrees)) > 6:
        raise OptionError(f"{where} {name} = {value}: the monomials' degree goes from 1 to 6; "
                          "give a lower degree (3 covers a cubic curve)")
    return degrees


def _grid(value: int | Sequence[int]) -> list[int]:
    return [value] if isinstance(value, int) else list(dict.fromkeys(value))


def _holdout(value: Any, where: str, name: str) -> float:
    """The holdout option: 0 (none) or a share below 1."""
    share = number(nonneg=True)(value, where, name)
    if share >= 1:
        raise OptionError(f"{where} {name} = {share:g} is the share of the estimation data held "
                          "out: 0 (none) or below 1, e.g. 0.25")
    return share


def _split(data: Experiment | ExperimentSet, share: float
           ) -> tuple[Experiment | ExperimentSet, Experiment]:
    """(fitted, held out): the last record whole when there are several, else the last
    `share` of the one record."""
    records = [data] if isinstance(data, Experiment) else list(data)
    if len(records) > 1:
        fit_on: Any = ExperimentSet(records[:-1]) if len(records) > 2 else records[0]
        return fit_on, records[-1]
    whole = records[0]
    cut = round(whole.n_samples * (1 - share))
    if cut < 20 or whole.n_samples - cut < 20:
        raise DataError(f"[identify] holdout = {share:g} of {whole.n_samples} samples leaves "
                        "fewer than 20 to fit or to hold out; record more data or change "
                        "holdout")
    return whole.slice(0, cut), whole.slice(cut, None)


def _search(data: Experiment | ExperimentSet, states: Sequence[int], degrees: Sequence[int],
            options: Mapping[str, Any]) -> tuple[tuple[Candidate, ...], Any]:
    """Fit every (n_states, degree) on the fitted part, each search guarded by the held-out
    part; the candidates best first, and the best one's estimate."""
    fit_on, held = _split(data, options["holdout"])
    starts = [s for s in _starts(options["linear"]) if s != "auto"]
    auto = options.get("_auto")  # model choice's start: its own order, beside the others
    rows: list[Candidate] = []
    fits: dict[tuple[int, int, str], Any] = {}
    single = len(states) * len(degrees) * len(starts) + (len(degrees) if auto else 0) == 1

    def candidate(n: int, d: int, start: str) -> float:
        """Fit one candidate, add its row; its held-out RMS (inf: failed or diverged)."""
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ServoidWarning)
                est = _fit(fit_on, n, d, {**options, "linear": start}, held)
        except ServoidError as exc:
            if single or isinstance(exc, OptionError):
                raise  # nothing to choose instead, or a wrong option: say it as it is
            rows.append(Candidate(n, d, 0, np.inf, f"failed: {exc}"[:120], linear=start))
            return np.inf
        h = est.options["held_out"]
        finite = bool(np.isfinite(h["chosen"]))
        status = ("diverged on held-out" if not finite else
                  {"nonlinear": "nonlinear terms kept", "linear": "linear part kept "
                   "(E = F = 0)", "the linear start": "linear start kept (E = F = 0)"}
                  [h["kept"]])
        label = auto.label if start == "auto" else start
        rows.append(Candidate(n, d, est.parameters.size, h["chosen"] if finite else np.inf,
                              status, h["linear"], h["kept"], label))
        if finite:
            fits[n, d, label] = est
        return float(h["chosen"]) if finite else np.inf

    for n in states if starts else ():
        start = starts[0]
        if len(starts) > 1:
            # each start's linear model of this order (degree 1: E = F = 0, refined by output
            # error), scored on the held-out part; the better start grows the nonlinear terms
            scores = [candidate(n, 1, s) for s in starts]
            start = starts[int(np.argmin(scores))]
        for d in degrees:
            if d > 1 or len(starts) == 1:
                candidate(n, d, start)
    for d in degrees if auto else ():
        candidate(auto.model.n_states, d, "auto")
    rows.sort(key=lambda c: (c.rms, c.n_parameters))
    if not fits:
        raise ConvergenceError("every PNLSS candidate failed or its free run diverged on the "
                               f"held-out part ({'; '.join(sorted({c.status for c in rows}))}); "
                               "lower n_states or degree, or try linear = \"oe\"")
    best = rows[0]
    rows[0] = replace(best, status=f"chosen: lowest held-out RMS; {best.status}")
    return tuple(rows), fits[best.n_states, best.degree, best.linear]


def _plot_linear(result: PnlssResult, path: Path, overwrite: bool) -> None:
    from ..models import StateSpace
    from ..report import plot_bode

    model = result.estimate.model
    o = result.estimate.options
    start = o["linear_start"]
    named = o.get("linear_choice", {}).get("chosen", o["linear"])
    models = {"PNLSS linear part": model.linear_part().to_tf(),
              f"linear start ({named})": StateSpace(
                  start["A"], start["B"], start["C"], start["D"], dt=model.dt).to_tf()}
    n = result.estimate.n_samples
    plot_bode(models, path, f_min=max(1.0 / (n * model.dt), 1e-6),
              title=f"{result.title}: linear part", overwrite=overwrite)


def _plot_contribution(result: PnlssResult, path: Path, overwrite: bool) -> None:
    from ..report import new_figure, save_figure

    t, full, lin = result.contribution
    unit = result.estimate.model.output_unit
    fig = new_figure((8, 5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, full, lw=0.8, label="PNLSS free run")
    ax1.plot(t, lin, lw=0.8, label="its linear part (E = F = 0)")
    ax1.set_ylabel(f"output [{unit}]" if unit else "output")
    ax1.legend(loc="upper right", fontsize=8)
    ax2.plot(t, full - lin, lw=0.8, color="C3")
    ax2.set_ylabel("nonlinear terms")
    ax2.set_xlabel("time [s]")
    ax1.set_title("The nonlinear terms' contribution over the first validation record")
    save_figure(fig, path, overwrite)


METHOD = Method(
    name="pnlss",
    summary="polynomial nonlinear state space x⁺ = Ax + Bu + Eζ(x, u), y = Cx + Du + Fη(x, u) "
            "from a linear start, by Levenberg–Marquardt on the simulation error; states and "
            "degree from a grid on held-out data",
    options=(
        ROLE,
        OUTPUT,
        Option("n_states", 2, orders(1),
               "number of states (a list: a grid, chosen on the last quarter of the "
               "estimation data)"),
        Option("degree", 3, _degree,
               "highest degree of the monomials ζ = η (1: linear; a list: a grid as for "
               "n_states)"),
        Option("monomials", "full", choice(("full", "state", "input")),
               "monomials of states and inputs (full), of the states (state) or of the inputs "
               "(input)"),
        Option("linear", ["n4sid", "auto"], _linear,
               "the linear start: n4sid, OE turned into state space, the best linear "
               "approximation of a multisine test (bla: its ML fit in z; needs the plan), or "
               "auto: the linear model model choice picks on the fitted part (its order, not "
               "n_states); a list grows the nonlinear terms from each (n4sid and oe: the "
               "better per order) and keeps the lowest held-out RMS"),
        Option("plan", None, optional(text()),
               'the multisine plan file of linear = "bla" and weighting = "bla" (default: '
               "<data file>.plan.json beside it)"),
        Option("weighting", "none", choice(("none", "bla")),
               "the simulation error as it is (none), or per DFT line of each measured period "
               "weighted by 1/σ² of the output's noise from the spread over periods (bla: a "
               "multisine test with its plan, ≥ 2 periods per realisation)"),
        Option("ridge", 0.0, number(nonneg=True),
               "weight α of the penalty α·N·‖(E, F)‖² on the nonlinear coefficients"),
        Option("prune", 0.0, number(nonneg=True),
               "significance level α of the pruning: monomials whose E column and F entry the "
               "Wald test cannot tell from zero at α are removed and the rest refitted "
               "(0: none)"),
        Option("max_iter", 100, integer(minimum=0, maximum=10000),
               "most Levenberg–Marquardt iterations per stage"),
        Option("holdout", 0.25, _holdout,
               "share of the estimation data held out (the last record when there are "
               "several): the search keeps its iterate with the lowest free-run error there, "
               "never worse than its linear start, and a grid is chosen there (0: fit on all "
               "of it, unguarded)"),
        HORIZON,
    ),
    run=run,
    example=partial(open_loop, kind="wiener",
                    identify={"method": "pnlss", "n_states": 2, "degree": 3}),
)
