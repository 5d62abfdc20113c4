"""The reports in a real browser: the demo, ARX, FRF, servopneumatic and fleet reports.

Each page is loaded by headless Chromium (Debian's ``chromium``; ``.ci/run``
installs it when missing) inside a wrapper page at a desktop (1100 px) and a
phone (390 px) width. The test fails on a console error, on any request
that leaves the file (the page must be self-contained), on an image that
does not decode, on a missing viewport, on a page body wider than the
screen, on content wider than the phone screen outside a horizontally
scrolling box, and on a page without its verdict box (a decision line
reading ACCEPT, REJECT or INCONCLUSIVE first on the page). Each page is
also photographed at both widths (``SERVOID_SCREENSHOTS=<folder>`` keeps
the PNGs for a reviewer to look at). Every figure is checked in Python as
it is saved: each axes has a y label, an x label where its x tick labels
show, and a title that lies inside the figure. A deliberately broken page
(an external image and a script error) must fail the same checks.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
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
    bodyWidth: d.body.scrollWidth, bodyClient: d.body.clientWidth,
    first: (d.querySelector("h2") || {{}}).textContent || null,
    decision: (d.querySelector(".box .decision") || {{}}).textContent || null,
    wide: Array.from(d.querySelectorAll("table, figure, img, pre, p, h1, h2")).filter(
      function (e) {{ return e.getBoundingClientRect().right > vw + 1 && !e.closest(".scroll"); }}
    ).map(function (e) {{ return e.tagName + ": " + e.textContent.slice(0, 40); }})
  }});
}};
</script></body></html>"""


def _chromium(tmp: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp / 'chromium'}",
         "--allow-file-access-from-files", "--enable-logging=stderr", "--v=0",
         "--host-resolver-rules=MAP * ~NOTFOUND", *args],
        capture_output=True, text=True, timeout=120, check=False)


def browse(page: Path, width: int, tmp: Path) -> tuple[dict, list[str]]:
    """Load `page` at `width` px; return the page's measurements and the console errors."""
    wrapper = page.parent / f".wrap-{width}-{page.name}"
    wrapper.write_text(_WRAPPER.format(page=page.name, width=width), encoding="utf-8")
    try:
        done = _chromium(tmp, "--virtual-time-budget=5000", "--dump-dom",
                         wrapper.resolve().as_uri())
    finally:
        wrapper.unlink()
    found = re.search(r'<pre id="out">([^<]*)</pre>', done.stdout)
    assert found, f"Chromium did not render {page}: {done.stderr[-2000:]}"
    errors = [line for line in done.stderr.splitlines()
              if ":CONSOLE" in line and ("Uncaught" in line or "rror" in line)]
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&")), errors


WIDTHS = (1100, 390)  # a desktop window and a phone (an iPhone 12 to 15 is 390 px wide)


def problems(page: Path, tmp: Path) -> list[str]:
    """Everything wrong with a page at desktop and phone widths."""
    out = []
    for width in WIDTHS:
        m, errors = browse(page, width, tmp)
        out += [f"{width}px console: {e}" for e in errors]
        out += [f"{width}px request leaves the file: {r}" for r in m["resources"]]
        out += [f"{width}px image {k} does not decode" for k, w in enumerate(m["images"]) if not w]
        if not m["viewport"]:
            out.append("no viewport meta")
        if m["scrollWidth"] > m["clientWidth"] + 1:
            out.append(f"{width}px page wider than the screen: {m['scrollWidth']} px")
        if m["bodyWidth"] > m["bodyClient"] + 1:
            out.append(f"{width}px page body overflows sideways: {m['bodyWidth']} px in "
                       f"{m['bodyClient']} px")
        out += [f"{width}px overflows: {w}" for w in m["wide"]]
        if m["first"] != "Verdict":
            out.append(f"{width}px the first section is {m['first']!r}, not the verdict")
        if not re.match(r"(ACCEPT|REJECT|INCONCLUSIVE) — \S", m["decision"] or ""):
            out.append(f"{width}px no decision line in a verdict box: {m['decision']!r}")
    return out


def screenshot(page: Path, name: str, width: int, out: Path, tmp: Path) -> Path:
    """A PNG of the top of `page` at `width` px (3000 px tall), as ``<name>-<width>.png``."""
    png = out / f"{name}-{width}.png"
    done = _chromium(tmp, "--hide-scrollbars", f"--window-size={width},3000",
                     f"--screenshot={png}", page.resolve().as_uri())
    assert png.is_file(), f"Chromium took no screenshot of {page}: {done.stderr[-2000:]}"
    return png


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
            if ax.get_title():
                box = ax.title.get_window_extent(fig._get_renderer())
                if box.x0 < -1 or box.x1 > fig.bbox.width + 1:
                    missing.append(f"{Path(str(fname)).name}: title cut: {ax.get_title()!r}")
        return original(fig, fname, *args, **kwargs)

    matplotlib.figure.Figure.savefig = checked
    try:
        yield missing
    finally:
        matplotlib.figure.Figure.savefig = original


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory, labels) -> dict[str, Path]:
    from servoid.fleet import run_fleet
    from servoid.plants.ehsa._fleet import write_virtual_fleet

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
    frf = bench / "frf.toml"  # the same record's measured response and a fitted model
    frf.write_text(re.sub(r"(?s)\[identify\].*?(?=\n\[|\Z)", '[identify]\nmethod = "frf"\n'
                          'input = "r"\nphase_frequency = 10.0\nn_poles = 3\n', text),
                   encoding="utf-8")
    assert main(["identify", str(frf), "--out", str(root / "frf-results")]) == 0
    assert main(["bench", "pneumatic", "--out", str(root / "pn"), "--duration", "4"]) == 0
    assert main(["identify", str(root / "pn" / "pneumatic.toml"), "--out",
                 str(root / "pn-results")]) == 0
    fleet = write_virtual_fleet(root / "fleet", units=6, bad_every=3, corrupt=1, seed=1)
    result = run_fleet(fleet.fleet_file, workers=1, progress=False)
    return {"demo": root / "demo" / "report" / "report.html",
            "arx": root / "arx-results" / "report.html",
            "frf": root / "frf-results" / "report.html",
            "pneumatic": root / "pn-results" / "report.html",
            "fleet": result.folder / "report.html"}


@pytest.mark.parametrize("name", ["demo", "arx", "frf", "pneumatic", "fleet"])
def test_report_renders_clean(reports, name, tmp_path):
    assert problems(reports[name], tmp_path) == []


@pytest.mark.parametrize("name", ["demo", "arx", "frf", "pneumatic", "fleet"])
def test_screenshots_at_desktop_and_phone_width(reports, name, tmp_path):
    keep = os.environ.get("SERVOID_SCREENSHOTS")
    out = Path(keep) if keep else tmp_path
    out.mkdir(parents=True, exist_ok=True)
    for width in WIDTHS:
        png = screenshot(reports[name], name, width, out, tmp_path)
        head = png.read_bytes()[:24]
        assert head[:8] == b"\x89PNG\r\n\x1a\n"
        assert struct.unpack(">I", head[16:20])[0] == width  # the page laid out at this width


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


def test_a_page_without_its_verdict_or_too_wide_is_caught(reports, tmp_path):
    page = tmp_path / "plain.html"
    html = reports["arx"].read_text(encoding="utf-8")
    html = html.replace("<h2>Verdict</h2>", "<h2>Summary</h2>")
    html = html.replace('class="decision', 'class="x')
    page.write_text(html.replace("</body>", '<div style="width:1500px">a wide line</div></body>'),
                    encoding="utf-8")
    found = problems(page, tmp_path)
    assert any("the first section is 'Summary', not the verdict" in p for p in found)
    assert any("no decision line in a verdict box" in p for p in found)
    assert any("390px page body overflows sideways" in p for p in found)
