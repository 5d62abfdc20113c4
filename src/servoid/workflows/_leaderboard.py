"""The leaderboard of a multi-method run: every candidate side by side, the chosen one marked.

:func:`choose` scores the candidates on held-out data (:mod:`._choice`),
picks one, fits every admissible candidate on the whole estimation data and
validates it on the ``[validation]`` records, and returns a
:class:`ChoiceResult`: the chosen candidate's result (its model, verdict,
report sections and ``results.json``) with the leaderboard beside it — a
console table, a ``"choice"`` entry in ``results.json`` (every candidate's
scores, status, fit time and model), and a report section with the table,
the candidates' simulations overlaid on the first validation record and
their Bode diagrams overlaid with ±2σ bands.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ConvergenceError, ServoidError
from ..data import ExperimentSpec, as_segments
from ..report import Check, Figure, Page, Section, Table, Verdict, new_figure, save_figure
from ..validate import ValidationReport
from ._choice import (
    REFIT_TOLERANCE,
    Fold,
    Scheme,
    Score,
    _HeldSpec,
    _status,
    candidates_of,
    declares_loop,
    fit_on,
    folds_of,
    map_candidates,
    parsed_options,
    pick,
    refit_gap,
    scheme_of,
    score_candidates,
    score_name,
)
from ._gate import gate as gate_of
from ._methods import get_method
from ._registry import FigureWriter
from ._summary import Displayed, RecordSummary

__all__ = ["ChoiceResult", "Entry", "candidate_models", "choose", "fit_choice"]

#: Candidates drawn in the overlaid figures (the chosen and the best-scored others).
_DRAWN = 6


@dataclass(frozen=True, eq=False)
class Entry:
    """One candidate of the leaderboard: its held-out score and its full fit."""

    score: Score
    result: Any = None
    error: str = ""
    seconds: float = math.nan
    refit_gap: float = math.nan
    fitted_on: str = "all"

    @property
    def label(self) -> str:
        """The candidate's name."""
        return self.score.candidate.label

    @property
    def validation(self) -> ValidationReport | None:
        """Its validation on the first ``[validation]`` record (None: not run, or diverged)."""
        if self.result is None:
            return None
        first = self.result.validations[0]
        return first if isinstance(first, ValidationReport) else None

    def row(self, chosen: str) -> dict[str, Any]:
        """Plain data for ``results.json``."""
        s = self.score
        v = self.validation
        nl = getattr(v, "nonlinearity", None) if v is not None else None
        model = None
        if self.result is not None:  # the entry load_results rebuilds a model from
            model = self.result.to_dict().get("model")
        return {"label": self.label, "method": s.candidate.method,
                "options": dict(s.candidate.table), "chosen": self.label == chosen,
                "status": s.status, "held_out_fit_percent": _finite(s.mean),
                "held_out_se": _finite(s.se), "n_parameters": s.n_parameters,
                "fit_seconds": _finite(s.seconds), "full_fit_seconds": _finite(self.seconds),
                "held_out_nonlinearity": s.nonlinearity,
                "held_out_blocks": [_finite(b) for b in s.blocks],
                "refit_gap_points": _finite(self.refit_gap), "fitted_on": self.fitted_on,
                "validation_fit_percent": None if v is None else _finite(v.fit_percent),
                "validation_independence_pvalue": None if v is None else
                _finite(v.residuals.independence_pvalue),
                "validation_nonlinearity": None if nl is None else nl.to_dict(),
                "error": self.error or None, "model": model}


@dataclass(frozen=True, eq=False, repr=False)
class ChoiceResult(Displayed):
    """Several candidates scored on held-out data, one chosen, all validated.

    Attributes
    ----------
    spec : ExperimentSpec
    chosen : Identification
        The chosen candidate's result on the whole estimation data.
    entries : tuple of Entry
        Every candidate, in the order scored.
    label : str
        The chosen candidate's name.
    reason : str
        Why it was chosen, in words.
    rankable : bool
        False when the chosen candidate's fit is not reproducible (its
        model fitted on the folds differs from the one fitted on all the
        estimation data by more than ``REFIT_TOLERANCE`` fit points on the
        folds' own samples): the held-out scores then judge other models
        than the ones returned, and the reason says so.
    scheme : Scheme
        How the candidates were scored.
    gate : str
        For ``auto``: whether the nonlinear families were added, and why.
    """

    spec: ExperimentSpec
    chosen: Any
    entries: tuple[Entry, ...]
    label: str
    reason: str
    scheme: Scheme
    gate: str = ""
    rankable: bool = True
    folder: Path | None = None
    files: tuple[Path, ...] = field(default=())
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    @property
    def method(self) -> str:
        """The chosen candidate's method."""
        return str(getattr(self.chosen, "method", self.entries[0].score.candidate.method))

    @property
    def estimate(self) -> Any:
        """The chosen candidate's estimate."""
        return getattr(self.chosen, "estimate", None)

    @property
    def validations(self) -> tuple[Any, ...]:
        """The chosen candidate's validations."""
        return tuple(getattr(self.chosen, "validations", ()))

    def candidate(self, label: str) -> Any:
        """The full-fit result of a candidate by its label (as the leaderboard names it)."""
        for e in self.entries:
            if e.label == label:
                if e.result is None:
                    raise ConvergenceError(f"candidate {label!r} has no model ({e.score.status}"
                                           f"{': ' + e.error if e.error else ''})")
                return e.result
        raise KeyError(f"no candidate {label!r}; the candidates are "
                       f"{', '.join(e.label for e in self.entries)}")

    # -- console, JSON ----------------------------------------------------------------------
    def table(self) -> Table:
        """The leaderboard as a report table, best held-out score first."""
        rows = []
        for e in _ranked(self.entries):
            s = e.score
            v = e.validation
            nl = getattr(v, "nonlinearity", None) if v is not None else None
            rows.append((
                ("▶ " if e.label == self.label else "") + e.label,
                str(s.n_parameters) if s.n_parameters else "—",
                "—" if not math.isfinite(s.mean) else
                f"{s.mean:.2f}" + ("" if not math.isfinite(s.se) else f" ± {s.se:.2f}"),
                "—" if v is None else f"{v.fit_percent:.2f}",
                "—" if v is None else ("independent" if v.residuals.is_independent else
                                       "correlated"),
                "—" if nl is None or not nl.tested else
                ("LEFT" if nl.detected else "none"),
                f"{s.seconds:.2f}",
                (s.status if s.status == "ok" else s.status[:60]) +
                ("" if e.fitted_on == "all" else f"; the model of {e.fitted_on}")))
        return Table(("candidate", "parameters", "held-out fit %", "validation fit %",
                      "input–residual", "nonlinearity", "fit time s", "status"),
                     tuple(rows), "Leaderboard (▶ the chosen candidate; why: above)")

    def __str__(self) -> str:
        table = self.table()
        widths = [max(len(c), *(len(r[i]) for r in table.rows))
                  for i, c in enumerate(table.columns)]
        head = f"model choice among {len(self.entries)} candidates: {self.scheme.text}"
        lines = [head, "  " + "  ".join(c.ljust(w) for c, w in zip(table.columns, widths,
                                                                     strict=True))]
        lines += ["  " + "  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True))
                  for r in table.rows]
        if self.gate:
            lines.append(f"  {self.gate}")
        lines.append(f"  chosen: {self.label} — {self.reason}")
        return "\n".join(lines + [str(self.chosen)])

    def to_dict(self) -> dict[str, Any]:
        """The chosen candidate's ``results.json`` with the leaderboard under ``"choice"``."""
        out = dict(self.chosen.to_dict())
        out["choice"] = {"chosen": self.label, "reason": self.reason, "scheme": self.scheme.text,
                         "folds": self.scheme.folds, "holdout": self.scheme.holdout,
                         "purpose": self.scheme.purpose, "rule": self.scheme.rule,
                         "gate": self.gate or None, "rankable": self.rankable,
                         "candidates": [e.row(self.label) for e in self.entries]}
        out["verdict"] = self.verdict().to_dict()
        return out

    def summary(self) -> RecordSummary:
        """The chosen candidate's summary (the fleet row)."""
        return self.chosen.summary()

    def models(self) -> dict[str, Any]:
        """The chosen candidate's models."""
        return dict(self.chosen.models())

    def verdict(self) -> Verdict:
        """The chosen candidate's verdict, with the choice as a check.

        The leaderboard itself is the page's "Model choice" section, not a
        second copy in the verdict box.
        """
        v = self.chosen.verdict()
        check = Check("model choice", self.label, "info" if self.rankable else "caution",
                      f"chosen among {len(self.entries)} candidates on held-out data: "
                      f"{self.reason}")
        return Verdict(v.tested, (*v.checks, check), v.conditions, v.tables)

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read."""
        return tuple(self.chosen.inputs())

    def figures(self) -> dict[str, FigureWriter]:
        """The chosen candidate's figures, and the candidates overlaid."""
        out = dict(self.chosen.figures())
        drawn = self._drawn()
        if drawn:
            out["candidates.png"] = partial(_plot_overlay, drawn, self.label)
        bands = [e for e in drawn if _has_band(e.result)]
        if bands:
            out["candidates-bode.png"] = partial(_plot_bodes, bands, self.label)
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The chosen candidate's page, opened by the model choice."""
        page = self.chosen.page(files)
        figures = []
        if "candidates.png" in files:
            figures.append(Figure.from_file(files["candidates.png"],
                                            "The candidates simulated on the first validation "
                                            "record, over the measurement"))
        if "candidates-bode.png" in files:
            figures.append(Figure.from_file(files["candidates-bode.png"],
                                            "Bode diagrams of the linear candidates (±2σ)"))
        section = Section("Model choice", paragraphs=tuple(p for p in (
            f"{len(self.entries)} candidates {self.scheme.text}.",
            self.gate and f"{self.gate[0].upper()}{self.gate[1:]}.",
            f"Chosen: {self.label} — {self.reason}.") if p),
            tables=(self.table(),), figures=tuple(figures))
        return dataclasses.replace(page, sections=(section, *page.sections),
                                   subtitle=f"{self.label}, chosen among "
                                            f"{len(self.entries)} candidates")

    def _drawn(self) -> list[Entry]:
        ranked = [e for e in _ranked(self.entries) if e.validation is not None]
        chosen = [e for e in ranked if e.label == self.label]
        others = [e for e in ranked if e.label != self.label]
        return (chosen + others)[:_DRAWN]


def choose(spec: ExperimentSpec, options: Mapping[str, Any],
           truth: Mapping[str, float] | None) -> ChoiceResult:
    """Score, choose, fit and validate: the run of ``method = [...]`` and ``"auto"``."""
    candidates = candidates_of(spec, options)
    estimation, _validations = spec.records()
    folds = folds_of(estimation, int(options["folds"]), float(options["holdout"]))
    scores = score_candidates(spec, candidates, options, folds)
    scores = _in_the_loop(spec, scores)
    gate = ""
    if spec.identify.get("method") == "auto":
        scores, gate = gate_of(spec, options, folds, scores)
    what = score_name(options)
    if pick(scores, options["rule"], what)[0] is None:
        listed = "; ".join(f"{s.candidate.label}: {s.status}" for s in scores)
        raise ConvergenceError(f"no candidate gave a stable model that could be scored on the "
                               f"held-out data ({listed}); try other orders or methods")
    # the chosen one is fitted first, with the run's warnings and the truth
    chosen, reason, fitted, passed = fit_choice(spec, options, folds, scores, what, truth,
                                                quiet=False)
    if chosen is None:
        raise ConvergenceError("no scored candidate could be fitted on the estimation data ("
                               + "; ".join(f"{label}: {why}" for label, why in passed)
                               + "); try other orders or methods")
    result = fitted[id(chosen)].result
    if passed:
        reason += (f" ({', '.join(label for label, _ in passed)} scored better but failed on "
                   "the whole estimation data: passed over)")
    if fitted[id(chosen)].kept:
        reason += f"; {fitted[id(chosen)].kept}"
    # the others for the leaderboard (on the fleet's cluster when it runs there)
    rest = [s for s in scores if s.admissible and id(s) not in fitted]
    for s, outcome in zip(rest, map_candidates(partial(_whole_fit, spec, options, tuple(folds)),
                                               rest), strict=True):
        fitted[id(s)] = outcome
    entries = []
    for s in scores:
        if not s.admissible:
            entries.append(Entry(s))
            continue
        f = fitted[id(s)]
        entries.append(Entry(s, f.result, error=f.error, seconds=f.seconds,
                             refit_gap=f.refit_gap, fitted_on=f.fitted_on))
    caveat = _reproducibility(entries, chosen)
    return ChoiceResult(spec, result, tuple(entries), chosen.candidate.label,
                        reason + caveat, scheme_of(options), gate, rankable=not caveat,
                        digests=getattr(result, "digests", {}))


def _in_the_loop(spec: ExperimentSpec, scores: Sequence[Score]) -> list[Score]:
    """In a declared loop the fits of (u, y) as if open are not chosen.

    Held-out data from the same loop carry the same feedback, so they
    cannot show such a fit's bias; the closed-loop candidates and the
    direct approach are consistent there.  When none of those could be
    scored the open-loop fits stay (each with its own feedback caution).
    """
    if not declares_loop(spec):
        return list(scores)
    consistent = [s for s in scores if s.admissible and not s.open_loop]
    if not consistent:
        return list(scores)
    return [dataclasses.replace(s, status="passed over: fits (u, y) as if open, biased in "
                                "the loop the file declares") if s.admissible and s.open_loop
            else s for s in scores]


def fit_choice(spec: ExperimentSpec, options: Mapping[str, Any], folds: Sequence[Fold],
               scores: Sequence[Score], what: str, truth: Mapping[str, float] | None = None,
               quiet: bool = True, usable: Callable[[Fitted], str] | None = None
               ) -> tuple[Score | None, str, dict[int, Fitted], list[tuple[str, str]]]:
    """Pick among `scores` and fit the pick (:func:`_whole_fit`); a pick with no model, or
    one `usable` finds fault with (its words), is passed over for the next pick.

    Returns the chosen score (None: none left) and the reason, every attempted fit by the
    ``id`` of its score, and the (label, why) of each pick passed over.
    """
    fitted: dict[int, Fitted] = {}
    passed: list[tuple[str, str]] = []
    while True:
        chosen, reason = pick([s for s in scores if id(s) not in fitted], options["rule"], what)
        if chosen is None:
            return None, reason, fitted, passed
        f = fitted[id(chosen)] = _whole_fit(spec, options, folds, chosen, truth, quiet)
        why = f.error if f.result is None else usable(f) if usable else ""
        if f.result is not None and not why:
            return chosen, reason, fitted, passed
        passed.append((chosen.candidate.label, why))


@dataclass(frozen=True)
class Fitted:
    """A candidate's model for the leaderboard and where it was fitted.

    Attributes
    ----------
    result : Identification or None
        Validated on the ``[validation]`` records (None: no fit succeeded).
    error : str
        Why the fit on the whole estimation data failed ('' when it did not).
    seconds : float
        Wall time of the fits.
    fitted_on : str
        ``"all"`` (the estimation data), or ``"fold k"`` (the fit part of
        fold k, 1-based): the model scored on held-out data, returned
        because the fit on all the data failed or ended elsewhere.
    kept : str
        Why a fold's model was returned, in words ('' when it was not).
    refit_gap : float
        The returned model's :func:`refit_gap` (NaN: no model).
    """

    result: Any
    error: str = ""
    seconds: float = math.nan
    fitted_on: str = "all"
    kept: str = ""
    refit_gap: float = math.nan


def _whole_fit(spec: ExperimentSpec, options: Mapping[str, Any], folds: Sequence[Fold],
               score: Score, truth: Mapping[str, float] | None = None,
               quiet: bool = True) -> Fitted:
    """A candidate fitted on the whole estimation data — or its scored fold model.

    The model fitted on all the estimation data is returned when it is
    the model the held-out data scored (its refit gap within
    :data:`REFIT_TOLERANCE`).  When it is not — its fit failed, is
    unstable, or ended elsewhere than the folds' fits (a search or an
    iteration that stops at another point on more data) — each fold's fit
    is repeated, validated on the ``[validation]`` records, and the one
    that simulates all the estimation data best is returned if it does so
    better than the whole-data model: the model the held-out score judged.
    Only the estimation data decide; the validation records are not used.
    """
    start = time.perf_counter()
    method = get_method(score.candidate.method)
    parsed = parsed_options(score.candidate, options, spec)
    role = str(parsed.get("input", "u"))
    result, error = None, ""
    try:
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")  # only the chosen model's notes are warned
            result = method.run(spec, parsed, truth)
    except ServoidError as exc:
        error = str(exc)
    def gap_of(fit: Any) -> float:
        return refit_gap(score, [fit_on(getattr(fit, "estimate", None), f.fit, role)
                                 for f in folds])

    whole, gap = math.nan, math.nan
    if result is not None:
        gap = gap_of(result)
        if _status(result) == "ok" and not abs(gap) > REFIT_TOLERANCE:
            return Fitted(result, seconds=time.perf_counter() - start, refit_gap=gap)
    estimation, validations = spec.records()  # read again only here: the exception
    if result is not None:
        whole = fit_on(getattr(result, "estimate", None), estimation, role)
    best: tuple[float, int, Any] | None = None
    for k, fold in enumerate(folds):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                candidate = method.run(_HeldSpec(spec, Fold(fold.fit, tuple(validations))),
                                       parsed, truth)
        except ServoidError:
            continue
        if _status(candidate) != "ok":
            continue
        own = fit_on(getattr(candidate, "estimate", None), estimation, role)
        if math.isfinite(own) and (best is None or own > best[0]):
            best = (own, k, candidate)
    seconds = time.perf_counter() - start
    if best is None or (result is not None and _status(result) == "ok" and
                        not best[0] > whole):
        return Fitted(result, error, seconds, refit_gap=gap)
    own, k, candidate = best
    n_fold = sum(seg.n_samples for seg in as_segments(folds[k].fit))
    n_all = sum(seg.n_samples for seg in as_segments(estimation))
    if result is None:
        why = f"failed ({error.split(':')[0]})"
    elif _status(result) != "ok":
        why = "is unstable"
    else:
        why = (f"ended elsewhere: it simulates them at {whole:.1f} %, the model fitted to "
               f"{'the fold' if len(folds) == 1 else f'fold {k + 1}'} at {own:.1f} %")
    kept = (f"the fit of {score.candidate.label} on all the estimation data {why}; the model "
            f"the held-out data scored, fitted on {n_fold} of the {n_all} estimation samples, "
            "is returned")
    return Fitted(candidate, error, seconds, f"fold {k + 1}", kept, gap_of(candidate))


def _reproducibility(entries: Sequence[Entry], chosen: Score) -> str:
    """The reason's caveat when the chosen candidate's fit is not reproducible ('' if it is)."""
    mine = next(e for e in entries if e.score is chosen)
    if not abs(mine.refit_gap) > REFIT_TOLERANCE:
        return ""
    fold = float(np.nanmean(chosen.fold_fits))
    others = [e for e in entries if e is not mine and abs(e.refit_gap) > REFIT_TOLERANCE]
    listed = "; ".join(f"{e.label} {e.refit_gap:+.1f}" for e in others[:4])
    return (f"; but the held-out data cannot rank these candidates here: the chosen candidate's "
            f"fit changes with the samples it is given (on the samples its held-out model was "
            f"fitted to, that model fits {fold:.1f} % and the model fitted to all the estimation "
            f"data {fold + mine.refit_gap:.1f} %), so its held-out score judges another model "
            f"than the one returned" +
            (f" ({len(others)} other candidate{'s' if len(others) > 1 else ''} too; whole-data "
             f"model minus fold model, in fit points: {listed})" if others else "") +
            "; a longer estimation record makes the fits reproducible; until then judge the "
            "candidates on the [validation] records")


def _ranked(entries: Sequence[Entry]) -> list[Entry]:
    return sorted(entries, key=lambda e: (not e.score.admissible,
                                          -e.score.mean if math.isfinite(e.score.mean) else 0))


def _finite(x: Any) -> float | None:
    try:
        value = float(x)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _has_band(result: Any) -> bool:
    est = getattr(result, "estimate", None)
    model = getattr(est, "model", None)
    return model is not None and (hasattr(model, "freqresp") or
                                  hasattr(model, "transfer_function")) and \
        est.model_function is not None


def _plot_overlay(entries: Sequence[Entry], chosen: str, path: Path, overwrite: bool) -> None:
    fig = new_figure((8.0, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    first = entries[0].validation
    assert first is not None
    ax.plot(first.time, first.measured, color="0.3", lw=1.0, label="measured")
    for e in entries:
        v = e.validation
        assert v is not None
        style = {"lw": 1.8} if e.label == chosen else {"lw": 0.9, "alpha": 0.8}
        ax.plot(v.time[v.first:], v.simulated[v.first:],
                label=f"{'▶ ' if e.label == chosen else ''}{e.label} ({v.fit_percent:.1f} %)",
                **style)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{first.output}" + (f" [{first.unit}]" if first.unit else ""))
    ax.set_title(f"Candidates simulated on {first.experiment or 'the validation record'}")
    ax.legend(fontsize=7, loc="best")
    save_figure(fig, path, overwrite)


def _plot_bodes(entries: Sequence[Entry], chosen: str, path: Path, overwrite: bool) -> None:
    from ..estimate import frequency_band
    from ..report import plot_bode_bands

    first = entries[0].validation
    assert first is not None
    dt = float(first.time[1] - first.time[0])
    nyquist = 0.5 / dt
    f = np.logspace(np.log10(nyquist / max(first.measured.size, 1000)),
                    np.log10(nyquist * 0.999), 300)
    bands = {}
    for e in entries:
        try:
            bands[("▶ " if e.label == chosen else "") + e.label] = frequency_band(
                e.result.estimate, f)
        except (ServoidError, ValueError, np.linalg.LinAlgError):
            continue
    if bands:
        plot_bode_bands(bands, path, title="Candidates (±2σ)", overwrite=overwrite)
    else:  # nothing to draw: an empty figure says so
        fig = new_figure((6.0, 2.0))
        fig.text(0.5, 0.5, "no frequency response to draw", ha="center")
        save_figure(fig, path, overwrite)


def candidate_models(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Label → model of every candidate a multi-method run's ``results.json`` holds.

    Returns the models and their leaderboard rows (label → row).

    Raises
    ------
    OptionError
        The file is not the results of a multi-method run (``method = [...]``
        or ``"auto"``).
    """
    from .._checks import as_path, read_json
    from .._errors import OptionError
    from ._results import _from_model_dict

    path = as_path("results file", path)
    data = read_json(path, "results file")
    choice = data.get("choice") if isinstance(data, Mapping) else None
    if not isinstance(choice, Mapping) or not isinstance(choice.get("candidates"), list):
        raise OptionError(f"{path} is not the results of a multi-method run (method = [...] "
                          "or \"auto\"): it has no candidates")
    out: dict[str, Any] = {}
    rows: dict[str, Any] = {}
    for row in choice["candidates"]:
        if isinstance(row, Mapping) and isinstance(row.get("model"), Mapping):
            model = _from_model_dict(row["model"], path, None)
            if model is not None:
                out[str(row.get("label"))] = model
                rows[str(row.get("label"))] = row
    return out, rows
