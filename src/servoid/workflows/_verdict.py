"""The pieces every result's verdict is built from: test conditions and checks.

Each result builds its :class:`~servoid.report.Verdict` from its own
objects (validation reports, estimates, structure tests) with these
helpers, so a check and the note about the same number read the same
fields: :func:`validation_checks` follows :meth:`ValidationReport.notes
<servoid.validate.ValidationReport.notes>` case by case (a fit below zero
and input-correlated residuals reject the model; coloured residuals reject
only a noise model, and an output-error model has none).

The band of a record is the one its excitation declares (a design record
in the data file's notes), else read from the spectrum of the excitation
channel: the frequencies where its Welch power spectrum lies within
:data:`BAND_DB` of its peak, at the resolution of the spectrum.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..data import Experiment, ExperimentSet
from ..report import Check, Conditions, Verdict, pvalue_text
from ..validate import ValidationReport

__all__ = ["BAND_DB", "NO_PEAK", "count_check", "covariance_is_robust", "diverged_check",
           "excited_band", "interval_check", "loop_verdict", "nonlinearity_checks",
           "record_conditions", "spec_conditions", "spec_text", "validation_checks"]

#: Level below the input spectrum's peak that bounds the excited band [dB]: the -3 dB band
#: servoid's excitation designers declare (servoid.signals), read from the spectrum.
BAND_DB = 3.0
#: Shortest Welch segment of the band estimate [samples] (the whole of a shorter record).
_SEGMENT = 256
#: Longest segment [samples]: lines 2⁻¹⁶ of the rate apart (15 mHz at 1 kHz).
_LONGEST = 1 << 16
#: Most segments averaged (spread over a longer record): the estimate's spread is then
#: about 1/√32 of the power, 0.8 dB, and a 1e7-sample record costs 32 FFTs, not 300.
_AVERAGES = 32


def excited_band(x: Any, dt: float) -> tuple[tuple[float, float], float] | None:
    """The band of a signal's spectrum within :data:`BAND_DB` of its peak.

    The spectrum is Welch's (Hann window, half-overlapping segments) over
    segments of an eighth of the record (at least 256 samples, at most
    :data:`_LONGEST`), which steadies a random signal's; when the band it
    finds is narrower than three of its lines (a sine over a few periods),
    the whole record's periodogram resolves it instead (up to
    :data:`_LONGEST` samples, the record's end).

    Returns
    -------
    ((f_low, f_high), resolution) or None
        The band [Hz] and the spectrum's line spacing [Hz]; None for a
        constant (or too short) signal.
    """
    v = np.asarray(x, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 8:
        return None
    v = v - v.mean()
    if not np.any(v):
        return None
    found = _band(v, dt, min(max(_SEGMENT, v.size // 8), _LONGEST))
    if found is not None and found[0][1] - found[0][0] < 3 * found[1] and v.size > _SEGMENT:
        found = _band(v[-_LONGEST:], dt, min(v.size, _LONGEST))
    return found


def _band(v: Any, dt: float, nperseg: int) -> tuple[tuple[float, float], float] | None:
    """Band and line spacing of an averaged periodogram, one segment in memory at a time."""
    nperseg = min(nperseg, v.size)
    window = np.hanning(nperseg + 2)[1:-1]  # no zero ends: a one-segment record keeps them
    starts = np.arange(0, v.size - nperseg + 1, max(nperseg // 2, 1))
    if starts.size > _AVERAGES:  # a long record: as many segments as steady the estimate
        starts = starts[np.linspace(0, starts.size - 1, _AVERAGES).astype(int)]
    power = np.zeros(nperseg // 2 + 1)
    for start in starts:
        segment = v[start:start + nperseg]
        power += np.abs(np.fft.rfft((segment - segment.mean()) * window)) ** 2
    power[0] = 0.0  # the mean is not excitation
    peak = float(power.max())
    if not peak > 0.0:
        return None
    lines = np.flatnonzero(power >= peak * 10.0 ** (-BAND_DB / 10.0))
    spacing = 1.0 / (nperseg * dt)
    return (float(lines[0] * spacing), float(lines[-1] * spacing)), spacing


def record_conditions(exp: Experiment, label: str, channel: str | None = None) -> Conditions:
    """Rate, length, excitation and band of one record.

    Parameters
    ----------
    exp : Experiment
        The record as identified (after preprocessing).
    label : str
        Its role and name (``"estimation: run0.csv"``).
    channel : str, optional
        The excitation channel; default the reference r, else the input u.
    """
    kind, declared = _excitation(exp.notes)
    rate = 1.0 / exp.dt
    # the named channel, else the reference, else the input: the first that is not constant
    candidates = [c for c in dict.fromkeys((channel, *exp.names_of("r"), *exp.names_of("u")))
                  if c is not None and c in exp.names]
    if not candidates:
        return Conditions(label, rate, exp.n_samples, kind, "", None, "no input channel")
    if declared is not None:
        return Conditions(label, rate, exp.n_samples, kind, candidates[0], declared,
                          "declared by the excitation")
    for name in candidates:
        found = excited_band(exp[name], exp.dt)
        if found is not None:
            band, resolution = found
            return Conditions(label, rate, exp.n_samples, kind, name, band,
                              f"spectrum within {BAND_DB:g} dB of its peak, lines "
                              f"{resolution:.3g} Hz apart")
    return Conditions(label, rate, exp.n_samples, kind, candidates[0], None)


def spec_conditions(spec: Any, estimation: Experiment | ExperimentSet,
                    validations: Sequence[Experiment], channel: str | None = None,
                    ) -> tuple[Conditions, ...]:
    """Conditions of the estimation record(s) and each validation record of a spec."""
    parts = [estimation] if isinstance(estimation, Experiment) else list(estimation)
    out = []
    if spec.validation.files:
        names = [p.name for p in spec.data_paths]
        for k, part in enumerate(parts):
            name = names[k] if k < len(names) else part.name
            out.append(record_conditions(part, f"estimation: {name}", channel))
        for path, v in zip(spec.validation_paths, validations, strict=False):
            out.append(record_conditions(v, f"validation: {path.name}", channel))
        return tuple(out)
    name = spec.data_path.name
    out.append(record_conditions(parts[0], f"estimation: {name}, first part", channel))
    for v in validations:
        out.append(record_conditions(v, f"validation: {name}, held-back part", channel))
    return tuple(out)


def covariance_is_robust(kind: object) -> bool:
    """Whether a covariance note names one that allows for coloured residuals."""
    return str(kind or "").startswith(("robust", "sandwich"))


def validation_checks(report: ValidationReport, *, covariance: object = None,
                      record: str = "") -> list[Check]:
    """Fit, input–residual independence and whiteness of one validation, as checks.

    Case by case what :meth:`ValidationReport.notes` says of the same
    numbers: a negative fit and input-correlated residuals reject the
    model; coloured residuals reject a noise model (then intervals that
    assume white residuals are too narrow) and say nothing against an
    output-error model, which has none.  On a closed-loop record (the test
    runs on the lags where the input leads) an output-error model's
    coloured residuals correlate with past inputs even for the true plant,
    because the loop feeds the noise back into the input: there the
    correlation is the note's "or the data were taken in closed loop" and
    leaves the verdict inconclusive instead of rejecting.

    Parameters
    ----------
    report : ValidationReport
        The validation.
    covariance : str, optional
        The estimate's covariance kind (``"robust"``, ``"white"``, …).
    record : str
        The record's name, prefixed to each check when there are several.
    """
    on = f" ({record})" if record else ""
    r = report.residuals
    out = []
    fit = report.fit_percent
    if fit < 0:
        out.append(Check(f"simulation fit{on}", f"{fit:.1f} %", "fail",
                         "the model's simulation is further from the measured output than the "
                         "output's mean value"))
    else:
        out.append(Check(f"simulation fit{on}", f"{fit:.1f} %", "pass",
                         "the model's simulation (not its prediction) follows the measured "
                         "output on data not used for fitting"))
    p_ind = r.independence_pvalue
    if p_ind == p_ind:  # tested (an input was there)
        lags = " at the lags where the input leads (closed loop)" if r.causal else ""
        if r.is_independent:
            out.append(Check(f"input–residual independence{on}", pvalue_text(p_ind), "pass",
                             f"no input dynamics left in the residuals{lags}"))
        elif r.causal and not report.noise_model and not r.is_white:
            # in a loop the input carries the past noise: with coloured noise the residuals of
            # the true plant correlate with past inputs too, so the test cannot decide
            out.append(Check(f"input–residual independence{on}", pvalue_text(p_ind), "caution",
                             "the residuals correlate with past inputs: the dynamics are not "
                             "captured, or the coloured noise comes back through the loop "
                             "(closed-loop record; the true plant does this too) — a noise "
                             "model (bj) whitens the residuals and decides"))
        else:
            out.append(Check(f"input–residual independence{on}", pvalue_text(p_ind), "fail",
                             "the residuals correlate with the input: the dynamics from the "
                             "input are not captured"))
    out += nonlinearity_checks(report, on)
    robust = covariance_is_robust(covariance)
    p_white = pvalue_text(r.whiteness_pvalue)
    if r.is_white:
        out.append(Check(f"residual whiteness{on}", p_white, "pass",
                         "white: nothing left that the noise model misses" if report.noise_model
                         else "white"))
    elif not report.noise_model:
        out.append(Check(f"residual whiteness{on}", p_white, "info",
                         "coloured; an output-error model describes the dynamics, not the "
                         "noise, so this does not reject it (the input–residual and "
                         "higher-order tests judge the dynamics)"))
    else:
        out.append(Check(f"residual whiteness{on}", p_white, "caution",
                         "not white: the noise model is rejected by the data"
                         + ("; the intervals here are robust (they allow for coloured "
                            "residuals)" if robust else
                            "; intervals that assume white residuals are too narrow")))
    if report.clipped:
        out.append(Check(f"clipped samples{on}", str(report.clipped), "info",
                         f"simulated samples clipped to the declared limits of "
                         f"{report.output!r}"))
    return out


def nonlinearity_checks(report: ValidationReport, on: str = "") -> list[Check]:
    """The higher-order correlation tests of one validation, as a check (none untested).

    Beside the linear input–residual test: a model whose residuals correlate
    with u², ε²·u² or ε·u leaves a nonlinearity unexplained
    (:func:`~servoid.validate.nonlinearity_tests`), a caution that names the
    families that could capture it.
    """
    nl = getattr(report, "nonlinearity", None)
    if nl is None or not nl.tested:
        return []
    name = f"higher-order (nonlinearity) tests{on}"
    if nl.detected:
        return [Check(name, pvalue_text(nl.pvalue), "caution",
                      f"the residuals correlate with nonlinear functions of the input "
                      f"({nl.strongest} strongest): the model leaves a nonlinearity "
                      "unexplained — a block-oriented model or a NARX may capture it")]
    return [Check(name, pvalue_text(nl.pvalue), "pass",
                  "no nonlinear function of the input (" + ", ".join(nl.tested) + ") left in "
                  "the residuals")]


def interval_check(covariance: object) -> Check:
    """Which covariance the parameter intervals come from, and what it assumes."""
    robust = covariance_is_robust(covariance)
    return Check("intervals", str(covariance), "info",
                 "robust: they allow for coloured residuals" if robust else
                 "they assume the residuals the model's noise model predicts")


def diverged_check(run: Any) -> Check:
    """A validation record on which the free run diverged: the model fails it."""
    record = run.experiment or "the held-back part"
    return Check(f"free run ({record})", f"diverges at t = {run.time:.6g} s", "fail",
                 f"the simulation is unstable on this record (sample {run.sample}); no "
                 "metrics")


def count_check(name: str, items: Sequence[str], meaning: str, outcome: str = "info") -> Check:
    """How many notes (or flags) a run gave, pointing at where they are listed."""
    return Check(name, str(len(items)), outcome if items else "info",  # type: ignore[arg-type]
                 meaning if items else "none")


def loop_verdict(ident: Any) -> Verdict:
    """The rigid-axis verdict: closed-loop simulation of data the fit did not use.

    ``ident`` is an :class:`~servoid.plants.rigid.InverseDynamicsIdentification`:
    each estimate simulated in the known loop on the held-back part
    (``[split]``) or on each other record (``[validation] file``); a
    relative error of 100 % or more (no better than predicting zero) fails.
    """
    checks: list[Check] = []
    held: list[tuple[str, str, Mapping[str, float]]] = [
        ("held-back part", key, errs) for key, errs in (ident.holdout or {}).items()]
    for record, scores in list((ident.validation or {}).items())[1:]:  # the first is fitted
        held += [(record, key, errs) for key, errs in scores.items()]
    for record, key, errs in held:
        for channel in ("position", "force"):
            err = float(errs[channel])
            name = f"{channel} error, {key} ({record})"
            if not err < 100.0:
                checks.append(Check(name, f"{err:.4g} %", "fail",
                                    "the simulated loop is no closer to the measurement than "
                                    "zero"))
            else:
                checks.append(Check(name, f"{err:.4g} %", "pass",
                                    "closed-loop simulation from the reference, relative error "
                                    "100·‖y − ŷ‖/‖y‖ on data the fit did not use"))
    if not held:
        checks.append(Check("held-back data", "none", "caution",
                            "every record was used for fitting ([split] holdout = false or no "
                            "[validation] file): nothing tested the model on new data"))
    first = next(iter(ident.estimates))
    errs = ident.loop_errors[first]
    checks.append(Check(f"position error, {first} (estimation record)",
                        f"{errs['position']:.4g} %", "info",
                        "closed-loop simulation of the record it was fitted on"))
    checks.append(Check(f"force error, {first} (estimation record)", f"{errs['force']:.4g} %",
                        "info", "closed-loop simulation of the record it was fitted on"))
    checks.append(count_check("notes", ident.notes, "listed under Notes"))
    tested = (f"the rigid-axis inverse dynamic model ({', '.join(ident.estimates)}) in its "
              "known position loop, simulated from the reference on "
              + ("the held-back part of the record" if ident.holdout else
                 "each validation record" if ident.validation else "the record it was fitted on")
              + ".")
    return Verdict(tested, tuple(checks), ident.conditions)


#: A resonance frequency where the gain has no peak above its low-frequency level.
NO_PEAK = "none (no peak)"


def spec_text(name: str, value: float, numbers: Mapping[str, float]) -> str:
    """A spec number as shown: an undefined one says why.

    The resonance frequency of a response without a peak (peak 0 dB) is
    :data:`NO_PEAK`; any other undefined number lies outside the band.
    """
    if value == value and math.isfinite(value):
        return f"{value:.5g}"
    if name == "resonance frequency [Hz]" and numbers.get("resonance peak [dB]") == 0.0:
        return NO_PEAK
    return "undefined in the measured band"


def _excitation(notes: Mapping[str, Any]) -> tuple[str, tuple[float, float] | None]:
    """The excitation's name and declared band [Hz] from a record's notes."""
    value = notes.get("excitation") if isinstance(notes, Mapping) else None
    if isinstance(value, Mapping):
        kind = str(value.get("kind") or "")
        band = value.get("band") or value.get("band_hz")
        try:
            low, high = (float(b) for b in band)  # type: ignore[union-attr]
        except (TypeError, ValueError):
            return kind, None
        return kind, (low, high) if 0.0 <= low < high else None
    return (str(value), None) if isinstance(value, str) and value else ("", None)
