"""Reports: figures, a single-file HTML page with its verdict, JSON results."""

from ._figures import new_figure, plot_residuals, plot_validation, save_figure
from ._html import Figure, Page, Section, Table, render_html, write_html
from ._json import to_jsonable, write_json
from ._lti_figures import plot_bode, plot_poles
from ._model_figures import plot_bode_bands, plot_pole_zero, plot_singular_values
from ._rigid_figures import plot_force_fit, plot_friction, plot_linear, plot_loop
from ._verdict import Check, Conditions, Verdict

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._figures import fit_titles as fit_titles
from ._text import plain as plain
from ._verdict import pvalue_text as pvalue_text

__all__ = [
    "Check",
    "Conditions",
    "Figure",
    "Page",
    "Section",
    "Table",
    "Verdict",
    "new_figure",
    "plot_bode",
    "plot_bode_bands",
    "plot_force_fit",
    "plot_friction",
    "plot_linear",
    "plot_loop",
    "plot_pole_zero",
    "plot_poles",
    "plot_residuals",
    "plot_singular_values",
    "plot_validation",
    "render_html",
    "save_figure",
    "to_jsonable",
    "write_html",
    "write_json",
]
