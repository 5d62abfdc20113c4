"""The Bode diagram of ``method = "frequency"``: lines, variance bands, distortion, model."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..report import new_figure, save_figure

__all__ = ["plot_frequency"]


def plot_frequency(measurement: Any, fit: Any, numbers: Any, hold: bool, path: Path,
                   overwrite: bool = False) -> None:
    """Save the measured lines (±2σ total and noise), the detection lines and the model.

    With ``hold`` the continuous model was fitted to the lines with the
    zero-order hold divided out; it is drawn times the hold, as the
    recorded lines see it.  The detection lines are drawn at the gain a line of their output power
    would show against the mean input power per excited line,
    ``sqrt(power/input_power)``, so their distance below the FRF is their
    level below the output.
    """
    fig = new_figure((8, 6.4))
    ax_m, ax_p = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    f = np.asarray(measurement.frequency)
    g = np.asarray(measurement.response)
    mag = 20 * np.log10(np.abs(g))
    phase = np.degrees(np.unwrap(np.angle(g)))
    ax_m.semilogx(f, mag, ".", color="0.3", ms=3, label=f"measured ({measurement.method})")
    ax_p.semilogx(f, phase, ".", color="0.3", ms=3)
    for var, colour, label in ((measurement.variance, "C0", "±2σ total"),
                               (measurement.noise_variance, "C2", "±2σ noise")):
        if var is None or (label.endswith("noise") and measurement.nonlinear_variance is None):
            continue
        rel = 2 * np.sqrt(np.asarray(var)) / np.abs(g)
        ax_m.fill_between(f, mag + 20 * np.log10(np.clip(1 - rel, 1e-3, None)),
                          mag + 20 * np.log10(1 + rel), color=colour, alpha=0.18, lw=0,
                          label=label)
        dph = np.degrees(np.arcsin(np.clip(rel, 0, 1)))
        ax_p.fill_between(f, phase - dph, phase + dph, color=colour, alpha=0.18, lw=0)
    d = measurement.distortion
    if d is not None and d.input_power > 0 and np.size(d.frequency):
        level = 10 * np.log10(np.maximum(np.asarray(d.power), 1e-300) / d.input_power)
        odd = np.asarray(d.odd, dtype=bool)
        if np.any(odd):
            ax_m.semilogx(d.frequency[odd], level[odd], "v", color="C3", ms=3,
                          label="odd detection lines")
        if np.any(~odd):
            ax_m.semilogx(d.frequency[~odd], level[~odd], "^", color="C1", ms=3,
                          label="even detection lines")
    grid = np.geomspace(max(f[0], 1e-6), f[-1], 600)
    gm = fit.model.freqresp(2 * np.pi * grid)
    if hold and measurement.dt is not None:
        wt2 = np.pi * grid * measurement.dt
        gm = gm * np.exp(-1j * wt2) * np.sinc(wt2 / np.pi)
    ax_m.semilogx(grid, 20 * np.log10(np.abs(gm)), color="C4", lw=1.4,
                  label=f"ML model ({fit.n_poles} poles, {fit.n_zeros} zeros"
                        + (", × ZOH)" if hold else ")"))
    model_phase = np.degrees(np.unwrap(np.angle(gm)))
    # the model's phase shares the lines' branch at the lowest line
    shift = 360.0 * round((phase[0] - model_phase[0]) / 360.0)
    ax_p.semilogx(grid, model_phase + shift, color="C4", lw=1.4)
    for n in numbers:
        if n.name == "resonance_frequency" and math.isfinite(n.value):
            ax_m.axvline(n.value, color="C4", lw=0.6, ls=":")
        if n.name == "bandwidth" and math.isfinite(n.value):
            ax_m.axvspan(n.ci_low if math.isfinite(n.ci_low) else n.value,
                         n.ci_high if math.isfinite(n.ci_high) else n.value, color="C4",
                         alpha=0.15, lw=0)
    unit = measurement.unit
    ax_m.set_ylabel(f"gain [dB{', ' + unit if unit else ''}]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=7, loc="lower left")
    ax_m.set_title("Frequency response, its variance, distortion and the ML model")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", lw=0.3)
    save_figure(fig, path, overwrite)
