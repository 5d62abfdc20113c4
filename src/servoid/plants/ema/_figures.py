"""The EMA report's figures (matplotlib ``Figure``, never pyplot)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["plot_equations", "plot_validation_run"]


def plot_validation_run(time: Any, measured: Mapping[str, Any], simulated: Mapping[str, Any],
                        span: tuple[int, int], path: str | os.PathLike[str],
                        overwrite: bool) -> None:
    """Measured vs simulated load position, its error and the motor current."""
    from ...report import new_figure, save_figure

    fig = new_figure((9, 8))
    axes = fig.subplots(3, 1, sharex=True)
    lo = span[0]
    x, xs = np.asarray(measured["position"]), np.asarray(simulated["position"])
    i, isim = np.asarray(measured["current"]), np.asarray(simulated["current"])
    axes[0].plot(time, 1e3 * x, color="0.2", lw=1.0, label="measured (LVDT)")
    axes[0].plot(time, 1e3 * xs, color="C1", lw=0.8, ls="--", label="simulated")
    axes[1].plot(time, 1e6 * (x - xs), color="C1", lw=0.6)
    axes[2].plot(time, i, color="0.2", lw=0.6, label="measured")
    axes[2].plot(time, isim, color="C1", lw=0.6, ls="--", label="simulated")
    for ax in axes:
        if lo > 0:
            ax.axvspan(time[0], time[lo], color="0.9", lw=0)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("load position [mm]")
    axes[1].set_ylabel("position error [µm]")
    axes[2].set_ylabel("motor current [A]")
    axes[2].set_xlabel("time [s]")
    axes[0].legend(loc="upper right", fontsize=7)
    axes[2].legend(loc="upper right", fontsize=7)
    if lo > 0:
        axes[0].set_title("free run from rest; shaded: the estimation part (not scored)",
                          fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_equations(series: Mapping[str, Sequence[Any]], units: Mapping[str, tuple[str, float]],
                   path: str | os.PathLike[str], overwrite: bool) -> None:
    """Each equation's filtered left-hand side against its fitted right-hand side."""
    from ...report import new_figure, save_figure

    fig = new_figure((9, 2.6 * len(series) + 0.6))
    axes = np.atleast_1d(fig.subplots(len(series), 1))
    for ax, (name, (t, y, fitted)) in zip(axes, series.items(), strict=True):
        unit, scale = units.get(name, ("", 1.0))
        ax.plot(t, scale * np.asarray(y), ".", color="0.3", ms=1.0, label="filtered measurement")
        ax.plot(t, scale * np.asarray(fitted), ".", color="C0", ms=0.8, label="fitted")
        ax.set_title(name, fontsize=9)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, markerscale=6)
    axes[-1].set_xlabel("time [s] (rows used; gaps: reversals and slow motion left out)")
    fig.tight_layout()
    save_figure(fig, path, overwrite)
