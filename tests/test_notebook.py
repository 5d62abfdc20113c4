"""The example notebook runs top to bottom, and every object it shows renders for Jupyter."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import matplotlib.figure

NOTEBOOK = Path(__file__).parents[1] / "examples" / "study1.ipynb"


def test_study1_notebook_runs_and_every_output_renders(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cells = [c for c in json.loads(NOTEBOOK.read_text(encoding="utf-8"))["cells"]
             if c["cell_type"] == "code"]
    assert len(cells) >= 8
    scope: dict = {}
    shown = []
    for cell in cells:
        tree = ast.parse("".join(cell["source"]))
        last = tree.body[-1] if tree.body and isinstance(tree.body[-1], ast.Expr) else None
        body = ast.Module(tree.body[:-1] if last else tree.body, type_ignores=[])
        exec(compile(body, "<cell>", "exec"), scope)  # noqa: S102 - the notebook's own code
        if last is not None:
            shown.append(eval(compile(ast.Expression(last.value), "<cell>", "eval"), scope))  # noqa: S307
    html = [obj._repr_html_() for obj in shown
            if hasattr(obj, "_repr_html_") and not isinstance(obj, matplotlib.figure.Figure)]
    assert len(html) >= 5 and all(h.startswith("<div") for h in html)
    assert sum(isinstance(obj, matplotlib.figure.Figure) for obj in shown) == 2
    truth_vs_estimate = shown[-1]
    for name, (truth, estimate) in truth_vs_estimate.items():
        assert abs(estimate - truth) / truth < 0.02, name
