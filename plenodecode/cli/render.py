"""``plenodecode RAW_OR_LF --refocus ALPHA -o out.png``: decode and refocus in one call (the card's form).

``--total-focus`` instead renders a focused-plenoptic (Raytrix) raw straight from its micro-images
(the pipeline's 'total-focus' product): no light field is decoded.  Without a focus option the photograph
is the camera's own: focused as captured (slope 0, as ``plenodecode batch``'s 'refocus' product), or for a
focused-plenoptic raw, whose decoded light field has a few lenses' worth of pixels, its total focus.
"""

from __future__ import annotations

from pathlib import Path

import click
from click.core import ParameterSource

from .common import (OneInputCommand, FINITE, FOCUSED_REFOCUS, POSITIVE, aperture_option, bit_depth_option,
                     calibration_kwargs, check_focus_options, check_output, describe_focus, exposure_option,
                     focus_choices, focus_hint, focus_options, focus_point, image_bit_depth, input_options,
                     note_if_dark, output_option, overwrite_option, progress_bar, quiet, refuse_focused_views,
                     refuse_writing_over_command_inputs, usage_errors, views_anyway_option, picture_size)
from .refocus import REFOCUS_METHOD_CHOICE

#: The refocusing options that mean nothing to --total-focus (parameter name -> option); each asks for a refocus of
#: the decoded light field, which a focused-plenoptic raw gives only with --views-anyway.
REFOCUS_ONLY = {"method": "--method", "aperture": "--aperture", "views_anyway": "--views-anyway"}


def _given(ctx: click.Context, name: str) -> bool:
    """True when the option ``name`` was typed on the command line (not its default)."""
    return ctx.get_parameter_source(name) is ParameterSource.COMMANDLINE


def check_render_options(ctx: click.Context, input_path: Path, *, alpha: float | None, slope: float | None,
                         total_focus: bool, patch: float | None, focus_at: object = None,
                         focus_distance: float | None = None, no_depth: bool = False) -> None:
    """Usage errors (exit 2, one line naming the option) for option combinations that make no sense, before
    any work: at most one of ``--refocus`` / ``--slope`` / ``--focus-at`` / ``--focus-distance`` /
    ``--total-focus`` (none: :func:`plenodecode.pipeline.products.photo_focus`); ``--patch`` only with
    ``--total-focus``, ``--method`` / ``--aperture`` only without it; ``--total-focus`` needs a raw."""
    from ..pipeline import input_kind

    check_focus_options({"--refocus ALPHA": alpha, "--slope S": slope, "--focus-at X,Y": focus_at,
                         "--focus-distance M": focus_distance, "--total-focus": total_focus or None}, no_depth,
                        optional=True)
    if patch is not None and not total_focus:
        raise click.UsageError("--patch applies to --total-focus only")
    if total_focus:
        for name, option in REFOCUS_ONLY.items():
            if _given(ctx, name):
                raise click.UsageError(f"{option} applies to --refocus / --slope, not to --total-focus")
        if input_kind(input_path) != "raw":
            raise click.UsageError(f"--total-focus renders a focused-plenoptic raw (Raytrix image + RayCalibData "
                                   f"XML); {input_path} is a {input_kind(input_path)} input")


@click.command("render", cls=OneInputCommand)
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@click.option("--refocus", "--alpha", "alpha", type=POSITIVE, default=None,
              help="Relative film depth alpha (Ng 2005): 1 = focus as captured, > 1 nearer, < 1 farther; the "
                   "refocusable range is printed (about 0.98-1.02 for a Lytro Illum).")
@click.option("--slope", type=FINITE, default=None, help="Refocus slope in px per view step instead of alpha.")
@focus_options
@click.option("--total-focus", "total_focus", is_flag=True,
              help="Focused-plenoptic (Raytrix) raw: the all-in-focus image tiled from its micro-images.")
@click.option("--patch", type=POSITIVE, default=None, metavar="P",
              help="With --total-focus: one patch size for every lens, px (= lens pitch / virtual depth; below the "
                   "micro-image diameter). Default: measured per lens.")
@output_option
@click.option("--method", type=REFOCUS_METHOD_CHOICE, default="shift-sum", show_default=True,
              help="Refocusing method.")
@aperture_option("Synthetic aperture radius (1 = all views).")
@bit_depth_option
@exposure_option
@input_options
@views_anyway_option
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, alpha: float | None, slope: float | None,
            focus_at: tuple[float, float, bool] | None, no_depth: bool, focus_distance: float | None, total_focus: bool,
            patch: float | None, output: Path, method: str, aperture: float, bit_depth: str, exposure: float | str,
            calibration: Path | None, white: Path | None, database: Path | None, self_calibrate: bool,
            views_anyway: bool, overwrite: bool) -> None:
    """Decode RAW_OR_LF (using the calibration database for raws) and write the photograph refocused at ALPHA
    (or --slope, --focus-at, --focus-distance), or with --total-focus the all-in-focus image of a
    focused-plenoptic (Raytrix) raw.  Outside the refocusable range the photograph is written with a warning.
    Without a focus option: focused as captured (slope 0), or a Raytrix raw's total focus; a Raytrix raw's decoded
    light field (one pixel per lens: --refocus, --slope, --method ...) is refused unless --views-anyway.

    \b
    Examples:
      plenodecode raw.lfr -o photo.png
      plenodecode raw.lfr --refocus 1.015 -o out.png
      plenodecode raw.lfr --focus-at 0.7,0.5 -o click.png
      plenodecode raw.lfr --refocus 0.98 -o far.png --database calib/ --bit-depth 8
      plenodecode photo.zarr --slope 0.5 -o out.png
      plenodecode raytrix.png --total-focus -o photo.png --white raytrix_white.png
    """
    from ..pipeline import check_total_focus_patch, open_source, render_product, write_product
    from ..pipeline.products import check_focus_reach, photo_focus

    check_render_options(ctx, input_path, alpha=alpha, slope=slope, total_focus=total_focus, patch=patch,
                         focus_at=focus_at, focus_distance=focus_distance, no_depth=no_depth)
    refuse_writing_over_command_inputs([output], input_path, calibration, white)
    check_output(output, overwrite)
    bits = image_bit_depth(ctx, bit_depth, output.suffix)
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      check=None if total_focus else {"refocus": {"alpha": alpha, "focus_distance": focus_distance}},
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    chosen = None
    # --method / --aperture / --views-anyway ask for a refocus of the decoded light field, even of a Raytrix raw
    asks_refocus = any(_given(ctx, name) for name in REFOCUS_ONLY)
    if not (total_focus or focus_at) and alpha is None and slope is None and focus_distance is None:
        chosen = photo_focus(src.focused, refocus=asks_refocus)
        total_focus, slope = chosen.get("total_focus", False), chosen.get("slope")
    if not total_focus and (chosen is None or asks_refocus):     # what was typed; photo_focus's own choice stands
        refuse_focused_views(src.focused, input_path, views_anyway, instead=FOCUSED_REFOCUS.format(raw=input_path))
    if total_focus:
        with usage_errors(param_hint="--patch"):
            check_total_focus_patch(src.calibration.grid, patch)       # its upper bound is the camera's
        photo = render_product(src, "total-focus", patch=patch, progress=progress_bar("rendering", ctx))
    else:
        with usage_errors(param_hint=focus_hint(alpha=alpha, focus_distance=focus_distance, focus_at=focus_at)):
            check_focus_reach(src, "refocus", slope=slope, alpha=alpha, focus_distance=focus_distance)  # undecoded
        point = focus_point(focus_at, src.lightfield.shape)
        with usage_errors(param_hint=focus_hint(alpha=alpha, focus_distance=focus_distance, focus_at=focus_at)):
            photo = render_product(src, "refocus", alpha=alpha, slope=slope, focus_distance=focus_distance,
                                   focus_at=point, focus_at_method="sharpness" if no_depth else "depth",
                                   method=method, aperture=aperture,
                                   progress=progress_bar("depth at --focus-at (fast)", ctx))
    with usage_errors():
        write_product(photo, output, bit_depth=bits, overwrite=overwrite, exposure=exposure)
    note_if_dark(ctx, photo, exposure)
    if not quiet(ctx):
        how = "total focus" if total_focus else describe_focus(photo.data)
        if chosen is not None and total_focus:      # a focused raw refocuses at a virtual depth, not by slope
            from ..decoding.focused import shown_virtual_depth_range

            lo, hi = shown_virtual_depth_range(src.calibration.grid)
            how = (f"the camera's total focus; refocus it at a virtual depth V of {lo:g} .. {hi:g} with "
                   f"'plenodecode refocus {input_path} --virtual-depth V -o "
                   f"{output.with_name(f'{output.stem}_vV{output.suffix}')}'")
        elif chosen is not None:
            ways = focus_choices(photo.data, ("--refocus", "--slope", "--focus-at", "--focus-distance"))
            how = f"focused as captured: {how}; choose the focus with {ways}"
        click.echo(f"wrote {output} ({picture_size(photo.images[0][1], bits)}; {how})")
