"""The figures README.md and docs/*.md quote are what their commands print.

The markers and their rules are described in ``tests/docs_check.py``; a failure names the
file and line, and ``python tests/docs_check.py --update FILE`` rewrites an output block
that a change in servoid moved. Slow sources (studies, long runs) are marked slow and run
with ``pytest -m slow`` or ``python tests/docs_check.py --slow``.
"""

from __future__ import annotations

import re

import docs_check
import pytest

MARKERS = [m for path in docs_check.DOCS for m in docs_check.markers(path)]


@pytest.mark.parametrize("marker", [
    pytest.param(m, id=m.label, marks=[pytest.mark.slow] if m.slow else [])
    for m in MARKERS])
def test_quoted_figures_match_their_source(marker):
    problem = docs_check.check(marker)
    assert problem is None, f"{marker.label}: {problem}"


def test_every_doc_has_figures_tied_to_commands():
    # the pages that quote results; a page that drops all its markers drops its check too
    quoted = {m.path.name for m in MARKERS}
    assert {"black-box.md", "block-oriented.md", "emps.md", "greybox-ode.md",
            "nonlinear-real.md", "study1-ehsa.md", "study2-pneumatic.md"} <= quoted


# A percentage with decimals is almost always a measured figure (a fit, an error, a coverage);
# each one in the docs sits under a marker, so none can drift from what servoid prints.
_PERCENT = re.compile(r"(?<![\w.])\d+\.\d+\s?%")


#: The models specification states requirements and the source studies' values (inputs to
#: servoid, not its results), e.g. "within 0.5%" of an acceptance check.
_SPECIFICATION = {"models-spec.md"}


def test_every_decimal_percentage_is_under_a_marker():
    loose = []
    for path in docs_check.DOCS:
        if path.name in _SPECIFICATION:
            continue
        lines = path.read_text(encoding="utf-8").splitlines()
        governed = {i for m in docs_check.markers(path) for i in range(*m.span)}
        fence = None  # the info string of the open fence
        for i, line in enumerate(lines):
            if line.lstrip().startswith("```"):
                fence = None if fence is not None else line.strip()[3:]
                continue
            if (fence and fence not in ("text", "console")) or i in governed:
                continue  # code and configuration (```python, ```toml, ```sh) are not figures
            for match in _PERCENT.finditer(docs_check._CODE_SPAN.sub(" ", line)):
                loose.append(f"{path.relative_to(docs_check.ROOT)}:{i + 1}: {match.group()}")
    assert not loose, "figures with no source (add a marker, see tests/docs_check.py):\n" + \
        "\n".join(loose)


# -- the checker itself ----------------------------------------------------------------------
def test_a_changed_figure_is_caught():
    # the figure the flexible-arm page once quoted against what the example prints
    doc = ["model  fit", "OE (nb = 4, nf = 4, nk = 1)  80.8 %      2"]
    out = "model  fit\nOE (nb = 4, nf = 4, nk = 1)  88.4 %      2\n"
    assert "80.8" in docs_check.compare(doc, out)
    assert docs_check.compare(["model  fit", "OE (nb = 4, nf = 4, nk = 1)  88.4 %      2"],
                              out) is None


@pytest.mark.parametrize(("doc", "out", "same"), [
    ("fit 88.4 %", "fit 88.5 %", True),         # one unit in the last digit: rounding
    ("fit 88.4 %", "fit 88.6 %", False),
    ("na = 4", "na = 5", False),                 # whole numbers are counts: exact
    ("σ̂² = 1.032e-06", "σ̂² = 1.033e-06", True),
    ("σ̂² = 1.032e-06", "σ̂² = 1.035e-06", False),
    ("reports: …/arm/report.html", "reports: /tmp/x/arm/report.html", True),
    ("reports: …/arm/report.html", "reports: /tmp/x/leg/report.html", False),
])
def test_lines_compare_text_exactly_and_numbers_to_their_last_digit(doc, out, same):
    assert (docs_check.compare([doc], out) is None) is same


def test_an_ellipsis_line_stands_for_any_lines_and_prompts_are_not_output():
    out = "head\na\nb\ntail\n"
    assert docs_check.compare(["$ servoid x", "head", "…", "tail"], out) is None
    assert docs_check.compare(["head", "…", "tail", "more"], out) is not None
    assert docs_check.compare(["head", "a"], out) is not None  # the output goes on


def test_numbers_markers_find_figures_outside_code_and_identifiers(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- numbers: file x.json -->\n"
                    "fit 95.6 % (b0, §3.1, `0.5`), error −3.1648, 91 % covered, "
                    "95 % intervals, σ = 1.2e-05\n\nnext paragraph 7.5\n", encoding="utf-8")
    (marker,) = docs_check.markers(page)
    assert docs_check.figures(marker.body) == ["95.6", "−3.1648", "91", "1.2e-05"]
    assert docs_check.missing_figures(marker, '{"a": 95.63, "b": -3.16481, "c": 0.9}') == \
        ["91", "1.2e-05"]


def test_update_rewrites_a_stale_output_block_and_keeps_the_prompt(tmp_path):
    page = tmp_path / "page.md"
    page.write_text('text\n<!-- output: python -c "print(\'fit 88.4 %\')" -->\n```\n'
                    '$ python example.py\nfit 80.8 %\n```\nafter\n', encoding="utf-8")
    (marker,) = docs_check.markers(page)
    assert "80.8" in docs_check.check(marker)
    assert len(docs_check.update(page, slow=False)) == 1
    assert page.read_text(encoding="utf-8") == (
        'text\n<!-- output: python -c "print(\'fit 88.4 %\')" -->\n```\n'
        '$ python example.py\nfit 88.4 %\n```\nafter\n')
    assert docs_check.check(docs_check.markers(page)[0]) is None
