"""Figures of LTI models: Bode diagrams and pole maps."""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np

from ..models import TransferFunction
from ._figures import new_figure, save_figure
from ._model_figures import Z_FRAME, draw_roots
from ._text import plain

__all__ = ["plot_bode", "plot_poles"]


def plot_bode(
    models: Mapping[str, TransferFunction],
    path: str | os.PathLike[str],
    f_min: float = 0.1,
    f_max: float | None = None,
    title: str = "",
    overwrite: bool = False,
) -> None:
    """Save a Bode diagram of several SISO models.

    Parameters
    ----------
    models : mapping of label to TransferFunction
        Continuous or discrete models; the first is drawn solid black (the reference).
    path : path
        Output image.
    f_min, f_max : float
        Frequency range [Hz]; ``f_max`` defaults to the lowest Nyquist frequency
        of the discrete models, else 100·f_min·10.
    title : str
        Figure title.
    overwrite : bool
        Replace an existing file.
    """
    nyquists = [0.5 / m.dt for m in models.values() if m.dt is not None]
    f_hi = f_max if f_max is not None else (min(nyquists) if nyquists else 1000.0 * f_min)
    f = np.logspace(np.log10(f_min), np.log10(f_hi), 600)
    fig = new_figure((8, 6))
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    for k, (label, model) in enumerate(models.items()):
        h = model.freqresp(2 * np.pi * f)
        style = {"color": "black", "lw": 2.0, "alpha": 0.5} if k == 0 else {"lw": 1.2, "ls": "--"}
        ax_m.semilogx(f, 20 * np.log10(np.abs(h)), label=plain(label), **style)
        ax_p.semilogx(f, np.degrees(np.unwrap(np.angle(h))), **style)
    ax_m.set_ylabel("magnitude [dB]")
    ax_p.set_ylabel("phase [°]")
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(alpha=0.3, which="both")
    ax_m.legend(fontsize=8)
    if title:
        ax_m.set_title(plain(title))
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_poles(
    continuous: Mapping[str, TransferFunction],
    discrete: Mapping[str, TransferFunction],
    path: str | os.PathLike[str],
    overwrite: bool = False,
) -> None:
    """Save pole maps in the s-plane and the z-plane."""
    fig = new_figure((10, 5.4))
    fig.set_layout_engine("constrained")  # it makes room for the legend below the z map
    ax_s, ax_z = fig.subplots(1, 2)
    markers = "xo+^sd"
    for k, (label, model) in enumerate(continuous.items()):
        p = model.poles()
        ax_s.plot(p.real, p.imag, markers[k % 6], ms=8, mfc="none", label=plain(label))
    ax_s.axvline(0, color="0.4", lw=0.8)
    ax_s.axhline(0, color="0.4", lw=0.8)
    ax_s.set_xscale("symlog", linthresh=1.0)  # integrator, ω_hp and far poles on one axis
    ax_s.set_xlabel("Re s [rad/s] (symmetric log)")
    ax_s.set_ylabel("Im s [rad/s]")
    ax_s.set_title("plant poles, s-plane")
    ax_s.grid(alpha=0.3)
    ax_s.legend(fontsize=8)
    theta = np.linspace(0, 2 * np.pi, 400)
    ax_z.plot(np.cos(theta), np.sin(theta), color="0.4", lw=0.8)
    far = 0
    for k, (label, model) in enumerate(discrete.items()):
        far += draw_roots(ax_z, model.poles(), Z_FRAME, markers[k % 6], f"C{k}",
                          f"{plain(label)} poles", ms=8, mfc="none")
        z = model.zeros()
        if z.size:
            far += draw_roots(ax_z, z, Z_FRAME, ".", f"C{k}", f"{plain(label)} zeros", ms=6)
    if far:
        ax_z.plot([], [], ">", color="0.4", ms=6, label="off the map: at its edge, |root| given")
    ax_z.set_xlim(-Z_FRAME, Z_FRAME)
    ax_z.set_ylim(-Z_FRAME, Z_FRAME)
    ax_z.set_aspect("equal")
    ax_z.set_xlabel("Re z")
    ax_z.set_ylabel("Im z")
    ax_z.set_title("closed-loop poles and zeros, z-plane")
    ax_z.grid(alpha=0.3)
    ax_z.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
    save_figure(fig, path, overwrite)
