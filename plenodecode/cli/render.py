"""``plenodecode RAW_OR_LF --refocus ALPHA -o out.png``: decode and refocus in one call (the card's form)."""

from __future__ import annotations

from pathlib import Path

import click

from .common import (bit_depth_option, calibration_kwargs, check_output, input_options, output_option,
                     overwrite_option, progress_bar, quiet, usage_errors)
from .refocus import REFOCUS_METHOD_CHOICE


@click.command("render")
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@click.option("--refocus", "alpha", type=float, default=None,
              help="Relative film depth alpha (Ng 2005): 1 = focus as captured, > 1 nearer, < 1 farther.")
@click.option("--slope", type=float, default=None, help="Refocus slope in px per view step instead of alpha.")
@output_option
@click.option("--method", type=REFOCUS_METHOD_CHOICE, default="shift-sum", show_default=True,
              help="Refocusing method.")
@click.option("--aperture", type=click.FloatRange(0, 1, min_open=True), default=1.0, show_default=True,
              help="Synthetic aperture radius (1 = all views).")
@bit_depth_option
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, alpha: float | None, slope: float | None, output: Path,
            method: str, aperture: float, bit_depth: str, calibration: Path | None, white: Path | None,
            database: Path | None, self_calibrate: bool, overwrite: bool) -> None:
    """Decode RAW_OR_LF (using the calibration database for raws) and write the photograph refocused at ALPHA.

    \b
    Examples:
      plenodecode raw.lfr --refocus 1.2 -o out.png
      plenodecode raw.lfr --refocus 0.98 -o far.png --database calib/ --bit-depth 8
      plenodecode photo.zarr --slope 0.5 -o out.png
    """
    from ..pipeline import open_source, render_product, write_product

    if (alpha is None) == (slope is None):
        raise click.UsageError("pass --refocus ALPHA or --slope S (one of them)")
    check_output(output, overwrite)
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    photo = render_product(src, "refocus", alpha=alpha, slope=slope, method=method, aperture=aperture)
    with usage_errors():
        write_product(photo, output, bit_depth=int(bit_depth), overwrite=overwrite)
    if not quiet(ctx):
        what = f"alpha {alpha:g}" if alpha is not None else f"slope {slope:g}"
        click.echo(f"wrote {output} ({what})")
