"""Figures that pyplot tracks, for the ``.plot()`` methods a user calls.

``Experiment.plot`` and ``ValidationReport.plot`` hand a figure to the user. In a
script, ``plt.show()`` and ``plt.savefig()`` must find it; in Jupyter, the inline
backend must show it, once. Both need a figure that pyplot created. The report package
draws its PNGs on pyplot-free figures instead (``servoid.report.new_figure``), so that
rendering a report leaves nothing in pyplot's list of open figures.
"""

from __future__ import annotations

from typing import Any

from matplotlib.figure import Figure

__all__ = ["PyplotFigure", "pyplot_figure"]

#: What ``matplotlib.get_backend()`` says under Jupyter's inline backend.
_INLINE = ("inline", "module://matplotlib_inline.backend_inline")


class PyplotFigure(Figure):
    """A pyplot figure that Jupyter shows once when it is also a cell's value."""

    def _repr_mimebundle_(self, include: Any = None, exclude: Any = None) -> None:
        # IPython asks for this bundle first and then renders the PNG with the image
        # formatter the inline backend registered. After the cell, that backend shows every
        # figure still open in pyplot: without closing it here, a figure that is the
        # cell's value would be shown twice. The backend closes what it shows anyway; a
        # closed figure can still be drawn and saved. Other backends (a window) keep it.
        import matplotlib
        import matplotlib.pyplot as plt

        if matplotlib.get_backend() in _INLINE:
            plt.close(self)  # a figure pyplot no longer holds is left as it is
        # nothing here: the image and text formatters fill the bundle


def pyplot_figure(figsize: tuple[float, float]) -> PyplotFigure:
    """Make a new figure with pyplot, as ``plt.figure(figsize=...)`` does.

    Parameters
    ----------
    figsize : tuple of float
        Width and height [inch].

    Returns
    -------
    PyplotFigure
        The current pyplot figure: ``plt.savefig()`` and ``plt.show()`` act on it, and
        Jupyter's inline backend shows it after the cell (once, also when it is the
        cell's value). Close it with ``plt.close(fig)`` when done, as any pyplot figure.
    """
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=figsize, FigureClass=PyplotFigure)
    assert isinstance(fig, PyplotFigure)
    return fig
