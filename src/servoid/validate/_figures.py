"""Figures of a validation: measured vs simulated output with a zoom, residual correlations."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import type_error
from .._drawing import plain, thinned
from ._report import ValidationReport
from ._residuals import _bartlett_autocorrelation, _lagged_sums, _unit_scale

if TYPE_CHECKING:  # matplotlib loads when a figure is drawn, not with servoid.validate
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["residuals_figure", "validation_figure"]

#: Most samples the zoom panel spans (a twentieth of the record up to this).
_ZOOM = 5000


def validation_figure(report: ValidationReport, unit: str = "", *,
                      new: Callable[[tuple[float, float]], Figure] | None = None) -> Figure:
    """Measured vs simulated output, its error and a zoom.

    The samples before ``report.first`` (measured initial conditions or an
    excluded transient) are shaded; ``unit`` defaults to the report's. The
    zoom panel shows a twentieth of the record (at least 200 samples)
    around the largest simulation error, where a reviewer should look.
    ``new(figsize)`` makes the figure: pyplot-free for reports, a pyplot
    figure for ``ValidationReport.plot``.
    """
    _check_report(report)
    t = report.time
    first = report.first
    fig = (new or _figure)((9, 7.5))
    grid = fig.add_gridspec(3, 1, height_ratios=[3, 1, 2.2])
    ax = fig.add_subplot(grid[0])
    ax_err = fig.add_subplot(grid[1], sharex=ax)
    ax_zoom = fig.add_subplot(grid[2])
    unit = unit or getattr(report, "unit", "")
    label_unit = f" [{plain(unit)}]" if unit else ""  # channel names and units as typed
    if first > 0:
        why = "initial conditions" if report.initial == "measured" else "excluded transient"
        for axis in (ax, ax_err):
            axis.axvspan(t[0], t[first], color="0.85", lw=0,
                         label=f"{why} ({first} samples)" if axis is ax else None)
    ax.plot(*thinned(t, report.measured), color="0.2", lw=1.0, label="measured")
    ax.plot(*thinned(t[first:], report.simulated[first:]), color="C1", lw=1.0,
            label=f"simulated (fit {report.fit_percent:.1f} %)")
    ax.plot(*thinned(t[first:], report.predicted[first:]), color="C0", lw=0.8, ls="--",
            label=f"{report.horizon}-step predicted (fit {report.prediction_fit_percent:.1f} %)")
    ax.set_ylabel(f"{plain(report.output)}{label_unit}")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"Validation{': ' + plain(report.experiment) if report.experiment else ''}")
    ax_err.plot(*thinned(t[first:], report.measured[first:] - report.simulated[first:]),
                color="C3", lw=0.8)
    ax_err.set_ylabel(f"error{label_unit}")
    ax_err.set_xlabel("time [s]")
    ax_err.grid(alpha=0.3)
    _zoom(ax_zoom, report, label_unit)
    fig.tight_layout()
    return fig


def _zoom(ax: Axes, report: ValidationReport, label_unit: str) -> None:
    t, first = report.time, report.first
    error = np.abs(report.measured[first:] - report.simulated[first:])
    n = t.size - first
    # a twentieth of the record, 200 to _ZOOM samples: on a long record a twentieth is no zoom
    width = min(max(n // 20, 200), _ZOOM, n)
    centre = first + (int(np.nanargmax(error)) if np.isfinite(error).any() else 0)
    lo = int(np.clip(centre - width // 2, first, t.size - width))
    part = slice(lo, lo + width)
    ax.plot(*thinned(t[part], report.measured[part]), color="0.2", lw=1.0, label="measured")
    ax.plot(*thinned(t[part], report.simulated[part]), color="C1", lw=1.0, label="simulated")
    ax.plot(*thinned(t[part], report.predicted[part]), color="C0", lw=0.8, ls="--",
            label="predicted")
    ax.set_title(f"zoom: {width} samples around the largest simulation error", fontsize=9)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{plain(report.output)}{label_unit}")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)


def residuals_figure(report: ValidationReport, u: ArrayLike | None = None, *,
                     new: Callable[[tuple[float, float]], Figure] | None = None) -> Figure:
    """Residual correlation plots with the bands the tests use.

    The autocorrelation band is ±z/√N, the spread of each lag of white
    residuals (the whiteness verdict is the Ljung–Box test over all lags).
    The cross-correlation band is what the independence test assumes under
    its null: with the input `u` given, ±z·√(P_ττ/N), where P is built
    from the input's correlations and, when the residuals are not white,
    weighted by their (Bartlett-tapered) autocorrelation (Ljung, *System
    Identification*, 2nd ed., eq. 16.69; :func:`servoid.validate.residual_analysis`),
    which for a slow input and coloured residuals is much wider than
    ±z/√N. A causal (closed-loop) test leaves the negative lags untested;
    they are drawn without a band.

    Parameters
    ----------
    report : ValidationReport
        The validation.
    u : array_like, shape (N,) or (N, n_inputs), optional
        The validation input over the report's samples; without it the
        cross-correlation band is the white-residual ±z/√N.
    new : callable
        ``new(figsize)`` makes the figure: pyplot-free by default.
    """
    _check_report(report)
    res = report.residuals
    n_cross = res.cross_correlation.shape[0]
    fig = (new or _figure)((9, 2.6 * (1 + n_cross)))
    axes = fig.subplots(1 + n_cross, 1)
    axes = np.atleast_1d(axes)
    verdict = "white" if res.is_white else "not white"
    _stem(axes[0], res.lags, res.autocorrelation, np.full(res.lags.size, res.bound))
    axes[0].set_title(
        f"residual autocorrelation: {verdict} (Ljung–Box p = {res.whiteness_pvalue:.3g}); "
        f"band ±{res.bound:.3g} at {100 * res.confidence:.0f} %"
    )
    bands, how = _cross_bands(report, u, n_cross)
    for k in range(n_cross):
        band = bands[k]
        if res.causal:
            band = np.where(res.cross_lags >= 0, band, np.nan)
        _stem(axes[k + 1], res.cross_lags, res.cross_correlation[k], band)
        axes[k + 1].set_title(
            f"input {k} – residual cross-correlation: independence p = "
            f"{res.independence_pvalue:.3g}; band {how}"
            + ("; negative lags not tested (closed loop)" if res.causal else ""))
    axes[0].set_ylabel("autocorrelation [-]")
    for ax in axes[1:]:
        ax.set_ylabel("cross-correlation [-]")
    for ax in axes:
        ax.set_xlabel("lag [samples]")
    fig.tight_layout()
    return fig


def _cross_bands(report: ValidationReport, u: ArrayLike | None,
                 n_cross: int) -> tuple[list[NDArray[np.float64]], str]:
    """Per input and lag, z times the null standard deviation of r_εu(τ)."""
    from scipy import stats

    res = report.residuals
    lags = res.cross_lags
    flat = [np.full(lags.size, res.bound)] * n_cross
    if u is None or n_cross == 0:
        return flat, f"±z/√N = ±{res.bound:.3g} (white-residual approximation)"
    first = report.first
    uu = np.asarray(u, dtype=float).reshape(report.measured.size, -1)[first:]
    if uu.shape[1] != n_cross:
        raise ValueError(f"u has {uu.shape[1]} inputs but the report {n_cross}")
    n = uu.shape[0]
    z = float(stats.norm.ppf(0.5 + res.confidence / 2))
    colour = None
    if not res.is_white:
        if report.noise_model:  # its one-step errors are not in the report
            return flat, (f"±z/√N = ±{res.bound:.3g} (the test widens it for the residuals' "
                          "colour, which this report does not hold)")
        e = report.measured[first:] - report.simulated[first:]
        e = _unit_scale(e - e.mean())
        colour = _bartlett_autocorrelation(e, int(res.lags[-1]))
    bands = []
    for col in uu.T:
        x = _unit_scale(col - col.mean())
        x = x - x.mean()
        norm2 = float(x @ x)
        if colour is None:
            # Σ_s x(s − τ)² over the record: the full energy less the samples shifted out
            head = np.concatenate([[0.0], np.cumsum(x**2)])
            tail = np.concatenate([[0.0], np.cumsum(x[::-1] ** 2)])
            shifted = np.where(lags >= 0, tail[np.minimum(lags, n)], head[np.minimum(-lags, n)])
            var = (norm2 - shifted) / norm2
        else:
            k_max = (colour.size - 1) // 2
            s_uu = _lagged_sums(x, x, k_max)
            var = np.full(lags.size, float(colour @ s_uu) / norm2)
        bands.append(z * np.sqrt(np.maximum(var, 0.0) / n))
    how = ("±z·√(P_ττ/N) of the independence test" + (", widened for the residuals' colour"
                                                       if colour is not None else ""))
    return bands, how


def _stem(ax: Axes, lags: np.ndarray, r: np.ndarray, band: np.ndarray) -> None:
    ax.vlines(lags, 0, r, color="C0", lw=1.2)
    ax.plot(lags, r, "o", color="C0", ms=3)
    ax.fill_between(lags, -band, band, color="C2", alpha=0.15, lw=0, step="mid")
    ax.axhline(0, color="0.3", lw=0.6)
    ax.grid(alpha=0.3)


def _figure(figsize: tuple[float, float]) -> Figure:
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def _check_report(report: object) -> None:
    if not isinstance(report, ValidationReport):
        raise type_error("report", report, "a ValidationReport (servoid.validate.validate)")
