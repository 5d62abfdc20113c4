"""``method = "frf"``: the measured frequency response, its spec numbers, a fitted model."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._errors import ServoidError
from ..data import Experiment, ExperimentSpec
from ..estimate import estimate_frf, fit_frf
from ..models import FrequencyResponseData, bandwidth, phase_lag, resonance_peak
from ..report import Check, Conditions, Figure, Page, Section, Table, Verdict, plot_bode_bands
from ._common import spec_inputs
from ._examples import open_loop
from ._lti import IdentificationResult, lti_result, spec_value
from ._options import choice, integer, number, optional, text
from ._registry import FigureWriter, Method, Option
from ._summary import Displayed, RecordSummary, summary_of
from ._verdict import NO_PEAK, count_check, spec_conditions, spec_text

__all__ = ["FRF", "FrfIdentification", "spec_numbers"]


@dataclass(frozen=True, eq=False, repr=False)
class FrfIdentification(Displayed):
    """A measured frequency response and the spec numbers read from it.

    Attributes
    ----------
    spec : ExperimentSpec
        The experiment file.
    frd : FrequencyResponseData
        The measured response (with its variance or coherence).
    numbers : mapping of str to float
        Bandwidth [Hz], phase lag at the named frequency [deg], resonance
        peak [dB] and its frequency [Hz] (NaN where undefined).
    notes : tuple of str
        Remarks (nonlinear distortion, an undefined number).
    folder, files
        Where the results were written.
    conditions : tuple of Conditions
        Rate, length, excitation and band of the record(s).
    digests : dict
        SHA-256 of the input files, each hashed once (see ``digest``).
    """

    spec: ExperimentSpec
    frd: FrequencyResponseData
    numbers: Mapping[str, float]
    notes: tuple[str, ...] = ()
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())
    conditions: tuple[Conditions, ...] = ()
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    def summary(self) -> RecordSummary:
        """The spec numbers as the record's scalars (no interval: read from the measurement).

        A fleet of FRF records trends them: ``bandwidth`` [Hz], ``phase_lag``
        [deg], ``resonance_peak`` [dB] and ``resonance_frequency`` [Hz].
        """
        return summary_of("frf", [spec_value(k, v) for k, v in self.numbers.items()],
                          self.verdict(), notes=self.notes)

    def models(self) -> dict[str, Any]:
        """The measured frequency response as ``"frd"``."""
        return {"frd": self.frd}

    def verdict(self) -> Verdict:
        """The spec numbers and how far the measured response can be trusted."""
        f = self.frd
        checks = []
        d = f.distortion
        if d is None or d.detected is None:
            checks.append(Check("nonlinear distortion", "not tested", "info",
                                "it needs a periodic excitation that leaves some lines "
                                "unexcited (estimator = \"periodic\")"))
        elif d.detected:
            checks.append(Check("nonlinear distortion", f"p = {d.p_value:.2g}", "caution",
                                "detected at the non-excited lines: the response is the best "
                                "linear approximation at this amplitude"))
        else:
            checks.append(Check("nonlinear distortion", f"p = {d.p_value:.2g}", "pass",
                                "none detected at the non-excited lines"))
        quality = _line_quality(f, self.numbers)
        if quality is not None:
            checks.append(quality)
        for name, value in self.numbers.items():
            if spec_text(name, value, self.numbers) == NO_PEAK:
                checks.append(Check(name, "none", "info",
                                    "the gain has no peak above its low-frequency level"))
            elif math.isnan(value):
                checks.append(Check(name, "undefined", "caution",
                                    "not defined inside the measured band"))
            else:
                checks.append(Check(name, _num(value), "pass",
                                    "no peak above the low-frequency level" if
                                    name == "resonance peak [dB]" and value == 0.0 else
                                    "read from the measured response"))
        checks.append(count_check("notes", self.notes, "listed under the response"))
        tested = (f"the {f.method} frequency response of {f.output_name} from {f.input_name}"
                  + (f" referred to {f.reference_name}" if f.reference_name else "")
                  + f" ({f.n_lines} lines, {f.n_averages} averages) and the spec numbers read "
                  "from it.")
        table = Table(("spec number", "value"),
                      tuple((k, spec_text(k, v, self.numbers)) for k, v in self.numbers.items()),
                      "Spec numbers")
        return Verdict(tested, tuple(checks), self.conditions, (table,))

    def __str__(self) -> str:
        f = self.frd
        lines = [f"measured frequency response ({f.method}, {f.n_lines} lines, "
                 f"{f.n_averages} averages) of {f.output_name} from {f.input_name}"
                 + (f", referred to {f.reference_name}" if f.reference_name else "")]
        lines += [f"  {name:<28} {spec_text(name, value, self.numbers)}"
                  for name, value in self.numbers.items()]
        lines += [f"  note: {n}" for n in self.notes]
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        return {
            "servoid_version": __version__, "method": "frf",
            "experiment_file": str(self.spec.source) if self.spec.source else None,
            "data_files": [{"path": str(p), "sha256": self.digest(p)}
                           for p in self.spec.data_paths],
            "spec_numbers": {k: (None if math.isnan(v) else v) for k, v in self.numbers.items()},
            "measured_frf": self.frd.to_dict(), "notes": list(self.notes),
            "verdict": self.verdict().to_dict(), "summary": self.summary().to_dict(),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return spec_inputs(self.spec)

    def figures(self) -> dict[str, FigureWriter]:
        """The measured Bode diagram with coherence or ±2σ."""
        return {"frf.png": partial(_plot, self.frd)}

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        f = self.frd
        body = Section(
            "Measured frequency response",
            paragraphs=(
                f"{f.method} estimate of {f.output_name} from {f.input_name}"
                + (f" referred to {f.reference_name} (consistent in closed loop)"
                   if f.reference_name else "")
                + f": {f.n_lines} lines, {f.n_averages} averages. The spec numbers read from it "
                "are in the verdict above.",
                *self.notes,
            ),
            figures=(Figure.from_file(files["frf.png"], "Measured frequency response with its "
                                      "±2σ band or coherence"),),
        )
        name = self.spec.source.name if self.spec.source else "experiment"
        return Page(title=f"Frequency response: {name}", subtitle="Measured, nonparametric",
                    sections=(body,),
                    meta=(("servoid", __version__), ("experiment file", str(self.spec.source))))


def spec_numbers(model: Any, *, level_db: float, phase_frequency: float | None,
                 reference_frequency: float | None = None) -> dict[str, float]:
    """Bandwidth, phase lag at a frequency and the resonance peak of a model or FRF."""
    out: dict[str, float] = {}
    out[f"bandwidth ({level_db:g} dB) [Hz]"] = _safe(
        lambda: bandwidth(model, level_db, reference_frequency=reference_frequency))
    if phase_frequency is not None:
        out[f"phase lag at {phase_frequency:g} Hz [deg]"] = _safe(
            lambda: phase_lag(model, phase_frequency))
    try:
        peak = resonance_peak(model, reference_frequency=reference_frequency)
        out["resonance peak [dB]"] = float(peak.peak_db)
        # no peak above the low-frequency level (0 dB): no resonance, so no frequency of one
        out["resonance frequency [Hz]"] = float(peak.frequency) if peak.peak_db > 0 else math.nan
    except ServoidError:  # an undefined number is reported as NaN, not a crash
        out["resonance peak [dB]"] = out["resonance frequency [Hz]"] = math.nan
    return out


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> FrfIdentification | IdentificationResult:
    """Measure the FRF; with ``n_poles`` also fit and validate a transfer function."""
    estimation, validations = spec.records()
    first = estimation if isinstance(estimation, Experiment) else estimation[0]
    frd = estimate_frf(first, input=options["input"], output=options["output"],
                       reference=options["reference"], method=options["estimator"],
                       nperseg=options["nperseg"], period=options["period"],
                       skip_periods=options["skip_periods"], f_max=options["f_max"])
    numbers = spec_numbers(frd, level_db=options["level_db"],
                           phase_frequency=options["phase_frequency"])
    notes = []
    if frd.distortion is not None and frd.distortion.detected:
        notes.append(f"nonlinear distortion detected at the non-excited lines (p = "
                     f"{frd.distortion.p_value:.2g}): the FRF is the best linear approximation "
                     "at this amplitude")
    if options["n_poles"] is None:
        return FrfIdentification(spec, frd, numbers, tuple(notes), conditions=spec_conditions(
            spec, estimation, (), _channel(first, options)))
    target = _without_hold(frd) if options["intersample"] == "zoh" else frd
    est = fit_frf(target, options["n_poles"], options["n_zeros"], delay=options["delay"])
    est = _with_channels(est, frd, options)
    fitted = spec_numbers(est.model, level_db=options["level_db"],
                          phase_frequency=options["phase_frequency"])
    title = f"continuous transfer function fitted to the FRF ({options['n_poles']} poles, " \
            f"{est.options.get('n_zeros', options['n_zeros'])} zeros)"
    return lti_result(spec, "frf", est, title, validations, options, measured=frd, truth=truth,
                      notes=notes, closed_loop=options["reference"] is not None,
                      records=estimation,
                      spec_numbers={k: (numbers[k], fitted[k]) for k in numbers},
                      how="frequency-domain least squares refined by maximum likelihood on the "
                          "FRF")


def _without_hold(frd: FrequencyResponseData) -> FrequencyResponseData:
    """The FRF with the zero-order hold's response divided out.

    A record whose input is a DAC staircase measures the sampled system
    G_d(e^{jωT}) ≈ G(jω)·e^{−jωT/2}·sinc(ωT/2) (the hold's response; the
    aliased terms are neglected, valid where G has rolled off well before
    the Nyquist frequency), so the continuous G is fitted to G_d divided by
    the hold.
    """
    if frd.dt is None:
        return frd
    wt2 = np.pi * np.asarray(frd.frequency) * frd.dt  # ωT/2
    hold = np.exp(-1j * wt2) * np.sinc(wt2 / np.pi)
    var = None if frd.variance is None else np.asarray(frd.variance) / np.abs(hold) ** 2
    return dataclasses.replace(frd, response=np.asarray(frd.response) / hold, variance=var)


def _with_channels(est: Any, frd: FrequencyResponseData, options: Mapping[str, Any]) -> Any:
    role = options["input"] if options["input"] in ("u", "r") else "u"
    return dataclasses.replace(est, options={**est.options, "input": role,
                                             "inputs": [frd.input_name],
                                             "output": frd.output_name,
                                             "intersample": options["intersample"]})


def _channel(exp: Experiment, options: Mapping[str, Any]) -> str | None:
    """The excitation channel: the reference of a closed-loop record, else the input."""
    for key in ("reference", "input"):
        name = options[key]
        if name in ("u", "r"):
            names = exp.names_of(name)
            name = names[0] if names else None
        if name:
            return str(name)
    return None


def _line_quality(frd: FrequencyResponseData, numbers: Mapping[str, float]) -> Check | None:
    """Median coherence (Welch) or relative std of the lines up to the bandwidth.

    Up to the bandwidth (or the resonance, if higher) lies what the spec
    numbers describe; beyond it the gain falls towards the noise.
    """
    f = np.asarray(frd.frequency, dtype=float)
    edges = [v for k, v in numbers.items() if k.startswith(("bandwidth", "resonance frequency"))
             and math.isfinite(v)]
    keep = (f > 0) & (f <= max(edges)) if edges else f > 0
    if not keep.any():
        return None
    where = f"over the {int(keep.sum())} lines up to {max(edges):.3g} Hz" if edges else \
        "over the lines"
    if frd.coherence is not None:
        value = float(np.median(np.asarray(frd.coherence)[keep]))
        return Check("coherence", f"median {value:.2f}", "info",
                     f"{where}; 1 where the output is linear in the input and noise-free")
    if frd.variance is not None:
        rel = np.sqrt(np.asarray(frd.variance)[keep]) / np.abs(np.asarray(frd.response)[keep])
        return Check("line uncertainty", f"median {100 * float(np.median(rel)):.2g} %", "info",
                     f"standard deviation of |G| relative to |G| {where}")
    return None


def _safe(fn: Any) -> float:
    try:
        return float(fn())
    except ServoidError:  # e.g. no −3 dB crossing inside the measured band
        return math.nan


def _num(x: float) -> str:
    return "undefined in the measured band" if math.isnan(x) else f"{x:.5g}"



def _plot(frd: FrequencyResponseData, path: Path, overwrite: bool) -> None:
    plot_bode_bands({}, path, measured=frd, unit=frd.unit, title="measured frequency response",
                    overwrite=overwrite)


FRF = Method(
    name="frf",
    summary="measured frequency response (Welch H1 with coherence, or averaged over excitation "
            "periods with its variance), the spec numbers, and optionally a continuous "
            "transfer function fitted to it",
    options=(
        Option("input", "u", text(), "input channel or role (u, r)"),
        Option("output", None, optional(text()), "output channel"),
        Option("reference", None, optional(text()),
               "reference channel or role (\"r\") of a closed-loop record: S_yr/S_ur"),
        Option("estimator", "auto", choice(("auto", "welch", "periodic")),
               "periodic averaging (the record's excitation period) or Welch"),
        Option("nperseg", None, optional(integer(minimum=8)), "Welch segment length [samples]"),
        Option("period", None, optional(integer(minimum=2)),
               "excitation period [samples] (default: from the record's notes)"),
        Option("skip_periods", 1, integer(minimum=0), "leading periods dropped as transient"),
        Option("f_max", None, optional(number(positive=True, unit="Hz")),
               "highest frequency kept [Hz]"),
        Option("level_db", -3.0, number(), "bandwidth level below the low-frequency gain [dB]"),
        Option("phase_frequency", None, optional(number(positive=True, unit="Hz")),
               "frequency of the phase-lag spec number [Hz]"),
        Option("n_poles", None, optional(integer(minimum=1)),
               "fit a continuous transfer function with this many poles"),
        Option("n_zeros", None, optional(integer(minimum=0)),
               "its zeros (default n_poles − 1)"),
        Option("delay", 0.0, number(nonneg=True, unit="s"), "its input delay [s]"),
        Option("intersample", "zoh", choice(("zoh", "foh", "bandlimited")),
               "the logged input between samples; zoh: the hold's response is divided out of "
               "the FRF before the fit, and the fit is validated with a ZOH"),
        Option("horizon", 5, integer(minimum=1), "k of the k-step prediction fit [samples]"),
    ),
    run=run,
    example=partial(open_loop, identify={"method": "frf"}),
)
