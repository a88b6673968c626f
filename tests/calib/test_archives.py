"""Calibration archives as the cameras write them: Illum caldata-<serial>.tar (both layouts) and F01
data.C.0..N volumes, indexed in place and used to decode a generated raw with the right white image."""

from __future__ import annotations

from dataclasses import replace

import pytest
from click.testing import CliRunner

from plenodecode.calib import store
from plenodecode.cli.main import cli
from plenodecode.errors import FormatError
from plenodecode.io import read_raw
from plenodecode.io.lightfield import load_lightfield
from plenodecode.io.lytro import write_lfp, write_lfr
from plenodecode.io.lytro.archive import CalibrationArchive
from plenodecode.synthetic import simulate, simulate_white, write_calibration_archive

#: (zoom, focus, lattice shift in pitches) of the white images; the raw is at the preset's zoom/focus and
#: white 1 is the one taken there (same lattice), the others come from other settings (shifted lattice).
SETTINGS = [(100.0, 0.0, 0.3), (None, None, 0.0), (None, -100.0, -0.3)]


def _camera(preset: str, shape: tuple[int, int]):
    """A scene raw and three white images of its camera (white 1 at the raw's zoom and focus)."""
    sim = simulate(preset, seed=4, shape=shape)
    md = sim.raw.metadata
    whites = []
    for k, (zoom, focus, shift) in enumerate(SETTINGS):
        off = (sim.preset.offset[0] + shift * sim.grid.pitch, sim.preset.offset[1])
        white, _ = simulate_white(preset, seed=10 + k, shape=shape, offset=off)
        meta = replace(white.metadata, zoom_step=md.zoom_step if zoom is None else zoom,
                       focus_step=md.focus_step if focus is None else focus)
        whites.append(replace(white, metadata=meta))
    return sim, whites


@pytest.fixture(scope="module")
def illum():
    return _camera("illum-mini", (400, 560))


@pytest.fixture(scope="module")
def f01():
    return _camera("f01-mini", (300, 320))


def _run(args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def _calibrate_and_decode(archive, scene, tmp_path):
    db, out = tmp_path / "db", tmp_path / "lf.npy"
    res = _run(["calibrate", "--database", db, archive])
    assert res.exit_code == 0, res.output
    assert "3 white image(s)" in res.output
    res = _run(["decode", scene, "--database", db, "-o", out])
    assert res.exit_code == 0, res.output
    return store.load_index(db), load_lightfield(out)


@pytest.mark.parametrize("layout", ["serial", "unitdata"])
def test_illum_tar_is_indexed_in_place_and_decodes_with_the_matching_white(illum, layout, tmp_path):
    sim, whites = illum
    serial = sim.raw.metadata.serial
    written = write_calibration_archive(whites, tmp_path / f"caldata-{serial}.tar", layout=layout)
    scene = write_lfr(tmp_path / "scene.lfr", sim.raw)
    entries, lf = _calibrate_and_decode(written.paths[0], scene, tmp_path)
    folder = serial if layout == "serial" else "unitdata"
    assert sorted(e.file for e in entries) == [f"../caldata-{serial}.tar::{folder}/MOD_{k:04d}.RAW" for k in range(3)]
    assert all(e.geometry_ref and e.geometry_ref.startswith("sha1-") for e in entries)
    assert not list(tmp_path.rglob("MOD_*"))                     # nothing was extracted
    source = lf.metadata["calibration"]["info"]["source"]
    assert source.endswith(f"{folder}/MOD_0001.RAW")             # the white taken at the raw's zoom and focus
    assert lf.metadata["devignetted"] is True


def test_f01_datac_volumes_follow_nextfile_and_decode_with_the_matching_white(f01, tmp_path):
    sim, whites = f01
    written = write_calibration_archive(whites, tmp_path / "sn", kind="f01-datac", files_per_volume=3)
    assert [p.name for p in written.paths] == ["data.C.0", "data.C.1"]   # MOD_0001's RAW and TXT straddle them
    with CalibrationArchive(written.paths[0]) as arch:
        assert arch.white_images() == [f"T1CALIB/MOD_{k:04d}.RAW" for k in range(3)]
    scene = write_lfp(tmp_path / "scene.lfp", sim.raw)
    entries, lf = _calibrate_and_decode(written.paths[0], scene, tmp_path)
    assert all("data.C.0::T1CALIB/MOD_" in e.file for e in entries)
    assert lf.metadata["calibration"]["info"]["source"].endswith("T1CALIB/MOD_0001.RAW")


def test_member_paths_read_through_read_raw(f01, illum, tmp_path):
    sim, whites = f01
    written = write_calibration_archive(whites, tmp_path / "f01", kind="f01-datac", files_per_volume=3)
    raw = read_raw(written.whites[1])
    assert raw.path == written.whites[1] and (raw.mosaic == whites[1].mosaic).all()
    assert raw.metadata.is_white_image and raw.metadata.focus_step == whites[1].metadata.focus_step
    tar = write_calibration_archive(illum[1][:1], tmp_path / "caldata.tar", layout="unitdata")
    assert (read_raw(tar.whites[0]).mosaic == illum[1][0].mosaic).all()
    with pytest.raises(FormatError, match="no member"):
        read_raw(f"{tar.paths[0]}::unitdata/MOD_0009.RAW")
    written.paths[1].unlink()                                    # a volume of the chain is missing
    with pytest.raises(FormatError, match="data.C.1.*missing"):
        read_raw(written.whites[0])


def test_geometry_correction_ref_picks_the_white_through_the_manifest(illum, tmp_path):
    sim, whites = illum
    same_lattice = [whites[1], replace(whites[1], metadata=replace(whites[1].metadata, zoom_step=700.0))]
    written = write_calibration_archive(same_lattice, tmp_path / "caldata.tar")
    store.build_database(written.paths[0], tmp_path / "db", fit=False)
    plain = read_raw(write_lfr(tmp_path / "plain.lfr", sim.raw))
    assert store.select_white(tmp_path / "db", plain).file.endswith("MOD_0000.RAW")      # nearest zoom/focus
    linked = read_raw(write_lfr(tmp_path / "linked.lfr", sim.raw,
                                geometry_correction=written.geometry_corrections[1]))
    assert store.select_white(tmp_path / "db", linked).file.endswith("MOD_0001.RAW")     # the GCT's white


def test_desktop_lfp_with_modulation_data_uses_its_own_white(f01, tmp_path):
    from plenodecode.pipeline import choose_calibration

    sim, whites = f01
    scene = write_lfp(tmp_path / "scene.lfp", sim.raw, modulation=whites[1])
    cal = choose_calibration(read_raw(scene), database=tmp_path / "no-db")
    assert cal.source == "camera" and "modulationDataRef" in cal.detail
    assert (cal.white.mosaic == whites[1].mosaic).all()


def test_synth_writes_the_archive_the_cli_indexes_and_decodes_with(tmp_path):
    out = tmp_path / "synth"
    res = _run(["synth", "illum-mini", "-o", out, "--shape", 300, 420, "--no-lightfield", "--archive", "illum-tar"])
    assert res.exit_code == 0, res.output
    tar = out / "caldata-B5143909630.tar"
    with CalibrationArchive(tar) as arch:
        assert arch.white_images() == ["B5143909630/MOD_0000.RAW"]
    assert _run(["calibrate", "--database", tmp_path / "db", tar]).exit_code == 0
    res = _run(["decode", out / "scene.lfr", "--database", tmp_path / "db", "-o", tmp_path / "lf.npy"])
    assert res.exit_code == 0, res.output
    source = load_lightfield(tmp_path / "lf.npy").metadata["calibration"]["info"]["source"]
    assert source == "../synth/caldata-B5143909630.tar::B5143909630/MOD_0000.RAW"
