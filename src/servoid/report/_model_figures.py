"""Figures of identified models: Bode with ±2σ bands, measured FRF, pole–zero maps, orders."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._figures import new_figure, save_figure
from ._text import plain

__all__ = ["Z_FRAME", "draw_roots", "plot_bode_bands", "plot_pole_zero", "plot_singular_values"]

#: Half-width of a z-plane map: the unit circle with a margin.
Z_FRAME = 1.4
#: Half-width of an s-plane map over the largest pole magnitude.
_S_MARGIN = 1.3


def plot_bode_bands(
    bands: Mapping[str, Any],
    path: str | os.PathLike[str],
    *,
    measured: Any | None = None,
    sigmas: float = 2.0,
    unit: str = "",
    title: str = "",
    overwrite: bool = False,
) -> None:
    """Save a Bode diagram with ±kσ bands and a measured FRF.

    Parameters
    ----------
    bands : mapping of label to FrequencyBand
        Each model's response on a frequency grid [Hz] with the standard
        deviations of magnitude [dB] and phase [deg].
    path : path
        Output image.
    measured : FrequencyResponseData, optional
        A measured FRF (``frequency`` [Hz], complex ``response``, and
        ``coherence`` when known), drawn as points with a coherence panel.
    sigmas : float
        Width of the bands in standard deviations.
    unit : str
        Unit of the gain (output unit / input unit), for the axis label.
    title : str
        Figure title.
    overwrite : bool
        Replace an existing file.
    """
    coherence = None if measured is None else getattr(measured, "coherence", None)
    rows = 3 if coherence is not None else 2
    fig = new_figure((8, 2.6 * rows + 0.6))
    axes = fig.subplots(rows, 1, sharex=True,
                        gridspec_kw={"height_ratios": [3, 2, 1][:rows]})
    ax_m, ax_p = axes[0], axes[1]
    if measured is not None:
        f = np.asarray(measured.frequency, dtype=float)
        h = np.asarray(measured.response, dtype=complex)
        keep = f > 0
        mag = 20 * np.log10(np.abs(h[keep]))
        phase = np.degrees(np.unwrap(np.angle(h[keep])))
        ax_m.semilogx(f[keep], mag, ".", color="0.35", ms=3, label="measured FRF")
        ax_p.semilogx(f[keep], phase, ".", color="0.35", ms=3)
        variance = getattr(measured, "variance", None)
        if variance is not None:  # ±kσ of each line: |G| ± kσ in dB, phase ± kσ/|G| rad
            rel = sigmas * np.sqrt(np.asarray(variance)[keep]) / np.abs(h[keep])
            low = 20 * np.log10(np.clip(1 - rel, 1e-3, None))
            ax_m.fill_between(f[keep], mag + low, mag + 20 * np.log10(1 + rel), color="0.35",
                              alpha=0.15, lw=0)
            dph = np.degrees(np.arcsin(np.clip(rel, 0, 1)))
            ax_p.fill_between(f[keep], phase - dph, phase + dph, color="0.35", alpha=0.15, lw=0)
    for k, (label, band) in enumerate(bands.items()):
        color = f"C{k}"
        mag, phase = band.magnitude_db, band.phase_deg
        f = band.frequency
        ax_m.semilogx(f, mag, color=color, lw=1.3, label=f"{plain(label)} (±{sigmas:g}σ)")
        ax_m.fill_between(f, mag - sigmas * band.magnitude_std_db,
                          mag + sigmas * band.magnitude_std_db, color=color, alpha=0.2, lw=0)
        ax_p.semilogx(f, phase, color=color, lw=1.3)
        ax_p.fill_between(f, phase - sigmas * band.phase_std_deg,
                          phase + sigmas * band.phase_std_deg, color=color, alpha=0.2, lw=0)
    _limit(ax_m, ax_p, bands, measured)
    ax_m.set_ylabel(f"magnitude [dB{' re 1 ' + plain(unit) if unit else ''}]")
    ax_p.set_ylabel("phase [°]")
    if coherence is not None:
        ax_c = axes[2]
        f = np.asarray(measured.frequency, dtype=float)
        ax_c.semilogx(f[f > 0], np.asarray(coherence)[f > 0], color="0.35", lw=1.0)
        ax_c.set_ylim(0, 1.05)
        ax_c.set_ylabel("coherence")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    axes[-1].set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=8, loc="best")
    if title:
        ax_m.set_title(plain(title))
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def plot_pole_zero(
    models: Mapping[str, Any],
    path: str | os.PathLike[str],
    *,
    title: str = "",
    overwrite: bool = False,
) -> None:
    """Save a pole–zero map of discrete or continuous models.

    Parameters
    ----------
    models : mapping of label to model
        Transfer functions (or anything with ``poles()``/``zeros()`` and
        ``dt``); discrete models are drawn in the z-plane with the unit
        circle, continuous ones in the s-plane [rad/s].
    path : path
        Output image.
    title : str
        Figure title.
    overwrite : bool
        Replace an existing file.
    """
    discrete = {k: m for k, m in models.items() if m.dt is not None}
    continuous = {k: m for k, m in models.items() if m.dt is None}
    panels = [(name, group) for name, group in (("z", discrete), ("s", continuous)) if group]
    fig = new_figure((5.2 * len(panels), 5.6))
    fig.set_layout_engine("constrained")  # it makes room for the legends below the maps
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (plane, group) in zip(axes, panels, strict=True):
        roots = {label: _roots(model) for label, model in group.items()}
        if plane == "z":
            frame = Z_FRAME
            theta = np.linspace(0, 2 * np.pi, 400)
            ax.plot(np.cos(theta), np.sin(theta), color="0.4", lw=0.8)
        else:  # the poles set the scale: a far zero must not shrink them to a dot
            poles = np.concatenate([p for p, _ in roots.values()] or [np.empty(0)])
            frame = _S_MARGIN * float(np.max(np.abs(poles), initial=0.0)) or 1.0
        ax.axhline(0, color="0.6", lw=0.6)
        ax.axvline(0, color="0.6", lw=0.6)
        far = 0
        for k, (label, (p, z)) in enumerate(roots.items()):
            far += draw_roots(ax, p, frame, "x", f"C{k}", f"{plain(label)} poles", ms=9, mew=1.6)
            if z.size:
                far += draw_roots(ax, z, frame, "o", f"C{k}", f"{plain(label)} zeros", ms=7,
                                  mfc="none")
        ax.set_xlim(-frame, frame)
        ax.set_ylim(-frame, frame)
        ax.set_aspect("equal")
        unit = "" if plane == "z" else " [rad/s]"
        ax.set_xlabel(f"Re {plane}{unit}")
        ax.set_ylabel(f"Im {plane}{unit}")
        ax.set_title(f"{plane}-plane" + (f": {plain(title)}" if title else ""))
        ax.grid(alpha=0.3)
        if far:
            ax.plot([], [], ">", color="0.4", ms=6, label="off the map: at its edge, |root| given")
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
    save_figure(fig, path, overwrite)


def draw_roots(ax: Any, roots: Any, frame: float, marker: str, color: str, label: str,
               **style: Any) -> int:
    """Plot roots inside a square map of half-width ``frame``; mark the others at its edge.

    A root outside the map is drawn where the ray from the origin towards
    it leaves the map, with an arrow pointing out and its magnitude (roots
    that land on the same spot share one mark and list their magnitudes),
    so a far zero neither hides the unit circle nor disappears.

    Returns
    -------
    int
        How many roots lie off the map.
    """
    r = np.asarray(roots, dtype=complex).ravel()
    size = np.maximum(np.abs(r.real), np.abs(r.imag))
    far = size > frame
    inside = r[~far]
    ax.plot(inside.real, inside.imag, marker, color=color, label=label, ls="none", **style)
    spots: dict[tuple[float, float], list[float]] = {}
    for z in r[far]:
        edge = z * (0.92 * frame / max(abs(z.real), abs(z.imag)))
        spots.setdefault((round(edge.real, 2), round(edge.imag, 2)), []).append(abs(z))
    taken = ax.__dict__.setdefault("_servoid_edge_labels", {})  # spots labelled by earlier calls
    for (x, y), sizes in spots.items():
        ax.plot(x, y, marker, color=color, ls="none", **style)
        angle = np.angle(complex(x, y))
        tip = (x + 0.075 * frame * np.cos(angle), y + 0.075 * frame * np.sin(angle))
        ax.annotate("", xy=tip, xytext=(x, y),
                    arrowprops={"arrowstyle": "->", "color": color, "lw": 1.2})
        text = ", ".join(f"{m:.3g}" for m in sorted(set(np.round(sizes, 12))))
        stacked = taken.get((x, y), 0)  # another model's roots on the same spot: one line down
        taken[(x, y)] = stacked + 1
        inward = (-14 * np.cos(angle), -14 * np.sin(angle) - 9 * stacked)  # [points]
        ha = "right" if np.cos(angle) > 0.5 else "left" if np.cos(angle) < -0.5 else "center"
        ax.annotate(text, xy=(x, y), xytext=inward, textcoords="offset points", color=color,
                    fontsize=7, ha=ha, va="center")
    return int(far.sum())


def plot_singular_values(
    values: Sequence[float],
    order: int,
    path: str | os.PathLike[str],
    *,
    overwrite: bool = False,
) -> None:
    """Save the subspace singular values with the chosen order marked.

    Parameters
    ----------
    values : sequence of float
        Singular values, largest first.
    order : int
        The chosen model order (the number of values kept).
    path : path
        Output image.
    overwrite : bool
        Replace an existing file.
    """
    sv = np.asarray(values, dtype=float)
    fig = new_figure((7, 3.6))
    ax = fig.subplots()
    idx = np.arange(1, sv.size + 1)
    ax.semilogy(idx, np.maximum(sv, np.finfo(float).tiny), "o-", color="C0", ms=4)
    ax.semilogy(idx[:order], np.maximum(sv[:order], np.finfo(float).tiny), "o", color="C3",
                ms=7, label=f"kept: order {order}")
    ax.axvline(order + 0.5, color="C3", lw=0.8, ls="--")
    ax.set_xlabel("index")
    ax.set_ylabel("singular value")
    ax.set_title("subspace singular values")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def _limit(ax_m: Any, ax_p: Any, bands: Mapping[str, Any], measured: Any) -> None:
    """Axis ranges from the models (the measured lines' noise must not squash them)."""
    if bands:
        mags = np.concatenate([b.magnitude_db for b in bands.values()])
        phases = np.concatenate([b.phase_deg for b in bands.values()])
    elif measured is not None:
        h = np.asarray(measured.response)[np.asarray(measured.frequency) > 0]
        mags = 20 * np.log10(np.abs(h))
        phases = np.degrees(np.unwrap(np.angle(h)))
        mags, phases = (np.percentile(x, [2, 98]) for x in (mags, phases))
    else:
        return
    mags, phases = mags[np.isfinite(mags)], phases[np.isfinite(phases)]
    if mags.size:
        ax_m.set_ylim(mags.min() - 15.0, mags.max() + 10.0)
    if phases.size:
        ax_p.set_ylim(phases.min() - 60.0, phases.max() + 60.0)


def _roots(model: Any) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    if hasattr(model, "transfer_function"):  # a polynomial model: its first input
        model = model.transfer_function(0)
    p = np.asarray(model.poles(), dtype=complex)
    z = np.asarray(model.zeros(), dtype=complex) if hasattr(model, "zeros") else np.empty(0)
    return p, z
