"""Which calibration database a raw uses when ``--database`` is not given, through the CLI.

``plenodecode sample_raws/illum-mini/scene.lfr -o x.png`` run from another folder said there was no calibration
database: the default was ``./calib`` of the working directory only.  It is now ``./calib``, else the ``calib/``
beside the raw or in a folder above it (as git finds ``.git``); the message names where it looked and ``info``
says which database a raw uses.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.images import read_image

ROOT = Path(__file__).resolve().parents[2]
ILLUM_MINI = ROOT / "sample_raws" / "illum-mini"


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def chosen(caplog) -> list[str]:
    """The calibration lines logged (:meth:`plenodecode.pipeline.Calibration.describe`), then forgotten."""
    lines = [r.getMessage() for r in caplog.records if r.name == "plenodecode.pipeline.calibration"]
    caplog.clear()
    return lines


def test_project_database_found_from_another_working_directory(tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)                                    # no calib/ here
    caplog.set_level("INFO", logger="plenodecode.pipeline.calibration")
    res = invoke(ILLUM_MINI / "scene.lfr", "-o", "photo.png")
    assert res.exit_code == 0, res.output
    assert chosen(caplog) == [f"calibration: database {ROOT / 'calib'}/ (white MOD_0000.RAW, cached grid)"]
    photo = read_image(tmp_path / "photo.png")
    assert photo.shape == (87, 125, 3) and photo.std() > 0.02 * np.iinfo(photo.dtype).max
    info = invoke("info", ILLUM_MINI / "scene.lfr")
    assert info.exit_code == 0, info.output
    assert f"calib    database {ROOT / 'calib'}/ (white MOD_0000.RAW, cached grid)" in info.output


def test_database_above_the_raw_and_the_current_folder_first(tmp_path, monkeypatch, caplog):
    """A database built in a project folder serves its raws two folders down; ./calib, when it has an index,
    comes first; with neither, the one-line error names every place it looked and writes nothing."""
    project = tmp_path / "project"
    raws = project / "shoot" / "day1"
    raws.mkdir(parents=True)
    for name in ("scene.lfr", "MOD_0000.RAW", "MOD_0000.TXT"):
        shutil.copy(ILLUM_MINI / name, raws / name)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    caplog.set_level("INFO", logger="plenodecode.pipeline.calibration")
    res = invoke(raws / "scene.lfr", "-o", "photo.png")
    lines = res.output.strip().splitlines()
    assert res.exit_code == 1 and len(lines) == 1, res.output
    assert (f"no calibration database (looked for its index.json in {elsewhere / 'calib'} (the current folder's), "
            f"then calib/ in {raws} and each folder above it)") in lines[0]
    assert not (elsewhere / "photo.png").exists()

    assert invoke("-q", "calibrate", "--database", project / "calib", raws).exit_code == 0
    chosen(caplog)
    res = invoke(raws / "scene.lfr", "-o", "photo.png")
    assert res.exit_code == 0, res.output
    assert chosen(caplog) == [f"calibration: database {project / 'calib'}/ (white MOD_0000.RAW, cached grid)"]
    assert (elsewhere / "photo.png").is_file()

    # ./calib of the working directory is looked at first (named relative, as typed by the user of old)
    assert invoke("-q", "calibrate", "--database", "calib", raws).exit_code == 0
    chosen(caplog)
    res = invoke(raws / "scene.lfr", "-o", "photo2.png")
    assert res.exit_code == 0 and chosen(caplog) == ["calibration: database calib/ (white MOD_0000.RAW, cached grid)"]


def test_batch_finds_the_database_above_its_raws(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = invoke("-q", "batch", ILLUM_MINI / "scene.lfr", "-o", "out", "--jobs", "1")
    assert res.exit_code == 0, res.output
    (photo,) = (tmp_path / "out" / "scene").glob("*.png")
    assert read_image(photo).std() > 0


def test_batch_row_of_a_raw_without_database_says_where_it_looked(tmp_path, monkeypatch):
    """The real R42 image (its own XML) decodes beside a Lytro raw that finds no database: the batch goes on, and
    the Lytro raw's row named '<cwd>/calib (no index.json)', a folder the batch had made up, not where it looked."""
    from tests.conftest import shared_path

    shots = tmp_path / "shoot"
    shots.mkdir()
    for f in (shared_path("raytrix-r42", "sc2_klein.png"), shared_path("raytrix-r42", "sc2_klein.xml"),
              ILLUM_MINI / "scene.lfr"):
        shutil.copy(f, shots / f.name)
    monkeypatch.chdir(tmp_path)                     # no calib/ here, beside the raws or above them
    res = invoke("-q", "batch", shots, "-o", "out", "--jobs", "1")
    assert res.exit_code == 1, res.output
    import json

    rows = {Path(r["source"]).name: r for r in json.loads((tmp_path / "out" / "summary.json").read_text())["results"]}
    assert rows["sc2_klein.png"]["status"] == "done"
    assert rows["scene.lfr"]["error"].startswith(
        f"no calibration for scene.lfr (camera ILLUM B5143909630): no calibration database (looked for its "
        f"index.json in {tmp_path / 'calib'} (the current folder's), then calib/ in {shots} and each folder above "
        "it); 'plenodecode calibrate --database calib FOLDER'"), rows["scene.lfr"]["error"]


def test_calibrate_for_uses_the_database_decoding_finds(tmp_path, monkeypatch):
    """'calibrate --for RAW -o grid.json' refused to run without --database although decoding RAW finds its
    database: it now writes the grid decoding would use (the project's, found above the raw from another folder,
    equal to '--database calib's), and without one says where it looked and which white images lie beside RAW."""
    from plenodecode.types import LensletGrid

    monkeypatch.chdir(tmp_path)
    res = invoke("calibrate", "--for", ILLUM_MINI / "scene.lfr", "-o", "found.json")
    assert res.exit_code == 0, res.output
    res = invoke("calibrate", "--database", ROOT / "calib", "--for", ILLUM_MINI / "scene.lfr", "-o", "given.json")
    assert res.exit_code == 0, res.output
    found, given = (LensletGrid.from_json((tmp_path / f).read_text()) for f in ("found.json", "given.json"))
    assert found.pitch == given.pitch and abs(found.pitch - 14.2857) < 1e-3
    assert np.array_equal(found.centres(), given.centres())
    shoot = tmp_path / "shoot"
    shutil.copytree(ILLUM_MINI, shoot)
    res = invoke("calibrate", "--for", shoot / "scene.lfr", "-o", "none.json")
    assert res.exit_code == 2 and not (tmp_path / "none.json").exists()
    assert (f"Error: --for scene.lfr picks a white image from a calibration database, and there is none (looked for "
            f"its index.json in {tmp_path / 'calib'} (the current folder's), then calib/ in {shoot} and each folder "
            f"above it); pass --database DIR, or build one with 'plenodecode calibrate --database calib {shoot}' from "
            "the white images beside it (MOD_0000.RAW)") in " ".join(res.output.split()), res.output
