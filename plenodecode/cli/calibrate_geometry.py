"""``plenodecode calibrate-geometry``: the camera's ray geometry (H, distortion) from checkerboard captures."""

from __future__ import annotations

from pathlib import Path

import click

from .common import (BOARD, calibration_kwargs, check_grid_file, check_output, database_option, mosaic_options,
                     overwrite_option, progress_bar, quiet, refuse_database_with_grid, refuse_writing_over_inputs,
                     usage_errors)


@click.command("calibrate-geometry")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path), metavar="DIR...")
@click.option("--board", required=True, type=BOARD, metavar="ROWSxCOLSxSQUARE_M",
              help="Inner corners (rows x columns, not squares) and the square size in metres, e.g. 8x6x0.0036.")
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), required=True,
              help="Calibration JSON to write.")
@click.option("--report", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also write a self-contained HTML report (H, distortion, errors per capture, distortion field).")
@click.option("--toolbox", is_flag=True, help="Write the Light Field Toolbox's CalInfo.json layout (1-based H).")
@click.option("--no-distortion", is_flag=True, help="Keep the distortion at zero (H and poses only).")
@click.option("--calibration", "-g", "calibration", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, callback=check_grid_file, help="Lenslet grid JSON the raws are decoded with.")
@click.option("--white", "-w", "white", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="White image of the same zoom/focus the raws are decoded with.")
@database_option
@mosaic_options
@overwrite_option
@click.pass_context
def command(ctx: click.Context, inputs: tuple[Path, ...], board, output: Path, report: Path | None, toolbox: bool,
            no_distortion: bool, calibration: Path | None, white: Path | None, database: Path | None,
            overwrite: bool) -> None:
    """Calibrate the camera's ray model from checkerboard captures (raws or saved light fields) in DIR.

    Every raw is decoded with the same lenslet calibration (--calibration / --white / --database, as
    'plenodecode decode'; never rectified), the board's corners are found in each sub-aperture view,
    and H, the distortion and the board poses are fitted by ray reprojection (Dansereau et al. 2013).
    A capture without the whole board, or a file that cannot be read, is reported and
    skipped; at least 3 must remain.

    \b
    Examples:
      plenodecode calibrate-geometry captures/ --board 8x6x0.0036 -w captures/MOD_0000.RAW -o cal.json
      plenodecode calibrate-geometry captures/ --board 19x19x0.00361 -o CalInfo.json --toolbox --report cal.html
    """
    from ..pipeline.geometry import calibrate_geometry_files, write_geometry_outputs

    refuse_database_with_grid(calibration, white, database)
    # the captures (the files of each DIR) and the calibration inputs, with their sidecars, are never written over
    read = [f for p in inputs for f in (sorted(p.iterdir()) if p.is_dir() else [p])]
    for path, option in ((output, "-o / --output"), (report, "--report")):
        if path is not None:
            refuse_writing_over_inputs([path], [*read, calibration, white], param_hint=option)
    check_output(output, overwrite)
    if report is not None:
        check_output(report, overwrite, "--report")
        if report.resolve() == output.resolve():
            raise click.BadParameter("must differ from -o/--output", param_hint="--report")
    options = calibration_kwargs(calibration, white, database, False)
    bar = progress_bar("captures", ctx)

    def captures(done: int, total: int) -> None:
        bar(done, total)
        if done == total and not quiet(ctx):     # the fit that follows takes as long as a few captures
            click.echo("fitting the ray model (H, distortion, board poses) to the corners ...", err=True)

    run = calibrate_geometry_files(inputs, board, grid=options["grid"], white=options["white"],
                                   database=options["database"], mosaic=options["mosaic"],
                                   distortion=not no_distortion, progress=captures)
    with usage_errors():
        written = write_geometry_outputs(run, output, report=report, toolbox=toolbox, overwrite=overwrite)
    for name, reason in run.skipped:
        click.echo(f"skipped {name}: {reason}", err=True)
    if not quiet(ctx):
        info = run.calibration.info
        click.echo(f"{len(run.names)} captures, {sum(c.count for c in run.corners)} views: ray RMS "
                   f"{info['rms_ray_m'] * 1e3:.4f} mm, {info['rms_px']:.3f} px")
        cover = info.get("coverage")
        if cover:
            click.echo(f"boards covered {100 * cover['area']:.0f} % of the field, corners up to "
                       f"{100 * cover['radius']:.0f} % of its radius"
                       + (f"; distortion extrapolated over the outer {100 * cover['beyond_radius']:.0f} %"
                          if info.get("distortion_estimated") and cover["beyond_radius"] > 0 else ""))
        click.echo("wrote " + ", ".join(str(p) for p in written))
