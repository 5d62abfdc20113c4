"""Rigid axis with friction: a closed-loop record → M, Fv, Fc and a report.

The workflow of ``[identify] method = "inverse-dynamics"``: inverse-model
least squares (IDIM-LS, symmetric and asymmetric friction), the identified
axis simulated in its known cascaded loop, an optional closed-loop
output-error refinement, an optional linear model from the plant input to
the position for comparison, and a cross-check that fits on the
estimation part of ``[split]`` and simulates the held-back part.
Reference for the method and the EMPS data: Janot, Gautier, Brunot,
*Data Set and Reference Models of EMPS*, 2019.

Cross-test. With ``[validation] file`` (then no ``[split]``) every
estimate is scored on each validation record as well: the inverse model's
relative error on that record, processed by the same pipeline, and the
closed-loop simulation errors of position and force.

Loop inputs. ``[loop] disturbance`` names a channel holding a measured
force [N] on the axis (e.g. the EMPS force pulses, gtau times the pulse
voltage), ``disturbance_at`` (``"drive"`` or ``"load"``) where it enters,
and ``reference_offset`` [m] a constant added to the reference; every
closed-loop simulation and the refinement use them. A record whose file
lacks the disturbance channel (a record without pulses) gets zero there,
and the run's notes say so.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ... import __version__
from ..._checks import as_float, as_int_list, as_mapping, read_json
from ..._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    OptionError,
    ServoidWarning,
)
from ...data import Experiment, ExperimentSpec
from ...estimate import Estimate, fit_arx
from ...report import (
    Conditions,
    Figure,
    Page,
    Section,
    Table,
    Verdict,
    plot_force_fit,
    plot_friction,
    plot_linear,
    plot_loop,
)
from ...validate import relative_error, simulate_from_data
from ...workflows._common import parameter_table, report_options
from ...workflows._options import boolean, choice, choices, integer, number, optional, text
from ...workflows._registry import FigureWriter, Method, Option, TableSchema
from ...workflows._summary import Displayed, RecordSummary, summary_of
from ...workflows._verdict import loop_verdict, record_conditions
from ._axis import CascadeController, RigidAxis, simulate_rigid_loop
from ._inverse import (
    FRICTION_MODELS,
    INVERSE_PIPELINES,
    fit_closed_loop_oe,
    fit_inverse_dynamics,
    inverse_dynamics_regression,
)

__all__ = ["LOOP", "METHOD", "METHODS", "InverseDynamicsIdentification",
           "controller_from_table"]

_LOOP_KEYS = ("kp", "kv", "gtau", "saturation")
_DISTURBANCE_AT = ("drive", "load")
# settings that only pipeline = "servoid" takes (the published one fixes them)
_SERVOID_ONLY = ("decimation_filter", "differentiation", "trim")


@dataclass(frozen=True, eq=False, repr=False)
class InverseDynamicsIdentification(Displayed):
    """IDIM-LS, closed-loop checks and refinement of a rigid axis.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    controller : CascadeController
        The known loop.
    estimates : mapping of str to Estimate
        ``"idim-ls <model>"`` per friction model, ``"closed-loop-oe <model>"`` if refined.
    loop_errors : mapping of str to mapping
        Per estimate: relative errors [%] of the simulated position and force.
    linear : mapping or None
        Linear model from plant input to position: orders and relative errors.
    holdout : mapping or None
        Per method: closed-loop relative errors on the held-back part of a fit on the rest.
    validation : mapping or None
        Cross-test, per record then per estimate: ``inverse`` (relative
        error of the inverse model on that record [%]) and the closed-loop
        relative errors; the estimation record comes first.
    loop_inputs : mapping
        ``[loop]`` disturbance channel, where it enters, reference offset.
    published : mapping or None
        Reference values to compare with (``[report] truth``).
    folder : pathlib.Path or None
        The results folder, if written.
    files : tuple of pathlib.Path
        The files written.
    notes : tuple of str
        Remarks for the reader.
    data : Experiment or None
        The record identified (for the figures).
    options : mapping
        The ``[identify]`` options used.
    records : tuple of Experiment
        The validation records (for the figures).
    conditions : tuple of Conditions
        Rate, length, excitation and band of each record.
    """

    spec: ExperimentSpec
    controller: CascadeController
    estimates: Mapping[str, Estimate]
    loop_errors: Mapping[str, Mapping[str, float]]
    linear: Mapping[str, Any] | None = None
    holdout: Mapping[str, Mapping[str, float]] | None = None
    validation: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None
    loop_inputs: Mapping[str, Any] = field(default_factory=dict)
    published: Mapping[str, Any] | None = None
    folder: Path | None = None
    files: tuple[Path, ...] = ()
    notes: tuple[str, ...] = field(default=())
    data: Experiment | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    records: tuple[Experiment, ...] = ()
    conditions: tuple[Conditions, ...] = ()
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    def verdict(self) -> Verdict:
        """Closed-loop simulation of data the fit did not use, estimate by estimate."""
        return loop_verdict(self)

    def summary(self) -> RecordSummary:
        """The primary IDIM-LS estimate's M, Fv, Fc (…) with σ and intervals, the decision."""
        return summary_of("inverse-dynamics", self.estimate.table(0.95), self.verdict(),
                          notes=self.notes)

    def models(self) -> dict[str, Any]:
        """The rigid axis of each estimate (``"idim-ls symmetric"``, …)."""
        return {key: est.model for key, est in self.estimates.items()}

    @property
    def estimate(self) -> Estimate:
        """The primary IDIM-LS estimate (first friction model)."""
        return next(iter(self.estimates.values()))

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        out: dict[str, Any] = {
            "servoid_version": __version__,
            "method": "inverse-dynamics",
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": self.digest(self.spec.data_path),
            "controller": {"kp": self.controller.kp, "kv": self.controller.kv,
                           "gtau": self.controller.gtau,
                           "saturation": self.controller.saturation},
            "estimates": {},
            "linear": {k: v for k, v in self.linear.items() if k != "simulated"}
            if self.linear else None,
            "holdout": {k: dict(v) for k, v in self.holdout.items()} if self.holdout else None,
            "loop_inputs": dict(self.loop_inputs),
            "validation": {rec: {k: dict(v) for k, v in scores.items()}
                           for rec, scores in self.validation.items()}
            if self.validation else None,
            "published": dict(self.published) if self.published else None,
            "notes": list(self.notes),
            "verdict": self.verdict().to_dict(),
            "summary": self.summary().to_dict(),
        }
        for key, est in self.estimates.items():
            entry = est.to_dict()
            entry["loop_relative_error"] = dict(self.loop_errors[key])
            entry["comparison"] = self._compare(key, est)
            out["estimates"][key] = entry
        return out

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        out = [self.spec.data_path, *self.spec.validation_paths]
        if self.spec.source:
            out.append(Path(self.spec.source))
        truth = report_options(self.spec.report).get("truth")
        if truth:
            out.append(self.spec.base_dir / truth)
        return tuple(out)

    def figures(self) -> dict[str, FigureWriter]:
        """Force fit, friction, closed loop and the linear comparison."""
        out: dict[str, FigureWriter] = {
            "force_fit.png": partial(_plot_force_fit, self),
            "friction.png": partial(_plot_friction, self),
            "closed_loop.png": partial(_plot_loop, self),
        }
        if self.linear:
            out["linear.png"] = partial(_plot_linear, self)
        for k in range(len(self.records)):
            out[f"validation_loop_{k + 1}.png"] = partial(_plot_loop, self, record=k)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        return _page(self, files)

    def _compare(self, key: str, est: Estimate) -> dict[str, Any] | None:
        ref = (self.published or {}).get(key.split(" ")[-1])
        if not isinstance(ref, Mapping):
            return None
        rows: dict[str, Any] = {}
        for name, value, std in zip(est.names, est.parameters, est.std, strict=True):
            if name in ref.get("parameters", {}):
                pub = ref["parameters"][name]
                rows[name] = {"value": float(value), "std": float(std),
                              "published": pub.get("value"), "published_std": pub.get("std"),
                              "difference_percent": 100.0 * (value / pub["value"] - 1.0)}
        return {"parameters": rows, "relative_error": est.options.get("relative_error"),
                "published_relative_error": ref.get("relative_error")}

    def __str__(self) -> str:
        lines = [f"inverse-dynamics identification of {self.spec.source or self.spec.file}"]
        for key, est in self.estimates.items():
            errs = self.loop_errors[key]
            extra = (f", IDIM relative error {est.options['relative_error']:.4g} %"
                     if "relative_error" in est.options and est.method == "idim-ls" else "")
            lines.append(f"  {key}{extra}; closed loop: position {errs['position']:.4g} %, "
                         f"force {errs['force']:.4g} %")
            comparison = self._compare(key, est) or {"parameters": {}}
            for row in est.table():
                pub = comparison["parameters"].get(row.name)
                ref = "" if pub is None else (f"   published {pub['published']:.6g}"
                                              f" ({pub['difference_percent']:+.2f} %)")
                lines.append(f"    {row.name:<7} {row.value:>10.6g} ± {row.std:<8.2g} "
                             f"[{row.ci_low:.6g}, {row.ci_high:.6g}] {row.unit}{ref}")
        if self.linear:
            lines.append(f"  linear {self.linear['structure']}: simulation relative error "
                         f"{self.linear['relative_error']:.3g} % (position)")
        if self.holdout:
            for key, errs in self.holdout.items():
                lines.append(f"  held-back closed loop, {key}: position {errs['position']:.4g} %,"
                             f" force {errs['force']:.4g} %")
        for record, scores in (self.validation or {}).items():
            lines.append(f"  cross-test on {record} (inverse model; closed loop from the "
                         "measured state):")
            for key, errs in scores.items():
                lines.append(f"    {key:<26} inverse {errs['inverse']:.4f} %; position "
                             f"{errs['position']:.4g} %, force {errs['force']:.4f} %")
        lines += [f"  note: {n}" for n in self.notes]
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)


def controller_from_table(
    table: Mapping[str, Any], notes: Mapping[str, Any] | None = None
) -> CascadeController:
    """Build the EMPS-type cascade controller from ``[loop]``.

    Keys: ``kp`` [1/s], ``kv`` [V/(m/s)], ``gtau`` [N/V], ``saturation`` [V]
    (default 10). A missing gain is taken from the data file's scalars
    (``notes``) of the same name, if there. The loop-input keys
    ``disturbance``, ``disturbance_at`` and ``reference_offset`` are
    allowed and read by the workflow, not here (every key: :data:`LOOP`).

    Parameters
    ----------
    table : mapping
        The ``[loop]`` table.
    notes : mapping, optional
        Scalars read from the data file.

    Returns
    -------
    CascadeController
        The known loop.
    """
    return _controller(LOOP.parse(table, "inverse-dynamics"), notes)


def _controller(loop: Mapping[str, Any], notes: Mapping[str, Any] | None) -> CascadeController:
    """The cascade of a checked ``[loop]``, a gain it leaves out taken from the file's scalars."""
    notes = {} if notes is None else as_mapping("notes", notes)
    values: dict[str, float] = {}
    for key in _LOOP_KEYS:
        if loop[key] is not None:
            values[key] = loop[key]  # checked by LOOP
            continue
        value = notes.get(key, 10.0 if key == "saturation" else None)
        if value is None:
            raise DataError(
                f"[loop] {key} is needed for the closed-loop simulation and is neither in the "
                "experiment file nor a scalar of the data file; add it under [loop]"
            )
        values[key] = as_float(key, value, positive=True, finite=key != "saturation",
                               where="data file scalar")
    return CascadeController(values["kp"], values["kv"], values["gtau"], values["saturation"])


def _positive(finite: bool = True) -> Any:
    def check(value: Any, where: str, name: str) -> float:
        return as_float(name, value, positive=True, finite=finite, where=where)
    return check


#: ``[loop]`` of the rigid axis: its cascade (u = kv·(kp·(r − q) − q̇), force gtau·u within
#: ±saturation) and what enters the loop besides the reference.
LOOP = TableSchema("loop", (
    Option("kp", None, optional(_positive()),
           "position gain [1/s]; none: the data file's scalar kp"),
    Option("kv", None, optional(_positive()),
           "velocity gain [V/(m/s)]; none: the data file's scalar kv"),
    Option("gtau", None, optional(_positive()),
           "drive gain [N/V]; none: the data file's scalar gtau"),
    Option("saturation", None, optional(_positive(finite=False)),
           "drive voltage limit [V]; none: the data file's scalar, else 10"),
    Option("disturbance", None, optional(text()),
           "a channel holding a measured force on the axis [N] (unit N), added in every "
           "closed-loop simulation"),
    Option("disturbance_at", "drive", choice(_DISTURBANCE_AT), "where the disturbance enters"),
    Option("reference_offset", 0.0, number(unit="m"), "constant added to the reference [m]"),
), help="the known cascade and the loop's other inputs")


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, Any] | None) -> InverseDynamicsIdentification:
    """Run the rigid-axis identification an experiment file asks for.

    ``[identify]`` keys: see :data:`METHOD` (``servoid methods
    inverse-dynamics``); ``[loop]``: see :func:`controller_from_table`
    and the module notes. ``truth`` (or ``[report] truth``, a JSON file)
    holds published reference results to compare with.
    """
    options = _checked(options)
    loop = _loop_inputs(spec, options["[loop]"])
    notes: list[str] = []
    data = _load_record(spec, None, loop, notes)
    records = tuple(_load_record(spec, path, loop, notes) for path in spec.validation_paths)
    if notes and len(notes) == 1 + len(records):
        raise DataError(
            f"[loop] disturbance = {loop['disturbance']!r}: no record has that channel's source "
            "in its file; check its [channels] entry, or remove the key")
    controller = _controller(options["[loop]"], data.notes)
    published = truth if truth is not None else _published_from_spec(spec)
    channels = {k: options[k] for k in ("position", "force")}
    idim = _idim_settings(options)
    estimates: dict[str, Estimate] = {}
    for model in options["model"]:
        estimates[f"idim-ls {model}"] = fit_inverse_dynamics(data, model=model, **channels, **idim)
    if options["refine"]:
        for model in options["model"]:
            start = estimates[f"idim-ls {model}"]
            estimates[f"closed-loop-oe {model}"] = fit_closed_loop_oe(
                data, controller, start, output=options["refine_output"],
                reference=options["reference"], integration=options["integration"],
                **channels, **loop)
    loop_errors = {key: _loop_errors(data, controller, est.model, options, loop)
                   for key, est in estimates.items()}
    linear = _linear(data, options) if options["linear"] else None
    holdout = None
    if options["holdout"] and not records:
        holdout = _holdout(spec, data, controller, options, channels, idim, loop)
    validation = None
    if records:
        names = (spec.data_path.name, *(p.name for p in spec.validation_paths))
        if len(set(names)) < len(names):  # same file name in two folders: as written
            names = (spec.file, *spec.validation.files)
        validation = {name: _cross_test(rec, controller, estimates, options, loop)
                      for name, rec in zip(names, (data, *records), strict=True)}
    notes += _notes(estimates, loop_errors)
    return InverseDynamicsIdentification(spec, controller, estimates, loop_errors, linear,
                                         holdout, validation, loop, published,
                                         notes=tuple(notes), data=data, options=options,
                                         records=records,
                                         conditions=_conditions(spec, data, records, holdout))


def _conditions(spec: ExperimentSpec, data: Experiment, records: tuple[Experiment, ...],
                holdout: Any) -> tuple[Conditions, ...]:
    """The records' conditions: the record fitted and what was held back."""
    name = spec.data_path.name
    if holdout:  # the reported estimates use the whole record; the check refits the first part
        held = spec.split_data(data)[1]
        return (record_conditions(data, f"estimation: {name}"),
                record_conditions(held, f"validation: {name}, held-back part (checked on a "
                                  "fit of the first part)"))
    return (record_conditions(data, f"estimation: {name}"),
            *(record_conditions(r, f"validation: {p.name}")
              for p, r in zip(spec.validation_paths, records, strict=False)))


# -- steps ------------------------------------------------------------------------------------


def _checked(options: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(options)
    orders = out["linear_orders"]
    if isinstance(orders, (list, tuple)) and len(orders) != 3:
        raise DataError(f"[identify] linear_orders must be [na, nb, nk], got {list(orders)!r}")
    orders = as_int_list("linear_orders", orders, length=3, minimum=0, where="[identify]")
    if orders[1] < 1:
        raise DataError(f"[identify] linear_orders = [na, nb, nk] needs nb >= 1, got {orders!r}")
    out["linear_orders"] = orders
    if out["pipeline"] == "published":
        fixed = [k for k in _SERVOID_ONLY if out[k] is not None]
        if fixed:
            raise OptionError(
                f"[identify] {', '.join(fixed)}: only pipeline = \"servoid\" takes "
                f"{'this setting' if len(fixed) == 1 else 'these settings'}; pipeline = "
                "\"published\" is the reference's MATLAB recipe exactly. Remove the key(s), or "
                "set pipeline = \"servoid\"")
    return out


def _idim_settings(options: Mapping[str, Any]) -> dict[str, Any]:
    """The fit_inverse_dynamics keywords of a run (or of an estimate's options)."""
    out = {k: options[k] for k in ("pipeline", "cutoff", "order", "decimation")}
    if options["pipeline"] == "servoid":
        out.update({k: options.get(k) for k in _SERVOID_ONLY})
    return out


def _loop_inputs(spec: ExperimentSpec, table: Mapping[str, Any]) -> dict[str, Any]:
    """The loop's other inputs of a checked ``[loop]``, the disturbance held to [channels]."""
    name = table["disturbance"]
    if name is not None:
        declared = {ch.name: ch for ch in spec.channels}
        if name not in declared:
            raise DataError(
                f"[loop] disturbance = {name!r} is not a channel of [channels] "
                f"({', '.join(declared)}); declare it as [channels.{name}] with its source, "
                "gain (to newtons) and unit = \"N\"")
        unit = declared[name].unit
        if unit not in (None, "", "N"):
            raise DataError(
                f"[loop] disturbance = {name!r} has unit {unit!r}, but the disturbance is a "
                f"force [N]; give [channels.{name}] the gain to newtons (for a voltage added to "
                "the drive: gain = gtau) and unit = \"N\"")
    return {"disturbance": name, "disturbance_at": str(table["disturbance_at"]),
            "reference_offset": table["reference_offset"]}


def _load_record(spec: ExperimentSpec, path: Path | None, loop: Mapping[str, Any],
                 notes: list[str]) -> Experiment:
    """Read a record; one without the disturbance channel's source gets zeros there."""
    name = loop["disturbance"]
    try:
        return spec.load(path)
    except ChannelError:
        if name is None:
            raise
    reduced = replace(spec, channels=tuple(ch for ch in spec.channels if ch.name != name))
    exp = reduced.load(path)  # raises if something else is missing too
    source = next(ch.source for ch in spec.channels if ch.name == name)
    notes.append(f"{Path(path or spec.data_path).name} has no {source!r}: its disturbance "
                 f"{name!r} is taken as zero (a record without pulses)")
    return exp.add_channel(name, np.zeros(exp.n_samples), role="side", unit="N")


def _simulate(data: Experiment, controller: CascadeController, axis: RigidAxis,
              options: Mapping[str, Any], loop: Mapping[str, Any],
              from_rest: bool = False) -> tuple[Any, str, str, str]:
    r_name = options["reference"] or _only(data, "r")
    q_name = options["position"] or _only(data, "y")
    f_name = options["force"] or ("force" if "force" in data.names else _only(data, "u"))
    q = data[q_name]
    # from the measured state, or (as the reference seems to) at rest on the reference
    q0, v0 = (None, 0.0) if from_rest else (float(q[0]), float((q[1] - q[0]) / data.dt))
    dist = None if loop["disturbance"] is None else data[loop["disturbance"]]
    sim = simulate_rigid_loop(axis, controller, data[r_name], data.dt, q0=q0, v0=v0,
                              integration=options["integration"], disturbance=dist,
                              disturbance_at=loop["disturbance_at"],
                              reference_offset=loop["reference_offset"])
    return sim, r_name, q_name, f_name


def _loop_errors(data: Experiment, controller: CascadeController, axis: RigidAxis,
                 options: Mapping[str, Any], loop: Mapping[str, Any]) -> dict[str, float]:
    sim, _, q_name, f_name = _simulate(data, controller, axis, options, loop)
    rest = _simulate(data, controller, axis, options, loop, from_rest=True)[0]
    q, f = data[q_name], data[f_name]
    return {"position": float(relative_error(q, sim.position)),
            "force": float(relative_error(f, sim.force)),
            "position_from_rest": float(relative_error(q, rest.position)),
            "force_from_rest": float(relative_error(f, rest.force)),
            "saturated_fraction": sim.saturated}


def _cross_test(record: Experiment, controller: CascadeController,
                estimates: Mapping[str, Estimate], options: Mapping[str, Any],
                loop: Mapping[str, Any]) -> dict[str, dict[str, float]]:
    """Every estimate scored on one record: inverse model and closed loop."""
    out: dict[str, dict[str, float]] = {}
    channels = {k: options[k] for k in ("position", "force")}
    regressions: dict[str, Any] = {}
    for key, est in estimates.items():
        model = key.split(" ")[-1]
        if model not in regressions:
            regressions[model] = inverse_dynamics_regression(
                record, model=model, **channels, **_idim_settings(options))
        reg = regressions[model]
        inverse = 100.0 * float(np.linalg.norm(reg.force - reg.regressors @ est.parameters)
                                / np.linalg.norm(reg.force))
        out[key] = {"inverse": inverse,
                    **_loop_errors(record, controller, est.model, options, loop)}
    return out


def _linear(data: Experiment, options: Mapping[str, Any]) -> dict[str, Any]:
    na, nb, nk = options["linear_orders"]
    q_name = options["position"] or _only(data, "y")
    u_name = _only(data, "u")
    with warnings.catch_warnings():
        # an integrating plant gives an ARX pole at 1: expected here, not suspicious
        warnings.simplefilter("ignore", ServoidWarning)
        est = fit_arx(data.select(u_name, q_name), na, nb, nk)
    y_sim, first = simulate_from_data(est.model, data[q_name], data[u_name])
    poles = np.roots(est.model.a)
    return {"structure": f"ARX({na},{nb},{nk})", "input": u_name, "output": q_name,
            "relative_error": float(relative_error(data[q_name][first:], y_sim[first:])),
            "poles": [{"re": float(p.real), "im": float(p.imag)} for p in poles],
            "parameters": dict(zip(est.names, est.parameters.tolist(), strict=True)),
            "simulated": y_sim}


def _holdout(spec: ExperimentSpec, data: Experiment, controller: CascadeController,
             options: Mapping[str, Any], channels: Mapping[str, Any],
             idim: Mapping[str, Any], loop: Mapping[str, Any]) -> dict[str, dict[str, float]]:
    estimation, validation = spec.split_data(data)
    model = options["model"][0]
    out: dict[str, dict[str, float]] = {}
    est = fit_inverse_dynamics(estimation, model=model, **channels, **idim)
    out[f"idim-ls {model}"] = _loop_errors(validation, controller, est.model, options, loop)
    if options["refine"]:
        oe = fit_closed_loop_oe(estimation, controller, est, output=options["refine_output"],
                                reference=options["reference"],
                                integration=options["integration"], **channels, **loop)
        out[f"closed-loop-oe {model}"] = _loop_errors(validation, controller, oe.model, options,
                                                      loop)
    return out


def _notes(estimates: Mapping[str, Estimate], loop: Mapping[str, Mapping[str, float]]
           ) -> list[str]:
    notes = []
    for model in FRICTION_MODELS:
        ls, oe = f"idim-ls {model}", f"closed-loop-oe {model}"
        if ls in estimates and oe in estimates:
            gain = loop[ls]["force"] - loop[oe]["force"]
            notes.append(
                f"{model}: closed-loop OE changes the simulated force error by {-gain:+.3g} "
                f"percentage points ({loop[ls]['force']:.4g} → {loop[oe]['force']:.4g} %) and "
                f"the position error from {loop[ls]['position']:.3g} to "
                f"{loop[oe]['position']:.3g} %; its standard deviations assume white output "
                "errors, which closed-loop simulation errors are not: read them as lower bounds")
    return notes


def _only(data: Experiment, role: Any) -> str:
    names = data.names_of(role)
    if len(names) != 1:
        data.signal(role)
        raise DataError(f"the experiment has {len(names)} {role!r} channels; name one in "
                        "[identify]")
    return names[0]


def _published_from_spec(spec: ExperimentSpec) -> dict[str, Any] | None:
    name = report_options(spec.report).get("truth")
    if name is None:
        return None
    path = spec.base_dir / name
    data = read_json(path, "truth file")
    if not isinstance(data, Mapping):
        raise FileFormatError(f"truth file {path} must hold a JSON object, got "
                              f"{type(data).__name__}")
    _check_published(data, f"truth file {path}:")
    return dict(data)


def _check_published(data: Mapping[str, Any], where: str) -> None:
    """The parts of a reference-results file that the comparison reads must be numbers."""

    def number(name: str, value: Any) -> None:
        if value is not None:
            as_float(name, value, finite=False, where=where)

    for model in FRICTION_MODELS:
        if model not in data:
            continue
        ref = as_mapping(model, data[model], where=where)
        params = as_mapping(f"{model}.parameters", ref.get("parameters", {}), where=where)
        for name, entry in params.items():
            entry = as_mapping(f"{model}.parameters.{name}", entry, where=where)
            if "value" not in entry:
                raise FileFormatError(f"{where} {model}.parameters.{name} needs a \"value\"")
            as_float(f"{model}.parameters.{name}.value", entry["value"], where=where)
            number(f"{model}.parameters.{name}.std", entry.get("std"))
        number(f"{model}.relative_error", ref.get("relative_error"))
    if data.get("closed_loop") is not None:
        loop = as_mapping("closed_loop", data["closed_loop"], where=where)
        for key in ("position", "force"):
            number(f"closed_loop.{key}", loop.get(key))
    number("linear_relative_error", data.get("linear_relative_error"))


# -- output -----------------------------------------------------------------------------------


def _regressions(ident: InverseDynamicsIdentification) -> tuple[dict[str, Any], dict[str, Any]]:
    idim = {k: v for k, v in ident.estimates.items() if v.method == "idim-ls"}
    regressions = {
        key: inverse_dynamics_regression(
            ident.data, **{k: est.options[k] for k in ("position", "force", "model")},
            **_idim_settings(ident.options))
        for key, est in idim.items()
    }
    return regressions, idim


def _plot_force_fit(ident: InverseDynamicsIdentification, path: Path, overwrite: bool) -> None:
    plot_force_fit(*_regressions(ident), path, overwrite)


def _plot_friction(ident: InverseDynamicsIdentification, path: Path, overwrite: bool) -> None:
    plot_friction(*_regressions(ident), path, overwrite)


def _plot_loop(ident: InverseDynamicsIdentification, path: Path, overwrite: bool,
               record: int | None = None) -> None:
    data = ident.data if record is None else ident.records[record]
    options, loop = ident.options, ident.loop_inputs
    sims = {key: _simulate(data, ident.controller, est.model, options, loop)[0]
            for key, est in ident.estimates.items()}
    _, _, q_name, f_name = _simulate(data, ident.controller, ident.estimate.model, options,
                                     loop)
    plot_loop(data.time, data[q_name], data[f_name], sims, path, overwrite)


def _plot_linear(ident: InverseDynamicsIdentification, path: Path, overwrite: bool) -> None:
    data, linear = ident.data, ident.linear
    q_name = _simulate(data, ident.controller, ident.estimate.model, ident.options,
                       ident.loop_inputs)[2]
    plot_linear(data.time, data[q_name], linear["simulated"], linear["structure"], path,
                overwrite)


def _signed(x: float, unit: str) -> str:
    """A difference to 3 decimals; one that rounds to zero is 0.000, not -0.000."""
    text = f"{x:+.3f}"
    return f"{'0.000' if float(text) == 0.0 else text} {unit}"


def _fmt(x: float | None, digits: int = 6) -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


def _page(ident: InverseDynamicsIdentification, files: Mapping[str, Path]) -> Page:
    spec = ident.spec
    tables: list[Table] = []
    for key, est in ident.estimates.items():
        tables.append(parameter_table(est, key))
        comparison = ident._compare(key, est)
        if comparison and comparison["parameters"]:
            rows = tuple(
                (name, _fmt(c["value"]), _fmt(c["std"], 3), _fmt(c["published"]),
                 _fmt(c["published_std"], 3), _signed(c["difference_percent"], "%"))
                for name, c in comparison["parameters"].items())
            if comparison.get("published_relative_error") is not None \
                    and est.method == "idim-ls":
                rows += (("relative error [%]", _fmt(comparison["relative_error"], 5), "",
                          _fmt(comparison["published_relative_error"], 5), "",
                          _signed(comparison["relative_error"]
                                  - comparison["published_relative_error"], "pp")),)
            tables.append(Table(("parameter", "servoid", "std", "published", "published std",
                                 "difference"), rows, f"{key} against the reference"))
    loop_rows = []
    for key, errs in ident.loop_errors.items():
        pub = ((ident.published or {}).get("closed_loop") or {}) if "symmetric" in key else {}
        loop_rows.append((key, f"{errs['position']:.4g} %", f"{errs['force']:.4g} %",
                          f"{errs['position_from_rest']:.4g} %", f"{errs['force_from_rest']:.4g} %",
                          _fmt(pub.get("position")), _fmt(pub.get("force"))))
    tables.append(Table(
        ("estimate", "position", "force", "position (from rest)", "force (from rest)",
         "published position", "published force"),
        tuple(loop_rows), "Closed-loop simulation from the reference position, relative error "
        "100·‖y − ŷ‖/‖y‖ [%]: from the measured initial state, and at rest on r(0)"))
    if ident.holdout:
        tables.append(Table(
            ("fitted on the estimation part", "position error", "force error"),
            tuple((k, f"{v['position']:.4g} %", f"{v['force']:.4g} %")
                  for k, v in ident.holdout.items()),
            "Closed-loop simulation of the held-back part ([split])"))
    if ident.validation:
        tables.append(Table(
            ("record", "estimate", "inverse model", "position", "force", "position (from rest)",
             "force (from rest)"),
            tuple((record, key, f"{v['inverse']:.4f} %", f"{v['position']:.4g} %",
                   f"{v['force']:.4f} %", f"{v['position_from_rest']:.4g} %",
                   f"{v['force_from_rest']:.4f} %")
                  for record, scores in ident.validation.items() for key, v in scores.items()),
            "Cross-test ([validation] file): the estimates of the first record scored on every "
            "record — inverse-model relative error 100·‖τ − Φθ̂‖/‖τ‖ through the same pipeline, "
            "and closed-loop simulation errors [%]"))
    ctrl = ident.controller
    loop = ident.loop_inputs
    inputs = ""
    if loop.get("disturbance"):
        inputs += (f" Disturbance: channel {loop['disturbance']!r} [N] added at the "
                   f"{loop['disturbance_at']}.")
    if loop.get("reference_offset"):
        inputs += f" Reference offset {loop['reference_offset']:g} m."
    recipe = ("the reference's MATLAB script exactly (pipeline = \"published\": MATLAB filtfilt "
              "and decimate, diffcent, 49 samples dropped at the start)"
              if ident.options.get("pipeline") == "published" else
              "servoid's pipeline (pipeline = \"servoid\")")
    method = Section(
        "Method",
        paragraphs=(
            ("Inverse dynamic model τ = M q̈ + Fv q̇ + Fc sign(q̇) + offset (asymmetric: Fv±, Fc± "
            "per direction). IDIM-LS: zero-phase Butterworth low-pass of the position, central "
            "differences, parallel decimation of force and regressors through one anti-alias "
            "filter, least squares by QR with covariance σ̂²(ΦᵀΦ)⁻¹ (Janot, Gautier, Brunot, "
            f"Data Set and Reference Models of EMPS, 2019); here {recipe}."),
            (f"Known loop: v = kv·(kp·(r − q) − q̇f), kp = {ctrl.kp:g} 1/s, kv = {ctrl.kv:g} "
            f"V/(m/s), ±{ctrl.saturation:g} V, τ = gtau·v with gtau = {ctrl.gtau:.6g} N/V; q̇f "
            "from the backward difference of the two-sample mean. The direct model is simulated "
            "exactly between samples with stick/slip events at q̇ = 0." + inputs),
            ("Closed-loop OE refines the physical parameters so the simulated loop reproduces "
            "the measured position and force (Levenberg–Marquardt from the IDIM-LS estimate). "
            "Its standard deviations assume white output errors and are lower bounds."),
        ),
        tables=tuple(tables),
    )
    figs = [Figure.from_file(files["force_fit.png"], "Decimated force: measured vs IDIM-LS"),
            Figure.from_file(files["friction.png"], "Friction: τ − M q̈ against velocity"),
            Figure.from_file(files["closed_loop.png"],
                             "Closed loop: measured vs simulated position and force")]
    for k, rec in enumerate(ident.records):
        figs.append(Figure.from_file(files[f"validation_loop_{k + 1}.png"],
                                     f"Cross-test on {rec.name}: measured vs simulated position "
                                     "and force"))
    linear_sec = []
    if ident.linear:
        figs.append(Figure.from_file(files["linear.png"], "Linear model from the plant input"))
        pub = (ident.published or {}).get("linear_relative_error")
        linear_sec.append(Section("Linear model", paragraphs=(
            f"Best linear {ident.linear['structure']} model from {ident.linear['input']} to "
            f"{ident.linear['output']}, simulated from the measured input: relative error "
            f"{ident.linear['relative_error']:.3g} %"
            + (f" (published best linear model: {pub:g} %)" if pub is not None else "")
            + ". It has a pole at 1 (the integrator) and a second real pole standing in for "
            "friction; it drifts with any input offset and says nothing physical.",)))
    data_sec = Section("Experiment", paragraphs=tuple(
        f"{what} file {path.name} (sha256 {ident.digest(path)[:16]}…)."
        for what, path in (("Data", spec.data_path),
                           *(("Validation", p) for p in spec.validation_paths))))
    return Page(
        title=f"Rigid axis with friction: {spec.source.name if spec.source else 'experiment'}",
        subtitle="Inverse-model least squares, closed-loop simulation and output-error refinement",
        sections=(data_sec, method, Section("Figures", figures=tuple(figs)), *linear_sec,
                  Section("Notes", paragraphs=ident.notes or ("None.",))),
        meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
              ("data file", str(spec.data_path))),
    )


def _example(folder: Path, seed: int = 0) -> Path:
    """A simulated EMPS-like axis in its cascade (8 s at 1 kHz) and its experiment file."""
    from ...data import write_csv, write_experiment_spec

    dt, gtau = 1e-3, 35.15
    controller = CascadeController(kp=160.18, kv=243.45, gtau=gtau, saturation=10.0)
    t = dt * np.arange(8000)
    rng = np.random.default_rng(seed)
    # moves out and back with stops and reversals, a small multisine on top to excite the mass
    r = 0.05 * (1 - np.cos(2 * np.pi * 0.25 * t)) + 2e-3 * sum(
        np.sin(2 * np.pi * f * t + phase) for f, phase in zip((1.3, 2.9, 4.7),
                                                               rng.uniform(0, 2 * np.pi, 3),
                                                               strict=True))
    sim = simulate_rigid_loop(RigidAxis(95.0, 200.0, 20.0, -3.0), controller, r, dt)
    qm = sim.position + 1e-6 * rng.standard_normal(t.size)  # encoder-like noise [m]
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    record = Experiment.from_arrays(dt, r=r, u=sim.voltage, y=qm,
                                    names={"r": "qg", "u": "vir", "y": "qm"})
    write_csv(record, folder / "axis.csv", overwrite=True)
    toml = folder / "axis.toml"
    write_experiment_spec({
        "data": {"file": "axis.csv"},
        "channels": {"qg": {"role": "r", "unit": "m"}, "vir": {"role": "u", "unit": "V"},
                     "qm": {"role": "y", "unit": "m"},
                     "force": {"source": "vir", "role": "side", "gain": gtau, "unit": "N"}},
        "split": {"fraction": 0.5},
        "loop": {"kp": controller.kp, "kv": controller.kv, "gtau": gtau, "saturation": 10.0},
        "identify": {"method": "inverse-dynamics", "model": "symmetric"},
    }, toml, overwrite=True)
    return toml


METHOD = Method(
    name="inverse-dynamics",
    summary="rigid axis with friction in its known cascade loop ([loop] kp, kv, gtau): "
            "IDIM-LS of M, Fv, Fc, closed-loop OE refinement, hold-out check or cross-test "
            "([validation] file)",
    options=(
        Option("model", ["symmetric", "asymmetric"], choices(FRICTION_MODELS),
               "friction model or list; the first is primary"),
        Option("position", None, optional(text()), "position channel (default: the y channel)"),
        Option("force", None, optional(text()),
               "force channel (default: 'force', else the u channel)"),
        Option("reference", None, optional(text()), "reference channel (default: the r channel)"),
        Option("cutoff", 100.0, number(positive=True, unit="Hz"),
               "zero-phase low-pass before differentiation [Hz]"),
        Option("order", 4, integer(minimum=1), "Butterworth order of that low-pass"),
        Option("decimation", 10, integer(minimum=1), "decimation of the regression"),
        Option("pipeline", "published", choice(INVERSE_PIPELINES),
               "published: the reference's MATLAB script exactly (it predicts the other EMPS "
               "record better, docs/emps.md); servoid: adjustable filters"),
        Option("decimation_filter", None, optional(choice(("fir", "iir"))),
               "decimation filter, pipeline = \"servoid\" only; none means fir"),
        Option("differentiation", None, optional(choice(("central", "backward"))),
               "numerical derivative, pipeline = \"servoid\" only; none means central"),
        Option("trim", None, optional(integer(minimum=0)),
               "samples trimmed at each end [decimated samples], pipeline = \"servoid\" only; "
               "none means 1"),
        Option("refine", True, boolean(), "closed-loop output-error refinement"),
        Option("refine_output", "both", choice(("position", "force", "both")),
               "signals the refinement fits"),
        Option("integration", "exact", choice(("exact", "sign")),
               "friction integration in the loop simulation"),
        Option("linear", True, boolean(), "also fit a linear ARX from u to the position"),
        Option("linear_orders", [2, 2, 1], lambda v, w, n: as_int_list(n, v, minimum=0, where=w),
               "[na, nb, nk] of that ARX"),
        Option("holdout", True, boolean(),
               "fit on the estimation part of [split], simulate the rest (not with [validation])"),
    ),
    run=run,
    tables=(LOOP, "validation"),
    example=_example,
)

#: The plant's methods, as its record names them.
METHODS = (METHOD,)
