"""``plenodecode batch``: decode and render many raws, locally or on a Dask cluster."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..batch import BATCH_OUTPUTS as OUTPUT_CHOICES, DEFAULT_STACK_SLICES, SUMMARY_JSON
from ..pipeline import STACK_UNITS
from ..depth import DEFAULT_METHOD as DEFAULT_DEPTH_METHOD
from ..io.depthio import DEFAULT_MIN_CONFIDENCE
from .common import (FINITE, NON_NEGATIVE, POSITIVE, UNIT_INTERVAL, RegistryChoice, aperture_option, bit_depth_option,
                     calibration_option, check_writable, current_geometry, current_microscope_inputs,
                     current_mosaic_options, database_option, decoding_options, exposure_option, geometry_option,
                     jobs_option, microscope_options, mosaic_options, progress_bar,
                     refuse_database_with_grid, self_calibrate_option, views_anyway_option)
from .depth import parse_range
from .refocus import parse_stack
from .views import INTERP_CHOICE


def _parse_outputs(ctx: click.Context, param: click.Parameter, value: str) -> tuple[str, ...]:
    items = tuple(v.strip() for v in value.split(",") if v.strip())
    bad = [v for v in items if v not in OUTPUT_CHOICES]
    if bad or not items:
        raise click.BadParameter(f"{', '.join(bad) or 'nothing given'}; choose from {', '.join(OUTPUT_CHOICES)}")
    return items


def _check_scheduler(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """The --scheduler address, checked while the command line is parsed (Dask refuses a malformed one only after
    a minute, with a traceback)."""
    if value is None:
        return None
    from ..batch_workers import check_scheduler_address

    try:
        return check_scheduler_address(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc).removeprefix("scheduler: "), ctx, param) from None


def _check_white(white: Path | None, mosaic: Any) -> None:
    """--white, read once before the batch: a file that is no raw, or one uniformly dark (the dark frame given as
    the white), is a usage error naming the option, not one identical failure per raw (--dark: in
    :func:`~plenodecode.batch.up_front_refusals`, which reads it once for every raw)."""
    from ..calib.white import check_not_dark
    from ..errors import PlenodecodeError
    from ..pipeline.inputs import open_raw, quieted

    if white is None:
        return
    try:
        with quieted("plenodecode.io.generic"):      # its level notes come again with each raw
            raw = open_raw(white, mosaic=mosaic)
            check_not_dark(raw)
    except PlenodecodeError as exc:
        raise click.BadParameter(str(exc), param_hint="--white") from None


def _latency_note(summary) -> str:
    """' (first task 4.4 s, then 0.8 s per raw; peak 420 MB per worker)', or '' when nothing was decoded."""
    lat = summary.latency()
    if lat["first_task_s"] is None:
        return ""
    steady = "" if lat["steady_task_s"] is None else f", then {lat['steady_task_s']:.1f} s per raw"
    peak = "" if lat["worker_peak_mb"] is None else f"; peak {lat['worker_peak_mb']:.0f} MB per worker"
    return f" (first task {lat['first_task_s']:.1f} s{steady}{peak})"


def _echo_table(summary) -> None:
    """The summary table: one line per raw (its error when it failed, without the raw's path the row names; the
    outputs it left out)."""
    from ..report.batch import display_names, error_text

    names = display_names([r.source for r in summary.results])
    width = max([len("raw"), *map(len, names)])
    click.echo(f"{'raw':{width}s}  {'status':8s} {'seconds':>8s}  detail")
    for name, r in zip(names, summary.results):
        detail = error_text(r) if r.error else "; ".join((f"{len(r.outputs)} output{'s' * (len(r.outputs) != 1)}",
                                                    *r.left_out))
        click.echo(f"{name:{width}s}  {r.status:8s} {r.seconds:8.1f}  {detail}")


def _dark_notes(ctx: click.Context, summary: Any) -> None:
    """The single commands' note on a dark picture (:meth:`~plenodecode.batch.TaskResult.dark_note`), once per
    raw, naming it and its first picture (the index page's card says it too)."""
    from ..report.batch import display_names
    from .common import quiet

    if quiet(ctx):
        return
    for name, r in zip(display_names([r.source for r in summary.results]), summary.results):
        note = r.dark_note(name)
        if note is not None:
            click.echo(f"note: {note}", err=True)


def _in_option_names(text: str) -> str:
    """The library's advice (replacing outputs: ``--overwrite (overwrite=True)``, 'output folder'; a focus distance
    for metric depth; what serves instead of camera constants a raw lacks, 'refocus by slope instead') in the
    command's option names, as the single commands say it (:func:`~plenodecode.cli.main.use_instead`)."""
    from ..pipeline.needs import INSTEAD
    from .main import use_instead

    for keyword, said in INSTEAD.items():
        text = text.replace(said, use_instead(keyword))
    return text.replace(" (overwrite=True)", "").replace("choose another output folder", "choose another -o folder"
                                                          ).replace(" (depth_focus_distance=)", "")


def _refused(exc: FileExistsError) -> click.UsageError:
    """The usage error of an output the batch would replace: the library's advice in the options' names."""
    return click.UsageError(_in_option_names(str(exc)))


def _errors_in_option_names(summary: Any) -> Any:
    """``summary`` (a BatchSummary) with every raw's error in the command's option names (:func:`_in_option_names`:
    a folder that appeared after the up-front check fails its raw with the library's advice), as the table,
    summary.json and index.html show it."""
    import dataclasses

    results = tuple(r if not r.error else dataclasses.replace(r, error=_in_option_names(r.error))
                    for r in summary.results)
    return dataclasses.replace(summary, results=results)


def _no_database(db_dir: Path, default: bool, inputs: tuple[Path, ...], first: Path) -> str:
    """Why a batch whose raws all need the calibration database ``db_dir``, which is no folder, is refused (the
    default: where it was looked for, from ``first``, the first raw), with the command that builds it: from the
    inputs' folders that hold white images (``MOD_0000.RAW`` beside the raws), else from a FOLDER of them; and the
    options that do without one."""
    from ..calib.store import find_whites, where_looked

    folders = [p if p.is_dir() else p.parent for p in inputs]
    with_whites = [str(f) for f in dict.fromkeys(folders) if find_whites(f)]
    what = (f"no calibration database (looked for its index.json in {where_looked(first)}) and every raw here "
            "needs one" if default else f"{db_dir} is not a folder")
    source = (f"the white images in {' '.join(with_whites)}" if with_whites else "a FOLDER of the camera's white "
              "images")
    command = f"plenodecode calibrate --database {db_dir} {' '.join(with_whites) or 'FOLDER'}"
    return (f"{what}: build it from {source} with '{command}', or pass --database DIR, --white WHITE_IMAGE "
            "or --self-calibrate")


def _refuse_constants_none_has(refused: tuple[Any, ...]) -> None:
    """When not one raw has the camera constants an option needs (--focus-distance, --alpha, --metric, --ply,
    --stack-units alpha), raise the first raw's MissingConstantsError of ``refused`` (those of every readable raw,
    :attr:`~plenodecode.batch.UpFront.constants`) saying so, which the command group turns into a usage error naming
    the option (:func:`plenodecode.cli.main.constants_usage_error`).  A batch of real F01 JPEGs and synthetic raws
    with --focus-distance failed every raw and wrote a summary of that; with one raw that has them, the others fail
    on their rows."""
    from ..errors import MissingConstantsError

    if not refused:
        return
    first = refused[0]
    said = ("" if len(refused) == 1 else f"none of the {len(refused)} raws has what it needs "
            f"({_some_names([Path(e.source) for e in refused])}): ")
    raise MissingConstantsError(said + str(first), keyword=first.keyword, missing=first.missing,
                                source=said + first.source, need=first.need)


def _some_names(paths: list[Path]) -> str:
    """The first three file names, and how many more: 'a.png, b.png, c.png and 2 more'."""
    return ", ".join(p.name for p in paths[:3]) + (f" and {len(paths) - 3} more" if len(paths) > 3 else "")


def _is_lightfield_folder(folder: Path) -> bool:
    """An HCI scene folder or a light field saved as a folder of views (its ``lightfield.json``)."""
    from ..pipeline import input_kind

    return input_kind(folder) == "hci" or (folder / "lightfield.json").is_file()


def _microscope_fields() -> dict:
    """``dark`` and ``optics`` of :class:`~plenodecode.batch.BatchOptions` from ``--dark`` and the optics options."""
    found = current_microscope_inputs()
    dark, optics = found["dark"], found["optics"]
    return {"dark": None if dark is None else str(dark), "optics": None if optics is None else optics.to_dict()}


@click.command("batch")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Output folder: one sub-folder per raw, summary.json and index.html.")
@jobs_option
@click.option("--scheduler", default=None, metavar="ADDRESS", callback=_check_scheduler,
              help="Dask scheduler address (tcp://host:8786): run the tasks on that cluster (--jobs is ignored).")
@click.option("--outputs", default="photo", show_default=True, callback=_parse_outputs,
              help=f"Comma-separated products per raw: {', '.join(OUTPUT_CHOICES)}. 'photo': the camera's "
                   "photograph, as 'plenodecode RAW -o photo.png' writes it (focused as captured, or --slope / "
                   "--alpha / --focus-distance; a Raytrix raw's total focus).")
@calibration_option
@database_option
@self_calibrate_option
@click.option("--white", "-w", "white", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="White (radiometry) image for every raw: the lenslet grid and devignetting (microscopes; "
                   "instead of the database).")
@mosaic_options
@microscope_options
@geometry_option
@decoding_options
@click.option("--format", "lf_format", type=RegistryChoice("plenodecode.batch", "LIGHTFIELD_NAMES"), default="zarr",
              show_default=True,
              help="Format of the 'lightfield' product.")
@bit_depth_option
@exposure_option
@click.option("--slope", type=FINITE, default=0.0, show_default=True,
              help="Refocus slope of the 'refocus' and 'photo' products.")
@click.option("--alpha", "--refocus", "alpha", type=POSITIVE, default=None,
              help="Refocus the 'refocus' and 'photo' products at Ng's relative film depth ALPHA instead of "
                   "--slope.")
@click.option("--focus-distance", "focus_distance", type=POSITIVE, default=None, metavar="METRES",
              help="Refocus the 'refocus' and 'photo' products at this distance (m) instead of --slope (cameras "
                   "with geometry).")
@aperture_option("Synthetic aperture radius of the 'refocus' and 'photo' products (1 = all views).")
@click.option("--disparity-range", "disparity_range", metavar="LO:HI", default=None,
              callback=lambda ctx, param, value: parse_range(value),
              help="Disparities (px per view step) the 'depth' product searches [default: the method's].")
@click.option("--depth-method", type=RegistryChoice("plenodecode.depth", "DEPTH_METHODS"),
              default=DEFAULT_DEPTH_METHOD, show_default=True, help="Method of the 'depth' product.")
@click.option("--min-confidence", "min_confidence", type=UNIT_INTERVAL, default=DEFAULT_MIN_CONFIDENCE,
              show_default=True, help="Grey out the pixels of the 'depth' thumbnails below this confidence (0 = none).")
@click.option("--focal-stack", "focal_stack", metavar="START:STOP:N", default=None,
              help="Slices of the 'focal-stack' product (slopes, or alphas with --stack-units alpha) "
                   f"[default: {DEFAULT_STACK_SLICES} slopes over each raw's refocusable range].")
@click.option("--stack-units", type=click.Choice(list(STACK_UNITS)), default="slope", show_default=True,
              help="Units of --focal-stack's START and STOP.")
@click.option("--frames", "frames", type=click.IntRange(min=1), default=24, show_default=True,
              help="Viewpoints on the circle of the 'parallax' product.")
@click.option("--radius", type=NON_NEGATIVE, default=None,
              help="Circle radius of the 'parallax' product in view steps (default: 3/4 of the view grid's "
                   "half-size).")
@click.option("--fps", type=POSITIVE, default=12.0, show_default=True,
              help="Frames per second of the 'parallax' animation (parallax.gif).")
@click.option("--no-frames", is_flag=True,
              help="Write only the 'parallax' animation, not its frames (parallax_frames/frame_000.png ...).")
@click.option("--interp", type=INTERP_CHOICE, default="linear", show_default=True,
              help="Interpolation between neighbouring views of the 'parallax' product.")
@click.option("--metric", is_flag=True,
              help="The 'depth' product in metres (depth.pfm; um for a light-field microscope) instead of disparity, "
                   "from each raw's own focus distance (a raw whose metadata lacks it fails; when no raw has it, the "
                   "run is refused).")
@click.option("--ply", is_flag=True,
              help="The 'depth' product also writes a coloured point cloud beside its PFM (depth.ply or "
                   "disparity.ply; needs what --metric needs).")
@click.option("--depth-focus-distance", "depth_focus_distance", type=POSITIVE, default=None, metavar="METRES",
              help="Distance of the plane in focus (m) for --metric/--ply of every raw, instead of its metadata's "
                   "('plenodecode depth --focus-distance'; a batch's --focus-distance refocuses).")
@views_anyway_option
@click.option("--overwrite", is_flag=True, help="Redo raws a previous run finished and replace their outputs.")
@click.pass_context
def command(ctx: click.Context, inputs, out_dir, jobs, scheduler, outputs, calibration, database, self_calibrate,
            white, demosaic, resample, n_views, colour, no_hot_pixels, lf_format, bit_depth, exposure, slope, alpha,
            focus_distance, aperture, disparity_range, depth_method, min_confidence, focal_stack, stack_units, frames,
            radius, fps, no_frames, interp, metric, ply, depth_focus_distance, views_anyway, overwrite) -> None:
    """Decode every raw under INPUTS and write the chosen outputs per raw into OUTPUT/<name>/.

    Each raw is matched to its camera's calibration in the database (by serial, zoom and
    focus); image mosaics without a sidecar (taken from folders only at a known lenslet sensor's
    size, 3280 x 3280 or 7728 x 5368) are self-calibrated.  Bad files are reported, not fatal; the run ends with a table, summary.json and
    index.html, and exits 1 when any raw failed.  Run it again to resume: raws already done
    with the same input bytes and options are skipped.

    \b
    Example:
      plenodecode batch shoot/ -o decoded/ --outputs centre,refocus,depth --jobs 2
      plenodecode batch shoot/ -o decoded/ --scheduler tcp://10.0.0.5:8786
    """
    from ..batch import (DONE_MARKER, BatchOptions, check_outputs_to_replace, check_summary_files, find_raws,
                         run_batch, up_front_refusals, write_summary)
    from ..io.discovery import (desktop_exports_not_taken, images_not_taken, needs_no_database,
                                 raws_without_metadata)
    from ..calib.store import DEFAULT_DB, find_database

    if alpha is not None and focus_distance is not None:
        raise click.UsageError("pass at most one of --alpha and --focus-distance (each replaces --slope)")
    stack = None if focal_stack is None else parse_stack(focal_stack, stack_units)
    if stack is None and stack_units != "slope":
        raise click.BadParameter(f"{stack_units} needs --focal-stack START:STOP:N in those units (without it a focal "
                                 "stack spans each raw's refocusable range in slopes)", param_hint="--stack-units")
    if "parallax" in outputs and not no_frames and bit_depth == "32":
        raise click.BadParameter("32 (float EXR) cannot be held by the parallax frames (PNG): pass 8 or 16, or "
                                 "--no-frames", param_hint="--bit-depth")
    refuse_database_with_grid(calibration, None, database)
    check_writable(out_dir / SUMMARY_JSON)
    if not overwrite:
        try:
            check_summary_files(out_dir)
        except FileExistsError as exc:
            raise _refused(exc) from None
    files = find_raws(inputs, exclude=[out_dir])
    # e.g. a microscope's raw beside its white and dark frames: only the user knows which image is the raw
    images = images_not_taken(inputs, exclude=[out_dir], stop_marker=DONE_MARKER, taken=files)
    # the views of an HCI scene or a saved light field are no raws to name: the folder is a light field
    lf_dirs = sorted({p.parent for p in images if _is_lightfield_folder(p.parent)})
    images = [p for p in images if p.parent not in lf_dirs]
    not_taken = (f"{len(images)} image(s) ({_some_names(images)}) were not taken: a folder yields an image only with "
                 f"a sidecar or at a known lenslet sensor's size: name the raw image itself") if images else ""
    one = len(lf_dirs) == 1
    lf_note = (f"{', '.join(map(str, lf_dirs))} {'is a light field' if one else 'are light fields'} (views), not "
               f"{'a raw' if one else 'raws'}: batch decodes raws; give {'it' if one else 'them'} to 'plenodecode "
               f"refocus', 'views' or 'depth' instead") if lf_dirs else ""
    # a Lytro library's IMG_0001-stk.lfp / -dm.lfp beside the raw IMG_0001.lfp: named once, not failed one by one
    exports = desktop_exports_not_taken(inputs, exclude=[out_dir], stop_marker=DONE_MARKER)
    export_note = (f"{len(exports)} Lytro Desktop export(s) ({_some_names(exports)}) hold no raw and were not taken: "
                   f"'plenodecode extract {exports[0]} -o DIR' writes out their pictures and depth maps"
                   ) if exports else ""
    # a camera's IMG_0001.RAW copied without its IMG_0001.TXT: named, not passed over in silence
    lone = raws_without_metadata(inputs, exclude=[out_dir], stop_marker=DONE_MARKER)
    lone_note = (f"{len(lone)} headerless Lytro raw(s) ({_some_names(lone)}) were not taken: such a raw is read with "
                 f"its metadata beside it ({lone[0].stem}.TXT or .json), which is missing; copy it next to the raw"
                 ) if lone else ""
    if not files:
        hint = (f"; {not_taken}, 'plenodecode batch {images[0].parent}/RAW_IMAGE -o OUT' (a microscope's with "
                f"-w WHITE_IMAGE)") if images else ""
        raise click.UsageError(f"no raws found under {', '.join(map(str, inputs))}{hint}"
                               + "".join(f"; {n}" for n in (lf_note, export_note, lone_note) if n))
    for note in (not_taken, lf_note, export_note, lone_note):
        if note and not (ctx.obj or {}).get("quiet"):
            click.echo(f"note: {note}", err=True)
    # no --database: ./calib, else the calib/ beside the first raw that has one or above it (find_database); none:
    # each raw looks for its own, and one that needs it fails saying where it looked
    found_db = database or next((d for d in map(find_database, files) if d is not None), None)
    db_dir = found_db or Path(DEFAULT_DB)
    # a --database typed that is no folder is refused; the default one missing only when no raw can do without it
    # (the others are decoded; those that need it fail with the reason, as a batch goes past any bad raw)
    if white is None and calibration is None and not self_calibrate and not db_dir.is_dir() and (
            database is not None and not all(needs_no_database(f) for f in files)
            or database is None and not any(needs_no_database(f) for f in files)):
        raise click.BadParameter(_no_database(db_dir, database is None, inputs, files[0]), param_hint="--database")
    mosaic = current_mosaic_options()
    options = BatchOptions(outputs=outputs, database=None if found_db is None else str(found_db), format=lf_format,
                           bit_depth=int(bit_depth),
                           exposure=exposure, slope=slope, alpha=alpha, focus_distance=focus_distance,
                           depth_method=depth_method, min_confidence=min_confidence, cfa=mosaic.cfa,
                           black_level=mosaic.black_level, white_level=mosaic.white_level,
                           input_encoding=mosaic.input_encoding, white=None if white is None else str(white),
                           geometry=None if current_geometry() is None else current_geometry().to_dict(),
                           views_anyway=views_anyway, grid=None if calibration is None else str(calibration),
                           self_calibrate=self_calibrate, demosaic=demosaic, resample=resample, n_views=n_views,
                           colour=colour, hot_pixels=not no_hot_pixels, aperture=aperture,
                           disparity_range=disparity_range, focal_stack=stack, stack_units=stack_units,
                           frames=frames, radius=radius, fps=fps, interp=interp, parallax_frames=not no_frames,
                           metric=metric, ply=ply, depth_focus_distance=depth_focus_distance,
                           **_microscope_fields())
    _check_white(white, mosaic)
    if not overwrite:       # a second run with other options must not replace the first run's folders
        try:
            check_outputs_to_replace(files, out_dir, options)
        except FileExistsError as exc:
            raise _refused(exc) from None
    # what no raw can serve, refused before decoding as the single commands refuse it; each raw read once for all
    found = up_front_refusals(files, options)
    _refuse_constants_none_has(found.constants)
    slope_hint = "--alpha" if alpha is not None else "--focus-distance" if focus_distance is not None else "--slope"
    # a dark frame that suits no raw, a slope past every raw's picture, an output no raw can serve, a focal stack past
    # every raw's picture
    for refused, hint in ((found.dark, "--dark"), (found.slope, slope_hint), (found.outputs, "--outputs"),
                          (found.stack, "--focal-stack")):
        if refused:
            raise click.BadParameter(refused, param_hint=hint)
    try:
        summary = run_batch(files, out_dir, options, jobs=jobs, scheduler=scheduler, overwrite=overwrite,
                            progress=progress_bar(f"decoding {len(files)} raw{'s' * (len(files) != 1)}", ctx))
    except FileExistsError as exc:      # output folders that appeared since the check above: refused as it refuses
        raise _refused(exc) from None
    except OSError as exc:   # cannot reach the scheduler, cannot create the output folder
        where = f"the Dask scheduler {scheduler} (--scheduler)" if scheduler else f"{out_dir}"
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        click.echo(f"error: cannot use {where}: {msg}", err=True)
        ctx.exit(1)
    summary = _errors_in_option_names(summary)
    js, index = write_summary(summary, out_dir, overwrite=overwrite)
    _dark_notes(ctx, summary)
    quiet = bool((ctx.obj or {}).get("quiet"))
    if not quiet:
        _echo_table(summary)
        partial = f" ({len(summary.partial)} leaving out outputs)" if summary.partial else ""
        click.echo(f"{summary.count('done')} done, {summary.count('skipped')} skipped, "
                   f"{summary.count('failed')} failed{partial} in {summary.seconds:.1f} s{_latency_note(summary)}; "
                   f"summary: {js}; index: {index}")
    n_failed = summary.count("failed")
    if n_failed:
        click.echo(f"error: {n_failed} of {len(summary.results)} raws failed; see {index}", err=True)
    if summary.partial:         # outputs asked for and not written: the run did not give all it was asked for
        click.echo(f"error: {len(summary.partial)} of {len(summary.results)} raws left out outputs they cannot "
                   f"serve (said on their rows); see {index}", err=True)
    if n_failed or summary.partial:
        ctx.exit(1)
