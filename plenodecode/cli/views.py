"""``plenodecode views``: every sub-aperture view, or one perspective view at a fractional position."""

from __future__ import annotations

from pathlib import Path

import click

from ._load import IMAGE_EXTENSIONS, input_options, load_input, prepare_folder, save_image
from .common import bit_depth_option, check_output, output_option, overwrite_option, progress_bar


@click.command("views")
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--view", "view", type=(float, float), default=None, metavar="V U",
              help="One perspective view at (fractional) view indices V U, written to OUTPUT (a file).")
@click.option("--interp", type=click.Choice(["linear", "cubic"]), default="linear", show_default=True,
              help="Interpolation between neighbouring views for fractional positions.")
@click.option("--ext", type=click.Choice(IMAGE_EXTENSIONS), default="png", show_default=True,
              help="Image type of the views written into the OUTPUT folder.")
@bit_depth_option
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, view: tuple[float, float] | None, interp: str,
            ext: str, bit_depth: str, white_dir: Path | None, calibration: Path | None, white: Path | None,
            overwrite: bool) -> None:
    """Write the sub-aperture views of RAW_OR_LF into the folder OUTPUT (view_VV_UU.png),
    or with --view V U the perspective view at that position into the file OUTPUT.

    \b
    Examples:
      plenodecode views photo.zarr -o views/ --bit-depth 8
      plenodecode views raw.lfr --view 7.5 6.25 -o persp.png --white-dir calib/
    """
    if view is not None:
        check_output(output, overwrite)
    lf = load_input(input_path, white_dir=white_dir, calibration=calibration, white=white,
                    progress=progress_bar("decoding", ctx))
    depth = int(bit_depth)
    quiet = bool((ctx.obj or {}).get("quiet"))
    if view is not None:
        from ..render import perspective

        try:
            img = perspective(lf, view[0], view[1], interp=interp)
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--view") from exc
        save_image(output, img, lf=lf, bit_depth=depth, overwrite=overwrite)
        if not quiet:
            click.echo(f"wrote {output} (view {view[0]:g}, {view[1]:g})")
        return
    nv, nu = lf.shape[:2]
    names = [f"view_{v:02d}_{u:02d}.{ext}" for v in range(nv) for u in range(nu)]
    prepare_folder(output, names, overwrite)
    bar = progress_bar("writing views", ctx)
    for i, name in enumerate(names):
        save_image(output / name, lf.data[i // nu, i % nu], lf=lf, bit_depth=depth, overwrite=overwrite)
        bar(i + 1, len(names))
    if not quiet:
        click.echo(f"wrote {len(names)} views ({nv}x{nu}) to {output}")
