"""The reports in a real browser: the demo, an ARX report and the servopneumatic report.

Each page is loaded by headless Chromium (Debian's ``chromium``; ``.ci/run``
installs it when missing) inside a wrapper page at a desktop (1100 px) and a
phone (375 px) width. The test fails on a console error, on any request
that leaves the file (the page must be self-contained), on an image that
does not decode, on a missing viewport, and on content wider than the
phone screen outside a horizontally scrolling box. Every figure is checked
in Python as it is saved: each axes has a y label, and an x label where
its x tick labels show. A deliberately broken page (an external image and
a script error) must fail the same checks.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import matplotlib.figure
import pytest

from servoid.cli import main

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed "
                                "(apt install chromium; .ci/run does it)")

_WRAPPER = """<!doctype html><html><body><pre id="out">pending</pre>
<iframe id="f" src="{page}" style="width:{width}px;height:900px;border:0"></iframe>
<script>
var f = document.getElementById("f");
f.onload = function () {{
  var d = f.contentDocument, w = f.contentWindow, vw = d.documentElement.clientWidth;
  document.getElementById("out").textContent = JSON.stringify({{
    scrollWidth: d.documentElement.scrollWidth, clientWidth: vw,
    resources: w.performance.getEntriesByType("resource").map(function (e) {{ return e.name; }}),
    viewport: !!d.querySelector("meta[name=viewport]"),
    images: Array.from(d.images).map(function (i) {{ return i.naturalWidth; }}),
    wide: Array.from(d.querySelectorAll("table, figure, img, pre, p, h1, h2")).filter(
      function (e) {{ return e.getBoundingClientRect().right > vw + 1 && !e.closest(".scroll"); }}
    ).map(function (e) {{ return e.tagName + ": " + e.textContent.slice(0, 40); }})
  }});
}};
</script></body></html>"""


def browse(page: Path, width: int, tmp: Path) -> tuple[dict, list[str]]:
    """Load `page` at `width` px; return the page's measurements and the console errors."""
    wrapper = page.parent / f".wrap-{width}-{page.name}"
    wrapper.write_text(_WRAPPER.format(page=page.name, width=width), encoding="utf-8")
    try:
        done = subprocess.run(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={tmp / 'chromium'}",
             "--allow-file-access-from-files", "--enable-logging=stderr", "--v=0",
             "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=5000",
             "--dump-dom", wrapper.resolve().as_uri()],
            capture_output=True, text=True, timeout=120, check=False)
    finally:
        wrapper.unlink()
    found = re.search(r'<pre id="out">([^<]*)</pre>', done.stdout)
    assert found, f"Chromium did not render {page}: {done.stderr[-2000:]}"
    errors = [line for line in done.stderr.splitlines()
              if ":CONSOLE" in line and ("Uncaught" in line or "rror" in line)]
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&")), errors


def problems(page: Path, tmp: Path) -> list[str]:
    """Everything wrong with a page at desktop and phone widths."""
    out = []
    for width in (1100, 375):
        m, errors = browse(page, width, tmp)
        out += [f"{width}px console: {e}" for e in errors]
        out += [f"{width}px request leaves the file: {r}" for r in m["resources"]]
        out += [f"{width}px image {k} does not decode" for k, w in enumerate(m["images"]) if not w]
        if not m["viewport"]:
            out.append("no viewport meta")
        if m["scrollWidth"] > m["clientWidth"] + 1:
            out.append(f"{width}px page wider than the screen: {m['scrollWidth']} px")
        out += [f"{width}px overflows: {w}" for w in m["wide"]]
    return out


@pytest.fixture(scope="module")
def labels(tmp_path_factory: pytest.TempPathFactory):
    """Axes without labels in every figure saved while the reports are made."""
    missing: list[str] = []
    original = matplotlib.figure.Figure.savefig

    def checked(fig, fname, *args, **kwargs):
        for ax in fig.axes:
            if not ax.axison or ax.get_label() == "<colorbar>":
                continue
            title = ax.get_title() or fig.get_suptitle() or str(fname)
            if not ax.get_ylabel().strip():
                missing.append(f"{Path(str(fname)).name}: y axis of {title!r}")
            shows_x = any(t.get_visible() and t.get_text() for t in ax.get_xticklabels())
            twins = ax.get_shared_x_axes().get_siblings(ax)  # a twinx axes shares the x label
            if shows_x and not any(a.get_xlabel().strip() for a in twins):
                missing.append(f"{Path(str(fname)).name}: x axis of {title!r}")
        return original(fig, fname, *args, **kwargs)

    matplotlib.figure.Figure.savefig = checked
    try:
        yield missing
    finally:
        matplotlib.figure.Figure.savefig = original


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory, labels) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("reports")
    assert main(["demo", "--out", str(root / "demo")]) == 0
    bench = root / "arx"
    assert main(["bench", "ehsa", "--out", str(bench), "--register", "9"]) == 0
    toml = bench / "ehsa.toml"
    text = toml.read_text(encoding="utf-8")
    text = re.sub(r"(?s)\[identify\].*?(?=\n\[|\Z)", '[identify]\nmethod = "arx"\ninput = "r"\nna = 3\n'
                  "nb = 3\nnk = 1\n", text)
    toml.write_text(text, encoding="utf-8")
    assert main(["identify", str(toml), "--out", str(root / "arx-results")]) == 0
    assert main(["bench", "pneumatic", "--out", str(root / "pn"), "--duration", "4"]) == 0
    assert main(["identify", str(root / "pn" / "pneumatic.toml"), "--out",
                 str(root / "pn-results")]) == 0
    return {"demo": root / "demo" / "report" / "report.html",
            "arx": root / "arx-results" / "report.html",
            "pneumatic": root / "pn-results" / "report.html"}


@pytest.mark.parametrize("name", ["demo", "arx", "pneumatic"])
def test_report_renders_clean(reports, name, tmp_path):
    assert problems(reports[name], tmp_path) == []


def test_every_axis_is_labelled(reports, labels):
    assert labels == [], "\n".join(labels)


def test_a_broken_page_is_caught(reports, tmp_path):
    page = tmp_path / "broken.html"
    html = reports["arx"].read_text(encoding="utf-8")
    page.write_text(html.replace("</body>", '<img src="https://example.com/x.png">'
                                 "<script>notDefined();</script></body>"), encoding="utf-8")
    found = problems(page, tmp_path)
    assert any("request leaves the file: https://example.com/x.png" in p for p in found)
    assert any("notDefined" in p for p in found)
