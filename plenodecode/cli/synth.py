"""``plenodecode synth PRESET -o OUT_DIR``: a synthetic raw, its white image and the ground truth; with
``--checkerboard ROWSxCOLSxSQUARE`` a geometric calibration set (checkerboard raws, white, true H and poses)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

if TYPE_CHECKING:
    from ..raymodel import Board

from .common import (BOARD, FINITE, POSITIVE, FiniteFloat, RegistryChoice, check_folder_output, overwrite_option,
                     progress_bar)

#: The largest sensor --shape simulates: rows or columns, and pixels (1.5 x the Illum's 7728 x 5368; a 12 Mpx
#: sensor takes about 0.4 GB and 9 s).
MAX_SIDE = 16384
MAX_PIXELS = 64 * 10**6

#: The simulated cameras, for the PRESET argument (:mod:`plenodecode.synthetic.presets` imports no numba).
PRESET_CHOICE = RegistryChoice("plenodecode.synthetic.presets", "PRESETS")
#: The named scenes, for --scene (:mod:`plenodecode.synthetic.thin` imports no numba either).
SCENE_CHOICE = RegistryChoice("plenodecode.synthetic.thin", "THIN_SCENES")


@click.command("synth")
@click.argument("preset", type=PRESET_CHOICE)
@click.option("-o", "--output", "out_dir", type=click.Path(path_type=Path, file_okay=False), required=True,
              help="Output folder (created if missing).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the scene textures and the noise.")
@click.option("--pitch", type=FiniteFloat(min=2, min_open=True), default=None,
              help="Lens pitch in px (default: the preset's).")
@click.option("--rotation", type=FiniteFloat(min=-0.5, max=0.5, min_open=True, max_open=True), default=None,
              help="Grid rotation in rad (default: the preset's).")
@click.option("--offset", type=(FINITE, FINITE), default=None, metavar="ROW COL",
              help="Shift of the lattice from the sensor centre, px, each within half the lens pitch "
                   "[default: the preset's].")
@click.option("--shape", type=(click.IntRange(16, MAX_SIDE), click.IntRange(16, MAX_SIDE)), default=None,
              metavar="H W", help=f"Sensor rows and columns, px, at most {MAX_PIXELS // 10**6} Mpx [default: the "
                                  "preset's].")
@click.option("--name", default=None, help="File stem of the raws and truth files [default: scene; board with "
                                            "--checkerboard].")
@click.option("--no-noise", is_flag=True, help="No shot/read noise and no hot pixels.")
@click.option("--scene", "scene_name", type=SCENE_CHOICE, default=None, metavar="NAME",
              help="A named thin-structure scene instead of the default one (unfocused presets): "
                   "slats|slits-h|v|o-j0.5|j1|j2-tex|weak, e.g. slats-v-j1-tex (thin near slats 1/2/3/5 px wide in "
                   "front of a far plane, or slits in a near surface; disparity jump; horizontal, vertical or oblique; "
                   "textured or weakly textured far plane).")
@click.option("--archive", type=click.Choice(["illum-tar", "f01-datac"]), default=None,
              help="Also put the white image into the camera's calibration archive in the output folder: the Illum "
                   "backup caldata-<serial>.tar or the F01 volume data.C.0 (for 'calibrate --database DIR ARCHIVE').")
@click.option("--lightfield/--no-lightfield", default=None,
              help="Store the ground-truth light field in the truth .npz (default: only for sensors up to 2 Mpx).")
@click.option("--checkerboard", "board", type=BOARD, default=None,
              help="Write a geometric calibration set instead of a scene: raws of a checkerboard of ROWS x COLS inner "
                   "corners and SQUARE m squares (e.g. 8x6x0.0036) at 0.3-0.6 m, tilted up to 35 degrees, with the "
                   "white image and geometry_truth.json (H, distortion, poses).")
@click.option("--captures", type=click.IntRange(1, 100), default=None,
              help="With --checkerboard: number of raws.  [default: 12]")
@click.option("--distortion", type=(FINITE,) * 5, default=None, metavar="K1 K2 K3 B1 B2",
              help="With --checkerboard: lens distortion of the simulated camera (toolbox convention) [default: none].")
@click.option("--distances", type=(POSITIVE, POSITIVE), default=None, metavar="NEAR FAR",
              help="With --checkerboard: range of board distances in m.  [default: 0.3 0.6]")
@click.option("--geometry", "geometry_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, help="With --checkerboard: take H and the distortion from this calibration (JSON of "
                                 "'calibrate-geometry' or a toolbox CalInfo.json) [default: a plausible H for the "
                                 "decoded shape, no distortion; --distortion overrides the file's].")
@click.option("--placement", type=click.Choice(["centre", "field"]), default=None,
              help="With --checkerboard: where the boards go: 'centre' near the middle of the field, 'field' at its "
                   "centre, edges and corners in turn, as a calibration guide asks, so that the distortion is "
                   "measured up to the corners.  [default: centre]")
@click.option("--views", "n_views", type=click.IntRange(min=1), default=None,
              help="With --checkerboard: views per axis of the decoded light fields the truth is for (odd; decode "
                   "with the same --views) [default: the decoder's].")
@overwrite_option
@click.pass_context
def command(ctx: click.Context, preset: str, out_dir: Path, seed: int, pitch: float | None, rotation: float | None,
            offset: tuple[float, float] | None, shape: tuple[int, int] | None, name: str | None, no_noise: bool,
            scene_name: str | None, lightfield: bool | None, archive: str | None, board: Board | None, captures: int | None,
            distortion: tuple[float, ...] | None, distances: tuple[float, float] | None, geometry_file: Path | None,
            placement: str | None, n_views: int | None, overwrite: bool) -> None:
    """Generate a synthetic plenoptic raw of PRESET with exact ground truth.

    Writes the scene raw in the camera's own format (Illum .lfr, F01 .lfp, a 16-bit PNG
    with JSON sidecar, or PNG + RayCalibData XML), its white image (MOD_0000.RAW + .TXT for
    Lytro presets) and NAME.truth.json / NAME.truth.npz (grid, lens centres, disparity).

    With --checkerboard: board_00.lfp ... (the camera's format), one white image and geometry_truth.json,
    the ground truth of 'plenodecode calibrate-geometry' for light fields decoded with that white image.

    \b
    Example:
      plenodecode synth illum-mini -o out/ --seed 3 --offset 0.25 -0.4
      plenodecode synth illum-mini -o out/ --archive illum-tar
      plenodecode synth illum-mini -o out/ --scene slats-o-j1-weak --no-noise
      plenodecode synth f01 -o boards/ --checkerboard 8x6x0.0036 --captures 12
    """
    from ..synthetic import get_preset, simulate, simulation_files, write_simulation
    from ..synthetic.archives import archive_name, write_calibration_archive

    if shape is not None and shape[0] * shape[1] > MAX_PIXELS:
        raise click.BadParameter(f"{shape[0]} x {shape[1]} is {shape[0] * shape[1] / 1e6:.0f} Mpx; at most "
                                 f"{MAX_PIXELS // 10**6} Mpx (1.5 x the Illum's 41 Mpx) are simulated",
                                 param_hint="--shape")
    _check_lattice(preset, pitch, rotation, offset, shape, n_views)
    scene = None
    if scene_name is not None:
        if get_preset(preset).focused:
            raise click.BadParameter(f"named scenes are for unfocused presets, not {preset!r}", param_hint="--scene")
        from ..synthetic.thin import THIN_SCENES

        scene = THIN_SCENES[scene_name]
    out = Path(out_dir)
    if board is not None:
        if scene_name is not None:
            raise click.UsageError("--scene does not apply to --checkerboard sets")
        _checkerboard_set(ctx, preset, out, board=board, captures=12 if captures is None else captures,
                          distortion=distortion, distances=distances, geometry_file=geometry_file, n_views=n_views,
                          placement=placement or "centre", seed=seed, pitch=pitch, rotation=rotation,
                          offset=offset, shape=shape, name=name or "board", noise=not no_noise, archive=archive,
                          lightfield=lightfield, overwrite=overwrite)
        return
    for option, value in (("--captures", captures), ("--distortion", distortion), ("--distances", distances),
                          ("--geometry", geometry_file), ("--placement", placement), ("--views", n_views)):
        if value is not None:
            raise click.UsageError(f"{option} needs --checkerboard")
    name = name or "scene"
    try:
        names = simulation_files(preset, name)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--name") from exc
    archive_path = None
    if archive is not None:
        camera = get_preset(preset)
        if camera.make != "Lytro":       # a Lytro archive holds Bayer MOD_NNNN.RAW white images only
            raise click.BadParameter(f"{archive} is a Lytro calibration archive; {preset!r} is not a Lytro camera "
                                     f"({camera.make} {camera.model}): its white image is written beside the raw",
                                     param_hint="--archive")
        archive_path = out / archive_name(archive, camera.serial)
        names = {**names, "archive": archive_path.name}
    check_folder_output(out, list(names.values()), overwrite, what="the synthetic raw")
    try:
        sim = simulate(preset, seed=seed, pitch=pitch, rotation=rotation, offset=offset, noise=not no_noise,
                       shape=shape, scene=scene, progress=progress_bar(f"simulating {preset}", ctx))
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from exc
    try:
        paths = write_simulation(sim, out, name=name, overwrite=overwrite, lightfield=lightfield)
    except FileExistsError as exc:   # appeared while simulating
        raise click.UsageError(f"{exc}; pass --overwrite to replace it") from exc
    if archive is not None:
        written = write_calibration_archive([sim], archive_path if archive == "illum-tar" else out, kind=archive,
                                            overwrite=overwrite)
        paths = {**paths, "archive": written.paths[0]}
    for key, path in paths.items():
        click.echo(f"{key:11s} {path}")


def _check_lattice(preset: str, pitch: float | None, rotation: float | None, offset: tuple[float, float] | None,
                   shape: tuple[int, int] | None, n_views: int | None) -> None:
    """Refuse, naming the option, a lattice the generator would draw but nothing could use: ``--offset`` past half
    a lens pitch (a shift by whole lenses draws the same lattice but writes an MLA offset of that size into the
    metadata), a ``--pitch`` / ``--shape`` that leaves fewer lenses than a calibration is checked on
    (:data:`~plenodecode.calib.check.MIN_LENSES`; 1 x 1 at ``--pitch 1e6``), ``--views`` more than see a micro-image
    (which decode refuses)."""
    from ..calib.check import MIN_LENSES
    from ..synthetic import get_preset
    from ..synthetic.lattice import make_grid

    camera = get_preset(preset)
    step = camera.pitch_px if pitch is None else pitch
    if offset is not None and max(abs(v) for v in offset) > step / 2:
        raise click.BadParameter(f"ROW and COL must each be within +-{step / 2:.4g} px (half the {step:.4g} px lens "
                                 f"pitch; a shift by a whole lens draws the same lattice), got {offset[0]:g} "
                                 f"{offset[1]:g}", param_hint="--offset")
    grid = make_grid(camera, pitch=pitch, rotation=rotation, offset=offset, shape=shape)
    if grid.shape[0] * grid.shape[1] < MIN_LENSES:
        h, w = grid.sensor_shape
        said = " / ".join(name for name, value in (("--pitch", pitch), ("--shape", shape)) if value is not None)
        raise click.BadParameter(f"{step:.4g} px lenses on a {h} x {w} px sensor are {grid.shape[0]} x "
                                 f"{grid.shape[1]} lenses; a calibration is checked on at least {MIN_LENSES} (a "
                                 "smaller pitch or a larger sensor)", param_hint=said or "--pitch")
    if n_views is not None and n_views > grid.max_views():
        raise click.BadParameter(f"{n_views} is more than the {grid.max_views()} views per axis that see a "
                                 f"micro-image of {step:.4g} px lenses", param_hint="--views")


def _checkerboard_set(ctx: click.Context, preset: str, out: Path, *, board: Board, captures: int,
                      distortion: tuple[float, ...] | None, distances: tuple[float, float] | None,
                      geometry_file: Path | None, n_views: int | None, placement: str, seed: int,
                      pitch: float | None, rotation: float | None, offset: tuple[float, float] | None,
                      shape: tuple[int, int] | None, name: str, noise: bool, archive: str | None,
                      lightfield: bool | None, overwrite: bool) -> None:
    """``synth --checkerboard``: check the options, simulate the set, write it, list the files."""
    from ..synthetic import get_preset, simulation_files
    from ..synthetic.checkerboard import SET_TRUTH_NAME, simulate_checkerboard_set, write_checkerboard_set

    for option, value in (("--archive", archive), ("--lightfield/--no-lightfield", lightfield)):
        if value is not None:
            raise click.UsageError(f"{option} does not apply to --checkerboard sets")
    if distances is not None and not distances[0] <= distances[1]:
        raise click.BadParameter(f"NEAR must not exceed FAR, got {distances[0]:g} {distances[1]:g}",
                                 param_hint="--distances")
    if n_views is not None and n_views % 2 == 0:
        raise click.BadParameter(f"must be odd, got {n_views}", param_hint="--views")
    intrinsics = None
    if geometry_file is not None:
        from ..errors import FormatError
        from ..io.calinfo import load_geometric_calibration

        try:
            camera = load_geometric_calibration(geometry_file)
        except FormatError as exc:
            raise click.BadParameter(str(exc), param_hint="--geometry") from exc
        intrinsics = camera.intrinsics
        distortion = camera.distortion if distortion is None else distortion
    if get_preset(preset).focused:
        raise click.BadParameter(f"{preset!r} is a focused (Raytrix) camera; checkerboard sets need an unfocused "
                                 "preset", param_hint="PRESET")
    try:
        names = [simulation_files(preset, f"{name}_{q:02d}")["raw"] for q in range(captures)]
        names.append(simulation_files(preset, name)["white"])
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--name") from exc
    check_folder_output(out, [*names, SET_TRUTH_NAME], overwrite, what="the calibration set")
    try:
        extra = {} if distances is None else {"distances": distances}
        cset = simulate_checkerboard_set(preset, board, captures, intrinsics=intrinsics, distortion=distortion,
                                         n_views=n_views, placement=placement, seed=seed, shape=shape,
                                         pitch=pitch, rotation=rotation, offset=offset, noise=noise, **extra,
                                         progress=progress_bar(f"checkerboard set of {preset}", ctx))
    except ValueError as exc:
        if "does not fit" in str(exc):
            bent = ("; or the distortion of --distortion / --geometry bends it out of the views"
                    if distortion is not None else "")
            raise click.BadParameter(f"{exc} (--distances{bent})", param_hint="--checkerboard") from exc
        raise click.UsageError(str(exc)) from exc
    try:
        paths = write_checkerboard_set(cset, out, name=name, overwrite=overwrite)
    except FileExistsError as exc:   # appeared while simulating
        raise click.UsageError(f"{exc}; pass --overwrite to replace it") from exc
    lf_shape = "x".join(str(v) for v in cset.truth.lf_shape)
    for key, path in paths.items():
        click.echo(f"{key:11s} {path}")
    views = f" --views {n_views}" if n_views is not None else ""
    click.echo(f"light field {lf_shape} (V x U x Y x X) when decoded with -w {paths['white'].name}{views}")
