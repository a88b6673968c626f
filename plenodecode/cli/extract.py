"""``plenodecode extract``: the embedded JPEGs, depth maps and H.264 streams of a Lytro file, with their metadata.

Processed Lytro files (``-stk.lfp`` focus stacks, ``-dm.lfp`` depth maps, Desktop "living pictures" ``.LFP``)
hold no raw to decode; what they hold is written as it is stored
(:func:`plenodecode.io.lytro.extract_contents`), plus ``contents.json``: one entry per item with its file,
type, size, shape, TOC key and the facts the TOC gives (focus lambda, frame count, depth range).
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from .common import OneInputCommand, check_folder_output, overwrite_option, quiet, usage_errors

#: The manifest written beside the extracted items.
MANIFEST = "contents.json"


def manifest_name(taken: list[str]) -> str:
    """:data:`MANIFEST`, or ``contents_1.json`` ... when an item of the container already has that name."""
    name, k = MANIFEST, 1
    while name in taken:
        name = f"contents_{k}.json"
        k += 1
    return name


@click.command("extract", cls=OneInputCommand)
@click.argument("input_path", metavar="FILE", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
              help="Folder the items are written into (created if missing).")
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, overwrite: bool) -> None:
    """Write every item embedded in the Lytro file FILE (.lfp, .LFP, -stk.lfp, -dm.lfp, .lfr) into the folder
    OUTPUT: JPEGs (.jpg), H.264 streams (.h264), depth / confidence maps and depth LUTs (.npy, float32; the
    maps also as pictures with a colour bar, .png),
    metadata (.json), a raw (frame.raw + frame.json), the table of contents (toc.json) and contents.json (each
    item's file, type, size, shape and TOC facts).  One line per file written.

    \b
    Examples:
      plenodecode extract IMG_0001-stk.lfp -o IMG_0001_stack/
      plenodecode extract IMG_0002-dm.lfp -o depth/ --overwrite
    """
    from ..io.atomic import write_text_atomic
    from ..io.lytro import TOC_FILE, content_file_name, extract_contents, preview_file_name, read_container
    from ..pipeline import staged_folder

    items = read_container(input_path).items
    files = [content_file_name(it) for it in items]
    previews = {f: preview_file_name(it) for f, it in zip(files, items) if preview_file_name(it) is not None}
    manifest = manifest_name([TOC_FILE, *files, *previews.values()])
    names = [TOC_FILE, *files, *previews.values(), manifest]
    check_folder_output(output, names, overwrite, what="every item")
    document = {"source": str(input_path), "toc": TOC_FILE,
                "items": [{"file": f, "name": it.name, "type": it.type, "size": it.size,
                           "shape": list(it.shape) if it.shape else None, "dtype": it.dtype, "key": it.key,
                           "sha1": it.sha1, "info": dict(it.info)} for f, it in zip(files, items)]}
    with usage_errors(), staged_folder(output, names, overwrite=overwrite) as stage:
        extract_contents(input_path, stage, overwrite=True)
        write_text_atomic(stage / manifest, json.dumps(document, indent=1, default=str))
    if quiet(ctx):
        return
    for f, it in zip(files, items):
        click.echo(f"{output / f}  {it.describe()}, {it.size} bytes")
        if f in previews:
            click.echo(f"{output / previews[f]}  its picture, colour bar in the file's units")
    click.echo(f"{output / TOC_FILE}  table of contents")
    click.echo(f"{output / manifest}  the items' metadata")
    click.echo(f"wrote {len(items)} items of {input_path.name} to {output}")
