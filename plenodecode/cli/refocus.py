"""``plenodecode refocus``: a refocused photograph (slope or alpha), or a focal stack with an all-in-focus image."""

from __future__ import annotations

from pathlib import Path

import click

from ._load import IMAGE_EXTENSIONS, METHOD_NAMES, input_options, load_input, prepare_folder, save_image, write_json
from .common import bit_depth_option, check_output, output_option, overwrite_option, progress_bar


def parse_stack(text: str) -> tuple[float, float, int]:
    """``'START:STOP:N'`` -> (start, stop, n); BadParameter otherwise."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise click.BadParameter(f"expected START:STOP:N (e.g. -1.5:1.5:30), got {text!r}",
                                 param_hint="--focal-stack") from None
    if n < 2:
        raise click.BadParameter(f"N must be at least 2, got {n}", param_hint="--focal-stack")
    return start, stop, n


@click.command("refocus")
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--slope", type=float, default=None, help="Refocus slope, px per view step (= the disparity in focus).")
@click.option("--alpha", type=float, default=None,
              help="Relative film depth (Ng 2005; 1 = as captured); needs the camera constants in the metadata.")
@click.option("--focal-stack", "stack", metavar="START:STOP:N", default=None,
              help="Write N photographs from START to STOP (slopes, or alphas with --stack-units alpha) and an "
                   "all-in-focus image into the OUTPUT folder.")
@click.option("--stack-units", type=click.Choice(["slope", "alpha"]), default="slope", show_default=True,
              help="Units of START and STOP.")
@click.option("--method", type=click.Choice(METHOD_NAMES), default="shift-sum", show_default=True,
              help="Refocusing method.")
@click.option("--aperture", type=click.FloatRange(0, 1, min_open=True), default=1.0, show_default=True,
              help="Synthetic aperture radius as a fraction of the view grid (1 = all views); smaller = more "
                   "depth of field.")
@click.option("--upsample", type=click.IntRange(1, 8), default=1, show_default=True,
              help="Spatial upsampling factor.")
@click.option("--ext", type=click.Choice(IMAGE_EXTENSIONS), default="png", show_default=True,
              help="Image type of the focal-stack files.")
@bit_depth_option
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, slope: float | None, alpha: float | None,
            stack: str | None, stack_units: str, method: str, aperture: float, upsample: int, ext: str,
            bit_depth: str, white_dir: Path | None, calibration: Path | None, white: Path | None,
            overwrite: bool) -> None:
    """Refocus RAW_OR_LF (a raw, a saved light field or an HCI scene folder).

    One photograph: --slope S or --alpha A, written to OUTPUT (.png, .tif, .exr).
    A focal stack: --focal-stack START:STOP:N writes OUTPUT/slice_000.png ...,
    OUTPUT/all_in_focus.png and OUTPUT/focal_stack.json (the slopes and alphas).

    \b
    Examples:
      plenodecode refocus photo.zarr --slope 0.8 -o near.png
      plenodecode refocus raw.lfr --alpha 1.02 --aperture 0.4 -o deep_dof.png --white-dir calib/
      plenodecode refocus photo.zarr --focal-stack -1.5:1.5:30 -o stack/ --method fourier-slice
    """
    chosen = sum(x is not None for x in (slope, alpha, stack))
    if chosen != 1:
        raise click.UsageError("pass exactly one of --slope, --alpha and --focal-stack")
    if stack is None:
        check_output(output, overwrite)
    else:
        start, stop, n = parse_stack(stack)
        names = [f"slice_{i:03d}.{ext}" for i in range(n)] + [f"all_in_focus.{ext}", "focal_stack.json"]
        prepare_folder(output, names, overwrite)

    import numpy as np

    from ..render import alpha_to_slope, focal_stack, refocus, slope_to_alpha
    from ..render.focalstack import depth_from_focus, refocus_per_pixel

    lf = load_input(input_path, white_dir=white_dir, calibration=calibration, white=white,
                    progress=progress_bar("decoding", ctx))
    depth = int(bit_depth)
    quiet = bool((ctx.obj or {}).get("quiet"))
    if stack is None:
        img = refocus(lf, slope=slope, alpha=alpha, method=method, aperture=aperture, upsample=upsample)
        save_image(output, img, lf=lf, bit_depth=depth, overwrite=overwrite)
        if not quiet:
            what = f"slope {slope:g}" if slope is not None else f"alpha {alpha:g}"
            click.echo(f"wrote {output} ({what}, {method}, aperture {aperture:g})")
        return
    values = np.linspace(start, stop, n)
    slopes = alpha_to_slope(values, lf) if stack_units == "alpha" else values
    order = np.argsort(slopes)
    imgs = focal_stack(lf, slopes, method=method, aperture=aperture, upsample=upsample,
                       progress=progress_bar("focal stack", ctx))
    for i in range(n):
        save_image(output / names[i], imgs[i], lf=lf, bit_depth=depth, overwrite=overwrite)
    slope_map, _ = depth_from_focus(imgs[order], np.asarray(slopes)[order])
    if upsample > 1:
        import cv2

        slope_map = cv2.resize(slope_map, (lf.shape[3], lf.shape[2]), interpolation=cv2.INTER_AREA)
    aif = refocus_per_pixel(lf, slope_map, aperture=aperture)
    save_image(output / names[n], aif, lf=lf, bit_depth=depth, overwrite=overwrite)
    try:
        alphas = [float(a) for a in slope_to_alpha(np.asarray(slopes), lf)]
    except Exception:  # noqa: BLE001 - alphas are informative only; the camera may not be known
        alphas = None
    write_json(output / names[n + 1], {"slopes": [float(s) for s in slopes], "alphas": alphas, "method": method,
                                       "aperture": aperture, "files": names[:n], "all_in_focus": names[n]},
               overwrite=overwrite)
    if not quiet:
        click.echo(f"wrote {n} slices, {names[n]} and {names[n + 1]} to {output}")
