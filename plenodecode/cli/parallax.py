"""``plenodecode parallax``: an animation along a circle of viewpoints, plus its numbered frames."""

from __future__ import annotations

from pathlib import Path

import click

from ..pipeline import parallax_frame_names
from .common import (OneInputCommand, FOCUSED_PHOTO, NON_NEGATIVE, POSITIVE, bit_depth_option, calibration_kwargs,
                     check_folder_output, check_output, exposure_option, image_bit_depth, input_options, note_if_dark,
                     output_option, overwrite_option, progress_bar, quiet, refuse_focused_views,
                     refuse_writing_over_command_inputs, usage_errors, views_anyway_option, picture_size)
from .views import INTERP_CHOICE


@click.command("parallax", cls=OneInputCommand)
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--frames", "n_frames", type=click.IntRange(min=1), default=24, show_default=True,
              help="Number of viewpoints on the circle.")
@click.option("--radius", type=NON_NEGATIVE, default=None,
              help="Circle radius in view steps (default: 3/4 of the view grid's half-size).")
@click.option("--fps", type=POSITIVE, default=12.0, show_default=True,
              help="Frames per second of the animation.")
@click.option("--frames-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder of the numbered frames (default: OUTPUT's name + '_frames').")
@click.option("--no-frames", is_flag=True, help="Write only the animation.")
@click.option("--interp", type=INTERP_CHOICE, default="linear", show_default=True,
              help="Interpolation between neighbouring views.")
@bit_depth_option
@exposure_option
@input_options
@views_anyway_option
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, n_frames: int, radius: float | None, fps: float,
            frames_dir: Path | None, no_frames: bool, interp: str, bit_depth: str, exposure: float | str,
            calibration: Path | None, white: Path | None, database: Path | None, self_calibrate: bool,
            views_anyway: bool, overwrite: bool) -> None:
    """Write a parallax animation of RAW_OR_LF to OUTPUT (.gif or .webp) and its frames as numbered images
    (frame_000.png ...).  A focused-plenoptic (Raytrix) raw is refused (exit 2) unless --views-anyway: its views
    have one pixel per lens.

    \b
    Examples:
      plenodecode parallax photo.zarr -o wobble.gif
      plenodecode parallax raw.lfr -o wobble.webp --frames 36 --radius 4 --fps 24 --database calib/
    """
    from ..pipeline import open_source, render_product, write_parallax

    if output.suffix.lower() not in (".gif", ".webp"):
        raise click.BadParameter(f"OUTPUT must end in .gif or .webp, got {output.name!r}", param_hint="-o")
    check_output(output, overwrite)
    if no_frames and frames_dir is not None:
        raise click.UsageError("--frames-dir names the folder of the frames that --no-frames leaves out: pass one")
    folder = None if no_frames else (frames_dir or output.with_name(output.stem + "_frames"))
    bits = int(bit_depth)
    if folder is not None:      # the frames are PNGs: a depth they cannot hold is refused before any work
        bits = image_bit_depth(ctx, bit_depth, ".png", param_hint="--bit-depth")
        check_folder_output(folder, parallax_frame_names(n_frames), overwrite)
    written = [output] + ([] if folder is None else [folder / name for name in parallax_frame_names(n_frames)])
    refuse_writing_over_command_inputs(written, input_path, calibration, white)
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    refuse_focused_views(src.focused, input_path, views_anyway, instead=FOCUSED_PHOTO.format(raw=input_path))
    src.lightfield         # decoded before the rendering, whose ValueError names --radius
    with usage_errors(param_hint="--radius"):
        rendered = render_product(src, "parallax", frames=n_frames, radius=radius, interp=interp,
                                  progress=progress_bar("rendering", ctx))
    with usage_errors():
        write_parallax(rendered, output, fps=fps, frames_dir=folder, bit_depth=bits, overwrite=overwrite,
                       exposure=exposure)
    note_if_dark(ctx, rendered, exposure, "the middle frame")
    if not quiet(ctx):
        click.echo(f"wrote {output} ({n_frames} frame{'s' * (n_frames != 1)} of {picture_size(rendered.images[0][1])})"
                   + ("" if folder is None else f" and frames in {folder}"))
