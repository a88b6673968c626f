"""``plenodecode decode``: decode a raw into a 4D light field and write it."""

from __future__ import annotations

import logging
from pathlib import Path

import click

from .common import (OneInputCommand, FOCUSED_PHOTO, encoded_note, RegistryChoice, bit_depth_option, calibration_kwargs,
                     decoding_options, empty_views_note, input_options, lightfield_bit_depth, lightfield_output_format,
                     lightfield_summary, output_option, overwrite_option, progress_bar, quiet,
                     refuse_database_with_grid, refuse_focused_views, refuse_writing_over_command_inputs, usage_errors,
                     views_anyway_option)

log = logging.getLogger(__name__)


def refuse_decoded_input(raw_path: Path) -> None:
    """A usage error naming RAW, before any work, for what is no raw: a saved light field or an HCI scene (decoded
    already: it says which command takes it) or another folder."""
    from ..io.lightfield import holds_lightfield
    from ..pipeline import input_kind

    kind = input_kind(raw_path)
    if kind == "raw" and not raw_path.is_dir():
        return
    if kind != "hci" and raw_path.is_dir() and not holds_lightfield(raw_path):
        raise click.BadParameter(f"{raw_path.name} is a folder; decode reads one raw file ('plenodecode batch "
                                 f"{raw_path} -o OUT/' decodes the raws of a folder)", param_hint="RAW")
    what = "an HCI scene" if kind == "hci" else "a saved light field"
    other = "lf.zarr" if raw_path.suffix.lower() == ".mat" else "lf.mat"
    raise click.BadParameter(f"{raw_path.name} is {what}, decoded already: 'plenodecode export {raw_path} -o "
                             f"{other}' converts it, 'plenodecode {raw_path} -o photo.png' renders it",
                             param_hint="RAW")


@click.command("decode", cls=OneInputCommand)
@click.argument("raw_path", metavar="RAW", type=click.Path(exists=True, path_type=Path))
@output_option
@input_options
@click.option("--format", "fmt", type=RegistryChoice("plenodecode.io.lightfield", "LIGHTFIELD_FORMATS", sort=True),
              default=None, help="Output format (default: from OUTPUT's extension; a path without one is a views "
                                 "folder).")
@bit_depth_option
@decoding_options
@views_anyway_option
@overwrite_option
@click.pass_context
def command(ctx: click.Context, raw_path: Path, output: Path, calibration: Path | None, white: Path | None,
            database: Path | None, self_calibrate: bool, fmt: str | None, bit_depth: str,
            demosaic: str, resample: str, n_views: int | None, colour: str, no_hot_pixels: bool,
            views_anyway: bool, overwrite: bool) -> None:
    """Decode RAW into a 4D light field (V, U, Y, X, C) and write it to OUTPUT.

    --format views writes the light field as a folder of input_Cam000.png ... (the HCI benchmark's naming, index
    v * U + u) + lightfield.json, which every command loads back; 'plenodecode views' writes pictures for viewing
    instead (edge gaps filled, view_VV_UU.png).

    The lenslet grid comes from --calibration, from --white (calibrated on the fly), from the camera's
    own calibration (Raytrix XML), or from the calibration database (--database, default ./calib, else
    calib/ beside the raw or above it) by camera serial, zoom and focus; an image mosaic without a sidecar is
    self-calibrated.  With --geometry the
    light field is rectified (undistorted pinhole views) and carries the calibrated ray model for metric depth.
    A focused-plenoptic (Raytrix) raw is refused (exit 2) unless --views-anyway: render it with
    'plenodecode render RAW --total-focus'.

    \b
    Examples:
      plenodecode decode scene.lfr --database calib/ -o scene.zarr
      plenodecode decode scene.lfr -g grid.json -w MOD_0000.RAW -o views/ --format views --bit-depth 8
      plenodecode decode lf.png -w white.png --dark dark.tif -o lf.mat
      plenodecode decode IMG_1.jpg -o lf.zarr
      plenodecode decode scene.lfr --geometry CalInfo.json -o rectified.zarr
    """
    from ..pipeline import (check_geometry, choose_calibration, decode_raw, open_raw, read_dark_frame,
                            stores_display_encoded, write_lightfield)
    from ..types import encoded_colour_state

    refuse_decoded_input(raw_path)
    refuse_database_with_grid(calibration, white, database)
    name = lightfield_output_format(output, fmt, overwrite)
    depth = lightfield_bit_depth(ctx, name, output, bit_depth)
    inputs = calibration_kwargs(calibration, white, database, self_calibrate)
    from ..io.lightfield import written_files

    refuse_writing_over_command_inputs(written_files(output, name), raw_path, calibration, white)
    dark, optics, geometry = inputs.pop("dark"), inputs.pop("optics"), inputs.pop("geometry")
    raw = open_raw(raw_path, mosaic=inputs["mosaic"], raytrix_xml=inputs.pop("raytrix_xml"), optics=optics)
    dark = read_dark_frame(dark, inputs["mosaic"], raw=raw)       # its size checked before the calibration
    cal = choose_calibration(raw, **inputs)
    refuse_focused_views(cal.grid.lens_type is not None, raw_path, views_anyway,
                         instead=FOCUSED_PHOTO.format(raw=raw_path))
    if n_views is not None and n_views > cal.grid.max_views():
        raise click.BadParameter(f"{n_views} is more than the {cal.grid.max_views()} views per axis that see a "
                                 f"micro-image (the lenses are {cal.grid.pitch:.2f} px apart and a view step is one "
                                 f"sensor pixel; the default is {cal.grid.n_views()})", param_hint="--views")
    if geometry is not None:
        check_geometry(geometry, calibration=cal, n_views=n_views)
    lf = decode_raw(raw, cal, dark=dark, demosaic=demosaic, resample=resample,
                    colour=colour, n_views=n_views, hot_pixels=not no_hot_pixels,
                    progress=progress_bar("decoding", ctx), geometry=geometry)
    encoded = stores_display_encoded(name, lf.colour, depth)
    with usage_errors():
        out = write_lightfield(lf, output, format=name, bit_depth=depth, overwrite=overwrite,
                               progress=progress_bar(f"writing {name}", ctx))
    if not quiet(ctx):
        rectified = ", rectified" if lf.geometry.ray_model else ""
        colour = encoded_colour_state(lf.colour) if encoded else lf.colour
        click.echo(f"wrote {out} ({name}: {lightfield_summary(lf.shape, colour)}"
                   f"{rectified}){encoded_note(name) if encoded else ''}" + empty_views_note(lf, name))
