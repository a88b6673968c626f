"""``plenodecode synth PRESET -o OUT_DIR``: a synthetic raw, its white image and the ground truth."""

from __future__ import annotations

from pathlib import Path

import click

from .common import FINITE, POSITIVE, RegistryChoice, check_output, overwrite_option, progress_bar

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
@click.option("--pitch", type=POSITIVE, default=None, help="Lens pitch in px (default: the preset's).")
@click.option("--rotation", type=FINITE, default=None, help="Grid rotation in rad (default: the preset's).")
@click.option("--offset", type=(FINITE, FINITE), default=None, metavar="ROW COL",
              help="Sub-pixel shift of the lattice from the sensor centre, px.")
@click.option("--shape", type=(click.IntRange(min=1), click.IntRange(min=1)), default=None, metavar="H W", help="Sensor size override.")
@click.option("--name", default="scene", show_default=True, help="File stem of the scene raw and truth files.")
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
@overwrite_option
@click.pass_context
def command(ctx: click.Context, preset: str, out_dir: Path, seed: int, pitch: float | None, rotation: float | None,
            offset: tuple[float, float] | None, shape: tuple[int, int] | None, name: str, no_noise: bool,
            scene_name: str | None, lightfield: bool | None, archive: str | None, overwrite: bool) -> None:
    """Generate a synthetic plenoptic raw of PRESET with exact ground truth.

    Writes the scene raw in the camera's own format (Illum .lfr, F01 .lfp, a 16-bit PNG
    with JSON sidecar, or PNG + RayCalibData XML), its white image (MOD_0000.RAW + .TXT for
    Lytro presets) and NAME.truth.json / NAME.truth.npz (grid, lens centres, disparity).

    \b
    Example:
      plenodecode synth illum-mini -o out/ --seed 3 --offset 0.25 -0.4
      plenodecode synth illum-mini -o out/ --archive illum-tar
      plenodecode synth illum-mini -o out/ --scene slats-o-j1-weak --no-noise
    """
    from ..synthetic import get_preset, simulate, simulation_files, write_simulation
    from ..synthetic.archives import archive_name, write_calibration_archive

    scene = None
    if scene_name is not None:
        if get_preset(preset).focused:
            raise click.BadParameter(f"named scenes are for unfocused presets, not {preset!r}", param_hint="--scene")
        from ..synthetic.thin import THIN_SCENES

        scene = THIN_SCENES[scene_name]
    out = Path(out_dir)
    try:
        names = simulation_files(preset, name)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--name") from exc
    archive_path = None
    if archive is not None:
        archive_path = out / archive_name(archive, get_preset(preset).serial)
        names = {**names, "archive": archive_path.name}
    if not overwrite:
        for fname in names.values():
            check_output(out / fname, overwrite)
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
