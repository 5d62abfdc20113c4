"""Pieces shared by the identification workflows."""

from __future__ import annotations

import dataclasses
import os
import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._checks import as_float, as_str, read_json
from .._errors import (
    DataError,
    FileFormatError,
    OptionError,
    OutputExistsError,
    ServoidError,
    ServoidWarning,
    SimulationDivergedError,
)
from .._words import option
from ..data import Experiment, ExperimentSet
from ..estimate import Estimate
from ..report import Figure, Section, Table, pvalue_text
from ..validate import ValidationReport, data_limits

__all__ = ["REPORT_KEYS", "DivergedRun", "check_outputs", "check_sizes", "data_limit_notes",
           "keyed", "parameter_table", "read_truth", "report_options", "sha256", "spec_inputs",
           "truth_from_spec", "validation_section", "warnings_as_notes"]

REPORT_KEYS = ("folder", "truth")


@dataclass(frozen=True)
class DivergedRun:
    """A validation record on which the model's free run diverged.

    It stands where a :class:`~servoid.validate.ValidationReport` would:
    the model failed this validation, and there are no metrics to give.

    Attributes
    ----------
    experiment : str
        The validation record's name ('' for the held-back part).
    output : str
        The output channel simulated.
    sample : int
        First sample whose simulated value is not finite.
    time : float
        Its time from the record's start [s].
    """

    experiment: str
    output: str
    sample: int
    time: float

    @classmethod
    def from_error(cls, error: SimulationDivergedError, experiment: str, output: str,
                   dt: float) -> DivergedRun:
        """The record of a :class:`~servoid.SimulationDivergedError`."""
        return cls(experiment, output, error.sample, error.sample * dt)

    @property
    def note(self) -> str:
        """The verdict in words, naming the sample, the time and the record."""
        record = repr(self.experiment) if self.experiment else "the held-back part"
        return (f"the free run diverges at sample {self.sample} (t = {self.time:.6g} s) of record "
                f"{record}: the model is unstable in simulation there, whatever its one-step "
                "fit, and fails this validation (no metrics); try a lower order or degree, or "
                "estimate on data that cover this record's range")

    def notes(self) -> tuple[str, ...]:
        """The verdict, as :meth:`ValidationReport.notes` gives them."""
        return (self.note,)

    def summary(self) -> dict[str, Any]:
        """What ``results.json`` holds for the record: where it diverged."""
        return {"experiment": self.experiment, "output": self.output,
                "diverged_at": {"sample": self.sample, "time": self.time}, "note": self.note}

    def __str__(self) -> str:
        record = f" {self.experiment!r}" if self.experiment else ""
        return (f"validation{record} of {self.output!r}: FAILED — the free run diverges at "
                f"sample {self.sample} (t = {self.time:.6g} s)")


@contextmanager
def warnings_as_notes() -> Iterator[list[str]]:
    """Collect the ServoidWarnings of a block as notes; pass any other warning on.

    The caller words the notes (a result warns each again, from the run,
    so a script still sees them as warnings).
    """
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        try:
            yield notes
        finally:
            others = []
            for w in caught:
                if issubclass(w.category, ServoidWarning):
                    notes.append(str(w.message))
                else:
                    others.append(w)
    for w in others:  # outside the catch, so the caller's filters decide
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def truth_from_spec(spec: Any, names: Sequence[str]) -> dict[str, float] | None:
    """The known values of ``names`` from ``[report] truth``, or None."""
    name = report_options(spec.report).get("truth")
    if name is None:
        return None
    base = spec.source.parent if spec.source else Path.cwd()
    return read_truth(base / name, list(names)) or None


def report_options(table: Mapping[str, Any]) -> dict[str, str]:
    """Check ``[report]``: only ``folder`` and ``truth``, both paths as strings."""
    unknown = sorted(set(table) - set(REPORT_KEYS))
    if unknown:
        raise OptionError(
            f"unknown key(s) in [report]: {', '.join(unknown)}; valid: {', '.join(REPORT_KEYS)}"
        )
    return {key: as_str(key, value, where="[report]") for key, value in table.items()}


def read_truth(path: Path, names: Sequence[str]) -> dict[str, float]:
    """The known parameters ``names`` found in a JSON truth file, as floats.

    The file is an object holding the names at its top level or under
    ``"parameters"``; names absent from it are left out.
    """
    data = read_json(path, "truth file")
    if not isinstance(data, Mapping):
        raise FileFormatError(f"truth file {path} must hold a JSON object, got "
                              f"{type(data).__name__}")
    if not all(k in data for k in names) and isinstance(data.get("parameters"), Mapping):
        data = data["parameters"]
    return {k: as_float(k, data[k], where=f"truth file {path}:") for k in names if k in data}


def spec_inputs(spec: Any) -> tuple[Path, ...]:
    """Every file a run of ``spec`` reads: data, validation records, the TOML, the truth."""
    out = [*spec.data_paths, *spec.validation_paths]
    if spec.source:
        out.append(Path(spec.source))
        truth = report_options(spec.report).get("truth")
        if truth:
            out.append(spec.source.parent / truth)
    return tuple(out)


@contextmanager
def keyed(keys: Mapping[str, str]) -> Iterator[None]:
    """Name the experiment-file key behind a library error about one of its parameters.

    ``keys`` maps a parameter the workflow passes on (``transient``) to the
    key it came from (``[validation] transient``); an error whose message
    starts with the parameter is re-raised starting with the key instead.
    """
    try:
        yield
    except ServoidError as exc:
        text = str(exc)
        for word, key in keys.items():
            if re.match(rf"{re.escape(word)}\b", text):  # servoid errors take one message
                raise type(exc)(key + text[len(word):]) from None
        raise


def check_sizes(paths: Sequence[Path], max_bytes: int) -> None:
    """Refuse a file larger than ``max_bytes`` before anything reads it.

    A missing file is left to the reader, whose message names it.
    """
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes < 1:
        raise OptionError(f"max_bytes (--max-bytes) must be a positive whole number of bytes, "
                          f"got {max_bytes!r}")
    for path in paths:
        size = path.stat().st_size if path.is_file() else 0
        if size > max_bytes:
            raise DataError(
                f"{path} has {size:,} bytes, over the budget of {max_bytes:,}; if the file is "
                "what you meant to read, raise --max-bytes (max_bytes=)"
            )


def check_outputs(targets: Sequence[Path], inputs: Sequence[Path], overwrite: bool) -> None:
    """Refuse to write over an input, or over earlier results unless ``overwrite``."""
    # realpath, not Path.resolve: a loop of links is left for the readers to name
    protected = {Path(os.path.realpath(p)) for p in inputs}
    for path in targets:
        if Path(os.path.realpath(path)) in protected:
            raise OutputExistsError(f"refusing to write {path}: it is an input of this run")
        if path.exists() and not overwrite:
            raise OutputExistsError(
                f"{path} exists from an earlier run; pass "
                f"{option('overwrite=True', '--overwrite')} or "
                "choose another folder"
            )


def parameter_table(estimate: Estimate, caption: str = "") -> Table:
    """Parameters with standard deviation and 95 % interval as a report table."""
    rows = tuple(
        (r.name, f"{r.value:.6g}", f"{r.std:.3g}", f"[{r.ci_low:.6g}, {r.ci_high:.6g}]", r.unit)
        for r in estimate.table(0.95)
    )
    return Table(("parameter", "estimate", "std", "95 % CI", "unit"), rows, caption)


def validation_section(report: ValidationReport, fig_sim: Path, fig_res: Path) -> Section:
    """Metrics, verdicts and figures of a validation as a report section."""
    res = report.residuals
    metrics = Table(
        ("metric", "value"),
        (
            ("samples", str(report.measured.size - report.first)),
            ("simulation fit", f"{report.fit_percent:.2f} %"),
            (f"{report.horizon}-step prediction fit", f"{report.prediction_fit_percent:.2f} %"),
            ("NRMSE", f"{report.nrmse:.4g}"),
            ("RMSE", f"{report.rmse:.4g}"),
            ("VAF", f"{report.vaf:.2f} %"),
            ("relative error", f"{report.relative_error:.3g} %"),
            ("residual whiteness (Ljung–Box)",
             f"{pvalue_text(res.whiteness_pvalue)} → {'white' if res.is_white else 'not white'}"),
            ("input–residual independence",
             "n/a" if res.independence_pvalue != res.independence_pvalue else
             f"{pvalue_text(res.independence_pvalue)} → "
             f"{'independent' if res.is_independent else 'correlated'}"),
            *_nonlinearity_rows(report),
        ),
        caption="On data not used for fitting",
    )
    return Section(
        "Validation",
        paragraphs=(
            (f"The model is simulated from the input alone on data not used for fitting "
             f"({_initial_text(report)}) and compared with the measurement. Residual "
             f"correlations are tested at {100 * res.confidence:.0f} % confidence."),
            *report.notes(),
        ),
        tables=(metrics,),
        figures=(
            Figure.from_file(fig_sim, "Measured vs simulated and predicted output"),
            Figure.from_file(fig_res, "Residual autocorrelation and input–residual "
                             "cross-correlation with confidence band"),
        ),
    )


def _nonlinearity_rows(report: ValidationReport) -> tuple[tuple[str, str], ...]:
    """The higher-order tests beside the linear ones: each correlation, then the decision."""
    nl = getattr(report, "nonlinearity", None)
    if nl is None or not nl.tested:
        return ()
    rows = tuple((f"higher-order test {k}", pvalue_text(nl.pvalues[k])) for k in nl.tested)
    return (*rows, ("unmodelled nonlinearity (combined)",
                    f"{pvalue_text(nl.pvalue)} → {'detected' if nl.detected else 'none'}"))


def _initial_text(report: ValidationReport) -> str:
    initial = getattr(report, "initial", "measured")
    if initial == "measured":
        return f"the first {report.first} samples set the initial conditions"
    if initial == "estimate":
        head = "from the initial state that fits the record best (least squares)"
    else:
        head = "from rest"
    if report.first:
        head += f"; the first {report.first} samples are excluded as a transient"
    return head


def sha256(path: Path) -> str:
    """SHA-256 of a file, hex: read once per run (:func:`servoid.data.file_sha256`)."""
    from ..data import file_sha256

    return file_sha256(path)


def data_limit_notes(estimate: Estimate, data: Experiment | ExperimentSet | None,
                     closed_loop: bool, outputs: list[str]) -> tuple[Estimate, list[str]]:
    """What the record cannot fix (servoid.validate.data_limits), in the options and as notes."""
    if data is None:
        return estimate, []
    first = data if isinstance(data, Experiment) else data[0]
    inputs = [n for n in estimate.options.get("inputs") or [] if n in first.names]
    refs = first.names_of("r")
    excitation = refs[0] if closed_loop and len(refs) == 1 else (
        inputs[0] if len(inputs) == 1 else None)
    outputs = [n for n in outputs if n in first.names]
    found = data_limits(data, excitation=excitation, inputs=inputs, outputs=outputs)
    if not found:
        return estimate, []
    options = {**estimate.options, "data_limits": [d.to_dict() for d in found]}
    return dataclasses.replace(estimate, options=options), [
        f"the data cannot fix every parameter: {d.text()}" for d in found]
