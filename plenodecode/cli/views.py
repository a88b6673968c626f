"""``plenodecode views``: every sub-aperture view, or one perspective view at a fractional position."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import click

from ..imaging import MIN_VIEW_DATA
from ..pipeline import IMAGE_EXTENSIONS
from .common import (OneInputCommand, FOCUSED_PHOTO, RegistryChoice, bit_depth_option, calibration_kwargs,
                     check_folder_output, check_output, exposure_option, image_bit_depth, input_options, note_if_dark,
                     output_option, overwrite_option, progress_bar, quiet, refuse_focused_views,
                     refuse_writing_over_command_inputs, usage_errors, views_anyway_option, picture_size)

#: Angular interpolation kernels of perspective views, for ``--interp``.
INTERP_CHOICE = RegistryChoice("plenodecode.render.viewpoints", "PERSPECTIVE_INTERPOLATIONS")


def _is_number(text: str) -> bool:
    """True when ``float(text)`` reads it (nan and inf too: :class:`ViewPosition` refuses those by name)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


class ViewPosition(click.ParamType):
    """``--view V,U`` -> ``(v, u)`` float, both finite and >= 0; a bad value is a usage error naming ``--view``."""

    name = "V,U"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        if len(parts) != 2 or not all(_is_number(p) for p in parts):
            self.fail(f"expected V,U (view row, view column, e.g. 4,4 or 7.5,6.25), got {value!r}", param, ctx)
        v, u = (float(p) for p in parts)
        if not (math.isfinite(v) and math.isfinite(u) and v >= 0 and u >= 0):
            self.fail(f"V and U must be finite and >= 0, got {value!r}", param, ctx)
        return v, u


class ViewsCommand(OneInputCommand):
    """``views``, whose ``--view`` takes ``V,U`` (as ``--focus-at`` takes ``X,Y``) and, as before, ``V U``: the
    second form is joined into the first before click parses the line."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        args = list(args)
        for i, arg in enumerate(args[:-2]):
            if arg == "--":
                break
            if arg == "--view" and _is_number(args[i + 1]) and _is_number(args[i + 2]):
                args[i + 1:i + 3] = [f"{args[i + 1]},{args[i + 2]}"]
                break
        return super().parse_args(ctx, args)


def _note_if_outside(view: tuple[float, float], weight: Any) -> None:
    """Say on stderr when a view ``--view`` interpolates from is partly outside the micro-images (data in under
    :data:`~plenodecode.imaging.MIN_VIEW_DATA` of its samples; ``weight`` (V, U, Y, X)): the picture shows the
    lenses' edges as stripes (the real F01 JPEG's corner views hold 44 %), which a folder of every view writes
    black."""
    from ..imaging import view_data_share

    share = view_data_share(weight)
    used = {(v, u) for v in {math.floor(view[0]), math.ceil(view[0])} for u in {math.floor(view[1]), math.ceil(view[1])}
            if v < share.shape[0] and u < share.shape[1]}
    low = min(share[v, u] for v, u in used)
    if low < MIN_VIEW_DATA:
        whole = share >= MIN_VIEW_DATA
        click.echo(f"note: view {view[0]:g}, {view[1]:g} is partly outside the micro-images (data in {low:.0%} of its "
                   f"samples): it shows the lenses' edges as stripes; {int(whole.sum())} of the {share.size} views are "
                   "whole, and the folder of every view writes the others black", err=True)


@click.command("views", cls=ViewsCommand)
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--view", "view", type=ViewPosition(), default=None, metavar="V,U",
              help="One perspective view at (fractional) view indices V,U (row, column; 'V U' works too), written "
                   "to OUTPUT (a file).")
@click.option("--interp", type=INTERP_CHOICE, default="linear", show_default=True,
              help="Interpolation between neighbouring views for fractional positions.")
@click.option("--ext", type=click.Choice(IMAGE_EXTENSIONS), default="png", show_default=True,
              help="Image type of the views written into the OUTPUT folder.")
@bit_depth_option
@exposure_option
@input_options
@views_anyway_option
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, view: tuple[float, float] | None, interp: str,
            ext: str, bit_depth: str, exposure: float | str, calibration: Path | None, white: Path | None,
            database: Path | None, self_calibrate: bool, views_anyway: bool, overwrite: bool) -> None:
    """Write the sub-aperture views of RAW_OR_LF into the folder OUTPUT (view_VV_UU.png),
    or with --view V,U the perspective view at that position into the file OUTPUT.

    These are pictures (edge gaps filled, empty corner views black), named by position; they do not load back.  A
    light field saved as a views folder, which does, is 'plenodecode decode RAW -o DIR --format views'
    (input_Cam000.png ..., the HCI naming, + lightfield.json).

    A focused-plenoptic (Raytrix) raw is refused (exit 2) unless --views-anyway: its views have one pixel per lens.

    \b
    Examples:
      plenodecode views photo.zarr -o views/ --bit-depth 8
      plenodecode views raw.lfr --view 7.5,6.25 -o persp.png --database calib/
    """
    from ..pipeline import open_source, render_product, write_product

    if view is not None:
        refuse_writing_over_command_inputs([output], input_path, calibration, white)
        check_output(output, overwrite)
    else:       # the names depend on the light field's shape: their clash is checked when they are written
        check_folder_output(output, [], overwrite, what="every view (without --view)")
        # an input in OUTPUT named like a view ('views out/view_00_00.png -o out/') would be written over
        clash = [output / p.name for p in (input_path, calibration, white) if p is not None
                 and re.fullmatch(rf"view_\d{{2,}}_\d{{2,}}\.{ext}", p.name, flags=re.IGNORECASE)]
        refuse_writing_over_command_inputs(clash, input_path, calibration, white)
    bits = (image_bit_depth(ctx, bit_depth, output.suffix) if view is not None
            else image_bit_depth(ctx, bit_depth, ext, param_hint="--ext"))
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    refuse_focused_views(src.focused, input_path, views_anyway, instead=FOCUSED_PHOTO.format(raw=input_path))
    if view is not None:        # said as the option's V,U, not the library's keywords v, u; a raw's before decoding
        from ..decoding.rectify import decoded_shape

        views = (src.input.shape[:2] if src.raw is None
                 else decoded_shape(src.calibration.grid, src.decode_options.get("n_views"))[:2])
        for label, index, n in (("V (view row)", view[0], views[0]), ("U (view column)", view[1], views[1])):
            if index > n - 1:
                raise click.BadParameter(f"{label} {index:g} is past the last view of this {views[0]} x "
                                         f"{views[1]} light field: 0 to {n - 1}", param_hint="--view")
    lf = src.lightfield
    with usage_errors(param_hint="--view"):
        rendered = render_product(src, "views", view=view, interp=interp)
    with usage_errors():
        written = write_product(rendered, output, bit_depth=bits, ext=ext, overwrite=overwrite, exposure=exposure,
                                progress=progress_bar("writing views", ctx))
    note_if_dark(ctx, rendered, exposure, "the view" if view is not None else "the centre view")
    if view is not None and lf.weight is not None and not quiet(ctx):
        _note_if_outside(view, lf.weight)
    if not quiet(ctx):
        if view is not None:
            click.echo(f"wrote {output} (view {view[0]:g}, {view[1]:g}; {picture_size(rendered.images[0][1], bits)})")
        else:
            nv, nu = lf.shape[:2]
            dark = rendered.images.dark
            names = ", ".join(f"view_{v:02d}_{u:02d}" for v, u in dark[:4]) + (", ..." if len(dark) > 4 else "")
            note = "" if not dark else (f"; {len(dark)} partly outside the micro-images (data in under "
                                        f"{MIN_VIEW_DATA:.0%} of their samples) written black: {names}")
            click.echo(f"wrote {len(written)} views ({nv}x{nu}, each {picture_size(rendered.images[0][1], bits)}) to "
                       f"{output}{note}")
