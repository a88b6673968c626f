"""``plenodecode depth``: disparity (or metric depth) of a raw or light field as PFM, EXR, PNG and PLY."""

from __future__ import annotations

import math
from pathlib import Path

import click

from ..depth import DEFAULT_METHOD
from ..io.atomic import refuse_folder
from ..io.depthio import DEFAULT_MIN_CONFIDENCE
from .common import (OneInputCommand, POSITIVE, UNIT_INTERVAL, RegistryChoice, calibration_kwargs, check_writable,
                     input_options, output_option, overwrite_option, progress_bar, quiet,
                     refuse_writing_over_command_inputs, usage_errors)


def parse_range(text: str | None) -> tuple[float, float] | None:
    """``'LO:HI'`` -> (lo, hi); BadParameter otherwise."""
    if text is None:
        return None
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise click.BadParameter(f"expected LO:HI (e.g. -3.5:3), got {text!r}", param_hint="--disparity-range") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise click.BadParameter(f"LO and HI must be finite, got {text!r}", param_hint="--disparity-range")
    if not lo < hi:
        raise click.BadParameter(f"LO must be below HI, got {text!r}", param_hint="--disparity-range")
    return lo, hi


def check_range_reach(src, rng: tuple[float, float] | None, text: str | None) -> None:
    """:func:`plenodecode.pipeline.products.check_disparity_reach` as a usage error naming ``--disparity-range``."""
    from ..pipeline.products import check_disparity_reach

    try:
        check_disparity_reach(src, rng)
    except ValueError as exc:
        raise click.BadParameter(f"{text}: {exc}", param_hint="--disparity-range") from None


def check_focused_options(ctx: click.Context) -> None:
    """A focused-plenoptic (Raytrix) raw's depth is searched over its virtual depth range from its micro-images:
    a usage error naming ``--method`` or ``--disparity-range`` when typed (options of a light field's depth)."""
    for name, opt in (("method", "--method"), ("disparity_range", "--disparity-range")):
        if ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE:
            raise click.BadParameter("a focused-plenoptic (Raytrix) raw's depth is its virtual depth, estimated from "
                                     "its micro-images over its lens types' range; leave this light-field option out",
                                     param_hint=opt)


def _shown_range(values, confidence, min_confidence: float, percentiles: tuple[float, float], unit: str,
                 label: str = "") -> str:
    """'LO .. HI UNIT LABEL' of ``values`` (Y, X) at ``percentiles`` over the pixels the PNG colours (confidence at
    least ``min_confidence``), then ' where confidence >= 0.1 (all pixels: LO .. HI)' when some are greyed out: the
    greyed-out ones (a microscope's featureless background) are noise and widened the range past the map's."""
    import numpy as np

    def span(v) -> str:
        v = v[np.isfinite(v)]
        lo, hi = np.percentile(v, percentiles) if v.size else (np.nan, np.nan)
        return f"{lo:.4g} .. {hi:.4g}"

    v = np.asarray(values, np.float64)
    shown = np.asarray(confidence) >= np.float32(min_confidence)
    text = f"{span(v[shown] if min_confidence > 0 else v)}{' ' * bool(unit)}{unit}{label}"
    if min_confidence <= 0 or shown.all():
        return text
    return f"{text} where confidence >= {min_confidence:g} (all pixels: {span(v)})"


def _below_note(confidence, min_confidence: float) -> str:
    """' (12 % below 0.1)': the share of pixels the PNG greys out, or '' with --min-confidence 0 (none are)."""
    import numpy as np

    if min_confidence <= 0:
        return ""
    return f" ({100 * float(np.mean(confidence < np.float32(min_confidence))):.0f} % below {min_confidence:g})"


@click.command("depth", cls=OneInputCommand)
@click.argument("input_path", metavar="RAW_OR_LF", type=click.Path(exists=True, path_type=Path))
@output_option
@click.option("--method", type=RegistryChoice("plenodecode.depth", "DEPTH_METHODS"), default=DEFAULT_METHOD, show_default=True,
              help="'costvolume' = accurate, 'fast' = preview in seconds.")
@click.option("--metric", is_flag=True, help="Write metric depth (m; for a light-field microscope um from the native "
                                            "object plane, positive away from the objective) instead of disparity "
                                            "(px per view step).")
@click.option("--ply", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write a coloured point cloud (needs the camera geometry, as --metric).")
@click.option("--disparity-range", "disparity_range", metavar="LO:HI", default=None,
              help="Search range in px per view step (default: from the metadata, else estimated); at most the "
                   "disparity at which the outermost views still overlap the centre one.")
@click.option("--focus-distance", "focus_distance", type=POSITIVE, default=None,
              help="Distance of the plane in focus (m), for --metric/--ply when the metadata lacks it.")
@click.option("--min-confidence", "min_confidence", type=UNIT_INTERVAL, default=DEFAULT_MIN_CONFIDENCE,
              show_default=True, help="Grey out the pixels of the colour-mapped PNG whose confidence is below this "
                                      "(0 = none); the confidence map is written beside (OUTPUT_confidence.exr/.png).")
@input_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, input_path: Path, output: Path, method: str, metric: bool, ply: Path | None,
            disparity_range: str | None, focus_distance: float | None, min_confidence: float,
            calibration: Path | None, white: Path | None, database: Path | None, self_calibrate: bool,
            overwrite: bool) -> None:
    """Estimate the depth of RAW_OR_LF (a raw, a saved light field, an HCI scene folder or a .npy).

    Writes OUTPUT (.pfm, readable by the HCI benchmark toolkit; -o X.png or X.exr names the same set),
    OUTPUT with .exr (32-bit float),
    OUTPUT with .png (colour map with a legend, pixels below --min-confidence grey) and the confidence
    map in [0, 1] as OUTPUT_confidence.exr and .png (laid out as OUTPUT's .png, --min-confidence marked on
    its colour bar): disparity in px per view step (HCI sign: positive = closer than the focus plane), or
    depth in metres with --metric (micrometres for a light-field microscope, whose optics come from
    --magnification, --na, ..., --optics FILE or a metadata.txt beside the raw).  A focused-plenoptic
    (Raytrix) raw gives its virtual depth (v = a / B) at the resolution of its total-focus image
    ('plenodecode RAW -o photo.png'), aligned with it pixel for pixel.

    \b
    Examples:
      plenodecode depth ../shared/data/hci-antinous -o antinous.pfm
      plenodecode depth photo.zarr -o depth.pfm --metric --ply cloud.ply
      plenodecode depth raw.lfr --method fast -o preview.pfm --database calib/
      plenodecode depth light_field.png -w radiometry_frame.png --dark dark_frame.tif --metric -o z.pfm
        --magnification 20 --na 0.5 --medium-index 1.33 --lens-pitch-um 125 --pixel-um 4.55
    """
    import numpy as np

    from ..io.depthio import depth_output_paths
    from ..pipeline import open_source, render_product, write_depth

    rng = parse_range(disparity_range)
    try:
        paths = depth_output_paths(output, ply=ply, confidence=True)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--output") from None
    for p in paths.values():
        check_writable(p)
    with usage_errors():
        for p in paths.values():
            refuse_folder(p)
    refuse_writing_over_command_inputs(list(paths.values()), input_path, calibration, white)
    if not overwrite:
        clash = [p for p in paths.values() if p.exists()]
        if clash:
            raise click.UsageError(f"{clash[0]} exists; pass --overwrite to replace it")
    src = open_source(input_path, progress=progress_bar("decoding", ctx),
                      check={"depth": {"metric": metric, "points": ply is not None, "focus_distance": focus_distance}},
                      **calibration_kwargs(calibration, white, database, self_calibrate))
    if metric or ply is not None:
        from ..pipeline.needs import check_focus_distance

        with usage_errors(param_hint="--focus-distance"):
            check_focus_distance(src.input, focus_distance)
    if src.focused:     # --metric / --ply are refused by render_product (virtual depth has no metric scale)
        check_focused_options(ctx)
        rendered = render_product(src, "depth", metric=metric, points=ply is not None,
                                  progress=progress_bar("depth (focused: virtual depth)", ctx))
        method = rendered.data["method"]
    else:
        check_range_reach(src, rng, disparity_range)
        rendered = render_product(src, "depth", method=method, disparity_range=rng, metric=metric,
                                  points=ply is not None, focus_distance=focus_distance,
                                  progress=progress_bar(f"depth ({method})", ctx))
    with usage_errors():
        written = write_depth(rendered, output, ply=ply, title=f"{input_path.name}: {method}",
                              min_confidence=min_confidence, overwrite=overwrite)
    if not quiet(ctx) and src.focused:
        v, conf = rendered.data["values"], rendered.data["depthmap"].confidence
        click.echo(f"focused-plenoptic raw: virtual depth "
                   f"{_shown_range(v, conf, min_confidence, (2, 98), '', ' (2nd..98th percentile)')} on the "
                   f"{v.shape[1]} x {v.shape[0]} total-focus grid, mean confidence {float(conf.mean()):.2f}"
                   f"{_below_note(conf, min_confidence)}, "
                   f"{rendered.data['depthmap'].params['seconds']:.1f} s")
        for p in written:
            click.echo(f"wrote {p}")
    elif not quiet(ctx):
        dm = rendered.data["depthmap"]
        d = dm.disparity
        click.echo(f"{method}: disparity {_shown_range(d, dm.confidence, min_confidence, (0, 100), 'px/view')}, "
                   f"mean confidence {float(dm.confidence.mean()):.2f}"
                   f"{_below_note(dm.confidence, min_confidence)}, "
                   f"{dm.params['seconds']:.1f} s")
        if metric:
            span = _shown_range(rendered.data["values"], dm.confidence, min_confidence, (2, 98), rendered.data["unit"],
                                " (2nd..98th percentile)")
            click.echo(f"depth {span}")
        for p in written:
            click.echo(f"wrote {p}")
