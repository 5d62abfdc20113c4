"""Run ``method = "ema"``: fit, free-run validation, results and report.

Reads the experiment file's channels (calibrated to A, V, rad, m), its
``[rig] anti_alias`` (the logger's filter on the analog channels, given to
the digital ones by :func:`fit_ema`), ``[identify]`` (the transmission and
the fit's options) and ``[loop]`` (the drive).  The record is split as
``[split]`` says, or ``[validation]`` names other records.  Validation
simulates the identified actuator in the known drive from the logged
reference, from rest at the record's start (the drive's integrators start
empty there): a free run, scored on the held-back part only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ... import __version__
from ..._errors import ChannelError, OptionError
from ...data import Experiment
from ...report import Check, Figure, Page, Section, Table, Verdict
from ...validate import fit_percent, residual_analysis
from ...workflows._common import read_truth, report_options
from ...workflows._registry import FigureWriter
from ...workflows._summary import Displayed, ParameterValue, RecordSummary, summary_of
from ...workflows._verdict import count_check, record_conditions
from ._control import EmaController
from ._figures import plot_equations, plot_validation_run
from ._filters import anti_alias_replica
from ._identify import PHYSICAL, EmaIdentification, fit_ema
from ._sim import simulate_ema
from ._workflow import drive

__all__ = ["EmaResult", "example", "run_ema"]

# what the validation's independence test decimates to: about 1 kHz, below the filters
_TEST_RATE = 1000.0


@dataclass(frozen=True, eq=False, repr=False)
class EmaResult(Displayed):
    """An EMA identification run: parameters, validation, report.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    identification : EmaIdentification
        The physical parameters with covariance and verdicts.
    controller : EmaController or None
        The drive from ``[loop]`` (None: no validation).
    validations : tuple of mapping
        Per validation record: name, fits [%], the independence test and
        the measured and simulated signals (for the figures).
    truth : mapping or None
        Known parameter values to compare with (``[report] truth``).
    options : mapping
        The ``[identify]`` options used.
    notes : tuple of str
        Remarks for the reader.
    folder : pathlib.Path or None
        The results folder, if written.
    files : tuple of pathlib.Path
        The files written.
    conditions : tuple of Conditions
        Rate, length, excitation and band of the estimation and validation records.
    digests : dict
        SHA-256 of the input files, each hashed once (see ``digest``).
    """

    spec: Any
    identification: EmaIdentification
    controller: EmaController | None
    validations: tuple[Mapping[str, Any], ...] = ()
    truth: Mapping[str, float] | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    folder: Path | None = None
    files: tuple[Path, ...] = ()
    conditions: tuple[Any, ...] = ()
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    def verdict(self) -> Verdict:
        """The free run in the known drive on data the fit did not use, record by record.

        The motor current's fit decides (the load position follows the
        reference whatever the model); a current error that follows the
        reference rejects the model; parameters the record did not determine
        leave the verdict inconclusive.
        """
        checks: list[Check] = []
        several = len(self.validations) > 1
        for v in self.validations:
            on = f" ({v['experiment']})" if several else ""
            fit = v["current_fit"]
            checks.append(Check(f"simulation fit{on}", f"{fit:.1f} %",
                                "fail" if fit < 0 else "pass",
                                "the simulated motor current is further from the measurement "
                                "than its mean value" if fit < 0 else
                                "free run of the motor current in the known drive, on data not "
                                "used for fitting"))
            p = v["independence_pvalue"]
            if p is not None:
                checks.append(Check(
                    f"input–residual independence{on}", f"p = {p:.3g}",
                    "pass" if v["independent"] else "fail",
                    "the current error does not follow the reference" if v["independent"] else
                    "the current error follows the reference: the dynamics are not captured"))
            checks.append(Check(f"load position fit{on}", f"{v['position_fit']:.1f} %", "info",
                                "the loop makes the load follow its reference whatever the "
                                "model: not a test of it"))
        if not self.validations:
            checks.append(Check("validation", "none", "caution",
                                "the identified actuator was not simulated on data the fit did "
                                "not use (no [loop], or [identify] validate = false)"))
        rows = self.identification.rows()
        unresolved = [r["name"] for r in rows if not r["identifiable"] and not r["given"]]
        checks.append(count_check("not identifiable", unresolved,
                                  "not determined by this record: " + ", ".join(unresolved),
                                  "caution"))
        checks.append(count_check("notes", self.notes, "listed under Notes"))
        tested = ("the electromechanical actuator's physical parameters from three equations "
                  "of the closed-loop record, the identified actuator simulated in its known "
                  "drive from the logged reference on "
                  + (f"{len(self.validations)} record(s) not used for fitting."
                     if self.validations else "no record (no validation)."))
        return Verdict(tested, tuple(checks), tuple(self.conditions))

    def summary(self) -> RecordSummary:
        """Every physical parameter with σ and interval, the current's free-run fit, decision."""
        rows = [ParameterValue(r["name"], r["value"], r["std"], r["ci_low"], r["ci_high"],
                               r["unit"]) for r in self.identification.rows()]
        summary = summary_of("ema", rows, self.verdict(), notes=self.notes)
        if self.validations:
            first = self.validations[0]
            return dataclasses.replace(summary, fit_percent=first["current_fit"],
                                       independent=first["independent"])
        return summary

    def models(self) -> dict[str, Any]:
        """The identified actuator as ``"ema"`` (:class:`EmaParameters`, for simulation)."""
        return {"ema": self.identification.parameters()}

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        ident = self.identification
        rows = ident.rows()
        for row in rows:
            if self.truth and row["name"] in self.truth:
                t = self.truth[row["name"]]
                row["truth"] = t
                row["error_in_std"] = (row["value"] - t) / row["std"] if row["std"] > 0 else None
        first = self.validations[0] if self.validations else None
        validation = None
        if first is not None:
            # the current's fit: the load's position follows the reference whatever the model
            validation = {
                "fit_percent": first["current_fit"],
                "fitted": "motor current (free run in the known drive)",
                "position_fit_percent": first["position_fit"],
                "residuals": {"is_white": None, "is_independent": first["independent"],
                              "independence_pvalue": first["independence_pvalue"],
                              "tested": "simulated current error against the reference "
                                        "(causal lags), decimated to about 1 kHz"},
                "records": [{k: v[k] for k in ("experiment", "samples", "position_fit",
                                               "current_fit", "independence_pvalue",
                                               "independent")}
                            for v in self.validations],
            }
        return {
            "servoid_version": __version__,
            "method": "ema",
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_file": str(self.spec.data_path),
            "data_sha256": self.digest(self.spec.data_path),
            "estimate": {"method": "ema", "n_samples": ident.n_rows, "confidence_level": 0.95,
                         "parameters": rows},
            "identification": ident.to_dict(),
            "validation": validation,
            "loop": None if self.controller is None else self.controller.to_dict(),
            "notes": list(self.notes),
            "verdict": self.verdict().to_dict(),
            "summary": self.summary().to_dict(),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        out = [*self.spec.data_paths, *self.spec.validation_paths]
        if self.spec.source:
            out.append(Path(self.spec.source))
            name = report_options(self.spec.report).get("truth")
            if name:
                out.append(self.spec.source.parent / name)
        return tuple(out)

    def figures(self) -> dict[str, FigureWriter]:
        """The equations' fits and each validation run."""
        out: dict[str, FigureWriter] = {"equations.png": partial(_plot_equations, self)}
        for k in range(len(self.validations)):
            out[f"validation_{k + 1}.png"] = partial(_plot_validation, self, k)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        return _page(self, files)

    def __str__(self) -> str:
        lines = [f"EMA identification of {self.spec.source or self.spec.data_path}"]
        lines += ["  " + line for line in str(self.identification).splitlines()[1:]
                  if not line.lstrip().startswith("note:")]
        if self.truth:
            worst = max(((abs(r["value"] - self.truth[r["name"]]) / r["std"], r["name"])
                         for r in self.identification.rows()
                         if r["name"] in self.truth and r["std"] > 0 and r["identifiable"]
                         and not r["given"]), default=None)
            if worst:
                lines.append(f"  against the truth: largest error {worst[0]:.2f} std ({worst[1]})")
        for v in self.validations:
            lines.append(f"  validation on {v['experiment']}: load position fit "
                         f"{v['position_fit']:.2f} %, current fit {v['current_fit']:.2f} %")
        lines += [f"  note: {n}" for n in self.notes]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)


def run_ema(spec: Any, options: Mapping[str, Any],
            truth: Mapping[str, Any] | None) -> EmaResult:
    """Run the EMA identification an experiment file asks for (see the module notes)."""
    for key, what in (("gear_ratio", "motor turns per screw turn"), ("lead", "screw lead [m]")):
        if options[key] is None:
            raise OptionError(f"[identify] {key} is needed ({what}, from the actuator's "
                              f"drawing): add {key} = … under [identify]")
    rig = spec.rig
    anti_alias = None
    if rig.anti_alias_order is not None:
        anti_alias = (int(rig.anti_alias_order), float(rig.anti_alias_cutoff))
        if spec.preprocess.decimate > 1 or spec.preprocess.lowpass is not None:
            raise OptionError(
                "method = \"ema\" gives the drive's digital channels (voltage, encoder) the "
                "[rig] anti_alias filter of the analog ones at the logging rate, so the record "
                "must reach it undecimated and unfiltered: remove [preprocess] decimate and "
                "lowpass (the fit reduces its own rows: [identify] row_step)")
    if spec.preprocess.detrend != "none":
        raise OptionError(
            f"[preprocess] detrend = \"{spec.preprocess.detrend}\" would remove the mean of the "
            "current and the voltage, which the physical equations need (friction and the "
            "constant load are in them): remove it for method = \"ema\"")
    controller = drive(options["[loop]"]) if spec.loop else None
    notes: list[str] = []
    record = spec.load(detrend=False)
    channels = {k: options[k] for k in ("current", "voltage", "angle", "position")}
    for key, name in channels.items():
        if name is not None and name not in record.names:
            raise ChannelError(f"[identify] {key} = {name!r} is not a channel of the record; "
                               f"its channels are {', '.join(record.names)}")
    if spec.validation_paths:
        estimation, start = record, None
    else:
        estimation, held = spec.split_data(record)
        start = round((held.t0 - record.t0) / record.dt)
    ident = fit_ema(
        estimation, gear_ratio=options["gear_ratio"], lead=options["lead"], **channels,
        anti_alias=anti_alias, motor_constant=options["motor_constant"],
        motor_constant_std=options["motor_constant_std"], load_mass=options["load_mass"],
        bandwidth=options["bandwidth"], bandwidth_electrical=options["bandwidth_electrical"],
        order=options["order"], row_step=options["row_step"], min_speed=options["min_speed"],
        max_relative_std=options["max_relative_std"],
        min_deflection_fit=options["min_deflection_fit"])
    notes += ident.notes
    validations: list[dict[str, Any]] = []
    checked: list[tuple[str, Experiment]] = []  # the validation records read
    if options["validate"] and controller is None:
        notes.append("no [loop] table: the drive is unknown, so the identified actuator was not "
                     "simulated on held-back data (no validation)")
    elif options["validate"]:
        ref_name = options["reference"] or _only(record, "r")
        if ref_name not in record.names:
            raise ChannelError(f"[identify] reference = {ref_name!r} is not a channel of the "
                               f"record; its channels are {', '.join(record.names)}")
        if start is not None:
            validations.append(_validate(record, start, ident, controller, channels, ref_name,
                                         anti_alias, "the held-back part"))
            checked.append((f"{spec.data_path.name}, held-back part", held))
        for path in spec.validation_paths:
            other = spec.load(path, detrend=False)
            checked.append((path.name, other))
            validations.append(_validate(other, 0, ident, controller, channels, ref_name,
                                         anti_alias, path.name))
    if truth is None:
        name = report_options(spec.report).get("truth")
        if name is not None:
            truth = read_truth(spec.base_dir / name, list(PHYSICAL)) or None
    conditions = (record_conditions(estimation, f"estimation: {spec.data_path.name}"
                                    + ("" if start is None else ", first part"),
                                    options["reference"]),
                  *(record_conditions(other, f"validation: {name}", options["reference"])
                    for name, other in checked))
    return EmaResult(spec, ident, controller, tuple(validations),
                     None if truth is None else {k: float(v) for k, v in truth.items()},
                     dict(options), tuple(notes), conditions=conditions)


def _only(record: Experiment, role: str) -> str:
    names = record.names_of(role)  # type: ignore[arg-type]
    if len(names) != 1:
        raise OptionError(f"the record has {len(names)} channels of role {role!r}; name the "
                          "reference channel with [identify] reference")
    return names[0]


def _validate(record: Experiment, start: int, ident: EmaIdentification,
              controller: EmaController, channels: Mapping[str, Any], ref_name: str,
              anti_alias: tuple[int, float] | None, label: str) -> dict[str, Any]:
    params = ident.parameters()
    dt = record.dt
    ref = np.asarray(record[ref_name])
    i_meas = np.asarray(record[channels["current"]])
    x_meas = np.asarray(record[channels["position"]])
    th = np.asarray(record[channels["angle"]])
    x0 = np.array([i_meas[0], th[0], 0.0, x_meas[0], 0.0])
    f0 = ident["F_0"] if "F_0" in ident.names else 0.0
    sim = simulate_ema(params, ref, dt, controller=controller, f_ext=f0, x0=x0)
    i_sim, x_sim = np.asarray(sim.current), np.asarray(sim.position)
    if anti_alias is not None:  # the logged analog channels passed the logger's filter
        i_sim = anti_alias_replica(i_sim, dt, anti_alias[0], anti_alias[1], "cubic")
        x_sim = anti_alias_replica(x_sim, dt, anti_alias[0], anti_alias[1], "cubic")
    span = slice(start, None)
    step = max(1, round(1.0 / (_TEST_RATE * dt)))
    err = (i_meas - i_sim)[span][::step]
    test = residual_analysis(err, ref[span][::step], causal=True)
    return {
        "experiment": label, "samples": int(i_meas.size - start), "start": start,
        "position_fit": float(fit_percent(x_meas[span], x_sim[span])),
        "current_fit": float(fit_percent(i_meas[span], i_sim[span])),
        "independence_pvalue": None if math.isnan(test.independence_pvalue)
        else float(test.independence_pvalue),
        "independent": test.is_independent,
        "series": {"time": record.time, "measured": {"position": x_meas, "current": i_meas},
                   "simulated": {"position": x_sim, "current": i_sim}},
    }


def _plot_validation(result: EmaResult, k: int, path: Path, overwrite: bool) -> None:
    v = result.validations[k]
    s = v["series"]
    plot_validation_run(s["time"], s["measured"], s["simulated"], (v["start"], len(s["time"])),
                        path, overwrite)


def _plot_equations(result: EmaResult, path: Path, overwrite: bool) -> None:
    units = {"electrical equation": ("voltage [V]", 1.0),
             "force balance": ("force at the nut [N]", 1.0),
             "deflection equation": ("screw deflection [µm]", 1e6)}
    plot_equations(result.identification.series, units, path, overwrite)


def _fmt(x: float | None, digits: int = 6) -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else \
        f"{x:.{digits}g}"


def _page(result: EmaResult, files: Mapping[str, Path]) -> Page:
    spec, ident = result.spec, result.identification
    truth = result.truth or {}
    rows = []
    for r in ident.rows():
        if r["given"]:
            interval = "given"
        elif r["identifiable"]:
            interval = f"[{r['ci_low']:.6g}, {r['ci_high']:.6g}]"
        else:
            interval = "not identifiable from this record"
        cells = [r["name"], PHYSICAL[r["name"]][1], _fmt(r["value"]), _fmt(r["std"], 3),
                 interval, r["unit"]]
        if truth:
            t = truth.get(r["name"])
            cells += [_fmt(t), "—" if t is None or r["std"] == 0 else
                      f"{(r['value'] - t) / r['std']:+.2f}"]
        rows.append(tuple(cells))
    columns = ["parameter", "what", "estimate", "std", "95 % interval", "unit"]
    if truth:
        columns += ["truth", "error / std"]
    params = Table(tuple(columns), tuple(rows),
                   "Physical parameters (delta method from the three equations' joint "
                   "covariance); a relative std above "
                   f"{ident.settings['max_relative_std']:g} reads: not identifiable")
    eqs = Table(("equation", "solved by", "rows", "fit [%]", "condition"),
                tuple((name, e["method"], str(ident.n_rows), f"{e['fit_percent']:.3f}",
                       f"{e['condition']:.3g}") for name, e in ident.equations.items()),
                f"Regressions on the state-variable-filtered record; "
                f"{100 * ident.kept:.0f} % of it usable (reversals and slow motion left out)")
    st = ident.settings
    method = Section("Method", paragraphs=((
        "Three linear equations in the measured signals, each passed through a state-variable "
        f"filter (order {st['order']}, {st['bandwidth']:g} Hz for the mechanics, "
        f"{st['bandwidth_electrical']:g} Hz for the electrical equation), after the drive's "
        "digital channels (voltage command, encoder) got the replica of the logger's "
        "anti-alias filter: u = R·i + L·di/dt + K_m·ω (least squares); the force balance of "
        "the drive train, K_m·n_t·i = M·ẍ_m − m_L·δ̈ + B·ẋ_m − b_L·δ̇ + C·sgn ẋ_m + F_0, "
        "by instrumental variables with encoder-only instruments; and the screw's deflection "
        "δ = (m_L ẍ_L + b_L ẋ_L + F_cL sgn ẋ_L + F_0 − c_s δ̇)/k_s (instrumental variables). "
        "Covariance: the three equations' joint sandwich, prewhitened Newey–West over the "
        "filter's memory."), (
        f"Transmission n_t = 2π·{ident.gear_ratio:g}/{ident.lead:g} m = "
        f"{2 * math.pi * ident.gear_ratio / ident.lead:.6g} rad/m.")), tables=(params, eqs))
    sections = [
        Section("Experiment", paragraphs=tuple(
            f"{what} file {path.name} (sha256 {result.digest(path)[:16]}…)."
            for what, path in (("Data", spec.data_path),
                               *(("Validation", p) for p in spec.validation_paths)))),
        method,
    ]
    figs = [Figure.from_file(files["equations.png"],
                             "Each equation: filtered measurement and fitted model, per row")]
    if result.validations:
        vt = Table(("record", "samples scored", "load position fit [%]", "current fit [%]",
                    "independence p (current error vs reference)"),
                   tuple((v["experiment"], str(v["samples"]), f"{v['position_fit']:.3f}",
                          f"{v['current_fit']:.3f}", _fmt(v["independence_pvalue"], 3))
                         for v in result.validations),
                   "Free run of the identified actuator in the known drive from the logged "
                   "reference, scored on data not used for fitting")
        ctrl = result.controller
        assert ctrl is not None
        sections.append(Section("Validation", paragraphs=((
            f"Drive ([loop]): kp_i = {ctrl.kp_i:g} V/A, ki_i = {ctrl.ki_i:g}, kp_w = "
            f"{ctrl.kp_w:g} A·s/rad, ki_w = {ctrl.ki_w:g}, kp_x = {ctrl.kp_x:g} (rad/s)/m, "
            f"ki_x = {ctrl.ki_x:g}; limits {ctrl.u_max:g} V, {ctrl.i_max:g} A, "
            f"{ctrl.w_max:g} rad/s; {ctrl.feedback} position feedback."), (
            "A closed-loop free run leaves the loop's response to the sensors' noise out of the "
            "simulation, so its error is coloured whatever the model: its whiteness is not "
            "tested. What a wrong model leaves is an error that follows the reference, "
            "which the independence test looks for.")), tables=(vt,)))
        for k, v in enumerate(result.validations):
            figs.append(Figure.from_file(files[f"validation_{k + 1}.png"],
                                         f"Validation on {v['experiment']}: measured vs "
                                         "simulated load position and motor current"))
    sections.append(Section("Figures", figures=tuple(figs)))
    sections.append(Section("Notes", paragraphs=result.notes or ("None.",)))
    return Page(
        title=f"EMA identification: {spec.source.name if spec.source else 'experiment'}",
        subtitle="Electromechanical actuator in its drive: physical parameters from a "
                 "closed-loop record",
        sections=tuple(sections),
        meta=(("servoid", __version__), ("experiment file", str(spec.source or "")),
              ("data file", str(spec.data_path))),
    )


def example(folder: Path, seed: int = 0) -> Path:
    """A short record of the virtual EMA rig (the default test, 4 s) and its experiment file."""
    from ._bench_files import write_bench

    return write_bench(folder, seed=seed, duration=4.0, format="csv", overwrite=True)[1]
