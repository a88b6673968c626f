"""HTML index of a batch run: one card per raw with a thumbnail of each output, or its error.

The index lives in the batch's output folder and links the thumbnails and outputs by relative
paths (so it stays small for hundreds of raws and keeps working when the folder is moved).  No
scripts: the page renders the same in any browser, without network access.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, Sequence

#: ``<meta name="generator">`` of the index; marks an index.html a later run may replace.
GENERATOR = "plenodecode batch index"

_STYLE = """
body{font-family:system-ui,-apple-system,sans-serif;margin:1.5em;color:#222;background:#fafafa}
h1{font-size:1.4em;margin:0 0 .4em} .sum{margin-bottom:1em} .sum b{font-size:1.1em}
.grid{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;padding:8px;min-width:330px;max-width:100%;
box-sizing:border-box}
.card>:not(.thumbs){width:0;min-width:100%}
.done{border-left:6px solid #2a2}.skipped{border-left:6px solid #68a}.failed{border-left:6px solid #c22}
.name{font-weight:600;overflow-wrap:anywhere;margin-bottom:4px}
.meta{color:#555;font-size:.85em;margin-bottom:6px}
.thumbs{display:flex;flex-wrap:wrap;gap:6px}
figure{margin:0;text-align:center;font-size:.8em}
figure img{display:block;width:160px;height:auto;background:#eee;border:1px solid #ccc}
figure img.legend{width:240px}
figcaption{margin-top:2px;overflow-wrap:anywhere}
.files{font-size:.85em;margin-top:6px;overflow-wrap:break-word}
.left,.note{color:#850;font-size:.85em;margin-top:6px}
.err{color:#a00;font-family:ui-monospace,monospace;font-size:.85em;white-space:pre-wrap;overflow-wrap:anywhere}
table{border-collapse:collapse;margin-top:1.2em;font-size:.85em}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left}
"""


def _rel(path: str, base: Path) -> str:
    """``path`` relative to ``base`` as a URL path (forward slashes, escaped for an attribute)."""
    rel = os.path.relpath(Path(path).resolve(), base.resolve())
    return html.escape(Path(rel).as_posix(), quote=True)


def error_text(r: Any) -> str | None:
    """``r.error`` without the raw's own path that the card or row already names: '/x/raws/a.lfr: not a Lytro
    container ...' -> 'not a Lytro container ...', 'No such file or directory: /x/raws/a.lfr' -> 'No such file or
    directory'.  Other paths (an output, a sidecar) stay; ``summary.json`` keeps the whole message."""
    if not r.error:
        return r.error
    text = r.error
    for path in dict.fromkeys((r.source, os.path.abspath(r.source), str(Path(r.source).resolve()))):
        if text.startswith(f"{path}: "):
            return text[len(path) + 2:]
        if text.endswith(f": {path}"):
            return text[:-len(path) - 2]
    return text


def _label(path: str) -> str:
    """An output's file name as a card shows it, a folder's with a trailing '/' (HTML-escaped)."""
    return html.escape(Path(path).name + ("/" if Path(path).is_dir() else ""))


def _card(r: Any, base: Path, shown: str) -> str:
    name = html.escape(shown)
    meta = f"{html.escape(r.status)} &middot; {r.seconds:.1f} s"
    figs, linked = [], set()
    thumbs = tuple(r.thumbnails) + (None,) * max(0, len(r.outputs) - len(r.thumbnails))
    for out, thumb in zip(r.outputs, thumbs):
        if not (thumb and Path(thumb).is_file()):
            continue
        # depth thumbnails carry a colour bar with its unit: shown larger so the text stays legible
        wide = ' class="legend"' if Path(out).suffix.lower() == ".pfm" else ""
        # a depth map's picture is its colour-mapped PNG, and opens it (a browser cannot show the PFM) when written;
        # the caption names the file the picture opens
        png = str(Path(out).with_suffix(".png"))
        opens = png if wide and png in r.outputs else out
        linked.add(opens)
        label = _label(opens)
        img = f'<img{wide} alt="{label}" src="{_rel(thumb, base)}">'
        figs.append(f'<figure><a href="{_rel(opens, base)}">{img}</a><figcaption>{label}</figcaption></figure>')
    # the outputs no picture opens (a depth map's PFM, parallax frames, a point cloud): file links under the pictures
    files = [f'<a href="{_rel(out, base)}">{_label(out)}</a>' for out in r.outputs if out not in linked]
    more = f'<div class="files">also: {" &middot; ".join(files)}</div>' if files else ""
    err = f'<div class="err">{html.escape(error_text(r))}</div>' if r.error else ""
    err += "".join(f'<div class="left">left out: {html.escape(note)}</div>' for note in getattr(r, "left_out", ()))
    dark = r.dark_note() if hasattr(r, "dark_note") else None     # as the terminal says it, without the raw's name
    err += f'<div class="note">note: {html.escape(dark)}</div>' if dark else ""
    return (f'<div class="card {html.escape(r.status)}"><div class="name" title="{html.escape(r.source)}">{name}</div>'
            f'<div class="meta">{meta}</div><div class="thumbs">{"".join(figs)}</div>{more}{err}</div>')


def clash_folders(files: Sequence[str | os.PathLike]) -> list[tuple[str, ...]]:
    """The folders that tell raws sharing a file stem apart: for each raw whose stem another raw in a different
    folder has, its folder relative to the common ancestor of that stem's folders (``a/IMG_1.LFR``,
    ``b/IMG_1.LFR`` -> ``('a',)``, ``('b',)``); ``()`` for the others.  Links are not followed (the name the user
    gave).  The output folders (:func:`plenodecode.batch.output_names`) and the shown names
    (:func:`display_names`) both take them."""
    paths = [Path(os.path.abspath(f)) for f in files]
    groups: dict[str, list[int]] = {}
    for i, path in enumerate(paths):
        groups.setdefault(path.stem, []).append(i)
    out: list[tuple[str, ...]] = [()] * len(paths)
    for group in groups.values():
        if len(group) > 1:
            root = Path(os.path.commonpath([str(paths[i].parent) for i in group]))
            for i in group:
                out[i] = paths[i].parent.relative_to(root).parts
    return out


def display_names(files: Sequence[str | os.PathLike]) -> list[str]:
    """How the terminal table and the index page name each raw: its file name, after the folders that tell it
    apart from raws of the same stem (:func:`clash_folders`), as its output folder is named: ``a/scene.lfr``,
    ``b/scene.lfr``; ``f01-mini/scene.lfp``, ``illum-mini/scene.lfr``."""
    return ["/".join((*folders, Path(f).name)) for f, folders in zip(files, clash_folders(files))]


def render_batch_index(summary: Any, base: str | os.PathLike = ".") -> str:
    """The index page of a :class:`plenodecode.batch.BatchSummary`.

    Parameters
    ----------
    summary : BatchSummary
    base : path-like
        Folder the page will be saved in; thumbnails and outputs are linked relative to it.

    Returns
    -------
    str
        A complete HTML document (UTF-8, no scripts).
    """
    base = Path(base)
    names = display_names([r.source for r in summary.results])
    cards = "".join(_card(r, base, n) for r, n in zip(summary.results, names))
    failed = [(r, n) for r, n in zip(summary.results, names) if r.status == "failed"]
    rows = "".join(f"<tr><td>{html.escape(n)}</td><td class='err'>{html.escape(error_text(r) or '')}"
                   f"</td></tr>" for r, n in failed)
    table = (f"<h2>Failures</h2><table><tr><th>raw</th><th>error</th></tr>{rows}</table>" if failed else "")
    n_partial = len(getattr(summary, "partial", ()))
    partial = (f'; <b>{n_partial}</b> left out outputs {"it" if n_partial == 1 else "they"} cannot serve'
               if n_partial else "")
    head = (f'<div class="sum"><b>{len(summary.results)}</b> raws: <b>{summary.count("done")}</b> decoded, '
            f'<b>{summary.count("skipped")}</b> skipped (already done), <b>{summary.count("failed")}</b> failed, '
            f'in {summary.seconds:.1f} s{partial}</div>')
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='generator' content='{GENERATOR}'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>plenodecode batch</title><style>{_STYLE}</style></head><body>"
            f"<h1>plenodecode batch</h1>{head}<div class='grid'>{cards}</div>{table}</body></html>\n")


def write_batch_index(summary: Any, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write :func:`render_batch_index` to ``path`` atomically (temporary name, then rename).

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    from ..io.atomic import write_text_atomic

    p = Path(path)
    return write_text_atomic(p, render_batch_index(summary, p.parent), overwrite=overwrite)
