"""``plenodecode batch`` refuses before any work what no raw could do (a focus distance or metric depth that no
raw has the constants for) and what cannot run at all (an unreachable --scheduler), in one line naming the option,
with nothing written."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import ROOT, shared_path

F01 = ROOT / "sample_raws" / "f01-mini" / "scene.lfp"
ILLUM = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
DB = ROOT / "calib"


def _folder(tmp_path, *files):
    folder = tmp_path / "shoot"
    folder.mkdir()
    for f in files:
        shutil.copy(f, folder / f.name)
    return folder


@pytest.mark.parametrize("extra, error", [
    (["--focus-distance", "1"], "Invalid value for --focus-distance: none of the 3 raws has what it needs (IMG_1.jpg, "
                                "scene.lfp, scene.lfr): IMG_1.jpg has no focal_length_m, f_number, lens_pitch_m in "
                                "its metadata, which a focus distance (metres -> slope) needs; use --slope S (px per "
                                "view step) instead"),
    (["--outputs", "depth", "--metric"], "Invalid value for --metric: none of the 3 raws has what it needs (IMG_1.jpg, "
                                         "scene.lfp, scene.lfr): IMG_1.jpg has no focal_length_m, f_number, "
                                         "lens_pitch_m in its metadata, which metric depth needs; use plain disparity "
                                         "(without --metric and --ply), or for a light-field microscope give its "
                                         "optics (--magnification, --na, --medium-index, --lens-pitch-um, --pixel-um, "
                                         "or --optics FILE.json) instead"),
], ids=["focus-distance", "metric"])
def test_batch_refuses_a_focus_no_raw_has_the_constants_for(tmp_path, monkeypatch, extra, error):
    """A real F01 JPEG beside the two Lytro sample raws, none with a focus distance in its metadata: '--focus-distance
    1' failed all three on their rows (exit 1) and wrote summary.json and index.html of that."""
    from plenodecode import batch

    monkeypatch.setattr(batch, "run_batch", lambda *a, **k: pytest.fail("the batch ran"))
    folder = _folder(tmp_path, shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), F01, ILLUM)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(out), "--database", str(DB), *extra])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == f"Error: {error}"
    assert not out.exists()


def test_batch_metric_of_one_raw_without_focus_distance_names_depth_focus_distance(tmp_path):
    """The batch's option for the depth's focus distance is --depth-focus-distance (its --focus-distance
    refocuses the photographs): the refusal says that one."""
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(_folder(tmp_path, F01)), "-o", str(out), "--database", str(DB),
                                   "--outputs", "depth", "--metric"])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == (
        "Error: Invalid value for --metric: scene.lfp has no focus_distance_m in its metadata, which metric depth "
        "needs; use --depth-focus-distance METRES (the distance in focus) instead")
    assert not out.exists()


def test_batch_metric_depth_of_the_raws_that_can_and_a_row_for_the_one_that_cannot(tmp_path):
    """With --depth-focus-distance the Illum sample raw can give metric depth and the real F01 JPEG still cannot (no
    focal length, f-number, lens pitch): the raw is written in metres, the JPEG fails on its row saying why, exit 1."""
    folder = _folder(tmp_path, shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), ILLUM)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(out), "--database", str(DB), "--outputs", "depth",
                                   "--metric", "--depth-focus-distance", "0.5", "--jobs", "1"])
    assert res.exit_code == 1, res.output
    rows = {r["source"].rsplit("/", 1)[-1]: r for r in json.loads((out / "summary.json").read_text())["results"]}
    assert rows["scene.lfr"]["status"] == "done" and rows["IMG_1.jpg"]["status"] == "failed"
    assert "IMG_1.jpg: metric depth needs the camera constants focal_length_m, f_number, lens_pitch_m" in \
        rows["IMG_1.jpg"]["error"]
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "scene", "summary.json"]
    from plenodecode.io.pfm import read_pfm

    depth = read_pfm(next(p for p in rows["scene.lfr"]["outputs"] if p.endswith("depth.pfm")))
    lo, hi = np.percentile(depth[np.isfinite(depth)], [5, 95])
    assert 0.3 < lo < hi < 0.8         # metres about the 0.5 m in focus, not disparities (px per view step)


def test_batch_unreachable_scheduler_fails_in_seconds_naming_the_option(tmp_path):
    """'--scheduler tcp://127.0.0.1:1' (nothing listens) waited Dask's 30 s connect timeout; the client now waits
    5 s, and the one line names --scheduler."""
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(_folder(tmp_path, F01)), "-o", str(out), "--database", str(DB),
                                   "--scheduler", "tcp://127.0.0.1:1"])
    assert res.exit_code == 1, res.output
    assert res.stderr.strip().splitlines()[-1] == (
        "error: cannot use the Dask scheduler tcp://127.0.0.1:1 (--scheduler): Timed out trying to connect to "
        "tcp://127.0.0.1:1 after 5 s")
    assert not out.exists()


def test_batch_reads_each_raw_once_before_its_first_task(tmp_path, monkeypatch):
    """The checks made before the first task (camera constants for --metric, --slope and --focal-stack past the
    pictures, view outputs no raw serves) each read the raws in a pass of their own: on two real F01 JPEGs beside the
    Lytro sample raws IMG_1.jpg was read 4 times before any task, once per check.  One pass now asks every check of
    each raw, and ends when all are settled (scene.lfp has the constants: scene.lfr is not read)."""
    from collections import Counter
    from pathlib import Path

    import plenodecode.pipeline.inputs as inputs
    from plenodecode import batch

    reads: Counter = Counter()
    real = inputs._read_raw

    def counting(p, *args, **kwargs):
        reads[Path(p).name] += 1
        return real(p, *args, **kwargs)

    started = []

    def first_task(*args, **kwargs):        # the batch starts: how many reads so far
        started.append(dict(reads))
        raise SystemExit(0)

    monkeypatch.setattr(inputs, "_read_raw", counting)
    monkeypatch.setattr(batch, "run_batch", first_task)
    folder = _folder(tmp_path, shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"),
                     shared_path("lytro-f01-lenslet-jpg", "IMG_2.jpg"), F01, ILLUM)
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(tmp_path / "out"), "--database", str(DB),
                                   "--outputs", "refocus,centre,focal-stack,depth", "--metric",
                                   "--depth-focus-distance", "0.5", "--slope", "0.5", "--focal-stack", "-0.5:0.5:3"])
    assert res.exit_code == 0 and started, res.output
    assert started[0] == {"IMG_1.jpg": 1, "IMG_2.jpg": 1, "scene.lfp": 1}


ANTLEG = ("lf-microscopy-antleg",)


@pytest.mark.parametrize("frames, error", [
    (["-w", "dark_frame.tif"], "Invalid value for --white: {dir}/dark_frame.tif is uniformly dark (99.9th percentile "
                               "0.0017 of the white level); expected a white image: use the microscope's radiometry "
                               "(flat-field) frame, e.g. {dir}/radiometry_frame.png beside it, not a dark frame"),
    (["--dark", "radiometry_frame.png"], "Invalid value for --dark: radiometry_frame.png is no dark frame for "
                                         "light_field.png: subtracted from it, the brightest 0.1 % keep 0.0% of the "
                                         "range"),
    (["--dark", "F01"], "Invalid value for --dark: IMG_1.jpg is 3280 x 3280 px but the raw light_field.png is 2592 x "
                        "2160; pass the dark frame of this camera"),
], ids=["dark-as-white", "white-as-dark", "other-camera-dark"])
def test_batch_refuses_a_white_or_dark_frame_that_suits_no_raw(tmp_path, frames, error):
    """The ant leg with its frames swapped or another camera's picture as the dark frame: batch failed the raw on its
    row (exit 1) after writing its summary and index, the message naming a file but not the option; refused now
    before any work, naming -w/--white or --dark, with nothing written."""
    folder = shared_path(*ANTLEG)
    f01 = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    option, name = frames
    given = ["-w", str(folder / "radiometry_frame.png")] if option == "--dark" else []
    given += [option, str(f01 if name == "F01" else folder / name)]
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(folder / "light_field.png"), "-o", str(out), *given])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1].startswith(f"Error: {error.format(dir=folder)}"), res.output
    assert not out.exists()


def test_batch_with_a_dark_frame_of_one_of_its_raws_runs_and_fails_the_other_on_its_row(tmp_path, monkeypatch):
    """The ant leg's dark frame suits the ant leg, not the F01 JPEG beside it: the batch is not refused (the JPEG
    fails on its row, as a batch goes past a bad file)."""
    from plenodecode import batch

    folder = shared_path(*ANTLEG)
    ran = []

    def first_task(files, *args, **kwargs):
        ran.append([f.name for f in files])
        raise SystemExit(0)

    monkeypatch.setattr(batch, "run_batch", first_task)
    res = CliRunner().invoke(cli, ["batch", str(shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")),
                                   str(folder / "light_field.png"), "-o", str(tmp_path / "out"), "--self-calibrate",
                                   "--dark", str(folder / "dark_frame.tif")])
    assert res.exit_code == 0 and ran == [["IMG_1.jpg", "light_field.png"]], res.output


def test_a_lytro_raw_without_its_metadata_is_named_not_passed_over(tmp_path):
    """A camera's IMG_0001.RAW copied without its IMG_0001.TXT was passed over in silence: alone, the batch said
    'no raws found'; beside other raws, nothing at all.  Now a note (or the refusal) names it and the missing file."""
    folder = _folder(tmp_path, ILLUM)
    shutil.copy(ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW", folder / "IMG_0001.RAW")
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(tmp_path / "out"), "--outputs", "centre",
                                   "--jobs", "1", "--database", str(DB)])
    assert res.exit_code == 0, res.output
    assert ("note: 1 headerless Lytro raw(s) (IMG_0001.RAW) were not taken: such a raw is read with its metadata "
            "beside it (IMG_0001.TXT or .json), which is missing") in res.stderr
    assert (tmp_path / "out" / "scene" / "centre.png").is_file()
    (folder / ILLUM.name).unlink()
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(tmp_path / "out2"), "--database", str(DB)])
    assert res.exit_code == 2 and not (tmp_path / "out2").exists()
    assert f"Error: no raws found under {folder}; 1 headerless Lytro raw(s) (IMG_0001.RAW)" in res.stderr
