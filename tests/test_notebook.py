"""examples/study1.ipynb runs top to bottom in a real Jupyter kernel and shows its figures."""

from __future__ import annotations

import ast
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).parents[1] / "examples" / "study1.ipynb"


@pytest.fixture(scope="module")
def executed(tmp_path_factory, request):
    """The notebook after a python3 kernel (ipykernel) ran every cell."""
    folder = tmp_path_factory.mktemp("notebook")
    # The kernel inherits this environment: without MPLBACKEND, ipykernel selects the inline
    # backend as Jupyter does for a user. A test runner's MPLBACKEND=Agg would hide figures.
    patch = pytest.MonkeyPatch()
    request.addfinalizer(patch.undo)
    patch.delenv("MPLBACKEND", raising=False)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(folder)}}).execute()
    return [cell for cell in notebook.cells if cell.cell_type == "code"]


def _outputs(cell, mime: str) -> list:
    return [o for o in cell.outputs if mime in o.get("data", {})]


def test_no_cell_fails(executed):
    assert len(executed) >= 8
    assert not [o for cell in executed for o in cell.outputs if o.output_type == "error"]


def test_each_plot_cell_shows_its_figure_once(executed):
    plots = [cell for cell in executed if cell.source.rstrip().endswith(".plot()")]
    assert len(plots) == 2
    for cell in plots:  # the figure is the cell's value and a pyplot figure: one image
        assert len(_outputs(cell, "image/png")) == 1, cell.source
    others = [cell for cell in executed if cell not in plots]
    assert not [cell.source for cell in others if _outputs(cell, "image/png")]


def test_results_render_as_html(executed):
    html = [o["data"]["text/html"] for cell in executed for o in _outputs(cell, "text/html")]
    assert len(html) >= 5 and all(h.startswith("<div") for h in html)


def test_the_estimate_is_within_two_percent_of_the_truth(executed):
    (value,) = _outputs(executed[-1], "text/plain")
    for name, (truth, estimate) in ast.literal_eval(value["data"]["text/plain"]).items():
        assert abs(estimate - truth) / truth < 0.02, name  # 35 dB SNR, 5110 samples
