"""``method = "narx"``: polynomial NARX, terms chosen by forward OLS, validated by free run."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from ..data import ExperimentSpec
from ..estimate import Estimate
from ..report import Section, Table
from ._arx import HORIZON, OUTPUT, ROLE
from ._common import keyed, parameter_table, warnings_as_notes
from ._examples import open_loop
from ._lti import IdentificationResult, lti_result
from ._options import choice, integer, number, optional, orders
from ._registry import Method, Option

__all__ = ["METHOD", "NarxResult"]

#: Library parameter → the experiment-file key, for errors raised below the workflow.
_KEYS = {name: f"[identify] {name}" for name in
         ("na", "nb", "nk", "degree", "max_terms", "tolerance", "criterion", "horizon")}


@dataclass(frozen=True, eq=False, repr=False)
class NarxResult(IdentificationResult):
    """A polynomial NARX model from an experiment file, validated.

    The fields are those of
    :class:`~servoid.workflows.IdentificationResult`: the estimate's model
    is a :class:`~servoid.nonlinear.NarxModel` whose
    ``options["selection"]`` lists the terms in the order they entered;
    each validation is a free run and a k-step prediction (or a
    :class:`~servoid.workflows._common.DivergedRun` where the free run
    diverged); ``truth`` holds known coefficients by term name.
    """

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``, with the term selection."""
        out = super().to_dict()
        out["model"] = self.estimate.model.to_dict()
        out["selection"] = list(self.estimate.options["selection"])
        return out

    def _headline(self) -> str:
        est = self.estimate
        o = est.options
        return (f"{self.title}: output {o['output']} from {', '.join(o['inputs'])} "
                f"({o['input']}); {est.parameters.size} of {o['n_candidates']} candidate "
                f"terms on {est.n_samples} samples, σ̂² = {est.noise_variance:.4g}")

    def _extra_lines(self) -> list[str]:
        o = self.estimate.options
        return [f"  term selection (forward OLS, {_criterion_words(o)}), in order of entry:",
                *("    " + line for line in _selection_lines(o["selection"]))]

    def _model_section(self, files: Mapping[str, Path]) -> Section:
        est = self.estimate
        tables = [parameter_table(est, "Coefficients refitted by least squares on the selected "
                                       "terms; std from σ̂²(ΦᵀΦ)⁻¹")]
        if self.truth:
            tables.append(_truth_table(est, self.truth))
        return Section("Model", paragraphs=(_model_text(est), str(est.model)),
                       tables=tuple(tables))

    def _extra_sections(self, files: Mapping[str, Path]) -> list[Section]:
        o = self.estimate.options
        return [Section(
            "Term selection",
            paragraphs=(
                (f"Forward orthogonal least squares over {o['n_candidates']} candidate terms "
                 f"({_criterion_words(o)}). ERR is the share of Σy² a term explains beyond the "
                 "terms above it (Chen, Billings & Luo 1989); 1 − ΣERR is what is still "
                 "unexplained after it. Terms tried after the last kept one show why the "
                 "criterion stopped."),),
            tables=(_selection_table(o["selection"]),))]

    def _subtitle(self) -> str:
        return (f"{self.title}, validated by free-run simulation on data not used for "
                "fitting")


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> NarxResult:
    """Fit a polynomial NARX model and validate it on each validation record."""
    from ..nonlinear import fit_narx

    estimation, validations = spec.records()
    with keyed(_KEYS), warnings_as_notes() as notes:
        estimate = fit_narx(estimation, na=options["na"], nb=options["nb"], nk=options["nk"],
                            degree=options["degree"], max_terms=options["max_terms"],
                            criterion=options["criterion"], tolerance=options["tolerance"],
                            input=options["input"], output=options["output"])
    o = estimate.options
    title = (f"NARX (na = {o['na']}, nb = {_short(o['nb'])}, nk = {_short(o['nk'])}, degree = "
             f"{o['degree']}, {estimate.parameters.size} terms)")
    result = lti_result(spec, "narx", estimate, title, validations, options, notes=notes,
                        truth=truth, modal=False, result_type=NarxResult,
                        records=estimation)
    assert isinstance(result, NarxResult)
    return result


# -- private ------------------------------------------------------------------------------


def _criterion_words(o: Mapping[str, Any]) -> str:
    if o["criterion"] == "err":
        return f"stopped when 1 − ΣERR fell below {o['tolerance']:g}"
    return f"number of terms by {o['criterion'].upper()} on the one-step residual variance"


def _selection_table(rows: Sequence[Mapping[str, Any]]) -> Table:
    body = []
    for k, r in enumerate(rows, start=1):
        crit = r.get("criterion")
        body.append((str(k), r["term"], f"{r['err']:.4g}", f"{r['unexplained']:.4g}",
                     "—" if crit is None else f"{crit:.6g}", str(r["kept"])))
    return Table(("step", "term", "ERR", "1 − ΣERR", "criterion", "kept"), tuple(body),
                 "Terms in the order they entered the forward selection; \"pruned\": entered, "
                 "then dropped because the criterion is lower without it")


def _selection_lines(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    table = _selection_table(rows)
    last = max((k for k, r in enumerate(rows) if r["kept"] != "no"), default=0)
    widths = [max(len(c), *(len(r[i]) for r in table.rows)) if table.rows else len(c)
              for i, c in enumerate(table.columns)]
    head = "  ".join(c.rjust(w) for c, w in zip(table.columns, widths, strict=True))
    return [head, *("  ".join(cell.rjust(w) for cell, w in zip(r, widths, strict=True))
                    for r in table.rows[: last + 4])]


def _truth_table(est: Estimate, truth: Mapping[str, float]) -> Table:
    rows = []
    for r in est.table():
        known = truth.get(r.name)
        z = "—" if known is None or not r.std > 0 else f"{(r.value - known) / r.std:+.2f}"
        rows.append((r.name, f"{r.value:.6g}", "—" if known is None else f"{known:.6g}", z))
    missed = [name for name in truth if name not in est.names]
    caption = "Estimate against the known value; z = (estimate − truth)/std"
    if missed:
        caption += f". Known terms not selected: {', '.join(missed)}"
    return Table(("term", "estimate", "truth", "z"), tuple(rows), caption)


def _model_text(est: Estimate) -> str:
    o = est.options
    return (f"Polynomial NARX of degree {o['degree']}: {est.parameters.size} terms kept of "
            f"{o['n_candidates']} candidates, fitted by least squares on the one-step "
            f"equations ({est.n_samples} samples); one-step residual variance "
            f"{est.noise_variance:.4g}; scaled condition number {o['condition']:.3g}. The "
            "coefficients' intervals assume white equation errors; the free-run validation "
            "below is how the model is judged.")


def _short(values: Sequence[int]) -> str:
    return str(values[0]) if len(values) == 1 else str(list(values))


METHOD = Method(
    name="narx",
    summary="polynomial NARX y(t) = Σ θ·(products of lagged y and u) + e: terms chosen by "
            "forward orthogonal least squares (ERR) and BIC/AIC, validated by free run",
    options=(
        ROLE,
        OUTPUT,
        Option("na", 2, integer(minimum=0, maximum=100),
               "output lags y(t-1) … y(t-na) among the candidates"),
        Option("nb", 2, orders(1), "input lags per input (a list: one value per input)"),
        Option("nk", 1, orders(0), "input delay per input [samples] (a list as for nb)"),
        Option("degree", 2, integer(minimum=1, maximum=10),
               "highest degree of the candidate monomials (1: linear ARX terms)"),
        Option("max_terms", None, optional(integer(minimum=1)),
               "most terms to keep (default: as many as the criterion wants)"),
        Option("criterion", "bic", choice(("bic", "aic", "err")),
               "how many terms: bic, aic (on the one-step residual variance) or err (stop "
               "when 1 − ΣERR < tolerance)"),
        Option("tolerance", 0.01, number(positive=True),
               "ERR threshold ρ in (0, 1) for criterion = \"err\" (above the noise share of "
               "Σy²)"),
        HORIZON,
    ),
    run=run,
    example=partial(open_loop, kind="narx",
                    identify={"method": "narx", "na": 1, "nb": 1, "degree": 2}),
)
