"""Figures written to files: pyplot-free figures, titles that fit, atomic saves."""

from __future__ import annotations

import os
import textwrap

from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from .._atomic import atomic_path
from ..validate import ValidationReport, residuals_figure, validation_figure

__all__ = ["fit_titles", "new_figure", "plot_residuals", "plot_validation", "save_figure"]


def new_figure(figsize: tuple[float, float]) -> Figure:
    """A matplotlib figure outside pyplot (no window, no state)."""
    return Figure(figsize=figsize)


def plot_validation(
    report: ValidationReport, path: str | os.PathLike[str], unit: str = "", overwrite: bool = False
) -> None:
    """Save :func:`validation_figure` of ``report`` to ``path``."""
    save_figure(validation_figure(report, unit), path, overwrite)


def plot_residuals(
    report: ValidationReport,
    path: str | os.PathLike[str],
    overwrite: bool = False,
    *,
    u: ArrayLike | None = None,
) -> None:
    """Save the residual correlations of ``report`` to ``path``.

    The figure is :func:`servoid.validate.residuals_figure` of ``report`` and the input ``u``.
    """
    save_figure(residuals_figure(report, u), path, overwrite)


def fit_titles(fig: Figure) -> bool:
    """Wrap every title that would be cut at the figure's edge; True if one was.

    A title is centred over its axes; it fits when it lies inside the
    figure.  One that does not is wrapped at the characters that fit (its
    width measured by the renderer), and the layout is redone so the
    second line does not cover the axes above.
    """
    try:
        renderer = fig._get_renderer()  # type: ignore[attr-defined]
    except AttributeError:  # pragma: no cover - a matplotlib without it: titles as set
        return False
    width = fig.bbox.width
    changed = False
    titles = [t for ax in fig.axes for t in (ax.title, ax._left_title, ax._right_title)]
    if getattr(fig, "_suptitle", None) is not None:
        titles.append(fig._suptitle)
    for title in titles:
        text = title.get_text()
        if not text:
            continue
        box = title.get_window_extent(renderer)
        if box.x0 >= 0 and box.x1 <= width:
            continue
        centre = 0.5 * (box.x0 + box.x1)
        room = 2.0 * min(centre, width - centre) * 0.96  # centred: the nearer edge decides
        longest = max(len(line) for line in text.splitlines())
        chars = max(int(longest * room / max(box.width, 1.0)), 16)
        title.set_text("\n".join(textwrap.fill(line, chars) for line in text.splitlines()))
        changed = True
    engine = fig.get_layout_engine()
    if changed and "Constrained" not in type(engine).__name__:  # constrained re-lays at draw
        fig.tight_layout()
    return changed


def save_figure(fig: Figure, path: str | os.PathLike[str], overwrite: bool = False) -> None:
    """Save a figure atomically in the format of its extension.

    Titles that would be cut at the figure's edge are wrapped first
    (:func:`fit_titles`).
    """
    fit_titles(fig)
    suffix = os.path.splitext(os.fspath(path))[1].lstrip(".") or "png"
    with atomic_path(path, overwrite) as tmp:
        fig.savefig(tmp, format=suffix, dpi=110)
