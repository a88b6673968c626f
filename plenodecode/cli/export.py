"""``plenodecode export``: convert a saved light field to another format."""

from __future__ import annotations

from pathlib import Path

import click

from ..pipeline import IMAGE_EXTENSIONS
from .common import (RegistryChoice, bit_depth_option, lightfield_output_format, output_option, overwrite_option,
                     progress_bar)


@click.command("export")
@click.argument("lf_in", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--format", "fmt", type=RegistryChoice("plenodecode.io.lightfield", "LIGHTFIELD_FORMATS", sort=True),
              default=None,
              help="Output format (default: from OUTPUT's extension; a path without one is a views folder).")
@bit_depth_option
@click.option("--image-type", type=click.Choice(IMAGE_EXTENSIONS), default=None,
              help="Image type of the 'views' format (default: png for 8/16 bit, exr for 32).")
@click.option("--srgb", is_flag=True, help="Apply the sRGB transfer function (display encoding) before writing.")
@overwrite_option
@click.pass_context
def command(ctx: click.Context, lf_in: Path, output: Path, fmt: str | None, bit_depth: str, image_type: str | None,
            srgb: bool, overwrite: bool) -> None:
    """Convert the light field LF_IN (zarr, views folder, .mat, .npy or ESLF image) to OUTPUT.

    \b
    Formats:
      zarr   OUT.zarr   Zarr v3, one chunk per view, float32 (lossless)
      views  OUT/       input_Cam000.png ... (HCI naming) + lightfield.json
      mat    OUT.mat    LFToolbox LF (j,i,l,k,c) uint16 with the weight channel
      npy    OUT.npy    float32 array (+ OUT.weight.npy, OUT.json)
      eslf   OUT.png    Stanford ESLF mosaic (+ OUT.json with the view counts)

    \b
    Examples:
      plenodecode export photo.zarr -o photo.mat
      plenodecode export photo.zarr -o views/ --format views --bit-depth 8 --srgb
    """
    from ..io.lightfield import load_lightfield, save_lightfield

    name = lightfield_output_format(output, fmt, overwrite)
    lf = load_lightfield(lf_in)
    try:
        out = save_lightfield(lf, output, format=name, bit_depth=int(bit_depth), overwrite=overwrite,
                              progress=progress_bar(f"writing {name}", ctx), encode_srgb=srgb,
                              image_ext=f".{image_type}" if image_type else None)
    except FileExistsError as exc:
        raise click.UsageError(f"{exc}; pass --overwrite") from exc
    except ValueError as exc:
        raise click.UsageError(str(exc)) from exc
    if not (ctx.obj or {}).get("quiet"):
        V, U, Y, X, C = lf.shape
        click.echo(f"wrote {out} ({name}: {V}x{U} views of {Y}x{X}x{C}, colour {'srgb' if srgb else lf.colour})")
