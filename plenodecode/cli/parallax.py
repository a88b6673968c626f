"""``plenodecode parallax``: an animation along a circle of viewpoints, plus its numbered frames."""

from __future__ import annotations

from pathlib import Path

import click

from ._load import input_options, load_input, needs_display_encoding, prepare_folder, save_image
from .common import bit_depth_option, check_output, output_option, overwrite_option, progress_bar


@click.command("parallax")
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--frames", "n_frames", type=click.IntRange(min=1), default=24, show_default=True,
              help="Number of viewpoints on the circle.")
@click.option("--radius", type=click.FloatRange(min=0), default=None,
              help="Circle radius in view steps (default: 3/4 of the view grid's half-size).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=12.0, show_default=True,
              help="Frames per second of the animation.")
@click.option("--frames-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder of the numbered frames (default: OUTPUT's name + '_frames').")
@click.option("--no-frames", is_flag=True, help="Write only the animation.")
@click.option("--interp", type=click.Choice(["linear", "cubic"]), default="linear", show_default=True,
              help="Interpolation between neighbouring views.")
@bit_depth_option
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, n_frames: int, radius: float | None, fps: float,
            frames_dir: Path | None, no_frames: bool, interp: str, bit_depth: str, white_dir: Path | None,
            calibration: Path | None, white: Path | None, overwrite: bool) -> None:
    """Write a parallax animation of RAW_OR_LF to OUTPUT (.gif or .webp) and its frames as numbered images
    (frame_000.png ...).

    \b
    Examples:
      plenodecode parallax photo.zarr -o wobble.gif
      plenodecode parallax raw.lfr -o wobble.webp --frames 36 --radius 4 --fps 24 --white-dir calib/
    """
    if output.suffix.lower() not in (".gif", ".webp"):
        raise click.BadParameter(f"OUTPUT must end in .gif or .webp, got {output.name!r}", param_hint="-o")
    check_output(output, overwrite)
    folder = frames_dir or output.with_name(output.stem + "_frames")
    names = [f"frame_{i:03d}.png" for i in range(n_frames)]
    if not no_frames:
        prepare_folder(folder, names, overwrite)

    from ..io.images import write_animation
    from ..render import render_parallax

    lf = load_input(input_path, white_dir=white_dir, calibration=calibration, white=white,
                    progress=progress_bar("decoding", ctx))
    try:
        frames = render_parallax(lf, n_frames, radius, interp=interp, progress=progress_bar("rendering", ctx))
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--radius") from exc
    anim = frames if frames.shape[-1] == 3 else frames.repeat(3, axis=-1)
    try:
        write_animation(output, anim, fps=fps, overwrite=overwrite, encode_srgb=needs_display_encoding(lf))
    except FileExistsError as exc:
        raise click.UsageError(f"{exc}; pass --overwrite") from exc
    if not no_frames:
        for name, frame in zip(names, frames):
            save_image(folder / name, frame, lf=lf, bit_depth=int(bit_depth), overwrite=overwrite)
    if not (ctx.obj or {}).get("quiet"):
        click.echo(f"wrote {output} ({n_frames} frames)" + ("" if no_frames else f" and frames in {folder}"))
