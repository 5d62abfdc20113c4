"""Several models validated on one record, side by side: :func:`compare` and :class:`Comparison`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._checks import type_error
from ..data import Experiment
from ._report import ValidationReport, validate

__all__ = ["Comparison", "compare"]

#: Columns of :attr:`Comparison.table`.
COLUMNS = ("model", "parameters", "simulation fit %", "prediction fit %", "whiteness p",
           "input–residual p", "nonlinearity p")


class Comparison(dict):  # type: ignore[type-arg]
    """Several models validated on the same record, side by side.

    Label → :class:`ValidationReport` of each model.

    A ``dict`` (what :func:`compare` returned before), with the side by side
    view: :attr:`table`, the best model first; ``str`` and ``_repr_html_``
    print it; :meth:`plot` overlays the simulations.
    """

    def __init__(self, reports: Mapping[str, ValidationReport],
                 parameters: Mapping[str, int] | None = None) -> None:
        if not isinstance(reports, Mapping) or not reports or \
                not all(isinstance(v, ValidationReport) for v in reports.values()):
            raise type_error("reports", reports, "a non-empty mapping of label to "
                             "ValidationReport (what compare returns)")
        if parameters is not None and not isinstance(parameters, Mapping):
            raise type_error("parameters", parameters, "a mapping of label to a count")
        super().__init__(reports)
        self.parameters = dict(parameters or {})

    @property
    def best(self) -> str:
        """The label with the highest simulation fit."""
        return max(self, key=lambda k: self[k].fit_percent)

    @property
    def table(self) -> list[tuple[str, ...]]:
        """One row per model (:data:`COLUMNS`), by simulation fit, best first."""
        rows = []
        for label in sorted(self, key=lambda k: -self[k].fit_percent):
            v = self[label]
            r = v.residuals
            nl = v.nonlinearity
            rows.append((label, str(self.parameters.get(label, "—")), f"{v.fit_percent:.2f}",
                         f"{v.prediction_fit_percent:.2f}", _p(r.whiteness_pvalue),
                         _p(r.independence_pvalue),
                         "—" if nl is None or not nl.tested else _p(nl.pvalue)))
        return rows

    def __str__(self) -> str:
        rows = [COLUMNS, *self.table]
        widths = [max(len(r[i]) for r in rows) for i in range(len(COLUMNS))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True))
                         for r in rows)

    def __repr__(self) -> str:
        return f"<Comparison of {len(self)} models: best {self.best!r}>"

    def _repr_html_(self) -> str:
        from .._display import html_block

        first = next(iter(self.values()))
        return html_block(f"comparison on {first.experiment or 'the record'}",
                          [("models", str(len(self))), ("best", self.best)], COLUMNS,
                          self.table)

    def plot(self) -> Any:
        """Overlay the measured output and each model's simulation.

        Returns
        -------
        matplotlib.figure.Figure
            A figure made by pyplot (shown inline in Jupyter); close it with
            ``plt.close(fig)`` when done.
        """
        from .._pyplot import pyplot_figure

        fig = pyplot_figure(figsize=(8.0, 4.0))
        ax = fig.add_subplot(1, 1, 1)
        first = next(iter(self.values()))
        ax.plot(first.time, first.measured, color="0.3", lw=1.0, label="measured")
        for label, v in self.items():
            ax.plot(v.time[v.first:], v.simulated[v.first:], lw=1.0,
                    label=f"{label} ({v.fit_percent:.1f} %)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(first.output + (f" [{first.unit}]" if first.unit else ""))
        ax.legend(fontsize=8)
        return fig


def compare(
    models: Mapping[str, Any],
    experiment: Experiment,
    **options: Any,
) -> Comparison:
    """Validate several models on the same record, side by side.

    Parameters
    ----------
    models : mapping of str to model or Estimate
        A label per model.
    experiment : Experiment
        The record.
    **options
        Passed to :func:`validate` (``initial``, ``input``, ``output``, …).

    Returns
    -------
    Comparison
        A dict of label → :class:`ValidationReport`, in the order of
        `models`, with :attr:`~Comparison.table`, ``_repr_html_`` and
        :meth:`~Comparison.plot`.
    """
    if not isinstance(models, Mapping) or not models:
        raise type_error("models", models, "a non-empty mapping of label to model")
    reports = {label: validate(m, experiment, **options) for label, m in models.items()}
    sizes = {label: int(np.size(m.parameters)) for label, m in models.items()
             if hasattr(m, "parameters") and hasattr(m, "covariance")}
    return Comparison(reports, sizes)


def _p(p: float) -> str:
    if not math.isfinite(p):
        return "—"
    return "< 1e-300" if p < 1e-300 else f"{p:.3g}"
