"""``plenodecode RAW_OR_LF --refocus ALPHA -o out.png``: decode and refocus in one call (the card's form)."""

from __future__ import annotations

from pathlib import Path

import click

from ._load import METHOD_NAMES, input_options, load_input, save_image
from .common import bit_depth_option, check_output, output_option, overwrite_option, progress_bar


@click.command("render")
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@click.option("--refocus", "alpha", type=float, default=None,
              help="Relative film depth alpha (Ng 2005): 1 = focus as captured, > 1 nearer, < 1 farther.")
@click.option("--slope", type=float, default=None, help="Refocus slope in px per view step instead of alpha.")
@output_option
@click.option("--method", type=click.Choice(METHOD_NAMES), default="shift-sum", show_default=True,
              help="Refocusing method.")
@click.option("--aperture", type=click.FloatRange(0, 1, min_open=True), default=1.0, show_default=True,
              help="Synthetic aperture radius (1 = all views).")
@bit_depth_option
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, alpha: float | None, slope: float | None, output: Path,
            method: str, aperture: float, bit_depth: str, white_dir: Path | None, calibration: Path | None,
            white: Path | None, overwrite: bool) -> None:
    """Decode RAW_OR_LF (using the calibration database for raws) and write the photograph refocused at ALPHA.

    \b
    Examples:
      plenodecode raw.lfr --refocus 1.2 -o out.png
      plenodecode raw.lfr --refocus 0.98 -o far.png --white-dir calib/ --bit-depth 8
      plenodecode photo.zarr --slope 0.5 -o out.png
    """
    if (alpha is None) == (slope is None):
        raise click.UsageError("pass --refocus ALPHA or --slope S (one of them)")
    check_output(output, overwrite)
    from ..render import refocus

    lf = load_input(input_path, white_dir=white_dir, calibration=calibration, white=white,
                    progress=progress_bar("decoding", ctx))
    img = refocus(lf, alpha=alpha, slope=slope, method=method, aperture=aperture)
    save_image(output, img, lf=lf, bit_depth=int(bit_depth), overwrite=overwrite)
    if not (ctx.obj or {}).get("quiet"):
        what = f"alpha {alpha:g}" if alpha is not None else f"slope {slope:g}"
        click.echo(f"wrote {output} ({what})")
