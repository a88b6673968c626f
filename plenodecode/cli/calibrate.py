"""``plenodecode calibrate``: fit the lenslet grid from white images; build or query a calibration database."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..errors import CalibrationError
from ..io.atomic import write_text_atomic
from .common import (FiniteFloat, RegistryChoice, check_output, overwrite_option, progress_bar,
                     refuse_writing_over_inputs)


def _write_text(path: Path, text: str) -> None:
    """Atomic write; the command has already checked ``--overwrite``."""
    write_text_atomic(path, text, overwrite=True)


@click.command("calibrate")
@click.argument("inputs", nargs=-1, type=click.Path(exists=True, path_type=Path), metavar="WHITE...")
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Grid JSON to write (required unless building a database).")
@click.option("--report", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also write a self-contained HTML calibration report.")
@click.option("--lattice", type=RegistryChoice("plenodecode.calib", "LATTICES"), default="auto", show_default=True,
              help="Lenslet lattice type.")
@click.option("--pitch", "pitch_hint", type=FiniteFloat(min=2, min_open=True), default=None,
              help="Approximate lens pitch in px (a hint; default from metadata or the image).")
@click.option("--database", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Calibration database folder: WHITE folders of MOD_NNNN.RAW/.TXT pairs, Illum "
                   "caldata-<serial>.tar backups and F01 data.C.0 archives (read in place) are indexed into it and "
                   "the grids it lacks are fitted and cached (no WHITE: only that); with --for RAW the grid of the "
                   "matching white image is written to -o.")
@click.option("--for", "for_raw", type=click.Path(exists=True, path_type=Path, dir_okay=False), default=None,
              help="Pick the white image for this raw (same serial, nearest zoom/focus) from --database, default "
                   "the database decoding it uses (./calib, else calib/ beside RAW or in a folder above it).")
@click.option("--scene", "--self-calibrate", "scene", is_flag=True,
              help="Self-calibrate from a scene raw or image (no white image).")
@click.option("--refine", is_flag=True, help="Raytrix: refine the RayCalibData grid on the image.")
@overwrite_option
@click.pass_context
def command(ctx: click.Context, inputs: tuple[Path, ...], output: Path | None, report: Path | None, lattice: str,
            pitch_hint: float | None, database: Path | None, for_raw: Path | None, scene: bool, refine: bool,
            overwrite: bool) -> None:
    """Fit the lenslet grid of a camera from one or more WHITE images (averaged).

    A Raytrix image (PNG + RayCalibData XML) gives the XML's grid (--refine fits it to the
    image); --scene finds the grid in a scene raw or a lenslet image (e.g. a JPEG).

    \b
    Examples:
      plenodecode calibrate MOD_0000.RAW -o grid.json --report grid.html
      plenodecode calibrate radiometry.png --lattice square -o grid.json
      plenodecode calibrate --database calib/ sample_raws/illum-mini/
      plenodecode calibrate --database calib/ caldata-B5143909630.tar   # not extracted
      plenodecode calibrate --database calib/ sn-A000424242/data.C.0    # follows nextFile
      plenodecode calibrate --database calib/            # fit and cache the grids the index lacks
      plenodecode calibrate --database calib/ --for scene.lfr -o grid.json
      plenodecode calibrate --for scene.lfr -o grid.json   # the database decoding finds
    """
    from ..calib import store
    from ..io.lytro.archive import archive_kind

    if database is not None or for_raw is not None:
        _refuse_unused_with_database(ctx, for_raw, inputs, output, report, scene, refine)
    if for_raw is not None and database is None:    # the database decoding RAW would use (find_database)
        database = store.find_database(for_raw)
        if database is None:
            beside = store.find_whites(for_raw.parent, recursive=False)
            source = (f"{for_raw.parent}' from the white images beside it ({', '.join(w.name for w in beside)})"
                      if beside else "FOLDER' from a FOLDER of the camera's white images")
            raise click.UsageError(f"--for {for_raw.name} picks a white image from a calibration database, and there "
                                   f"is none (looked for its {store.INDEX_NAME} in {store.where_looked(for_raw)}); "
                                   f"pass --database DIR, or build one with 'plenodecode calibrate --database calib "
                                   f"{source}")
    for path, option in ((output, "-o / --output"), (report, "--report")):
        if path is None:
            continue
        refuse_writing_over_inputs([path], [*inputs, for_raw], param_hint=option)
        if database is not None and path.resolve().is_relative_to(database.resolve()):
            raise click.BadParameter(f"{path} is inside the calibration database {database}, which only "
                                     "'calibrate --database' writes; choose a path outside it", param_hint=option)
    _check_names(output, report)
    if output is not None:
        check_output(output, overwrite)
    if report is not None:
        check_output(report, overwrite, "--report")
    if database is not None and for_raw is None:
        for folder in inputs:
            if not folder.is_dir() and archive_kind(folder) is None:
                raise click.UsageError(f"{folder} is neither a folder nor a calibration archive; --database indexes "
                                       "folders of white images, caldata-<serial>.tar and data.C.0")
        if not inputs and not (database / store.INDEX_NAME).is_file():
            raise click.UsageError("--database needs the folder(s) of MOD_NNNN.RAW/.TXT white images or the "
                                   "calibration archives to index")
        entries = []
        fit = {"lattice": lattice, "pitch_hint": pitch_hint}
        for folder in inputs:  # index the folder's whites, fit and cache their grids (store.cache_grids)
            entries = store.build_database(folder, database, overwrite=overwrite, **fit,
                                           progress=progress_bar(f"fitting whites in {folder}", ctx))
        if not inputs:  # the database alone: fit and cache the grids its index lacks
            entries = store.cache_grids(database, overwrite=overwrite, **fit,
                                        progress=progress_bar(f"fitting the white images of {database}", ctx))
        serials = sorted({str(e.serial) for e in entries})
        click.echo(f"{database}: {len(entries)} white image(s) of camera(s) {', '.join(serials)} ('plenodecode info "
                   f"{database}' lists them)")
        return
    if output is None:
        raise click.UsageError("missing -o/--output (the grid JSON to write)")
    white = None
    if database is not None:
        from ..io import read_raw
        raw = read_raw(for_raw)
        try:
            entry, grid = store.lookup_grid(raw, database, lattice=lattice, pitch_hint=pitch_hint)
        except CalibrationError as exc:
            raise CalibrationError(f"{exc}; or 'plenodecode calibrate WHITE -o {output}' fits a white image, "
                                   f"'plenodecode calibrate --scene {for_raw} -o {output}' finds the grid in the "
                                   "scene") from exc
        white = store.white_path(entry, database)
        click.echo(f"white image {white} (serial {entry.serial}, zoom {entry.zoom_step}, focus {entry.focus_step})",
                   err=True)
    else:
        if not inputs:
            raise click.UsageError("give at least one WHITE image (or --database with a folder)")
        if any(p.is_dir() for p in inputs):
            raise click.UsageError("a folder was given: use --database DIR to index a folder of white images")
        grid, white = _calibrate_inputs(ctx, inputs, lattice=lattice, pitch_hint=pitch_hint, scene=scene,
                                        refine=refine)
    if database is not None:  # a cached grid's warnings were logged when it was fitted, not now
        for msg in grid.info.get("warnings", []):
            click.echo(f"warning: {msg}", err=True)
    from ..report.calibration import angle_text, rms_text
    _write_text(output, grid.to_json())
    click.echo(f"grid  {output}  ({grid.lattice}, pitch {grid.pitch:.4f} px, rotation {angle_text(grid.rotation)}, "
               f"{grid.shape[0]}x{grid.shape[1]} lenses, lattice RMS {rms_text(grid)})")
    _warn_high_rms(grid, report)
    if report is not None:
        from ..report.calibration import write_calibration_report
        write_calibration_report(grid, white, report, overwrite=overwrite)
        click.echo(f"report {report}")


#: A white image's grid of a forced --lattice that fits fewer of the detected disks is refused (a hex white forced
#: square fits every other row: 18 % of the f01-mini's disks; right lattices fit 99-100 %).
MIN_FIT_SHARE = 0.5


def _check_names(output: Path | None, report: Path | None) -> None:
    """Usage errors before any work: the report written over the grid, or the two swapped (a grid JSON named .html,
    a report page not named .html), or a grid not named .json."""
    if output is not None and output.suffix.lower() in (".html", ".htm"):
        raise click.BadParameter(f"{output.name} names an HTML page; the grid is JSON (e.g. grid.json), the page is "
                                 "--report", param_hint="-o / --output")
    if output is not None and output.suffix.lower() != ".json":   # '-o g.xyz' wrote the JSON under that name
        raise click.BadParameter(f"the grid is written as JSON, the one format calibrate writes: name it "
                                 f"{output.with_suffix('.json').name}, not {output.name}", param_hint="-o / --output")
    if report is None:
        return
    if output is not None and report.resolve() == output.resolve():
        raise click.BadParameter("must differ from -o/--output (the grid JSON)", param_hint="--report")
    if report.suffix.lower() not in (".html", ".htm"):
        raise click.BadParameter(f"the report is an HTML page: name it .html, not {report.name}",
                                 param_hint="--report")


def _warn_high_rms(grid: Any, report: Path | None) -> None:
    """One line on stderr when a white image's grid fits worse than the report's 'check' limit (the report would
    say 'bad'; without --report nothing else would)."""
    from ..report.calibration import WHITE_RMS_PX, smooth_part, source_kind

    if source_kind(grid) != "white-image" or grid.residual_rms is None:
        return
    smooth = smooth_part(grid, grid.residual_rms)
    rest = grid.residual_rms if smooth is None else smooth["rest_rms_px"]
    if rest > WHITE_RMS_PX[1]:
        where = f"{report} shows where" if report is not None else "--report shows where"
        click.echo(f"warning: lattice RMS {rest:.3f} px is high for a white image (good <= {WHITE_RMS_PX[0]} px, "
                   f"check <= {WHITE_RMS_PX[1]} px): a scene, another camera's image, or a wrong --lattice? {where}", err=True)


def _refuse_unused_with_database(ctx: click.Context, for_raw: Path | None, inputs: tuple[Path, ...],
                                 output: Path | None, report: Path | None, scene: bool, refine: bool) -> None:
    """Usage errors, before any work, for options that would be ignored with --database or --for: -o and
    --report without --for (indexing writes no grid file), WHITE with --for, --scene and --refine (a database
    holds white images)."""
    unused = [opt for opt, given in (("-o/--output", output is not None and for_raw is None),
                                     ("--report", report is not None and for_raw is None),
                                     ("--scene", scene), ("--refine", refine)) if given]
    if unused and for_raw is not None:
        raise click.UsageError(f"{' and '.join(unused)} {'does' if len(unused) == 1 else 'do'} nothing with --for "
                               f"{for_raw.name}, which writes the grid of its white image from the calibration "
                               f"database; 'plenodecode calibrate --scene {for_raw.name} -o grid.json' finds the "
                               "grid in the scene")
    if unused:
        raise click.UsageError(f"{' and '.join(unused)} {'does' if len(unused) == 1 else 'do'} nothing with "
                               "--database DIR, which indexes white images and caches their grids inside DIR; "
                               "--database DIR --for RAW -o grid.json writes the grid of RAW's white image")
    if for_raw is not None and inputs:
        raise click.UsageError(f"--for {for_raw.name} picks the white image from the database, so WHITE "
                               f"({inputs[0].name}) is not used: index it first ('plenodecode calibrate --database "
                               "DIR FOLDER'), or calibrate it alone without --database")


def _calibrate_inputs(ctx: click.Context, inputs: tuple[Path, ...], *, lattice: str, pitch_hint: float | None,
                      scene: bool, refine: bool) -> tuple[Any, list[Any]]:
    """The grid of ``inputs`` and what it came from, read once (RawCaptures; the path of a scene image no raw
    reader takes), for the report: reading them again would repeat the readers' warnings."""
    from ..calib import calibrate
    from ..calib.selfcal import calibrate_from_scene, calibrate_raytrix
    from ..errors import FormatError
    from ..io import read_raw

    if scene:
        if len(inputs) != 1:
            raise click.UsageError("--scene takes exactly one raw or image")
        if refine:
            raise click.UsageError("--refine is for a Raytrix image's RayCalibData grid, not with --scene")
        try:
            source = read_raw(inputs[0])
        except FormatError:     # an image no raw reader takes (self-calibration reads it as an image)
            source = inputs[0]
        try:
            return calibrate_from_scene(source, lattice=lattice, pitch_hint=pitch_hint,
                                        progress=progress_bar("self-calibrating", ctx)), [source]
        except CalibrationError as exc:
            if lattice == "auto":
                raise
            raise CalibrationError(f"{exc} (with --lattice {lattice}: leave it out to detect the lattice)") from exc
    raws = [read_raw(p) for p in inputs]
    if "raytrix" in raws[0].metadata.extra:
        return calibrate_raytrix(raws[0], refine=refine), raws
    if refine:
        raise click.BadParameter(f"refines a Raytrix image's RayCalibData grid; {inputs[0].name} has none (a white "
                                 "image's grid is fitted to it anyway)", param_hint="--refine")
    from ..calib.white import check_not_dark

    for r in raws:          # a dark frame given as a white: said as such, not as a --pitch that failed
        check_not_dark(r)
    try:
        grid = calibrate(raws, lattice=lattice, pitch_hint=pitch_hint, progress=progress_bar("calibrating", ctx))
    except CalibrationError as exc:
        if pitch_hint is None:
            raise
        known = raws[0].metadata.lenslet_pitch_px()
        said = f"its metadata says {known:.3f} px" if known else "without it the pitch is estimated from the image"
        raise CalibrationError(f"{exc} (with --pitch {pitch_hint:g} px as the hint; {said}: check the value or "
                               "leave --pitch out)") from exc
    found, fit = grid.info.get("n_detected"), grid.info.get("n_fit")
    if lattice != "auto" and found and fit is not None and fit < MIN_FIT_SHARE * found:
        raise CalibrationError(f"only {fit} of the {found} disks detected fit a {lattice} lattice (the others lie "
                               f"between its lenses): {inputs[0].name} has another lattice; leave --lattice out "
                               "(auto) or give the other type")
    return grid, raws
