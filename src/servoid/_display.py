"""Notebook display: small HTML tables for ``_repr_html_`` (escaped, no external resources)."""

from __future__ import annotations

import html
from collections.abc import Sequence

__all__ = ["html_block", "number"]

_STYLE = ("border-collapse:collapse;font-size:90%;margin:.3em 0",
          "border:1px solid #ccc;padding:.15em .5em;text-align:right",
          "border:1px solid #ccc;padding:.15em .5em;text-align:left;background:#f3f3f3")


def number(x: float, digits: int = 6) -> str:
    """A number in at most `digits` significant digits."""
    return f"{x:.{digits}g}"


def html_block(title: str, facts: Sequence[tuple[str, str]] = (),
               columns: Sequence[str] = (), rows: Sequence[Sequence[str]] = (),
               note: str = "") -> str:
    """A title, a list of facts, an optional table and a note, as one HTML fragment."""
    table, td, th = _STYLE
    out = [f"<div><b>{html.escape(title)}</b>"]
    if facts:
        out.append("<br>" + " · ".join(f"{html.escape(k)}: {html.escape(v)}" for k, v in facts))
    if columns:
        out.append(f'<table style="{table}"><tr>'
                   + "".join(f'<th style="{th}">{html.escape(c)}</th>' for c in columns) + "</tr>")
        for row in rows:
            out.append("<tr>" + "".join(f'<td style="{td}">{html.escape(str(c))}</td>'
                                        for c in row) + "</tr>")
        out.append("</table>")
    if note:
        out.append(f"<div style=\"color:#555\">{html.escape(note)}</div>")
    out.append("</div>")
    return "".join(out)


def _domain(dt: float | None) -> str:
    return "continuous" if dt is None else f"discrete, dt = {dt:g} s"


def _poles(poles: object) -> str:
    import numpy as np

    p = np.asarray(poles)
    shown = ", ".join(f"{z.real:.4g}{z.imag:+.4g}j" if abs(z.imag) > 0 else f"{z.real:.4g}"
                      for z in p[:8])
    return shown + (" …" if p.size > 8 else "") if p.size else "none"


def model_html(kind: str, dt: float | None, poles: object,
               columns: Sequence[str] = (), rows: Sequence[Sequence[str]] = (),
               extra: Sequence[tuple[str, str]] = ()) -> str:
    """A model's summary: its kind, domain, poles and a table of coefficients."""
    return html_block(kind, [("domain", _domain(dt)), *extra, ("poles", _poles(poles))],
                      columns, rows)
