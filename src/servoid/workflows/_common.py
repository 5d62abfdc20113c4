"""Pieces shared by the identification workflows."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

from .._errors import OutputExistsError
from ..estimate import Estimate
from ..report import Figure, Section, Table
from ..validate import ValidationReport

__all__ = ["check_outputs", "parameter_table", "sha256", "validation_section"]


def check_outputs(targets: Sequence[Path], inputs: Sequence[Path], overwrite: bool) -> None:
    """Refuse to write over an input, or over earlier results unless ``overwrite``."""
    protected = {Path(p).resolve() for p in inputs}
    for path in targets:
        if path.resolve() in protected:
            raise OutputExistsError(f"refusing to write {path}: it is an input of this run")
        if path.exists() and not overwrite:
            raise OutputExistsError(
                f"{path} exists from an earlier run; pass --overwrite (overwrite=True) or "
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
            ("residual whiteness (Ljung–Box p)",
             f"{res.whiteness_pvalue:.3g} → {'white' if res.is_white else 'not white'}"),
            ("input–residual independence (p)",
             "n/a" if res.independence_pvalue != res.independence_pvalue else
             f"{res.independence_pvalue:.3g} → "
             f"{'independent' if res.is_independent else 'correlated'}"),
        ),
        caption="On data not used for fitting",
    )
    return Section(
        "Validation",
        paragraphs=(
            "The model is simulated from the input alone on the held-back data (the first "
            f"{report.first} samples set the initial conditions) and compared with the "
            f"measurement. Residual correlations are tested at {100 * res.confidence:.0f} % "
            "confidence.",
        ),
        tables=(metrics,),
        figures=(
            Figure.from_file(fig_sim, "Measured vs simulated and predicted output"),
            Figure.from_file(fig_res, "Residual autocorrelation and input–residual "
                             "cross-correlation with confidence band"),
        ),
    )


def sha256(path: Path) -> str:
    """SHA-256 of a file, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
