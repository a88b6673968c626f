"""Self-contained HTML reports: matplotlib figures inlined as base64 PNG, tables, atomic writing.

>>> from plenodecode.report.html import page, figure_html, table_html, write_html
>>> html = page("Title", [table_html([("pitch", "14.29 px")])])   # doctest: +SKIP
>>> write_html("report.html", html)                              # doctest: +SKIP

Nothing is loaded from outside the file: a report opens offline and can be mailed as is.
"""

from __future__ import annotations

import base64
import html as _html
import io
import os
from pathlib import Path
from typing import Any, Iterable, Sequence

from ..io.atomic import write_text_atomic

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:24px auto;max-width:1200px;
color:#222;line-height:1.4;padding:0 16px}
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.25em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 10px;text-align:left;
font-variant-numeric:tabular-nums}th{background:#f3f3f3}
.warn{background:#fff4e5;border-left:4px solid #f0a020;padding:6px 12px;margin:6px 0}
.ok{background:#eef8ee;border-left:4px solid #3a3;padding:6px 12px;margin:6px 0}
figure{margin:10px 0}figcaption{color:#555;font-size:.9em}img{max-width:100%;height:auto}
.muted{color:#666;font-size:.9em}
"""


def escape(text: Any) -> str:
    """HTML-escape any value's ``str``."""
    return _html.escape(str(text), quote=True)


def figure_png(fig: Any, *, dpi: int = 100) -> bytes:
    """PNG bytes of a matplotlib figure (the figure is closed afterwards)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def figure_html(fig: Any, caption: str = "", *, dpi: int = 100, alt: str | None = None,
                data: dict[str, str] | None = None) -> str:
    """An ``<figure>`` with the figure inlined as a base64 PNG ``data:`` URI; ``data`` adds ``data-<key>``
    attributes to it (facts of the drawing, e.g. marker sizes, for whoever reads the page's source)."""
    png = base64.b64encode(figure_png(fig, dpi=dpi)).decode("ascii")
    cap = f"<figcaption>{escape(caption)}</figcaption>" if caption else ""
    attrs = "".join(f' data-{escape(k)}="{escape(v)}"' for k, v in (data or {}).items())
    return (f'<figure{attrs}><img alt="{escape(alt or caption or "figure")}" '
            f'src="data:image/png;base64,{png}">{cap}</figure>')


def table_html(rows: Iterable[Sequence[Any]], header: Sequence[str] | None = None) -> str:
    """A table from rows of cells (escaped)."""
    out = ["<table>"]
    if header:
        out.append("<tr>" + "".join(f"<th>{escape(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{escape(c)}</td>" for c in row) + "</tr>")
    out.append("</table>")
    return "".join(out)


def notes_html(messages: Iterable[str], *, kind: str = "warn") -> str:
    """Boxed notes: ``kind`` 'warn' (orange) or 'ok' (green)."""
    if kind not in ("warn", "ok"):
        raise ValueError(f"kind must be 'warn' or 'ok', got {kind!r}")
    return "".join(f'<div class="{kind}">{escape(m)}</div>' for m in messages)


def section(title: str, *parts: str) -> str:
    """A ``<h2>`` titled section holding already-built HTML parts."""
    return f"<section><h2>{escape(title)}</h2>{''.join(parts)}</section>"


def page(title: str, parts: Sequence[str], *, subtitle: str = "") -> str:
    """A complete HTML5 document with inline CSS."""
    sub = f'<p class="muted">{escape(subtitle)}</p>' if subtitle else ""
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{escape(title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{escape(title)}</h1>{sub}{''.join(parts)}</body></html>")


def write_html(path: str | os.PathLike, text: str, *, overwrite: bool = False) -> Path:
    """Write an HTML document atomically (see :mod:`plenodecode.io.atomic`).

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    return write_text_atomic(path, text, overwrite=overwrite)


__all__ = ["escape", "figure_png", "figure_html", "table_html", "notes_html", "section", "page", "write_html"]
