"""examples/study1.ipynb runs top to bottom in a real Jupyter kernel and shows its figures."""

from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).parents[1] / "examples" / "study1.ipynb"


@pytest.fixture(scope="module")
def executed(tmp_path_factory, request):
    """The notebook after an IPython kernel (ipykernel) of this Python ran every cell."""
    folder = tmp_path_factory.mktemp("notebook")
    # A kernel spec of its own, so that a user's "python3" spec of another Python is not
    # used; the kernel's files (connection, history) stay in the scratch folder.
    spec = folder / "jupyter" / "kernels" / "servoid-test"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "servoid test", "language": "python"}))
    patch = pytest.MonkeyPatch()
    request.addfinalizer(patch.undo)
    patch.setenv("JUPYTER_PATH", str(folder / "jupyter"))
    patch.setenv("JUPYTER_RUNTIME_DIR", str(folder / "runtime"))
    patch.setenv("IPYTHONDIR", str(folder / "ipython"))
    # The kernel inherits this environment: without MPLBACKEND, ipykernel selects the inline
    # backend as Jupyter does for a user. A test runner's MPLBACKEND=Agg would hide figures.
    patch.delenv("MPLBACKEND", raising=False)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="servoid-test",
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
