"""Figures of a validation: measured vs simulated output, residual tests."""

from __future__ import annotations

import os

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .._atomic import atomic_path
from ..validate import ValidationReport

__all__ = ["new_figure", "plot_residuals", "plot_validation", "save_figure"]


def new_figure(figsize: tuple[float, float]) -> Figure:
    """A matplotlib figure outside pyplot (no window, no state)."""
    return Figure(figsize=figsize)


def plot_validation(
    report: ValidationReport, path: str | os.PathLike[str], unit: str = "", overwrite: bool = False
) -> None:
    """Save measured vs simulated and predicted output.

    The samples before ``report.first`` (measured initial conditions or an
    excluded transient) are shaded; ``unit`` defaults to the report's.
    """
    t = report.time
    first = report.first
    fig = new_figure((9, 5.5))
    ax, ax_err = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    unit = unit or getattr(report, "unit", "")
    label_unit = f" [{unit}]" if unit else ""
    if first > 0:
        why = "initial conditions" if report.initial == "measured" else "excluded transient"
        for axis in (ax, ax_err):
            axis.axvspan(t[0], t[first], color="0.85", lw=0,
                         label=f"{why} ({first} samples)" if axis is ax else None)
    ax.plot(t, report.measured, color="0.2", lw=1.0, label="measured")
    ax.plot(t[first:], report.simulated[first:], color="C1", lw=1.0,
            label=f"simulated (fit {report.fit_percent:.1f} %)")
    ax.plot(t[first:], report.predicted[first:], color="C0", lw=0.8, ls="--",
            label=f"{report.horizon}-step predicted (fit {report.prediction_fit_percent:.1f} %)")
    ax.set_ylabel(f"{report.output}{label_unit}")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"Validation{': ' + report.experiment if report.experiment else ''}")
    ax_err.plot(t[first:], report.measured[first:] - report.simulated[first:], color="C3", lw=0.8)
    ax_err.set_ylabel(f"error{label_unit}")
    ax_err.set_xlabel("time [s]")
    ax_err.grid(alpha=0.3)
    save_figure(fig, path, overwrite)


def plot_residuals(
    report: ValidationReport, path: str | os.PathLike[str], overwrite: bool = False
) -> None:
    """Save residual correlation plots with confidence bands."""
    res = report.residuals
    n_cross = res.cross_correlation.shape[0]
    fig = new_figure((9, 2.6 * (1 + n_cross)))
    axes = fig.subplots(1 + n_cross, 1)
    axes = np.atleast_1d(axes)
    verdict = "white" if res.is_white else "not white"
    _stem(axes[0], res.lags, res.autocorrelation, res.bound)
    axes[0].set_title(
        f"residual autocorrelation ({verdict}, Ljung–Box p = {res.whiteness_pvalue:.3g}); "
        f"band ±{res.bound:.3g} at {100 * res.confidence:.0f} %"
    )
    for k in range(n_cross):
        _stem(axes[k + 1], res.cross_lags, res.cross_correlation[k], res.bound)
        axes[k + 1].set_title(f"input {k} – residual cross-correlation")
    axes[-1].set_xlabel("lag [samples]")
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def _stem(ax: Axes, lags: np.ndarray, r: np.ndarray, bound: float) -> None:
    ax.vlines(lags, 0, r, color="C0", lw=1.2)
    ax.plot(lags, r, "o", color="C0", ms=3)
    ax.axhspan(-bound, bound, color="C2", alpha=0.15, lw=0)
    ax.axhline(0, color="0.3", lw=0.6)
    ax.grid(alpha=0.3)


def save_figure(fig: Figure, path: str | os.PathLike[str], overwrite: bool = False) -> None:
    """Save a figure atomically in the format of its extension."""
    suffix = os.path.splitext(os.fspath(path))[1].lstrip(".") or "png"
    with atomic_path(path, overwrite) as tmp:
        fig.savefig(tmp, format=suffix, dpi=110)
