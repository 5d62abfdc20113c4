"""Figures a user asks for are pyplot's; a report's figures never are."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # a script without a display; the test writes files only

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.image import imread  # noqa: E402
from scipy.signal import lfilter  # noqa: E402

from servoid.data import Experiment, write_csv, write_experiment_spec  # noqa: E402
from servoid.models import PolynomialModel  # noqa: E402
from servoid.validate import validate  # noqa: E402
from servoid.workflows import identify  # noqa: E402

TRUTH = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)


def _record(n: int = 600) -> Experiment:
    rng = np.random.default_rng(5)
    u = rng.standard_normal(n)
    y = TRUTH.simulate(u) + lfilter([1.0], TRUTH.a, 0.02 * rng.standard_normal(n))
    return Experiment.from_arrays(0.01, u=u, y=y)


@pytest.fixture(autouse=True)
def _no_open_figures():
    plt.close("all")
    yield
    plt.close("all")


def _ink(path) -> float:
    """The share of pixels that are not the background."""
    image = imread(path)[..., :3]
    return float(np.mean(np.any(np.abs(image - image[0, 0]) > 0.05, axis=-1)))


@pytest.mark.parametrize("what", ["experiment", "validation"])
def test_plot_then_pyplot_savefig_writes_the_figure(what, tmp_path):
    record = _record()
    figure = record.plot() if what == "experiment" else validate(TRUTH, record).plot()
    assert plt.gcf() is figure  # the figure a script's plt.savefig()/plt.show() acts on
    plt.savefig(tmp_path / "plot.png")
    # axes, lines and labels cover a few percent of the page; a blank figure covers none
    assert _ink(tmp_path / "plot.png") > 0.02
    plt.close(figure)
    assert plt.get_fignums() == []


def test_a_blank_pyplot_figure_has_no_ink(tmp_path):
    # what plt.savefig() wrote when .plot() built its figure outside pyplot
    plt.figure()
    plt.savefig(tmp_path / "blank.png")
    assert _ink(tmp_path / "blank.png") == 0.0


def test_a_report_leaves_nothing_open_in_pyplot(tmp_path):
    write_csv(_record(), tmp_path / "run.csv")
    table = {"data": {"file": "run.csv"},
             "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
             "identify": {"method": "arx", "na": 2, "nb": 2, "nk": 1}}
    write_experiment_spec(table, tmp_path / "e.toml")
    result = identify(tmp_path / "e.toml", tmp_path / "out")
    assert sorted(p.suffix for p in result.folder.iterdir()).count(".png") >= 2
    assert plt.get_fignums() == []  # every report figure is pyplot-free
