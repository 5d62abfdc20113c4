"""Figures that fit: titles inside the figure, pole–zero maps framed on what matters."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.models import TransferFunction
from servoid.report import new_figure, plot_pole_zero, plot_poles, save_figure
from servoid.report._model_figures import Z_FRAME


def _saved(monkeypatch, module: str) -> list:
    """Collect the figures a plotting function saves (and save nothing)."""
    figures: list = []
    monkeypatch.setattr(f"servoid.report.{module}.save_figure",
                        lambda fig, path, overwrite=False: figures.append(fig))
    return figures


def _fits(fig) -> bool:
    renderer = fig._get_renderer()
    return all(0 <= t.get_window_extent(renderer).x0 and
               t.get_window_extent(renderer).x1 <= fig.bbox.width
               for ax in fig.axes for t in (ax.title,) if t.get_text())


def test_a_title_wider_than_the_figure_is_wrapped_to_fit(tmp_path):
    fig = new_figure((9, 2.6))
    axes = fig.subplots(2, 1)
    text = ("input 0 – residual cross-correlation: independence p = 0.668; band ±z·√(P_ττ/N) "
            "of the independence test, widened for the residuals' colour")
    axes[1].set_title(text)
    axes[0].set_title("short")
    fig.tight_layout()
    assert not _fits(fig)  # as set, the title runs off both edges
    save_figure(fig, tmp_path / "r.png")
    assert _fits(fig)
    assert "\n" in axes[1].get_title() and axes[1].get_title().replace("\n", " ") == text
    assert axes[0].get_title() == "short"  # a title that fits is left alone


def test_a_z_plane_map_is_framed_on_the_unit_circle(monkeypatch):
    figures = _saved(monkeypatch, "_model_figures")
    # a well-damped pole pair near z = 0.9 and two far zeros (8.6 and -5.65), as a
    # discretised servo with a fast sampled zero has
    model = TransferFunction(np.poly([8.6, -5.65]), np.poly([0.9 + 0.1j, 0.9 - 0.1j]), dt=0.001)
    plot_pole_zero({"oe": model}, "unused.png")
    ax = figures[0].axes[0]
    assert ax.get_xlim() == pytest.approx((-Z_FRAME, Z_FRAME))  # not stretched to 8.6
    assert ax.get_ylim() == pytest.approx((-Z_FRAME, Z_FRAME))
    labels = {t.get_text() for t in ax.texts}
    assert {"8.6", "5.65"} <= labels  # the off-map zeros are named at the edge
    for line in ax.lines:  # everything drawn lies inside the frame
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        assert np.all(np.abs(x) <= Z_FRAME) and np.all(np.abs(y) <= Z_FRAME)
    assert any("off the map" in t.get_text() for t in ax.get_legend().get_texts())


def test_an_s_plane_map_is_framed_on_the_poles(monkeypatch):
    figures = _saved(monkeypatch, "_model_figures")
    model = TransferFunction(np.poly([-1000.0]), np.poly([-3 + 4j, -3 - 4j]))  # |p| = 5
    plot_pole_zero({"tf": model}, "unused.png")
    ax = figures[0].axes[0]
    assert ax.get_xlim() == pytest.approx((-6.5, 6.5))  # 1.3 × the largest pole magnitude
    assert "1e+03" in {t.get_text() for t in ax.texts}


def test_the_closed_loop_z_map_keeps_the_unit_circle(monkeypatch):
    figures = _saved(monkeypatch, "_lti_figures")
    plant = TransferFunction([1.0], [1.0, 1.0, 0.0])
    one = TransferFunction(np.poly([8.54, 1.78]), np.poly([0.95, -0.59]), dt=0.001)
    two = TransferFunction(np.poly([1.8]), np.poly([0.9, 0.5]), dt=0.001)
    plot_poles({"one-step": plant}, {"two-step": two, "one-step": one}, "unused.png")
    ax_z = figures[0].axes[1]
    assert ax_z.get_xlim() == pytest.approx((-Z_FRAME, Z_FRAME))
    # zeros on the same ray share one spot: one label lists them; another model's label
    # on that spot goes one line down instead of over it
    labels = {t.get_text(): t for t in ax_z.texts if t.get_text()}
    assert set(labels) == {"1.8", "1.78, 8.54"}
    assert labels["1.8"].xyann != labels["1.78, 8.54"].xyann
