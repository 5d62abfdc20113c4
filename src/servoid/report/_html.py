"""A single-file HTML report: sections of text, tables and embedded figures."""

from __future__ import annotations

import base64
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import jinja2

from .._atomic import atomic_path

__all__ = ["Figure", "Page", "Section", "Table", "render_html", "write_html"]

_MIME = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg"}


@dataclass(frozen=True)
class Table:
    """A table: column titles, rows of cells (already formatted)."""

    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""
    sortable: bool = False  # a click on a column title sorts the rows by it


@dataclass(frozen=True)
class Figure:
    """A figure embedded in the page (base64), with a caption."""

    data: str
    mime: str
    caption: str = ""

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], caption: str = "") -> Figure:
        """Read an image file and embed it."""
        path = Path(path)
        mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
        return cls(base64.b64encode(path.read_bytes()).decode("ascii"), mime, caption)


@dataclass(frozen=True)
class Section:
    """A titled section of paragraphs, tables and figures."""

    title: str
    paragraphs: tuple[str, ...] = ()
    tables: tuple[Table, ...] = ()
    figures: tuple[Figure, ...] = ()
    box: bool = False  # drawn framed: the page's verdict
    # (decision, line): the verdict's decision ("accept", "reject", "inconclusive") and its
    # line, drawn first and coloured by the decision
    decision: tuple[str, str] | None = None


@dataclass(frozen=True)
class Page:
    """A whole report page with provenance lines in ``meta``."""

    title: str
    sections: tuple[Section, ...]
    subtitle: str = ""
    meta: tuple[tuple[str, str], ...] = field(default_factory=tuple)


@lru_cache(maxsize=1)
def _template() -> jinja2.Template:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("servoid.report", "templates"),
        autoescape=True,  # every cell and caption is escaped: data names cannot inject markup
        trim_blocks=True,
        lstrip_blocks=True,
    )
    return env.get_template("report.html.j2")


def render_html(page: Page) -> str:
    """Render a page to one self-contained HTML string."""
    return _template().render(page=page)


def write_html(page: Page, path: str | os.PathLike[str], overwrite: bool = False) -> None:
    """Write a page as a self-contained HTML file, atomically."""
    text = render_html(page)
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
