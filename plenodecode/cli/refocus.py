"""``plenodecode refocus``: a refocused photograph (slope, alpha, a point or a distance), or a focal stack with an
all-in-focus image."""

from __future__ import annotations

from pathlib import Path

import click

from ..pipeline import IMAGE_EXTENSIONS, STACK_UNITS, focal_stack_names
from ..pipeline.products import stack_problem
from .common import (OneInputCommand, FINITE, FOCUSED_REFOCUS, POSITIVE, RegistryChoice, aperture_option,
                     bit_depth_option, calibration_kwargs, check_focus_options, check_folder_output, check_output,
                     describe_focus, exposure_option, focus_choices, focus_hint, focus_options, focus_point,
                     image_bit_depth, input_options, note_if_dark, output_option, overwrite_option, progress_bar, quiet,
                     refuse_focused_views, refuse_writing_over_command_inputs, usage_errors, views_anyway_option,
                     picture_size)

#: The refocus methods of the library, for ``--method`` (imported when the command needs them).
REFOCUS_METHOD_CHOICE = RegistryChoice("plenodecode.render", "REFOCUS_METHODS")


def parse_stack(text: str, units: str = "slope") -> tuple[float, float, int]:
    """``'START:STOP:N'`` -> (start, stop, n): finite START and STOP (> 0 in ``units='alpha'``), 2 <= N <=
    :data:`~plenodecode.pipeline.MAX_STACK_SLICES`; BadParameter naming ``--focal-stack`` otherwise."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise click.BadParameter(f"expected START:STOP:N (e.g. -1.5:1.5:30), got {text!r}",
                                 param_hint="--focal-stack") from None
    problem = stack_problem(start, stop, n, units)
    if problem is not None:
        raise click.BadParameter(problem.replace("(units 'alpha')", "(--stack-units alpha)"),
                                 param_hint="--focal-stack")
    return start, stop, n


#: Options of a light-field refocus that mean nothing to --virtual-depth (parameter name -> option).
LIGHT_FIELD_ONLY = {"slope": "--slope", "alpha": "--alpha", "stack": "--focal-stack", "method": "--method",
                    "aperture": "--aperture", "upsample": "--upsample", "views_anyway": "--views-anyway"}


def refocus_at_virtual_depth(ctx: click.Context, input_path: Path, output: Path, virtual_depth: float, *,
                             inputs: dict, bit_depth: int, overwrite: bool, exposure: float | str = 0.0) -> None:
    """``--virtual-depth V``: a focused-plenoptic (Raytrix) raw refocused at virtual depth V (the pipeline's
    'focused-refocus' product), with every check before any work: no light-field refocus option typed, a raw
    input, the output free, V within the camera's range (from its RayCalibData lens types)."""
    from click.core import ParameterSource

    from ..decoding.focused import check_virtual_depth
    from ..pipeline import input_kind, open_source, render_product, write_product

    for name, option in LIGHT_FIELD_ONLY.items():
        if ctx.get_parameter_source(name) is ParameterSource.COMMANDLINE:
            raise click.UsageError(f"{option} refocuses a light field; --virtual-depth renders a focused-plenoptic "
                                   "raw: pass one of them")
    if input_kind(input_path) != "raw":
        raise click.UsageError(f"--virtual-depth renders a focused-plenoptic raw (Raytrix image + RayCalibData XML); "
                               f"{input_path} is a {input_kind(input_path)} input")
    refuse_writing_over_command_inputs([output], input_path, inputs["grid"], inputs["white"])
    check_output(output, overwrite)
    bits = image_bit_depth(ctx, str(bit_depth), output.suffix)
    src = open_source(input_path, **inputs)
    if not src.focused:
        raise click.UsageError(f"--virtual-depth renders a focused-plenoptic raw (a grid with lens types, Raytrix); "
                               f"{input_path.name} is not one: use --slope or --alpha")
    with usage_errors(param_hint="--virtual-depth"):
        check_virtual_depth(src.calibration.grid, virtual_depth)
    photo = render_product(src, "focused-refocus", virtual_depth=virtual_depth)
    with usage_errors():
        write_product(photo, output, bit_depth=bits, overwrite=overwrite, exposure=exposure)
    note_if_dark(ctx, photo, exposure)
    if not quiet(ctx):
        render = photo.data["render"]
        click.echo(f"wrote {output} ({picture_size(photo.images[0][1], bits)}; virtual depth {virtual_depth:g}, "
                   f"patch {float(render.patch.flat[0]):.2f} px)")


@click.command("refocus", cls=OneInputCommand)
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--slope", type=FINITE, default=None, help="Refocus slope, px per view step (= the disparity in focus).")
@click.option("--alpha", "--refocus", "alpha", type=POSITIVE, default=None,
              help="Relative film depth (Ng 2005; 1 = as captured); needs the camera constants in the metadata.")
@focus_options
@click.option("--virtual-depth", "virtual_depth", type=POSITIVE, default=None, metavar="V",
              help="Focused-plenoptic (Raytrix) raws: refocus at virtual depth V (patch = lens pitch / V; the valid "
                   "range comes from the RayCalibData lens types).")
@click.option("--focal-stack", "stack", metavar="START:STOP:N", default=None,
              help="Write N photographs from START to STOP (slopes, or alphas with --stack-units alpha) and an "
                   "all-in-focus image into the OUTPUT folder.")
@click.option("--stack-units", type=click.Choice(list(STACK_UNITS)), default="slope", show_default=True,
              help="Units of START and STOP.")
@click.option("--method", type=REFOCUS_METHOD_CHOICE, default="shift-sum", show_default=True,
              help="Refocusing method.")
@aperture_option("Synthetic aperture radius as a fraction of the view grid (1 = all views); smaller = more "
                   "depth of field.")
@click.option("--upsample", type=click.IntRange(1, 8), default=1, show_default=True,
              help="Spatial upsampling factor: views fused at their sub-pixel positions; sharper than bicubic for "
                   "surfaces at the refocus slope (|slope| >= 0.3 px/view), equal to bicubic at slope 0.")
@click.option("--ext", type=click.Choice(IMAGE_EXTENSIONS), default="png", show_default=True,
              help="Image type of the focal-stack files.")
@bit_depth_option
@exposure_option
@input_options
@views_anyway_option
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, slope: float | None, alpha: float | None,
            focus_at: tuple[float, float, bool] | None, no_depth: bool, focus_distance: float | None,
            stack: str | None, stack_units: str, method: str, aperture: float, upsample: int, ext: str,
            bit_depth: str, exposure: float | str, calibration: Path | None, white: Path | None,
            database: Path | None, self_calibrate: bool, overwrite: bool, virtual_depth: float | None = None,
            views_anyway: bool = False) -> None:
    """Refocus RAW_OR_LF (a raw, a saved light field or an HCI scene folder).

    One photograph: --slope S, --alpha A, --focus-at X,Y or --focus-distance M (none: focused as
    captured, slope 0), written to OUTPUT (.png, .tif, .exr); outside the refocusable range it is written
    with a warning.  Of a focused-plenoptic (Raytrix) raw: --virtual-depth V (its decoded views, one pixel per
    lens, are refused unless --views-anyway).
    A focal stack: --focal-stack START:STOP:N writes OUTPUT/slice_000.png ...,
    OUTPUT/all_in_focus.png and OUTPUT/focal_stack.json (the slopes and alphas).

    \b
    Examples:
      plenodecode refocus photo.zarr --slope 0.8 -o near.png
      plenodecode refocus raw.lfr --alpha 1.01 --aperture 0.4 -o deep_dof.png --database calib/
      plenodecode refocus photo.zarr --focus-at 120,80 -o click.png
      plenodecode refocus photo.zarr --focal-stack -1.5:1.5:30 -o stack/ --method fourier-slice
      plenodecode refocus raytrix.png --virtual-depth 3.5 -o v3.5.png
    """
    from ..pipeline import open_source, render_product, write_product
    from ..pipeline.products import check_focus_reach

    check_focus_options({"--slope": slope, "--alpha": alpha, "--focus-at": focus_at,
                         "--focus-distance": focus_distance, "--focal-stack": stack, "--virtual-depth": virtual_depth},
                        no_depth, optional=True)
    as_captured = all(v is None for v in (slope, alpha, focus_at, focus_distance, stack, virtual_depth))
    if as_captured:             # no focus option: the photograph focused as captured, as batch's 'refocus' product
        slope = 0.0
    if virtual_depth is not None:
        inputs = calibration_kwargs(calibration, white, database, self_calibrate)
        return refocus_at_virtual_depth(ctx, input_path, output, virtual_depth, bit_depth=int(bit_depth),
                                        overwrite=overwrite, exposure=exposure, inputs=inputs)
    if stack is None:
        refuse_writing_over_command_inputs([output], input_path, calibration, white)
        check_output(output, overwrite)
        bits = image_bit_depth(ctx, bit_depth, output.suffix)
    else:
        start, stop, n = parse_stack(stack, stack_units)
        names = focal_stack_names(n, ext)
        check_folder_output(output, names, overwrite, what="a focal stack")
        refuse_writing_over_command_inputs([output / name for name in names], input_path, calibration, white)
        bits = image_bit_depth(ctx, bit_depth, ext, param_hint="--ext")
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      check={"refocus": {"alpha": alpha, "focus_distance": focus_distance}} if stack is None
                      else {"focal-stack": {"units": stack_units}},
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    refuse_focused_views(src.focused, input_path, views_anyway, instead=FOCUSED_REFOCUS.format(raw=input_path))
    with usage_errors(param_hint="--focal-stack" if stack is not None else
                      focus_hint(alpha=alpha, focus_distance=focus_distance, focus_at=focus_at)):
        if stack is None:       # a slope past the picture, known from the calibration: refused before decoding
            check_focus_reach(src, "refocus", slope=slope, alpha=alpha, focus_distance=focus_distance)
        else:
            check_focus_reach(src, "focal-stack", start=start, stop=stop, n=n, units=stack_units)
    if stack is None:
        point = focus_point(focus_at, src.lightfield.shape)
        with usage_errors(param_hint=focus_hint(alpha=alpha, focus_distance=focus_distance, focus_at=focus_at)):
            photo = render_product(src, "refocus", slope=slope, alpha=alpha, focus_distance=focus_distance,
                                   focus_at=point, focus_at_method="sharpness" if no_depth else "depth",
                                   method=method, aperture=aperture, upsample=upsample,
                                   progress=progress_bar("depth at --focus-at (fast)", ctx))
        with usage_errors():
            write_product(photo, output, bit_depth=bits, overwrite=overwrite, exposure=exposure)
        note_if_dark(ctx, photo, exposure)
        if not quiet(ctx):
            how = describe_focus(photo.data)
            if as_captured:
                ways = focus_choices(photo.data, ("--slope", "--alpha", "--focus-at", "--focus-distance"))
                how = f"focused as captured: {how}; choose the focus with {ways}"
            click.echo(f"wrote {output} ({picture_size(photo.images[0][1], bits)}; {how}; {method}, aperture "
                       f"{aperture:g})")
        return
    with usage_errors(param_hint="--focal-stack"):
        rendered = render_product(src, "focal-stack", start=start, stop=stop, n=n, units=stack_units, method=method,
                                  aperture=aperture, upsample=upsample, progress=progress_bar("focal stack", ctx))
    with usage_errors():
        write_product(rendered, output, bit_depth=bits, ext=ext, overwrite=overwrite, exposure=exposure)
    note_if_dark(ctx, rendered, exposure)
    if not quiet(ctx):
        click.echo(f"wrote {n} slices ({picture_size(rendered.images[0][1], bits)}), {names[n]} and {names[n + 1]} "
                   f"to {output}")
