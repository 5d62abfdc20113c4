"""Figures of a rigid axis with friction: force fit, friction law, closed loop."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._figures import new_figure, save_figure
from ._text import plain

__all__ = ["plot_force_fit", "plot_friction", "plot_linear", "plot_loop"]



def plot_force_fit(regressions: Mapping[str, Any], estimates: Mapping[str, Any],
                   path: str | os.PathLike[str], overwrite: bool) -> None:
    """Decimated measured force against each IDIM-LS prediction."""
    fig = new_figure((9, 5.5))
    ax, ax_err = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    first = next(iter(regressions.values()))
    ax.plot(first.time, first.force, color="0.2", lw=1.0, label="measured τ")
    for k, (key, reg) in enumerate(regressions.items()):
        est = estimates[key]
        fitted = reg.regressors @ est.parameters
        ax.plot(reg.time, fitted, color=f"C{k + 1}", lw=0.8,
                label=f"{plain(key)} ({est.options['relative_error']:.3g} %)")
        ax_err.plot(reg.time, reg.force - fitted, color=f"C{k + 1}", lw=0.6)
    ax.set_ylabel("force [N]")
    ax.legend(loc="upper right", fontsize=8)
    ax_err.set_ylabel("error [N]")
    ax_err.set_xlabel("time [s]")
    for a in (ax, ax_err):
        a.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_friction(regressions: Mapping[str, Any], estimates: Mapping[str, Any],
                  path: str | os.PathLike[str], overwrite: bool) -> None:
    """Friction τ − M q̈ against velocity, with the fitted laws."""
    fig = new_figure((7, 4.5))
    ax = fig.subplots()
    key0 = next(iter(regressions))
    reg = regressions[key0]
    est = estimates[key0]
    qd = reg.regressors[:, 1]
    if est.options["model"] == "asymmetric":
        qd = reg.regressors[:, 1] + reg.regressors[:, 3]
    ax.plot(qd, reg.force - est.parameters[0] * reg.regressors[:, 0], ".", ms=2, color="0.5",
            label="τ − M̂ q̈ (decimated)")
    v = np.linspace(qd.min(), qd.max(), 400)
    v = v[v != 0]
    for k, (key, e) in enumerate(estimates.items()):
        ax.plot(v, e.model.friction(v), color=f"C{k + 1}", lw=1.5, label=plain(key))
    ax.set_xlabel("velocity [m/s]")
    ax.set_ylabel("friction + offset [N]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_loop(time: Any, position: Any, force: Any, sims: Mapping[str, Any], path: str | os.PathLike[str],
              overwrite: bool) -> None:
    """Measured vs simulated closed loop: position, its error, force."""
    fig = new_figure((9, 8))
    axes = fig.subplots(3, 1, sharex=True)
    axes[0].plot(time, position, color="0.2", lw=1.0, label="measured")
    axes[2].plot(time, force, color="0.2", lw=0.8, label="measured")
    for k, (key, sim) in enumerate(sims.items()):
        axes[0].plot(time, sim.position, color=f"C{k + 1}", lw=0.8, ls="--", label=plain(key))
        axes[1].plot(time, 1e6 * (position - sim.position), color=f"C{k + 1}", lw=0.6,
                     label=plain(key))
        axes[2].plot(time, sim.force, color=f"C{k + 1}", lw=0.6, label=plain(key))
    axes[0].set_ylabel("position [m]")
    axes[1].set_ylabel("position error [µm]")
    axes[2].set_ylabel("force [N]")
    axes[2].set_xlabel("time [s]")
    for a in axes:
        a.grid(alpha=0.3)
        a.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_linear(time: Any, position: Any, simulated: Any, label: str, path: str | os.PathLike[str],
                overwrite: bool) -> None:
    """Measured position against the linear model's simulation."""
    fig = new_figure((9, 4))
    ax = fig.subplots()
    ax.plot(time, position, color="0.2", lw=1.0, label="measured")
    ax.plot(time, simulated, color="C3", lw=0.8, label=f"{plain(label)} simulated from the input")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position [m]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, overwrite)
