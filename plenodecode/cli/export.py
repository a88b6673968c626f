"""``plenodecode export``: convert a saved light field to another format, or write its interactive page."""

from __future__ import annotations

from pathlib import Path

import click

from ..pipeline import IMAGE_EXTENSIONS
from ..registry import lazy
from .common import (OneInputCommand, RegistryChoice, bit_depth_option, check_output, empty_views_note, encoded_note,
                     lightfield_bit_depth, lightfield_output_format, lightfield_summary, output_option,
                     overwrite_option, progress_bar, refuse_writing_over_inputs)

#: Exports that are pages for people, not light fields (they never load back; their extensions are
#: :data:`plenodecode.io.lightfield.PAGE_EXTENSIONS`): name -> ``write(lf, path, *, overwrite, progress)``.
PAGE_FORMATS = {"html": lazy("plenodecode.report.lightfield_page", "write_lightfield_page")}


class ExportFormatChoice(RegistryChoice):
    """The names of :data:`plenodecode.io.lightfield.LIGHTFIELD_FORMATS` and of :data:`PAGE_FORMATS`."""

    def __init__(self) -> None:
        super().__init__("plenodecode.io.lightfield", "LIGHTFIELD_FORMATS")

    @property
    def choices(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(sorted((*super().choices, *PAGE_FORMATS)))


def _page_format(output: Path, fmt: str | None, overwrite: bool) -> str | None:
    """The page format ``output`` is written in (``--format``, else its extension), or None for a light field."""
    from ..io.lightfield import PAGE_EXTENSIONS

    name = fmt if fmt is not None else PAGE_EXTENSIONS.get(output.suffix.lower())
    if name in PAGE_FORMATS:
        check_output(output, overwrite)
        return name
    return None


def _page_options_unused(ctx: click.Context, name: str, image_type: str | None, srgb: bool) -> None:
    """A page is always 8-bit sRGB: the options of light-field formats are usage errors with it."""
    given = [opt for opt, used in (("--bit-depth", ctx.get_parameter_source("bit_depth")
                                    == click.core.ParameterSource.COMMANDLINE),
                                   ("--image-type", image_type is not None), ("--srgb", srgb)) if used]
    if given:
        verb = "does" if len(given) == 1 else "do"
        raise click.UsageError(f"{' and '.join(given)} {verb} not apply to the {name} page (its images are always "
                               "8-bit sRGB)")


def _load(lf_in: Path):
    """The light field saved at ``lf_in``; a file that is none (a raw, most often) is a usage error naming LF_IN
    that says to decode it first, rather than the reader's words about light-field formats."""
    from ..errors import PlenodecodeError
    from ..io.discovery import MOSAIC_SUFFIXES, PAIR_SUFFIXES, RAW_SUFFIXES
    from ..io.lightfield import load_lightfield
    from ..pipeline import input_kind

    if input_kind(lf_in) != "raw" or lf_in.suffix.lower() not in (*RAW_SUFFIXES, *PAIR_SUFFIXES, *MOSAIC_SUFFIXES):
        return load_lightfield(lf_in)       # e.g. an HTML page: the reader says what it is
    try:
        return load_lightfield(lf_in)
    except (PlenodecodeError, ValueError) as exc:
        eslf = f" (read as an ESLF image: {exc})" if lf_in.suffix.lower() in (".png", ".tif", ".tiff") else ""
        raise click.BadParameter(f"{lf_in.name} is not a saved light field (zarr, views folder, .mat, .npy, ESLF "
                                 f"image){eslf}; export converts light fields: decode a raw first, 'plenodecode "
                                 f"decode {lf_in} -o lf.zarr', and export lf.zarr", param_hint="LF_IN") from None


@click.command("export", cls=OneInputCommand)
@click.argument("lf_in", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--format", "fmt", type=ExportFormatChoice(), default=None,
              help="Output format (default: from OUTPUT's extension; a path without one is a views folder).")
@bit_depth_option
@click.option("--image-type", type=click.Choice(IMAGE_EXTENSIONS), default=None,
              help="Image type of the 'views' format (default: png for 8/16 bit, exr for 32).")
@click.option("--srgb", is_flag=True, help="Apply the sRGB transfer function (display encoding) before writing "
                                            "(8-bit views and ESLF images always get it).")
@overwrite_option
@click.pass_context
def command(ctx: click.Context, lf_in: Path, output: Path, fmt: str | None, bit_depth: str, image_type: str | None,
            srgb: bool, overwrite: bool) -> None:
    """Convert the light field LF_IN (zarr, views folder, .mat, .npy or ESLF image) to OUTPUT.

    \b
    Formats:
      zarr   OUT.zarr   Zarr v3, one chunk per view, float32 (lossless)
      views  OUT/       input_Cam000.png ... (HCI naming, v * U + u) + lightfield.json
      mat    OUT.mat    LFToolbox LF (j,i,l,k,c) uint16 with the weight channel
      npy    OUT.npy    float32 array (+ OUT.weight.npy, OUT.json)
      eslf   OUT.png    Stanford ESLF mosaic (+ OUT.json with the view counts)
      html   OUT.html   one self-contained interactive page: click to refocus (focal
                        stack + depth map), drag to change the viewpoint; not a light field

    \b
    Examples:
      plenodecode export photo.zarr -o photo.mat
      plenodecode export photo.zarr -o views/ --format views --bit-depth 8 --srgb
      plenodecode export photo.zarr -o photo.html --format html
    """
    from ..io.lightfield import save_lightfield
    from ..pipeline import stores_display_encoded
    from ..types import encoded_colour_state

    page = _page_format(output, fmt, overwrite)
    if page is not None:
        _page_options_unused(ctx, page, image_type, srgb)
        name = page
    else:
        name = lightfield_output_format(output, fmt, overwrite)
        bit_depth = str(lightfield_bit_depth(ctx, name, output, bit_depth, image_type))
    from ..io.lightfield import written_files

    refuse_writing_over_inputs([output] if page is not None else written_files(output, name), [lf_in])
    lf = _load(lf_in)
    if srgb and lf.geometry.display_encoded:
        raise click.BadParameter(f"{lf_in.name} is sRGB-encoded already (colour {lf.colour!r}); leave --srgb out",
                                 param_hint="--srgb")
    encoded = page is None and stores_display_encoded(name, lf.colour, int(bit_depth))
    try:
        if page is not None:
            out = PAGE_FORMATS[page](lf, output, overwrite=overwrite, progress=progress_bar(f"writing {page}", ctx))
        else:
            out = save_lightfield(lf, output, format=name, bit_depth=int(bit_depth), overwrite=overwrite,
                                  progress=progress_bar(f"writing {name}", ctx), encode_srgb=True if srgb else None,
                                  image_ext=f".{image_type}" if image_type else None)
    except FileExistsError as exc:
        raise click.UsageError(f"{exc}; pass --overwrite") from exc
    except ValueError as exc:
        raise click.UsageError(str(exc)) from exc
    if not (ctx.obj or {}).get("quiet"):
        colour = encoded_colour_state(lf.colour) if srgb or encoded or page is not None else lf.colour
        click.echo(f"wrote {out} ({name}: {lightfield_summary(lf.shape, colour)})"
                   f"{encoded_note(name) if encoded else ''}" + empty_views_note(lf, name))
