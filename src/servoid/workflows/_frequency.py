"""``method = "frequency"``: nonparametric FRF with variance, ML model, acceptance numbers.

The run measures the response on its lines (:func:`servoid.frequency.estimate_bla`
for a multisine test with its plan file, :func:`~servoid.frequency.estimate_lpm` /
:func:`~servoid.frequency.estimate_lrm` for any other record), fits a transfer
function to it by (sample) maximum likelihood with the order chosen by the cost-function
test, reads the acceptance numbers from the fitted model with their 95 % intervals and
judges them against the experiment file's ``[acceptance]`` table under the fleet's rule.
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

from .._errors import DataError, OptionError
from .._version import __version__
from ..data import Experiment, ExperimentSpec
from ..frequency import (
    LIMIT_KEYS,
    RULE,
    AcceptanceCheck,
    FrfMeasurement,
    MlFit,
    SpecNumber,
    acceptance_numbers,
    estimate_bla,
    estimate_lpm,
    estimate_lrm,
    fit_ml,
    judge,
    select_ml_order,
)
from ..report import Check, Conditions, Figure, Page, Section, Table, Verdict
from ..signals import MultisinePlan, read_plan
from ._common import spec_inputs
from ._frequency_figure import plot_frequency
from ._options import boolean, choice, integer, number, optional, text
from ._registry import FigureWriter, Method, Option, TableSchema
from ._summary import Displayed, ParameterValue, RecordSummary, summary_of
from ._verdict import count_check, record_conditions

__all__ = ["FREQUENCY", "FrequencyIdentification"]

# the cost test: below this p-value the data reject the model; between it and 0.05, caution
_REJECT_P = 1e-3
_CAUTION_P = 0.05
#: the plan file beside a data file ``run.csv``
PLAN_SUFFIX = ".plan.json"


@dataclass(frozen=True, eq=False, repr=False)
class FrequencyIdentification(Displayed):
    """A measured FRF, the model fitted to it and the acceptance numbers.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    measurement : FrfMeasurement
        The nonparametric response with its variances (and distortion).
    fit : MlFit
        The chosen model.
    candidates : tuple of MlFit
        Every order tried (the chosen one among them).
    numbers : tuple of SpecNumber
        DC gain, bandwidth, phase lag, resonance, distortion.
    checks : tuple of AcceptanceCheck
        The acceptance limits applied.
    plan_file : Path or None
        The multisine plan read.
    hold : bool
        The zero-order hold was divided out of the lines before the fit.
    notes : tuple of str
        Remarks.
    folder, files, conditions, digests
        Where the results went; the record's conditions; input hashes.
    """

    spec: ExperimentSpec
    measurement: FrfMeasurement
    fit: MlFit
    candidates: tuple[MlFit, ...]
    numbers: tuple[SpecNumber, ...]
    checks: tuple[AcceptanceCheck, ...] = ()
    plan_file: Path | None = None
    hold: bool = False
    notes: tuple[str, ...] = ()
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())
    conditions: tuple[Conditions, ...] = ()
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    def summary(self) -> RecordSummary:
        """The acceptance numbers with their intervals: the fleet's columns."""
        rows = [ParameterValue(n.name, _f(n.value), _f(n.std), _f(n.ci_low), _f(n.ci_high),
                               n.unit) for n in self.numbers]
        return summary_of("frequency", rows, self.verdict(), notes=self.notes)

    def models(self) -> dict[str, Any]:
        """The fitted transfer function and the measured response."""
        return {"G": self.fit.model, "frd": self.measurement.to_frd()}

    def verdict(self) -> Verdict:
        """Acceptance limits, the cost-function test and the numbers with intervals."""
        m, fit = self.measurement, self.fit
        checks = [Check(f"acceptance: {c.name}", c.limit, "pass" if c.passed else "fail",
                        c.reason) for c in self.checks]
        p = fit.p_value
        outcome = "pass" if p >= _CAUTION_P else "caution" if p >= _REJECT_P else "fail"
        checks.append(Check(
            "cost-function test", f"V = {fit.cost:.4g}, p = {p:.2g}", outcome,
            f"expected {fit.expected_cost:.4g} ± {fit.cost_std:.2g} under the model "
            f"({fit.n_poles} poles, {fit.n_zeros} zeros, {fit.n_lines} lines)"
            + ("" if outcome == "pass" else ": the model leaves a systematic error; try "
               "another order or a narrower band")))
        d = m.distortion
        if d is not None:
            worst = max((v for v in (d.odd_db, d.even_db, d.total_db) if v is not None),
                        default=math.nan)
            odd_p = min((v for v in (d.odd_p, d.even_p) if v is not None), default=None)
            detected = odd_p is not None and odd_p < 0.01
            checks.append(Check("nonlinear distortion", _db(worst),
                                "caution" if detected else "pass",
                                ("detected on the detection lines: the FRF is the best linear "
                                 "approximation at this amplitude" if detected else
                                 "no more than the noise on the detection lines")))
        if m.nonlinear_variance is not None:
            share = float(np.sum(m.nonlinear_variance) / max(np.sum(m.variance), 1e-300))
            checks.append(Check("stochastic nonlinear share", f"{100 * share:.0f} %", "info",
                                "of the BLA's variance, from the scatter over realisations"))
        checks.append(count_check("notes", self.notes, "listed under the response"))
        tested = (f"the {m.method.upper()} frequency response of {m.output_name} from "
                  f"{m.input_name}" + (f" referred to {m.reference_name}" if m.reference_name
                                       else "")
                  + f" ({m.n_lines} lines) and a {'continuous' if fit.domain == 's' else 'discrete'}"
                  f" transfer function fitted to it by maximum likelihood; the acceptance "
                  f"numbers are read from that model with 95 % intervals. {RULE.capitalize()}.")
        table = Table(("number", "value", "95 % interval", "from the lines"),
                      tuple((n.label, _num(n.value), _interval(n), _num(n.measured))
                            for n in self.numbers), "Acceptance numbers")
        return Verdict(tested, tuple(checks), self.conditions, (table,))

    def __str__(self) -> str:
        m, fit = self.measurement, self.fit
        lines = [(f"{m.method} frequency response of {m.output_name} from {m.input_name} "
                  f"({m.n_lines} lines); ML model: {fit.n_poles} poles, {fit.n_zeros} zeros "
                  f"({fit.domain}), cost {fit.cost:.4g} (expected {fit.expected_cost:.4g}, "
                  f"p = {fit.p_value:.2g})")]
        lines += [f"  {n.label:<34} {_num(n.value):>10}  95 % {_interval(n)}"
                  for n in self.numbers]
        lines += [f"  acceptance {c.name}: {'pass' if c.passed else 'FAIL'} ({c.limit}; "
                  f"{c.reason})" for c in self.checks]
        lines += [f"  note: {n}" for n in self.notes]
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        return {
            "servoid_version": __version__, "method": "frequency",
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_files": [{"path": str(p), "sha256": self.digest(p)}
                           for p in self.spec.data_paths],
            "plan_file": None if self.plan_file is None else {
                "path": str(self.plan_file), "sha256": self.digest(self.plan_file)},
            "acceptance_numbers": [n.to_dict() for n in self.numbers],
            "acceptance": [c.to_dict() for c in self.checks],
            "ml_fit": self.fit.to_dict(),
            "orders_tried": [{"n_poles": f.n_poles, "n_zeros": f.n_zeros, "cost": f.cost,
                              "expected_cost": f.expected_cost, "p_value": f.p_value}
                             for f in self.candidates],
            "measurement": self.measurement.to_dict(), "notes": list(self.notes),
            "verdict": self.verdict().to_dict(), "summary": self.summary().to_dict(),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read (the plan file too)."""
        extra = (self.plan_file,) if self.plan_file is not None else ()
        return (*spec_inputs(self.spec), *extra)

    def figures(self) -> dict[str, FigureWriter]:
        """One Bode diagram: lines with ±2σ (total and noise), distortion, the model."""
        return {"frequency.png": partial(plot_frequency, self.measurement, self.fit,
                                         self.numbers, self.hold)}

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        m, fit = self.measurement, self.fit
        orders = Table(("poles", "zeros", "cost V", "expected", "p-value"),
                       tuple((str(f.n_poles), str(f.n_zeros), f"{f.cost:.4g}",
                              f"{f.expected_cost:.4g} ± {f.cost_std:.2g}", f"{f.p_value:.2g}")
                             for f in self.candidates), "Orders tried (cost-function test)")
        params = Table(("parameter", "value", "std"),
                       tuple((n, f"{v:.6g}", f"{s:.2g}") for n, v, s in
                             zip(fit.names, fit.parameters, fit.std, strict=True)),
                       "Fitted parameters")
        how = {"bla": f"best linear approximation from {m.realisations} realisations × "
                      f"{m.periods} periods (total variance: noise plus stochastic nonlinear "
                      "distortion)",
               "periodic": f"periodic FRF averaged over {m.periods} periods",
               "lpm": "local polynomial method (transient removed)",
               "lrm": "local rational method (transient removed)"}.get(m.method, m.method)
        body = Section(
            "Frequency response and model",
            paragraphs=(
                (f"{how}, {m.n_lines} lines; {fit.n_lines} independent lines fitted by "
                 f"{'sample ' if math.isfinite(fit.dof) else ''}maximum likelihood "
                 f"(start: {fit.start})."),
                *self.notes,
            ),
            figures=(Figure.from_file(files["frequency.png"],
                                      "Measured lines with ±2σ (total and noise), the "
                                      "detection lines' distortion and the fitted model"),),
            tables=(params, orders),
        )
        name = self.spec.source.name if self.spec.source else "experiment"
        return Page(title=f"Frequency-domain identification: {name}",
                    subtitle="Nonparametric FRF, maximum-likelihood model, acceptance numbers",
                    sections=(body,),
                    meta=(("servoid", __version__), ("experiment file", str(self.spec.source))))


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> FrequencyIdentification:
    """Measure, fit, read the numbers, judge them."""
    exp = spec.load()
    plan, plan_file = _plan(spec, options)
    estimator = options["estimator"]
    if estimator == "auto":
        estimator = "bla" if plan is not None else "lpm"
    band = {"f_min": options["f_min"], "f_max": options["f_max"]}
    if estimator == "bla":
        if plan is None:
            raise DataError(
                "[identify] estimator = \"bla\" needs the multisine plan: write the test with "
                "servoid excite random-multisine (it writes <file>.plan.json beside the data "
                "file) or name it with [identify] plan")
        measurement = estimate_bla(exp, plan, input=options["input"], output=options["output"],
                                   reference=options["reference"], start=options["start"],
                                   **band)
    elif estimator == "lrm":
        if options["reference"] is not None:
            raise OptionError("[identify] estimator = \"lrm\" is open loop; for a closed-loop "
                              "record (reference) use estimator = \"lpm\" or \"bla\"")
        measurement = estimate_lrm(exp, input=options["input"], output=options["output"],
                                   degree=options["degree"], **band)
    else:
        measurement = estimate_lpm(exp, input=options["input"], output=options["output"],
                                   reference=options["reference"], degree=options["degree"],
                                   **band)
    hold = options["domain"] == "s" and options["intersample"] == "zoh"
    target = _without_hold(measurement) if hold else measurement
    fit_options = {"domain": options["domain"], "variance": options["variance"],
                   "delay": None if options["estimate_delay"] else options["delay"],
                   "delay_samples": options["delay_samples"]}
    if options["domain"] == "z" and options["estimate_delay"]:
        raise OptionError("[identify] estimate_delay works for domain = \"s\"; a discrete model "
                          "takes delay_samples")
    if options["n_poles"] is not None:
        fit = fit_ml(target, options["n_poles"], options["n_zeros"], **fit_options)
        candidates: tuple[MlFit, ...] = (fit,)
    else:
        orders = [(n, n - 1 if options["domain"] == "s" else n)
                  for n in range(1, options["max_poles"] + 1)]
        fit, candidates = select_ml_order(target, orders, **fit_options)
    numbers = acceptance_numbers(fit, level_db=options["level_db"],
                                 phase_frequency=options["phase_frequency"],
                                 distortion=measurement.distortion)
    limits = {k: v for k, v in options["[acceptance]"].items() if v is not None}
    checks = judge(numbers, limits)
    notes = []
    if options["n_poles"] is None:
        notes.append(f"order chosen by the cost-function test among 1..{options['max_poles']} "
                     f"poles: {fit.n_poles}")
    if truth:
        notes.extend(_truth_notes(numbers, truth))
    channel = options["reference"] or options["input"]
    conditions = (record_conditions(exp, f"record: {spec.data_path.name}",
                                    _channel_name(exp, channel)),)
    return FrequencyIdentification(spec, measurement, fit, candidates, numbers, checks,
                                   plan_file, hold, tuple(notes), conditions=conditions)


# -- helpers -------------------------------------------------------------------------------------
def _plan(spec: ExperimentSpec, options: Mapping[str, Any],
          ) -> tuple[MultisinePlan | None, Path | None]:
    given = options["plan"]
    if given is not None:
        path = Path(given)
        path = path if path.is_absolute() else spec.base_dir / path
        return read_plan(path), path
    beside = spec.data_path.with_name(spec.data_path.stem + PLAN_SUFFIX)
    if beside.is_file() and options["estimator"] in ("auto", "bla"):
        return read_plan(beside), beside
    return None, None


def _without_hold(frm: FrfMeasurement) -> FrfMeasurement:
    """The lines with the zero-order hold's response divided out (a continuous fit)."""
    if frm.dt is None:
        return frm
    wt2 = np.pi * frm.frequency * frm.dt
    hold = np.exp(-1j * wt2) * np.sinc(wt2 / np.pi)
    scale = np.abs(hold) ** 2
    nl = frm.nonlinear_variance
    return dataclasses.replace(frm, response=frm.response / hold, variance=frm.variance / scale,
                               noise_variance=frm.noise_variance / scale,
                               nonlinear_variance=None if nl is None else nl / scale)


def _channel_name(exp: Experiment, key: str) -> str | None:
    if key in exp.names:
        return key
    names = exp.names_of(key) if key in ("u", "r", "y") else ()  # type: ignore[arg-type]
    return names[0] if names else None


def _truth_notes(numbers: tuple[SpecNumber, ...], truth: Mapping[str, float]) -> list[str]:
    out = []
    for n in numbers:
        if n.name in truth and math.isfinite(n.ci_low):
            t = float(truth[n.name])
            inside = n.ci_low <= t <= n.ci_high
            out.append(f"truth {n.name} = {t:.5g} {'inside' if inside else 'OUTSIDE'} the 95 % "
                       f"interval {_interval(n)}")
    return out


def _f(x: float) -> float:
    return float(x) if x is not None else math.nan


def _num(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{x:.5g}"


def _db(x: float) -> str:
    return "at the noise" if not math.isfinite(x) else f"{x:.1f} dB re output"


def _interval(n: SpecNumber) -> str:
    if not (math.isfinite(n.ci_low) and math.isfinite(n.ci_high)):
        return "—"
    return f"[{n.ci_low:.5g}, {n.ci_high:.5g}]" + (f" {n.unit}" if n.unit else "")


def _example(folder: Path, seed: int = 0) -> Path:
    from ._frequency_example import multisine_test

    return multisine_test(folder, seed)


#: ``[acceptance]``: the limits of the acceptance numbers, judged under the fleet's rule.
ACCEPTANCE = TableSchema(
    "acceptance",
    tuple(Option(key, None, optional(number()),
                 f"{'lowest' if key.endswith('_min') else 'highest'} "
                 f"{key.rsplit('_', 1)[0].replace('_', ' ')} the interval may reach")
          for key in LIMIT_KEYS),
    help="acceptance limits: pass only when the number's 95 % interval lies inside",
)

FREQUENCY = Method(
    name="frequency",
    summary="frequency response with its variance (BLA of a multisine test with noise and "
            "nonlinear-distortion variances, or the local polynomial method), a transfer "
            "function by maximum likelihood with its order from the cost test, and the "
            "acceptance numbers with 95 % intervals",
    options=(
        Option("input", "u", text(), "input channel or role (u)"),
        Option("output", None, optional(text()), "output channel"),
        Option("reference", None, optional(text()),
               "reference channel or role (\"r\") of a closed-loop record: the FRF from it"),
        Option("estimator", "auto", choice(("auto", "bla", "lpm", "lrm")),
               "bla: a multisine test and its plan; lpm/lrm: any record; auto: bla when a plan "
               "file lies beside the data file"),
        Option("plan", None, optional(text()),
               "the multisine plan file (default: <data file>.plan.json beside it)"),
        Option("start", 0, integer(minimum=0), "sample where the multisine test begins"),
        Option("degree", 2, integer(minimum=0, maximum=10),
               "degree of the LPM/LRM local polynomials"),
        Option("f_min", None, optional(number(nonneg=True, unit="Hz")), "lowest line [Hz]"),
        Option("f_max", None, optional(number(positive=True, unit="Hz")), "highest line [Hz]"),
        Option("domain", "s", choice(("s", "z")), "continuous (s) or discrete (z) model"),
        Option("n_poles", None, optional(integer(minimum=1, maximum=20)),
               "poles of the model (default: chosen by the cost test up to max_poles)"),
        Option("n_zeros", None, optional(integer(minimum=0, maximum=20)),
               "zeros (default n_poles − 1 in s, n_poles in z)"),
        Option("max_poles", 4, integer(minimum=1, maximum=20), "highest order the search tries"),
        Option("delay", 0.0, number(nonneg=True, unit="s"), "input delay of an s model [s]"),
        Option("estimate_delay", False, boolean(), "estimate the delay (s model)"),
        Option("delay_samples", 0, integer(minimum=0), "input delay of a z model [samples]"),
        Option("variance", "total", choice(("total", "noise")),
               "weights: total (noise and stochastic nonlinear) or noise variance"),
        Option("intersample", "zoh", choice(("zoh", "bandlimited")),
               "the logged input between samples; zoh: the hold is divided out before an s fit"),
        Option("level_db", -3.0, number(), "bandwidth level below the low-frequency gain [dB]"),
        Option("phase_frequency", None, optional(number(positive=True, unit="Hz")),
               "frequency of the phase-lag number [Hz]"),
    ),
    run=run,
    tables=(ACCEPTANCE,),
    example=_example,
)
