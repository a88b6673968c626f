"""Batch decoding: discovery, calibration lookup, products, failures, resuming, atomicity, CLI, Dask.

Generated 'illum-mini' raws on a tiny 200 x 280 sensor (17 x 20 lenses) keep it fast.
"""

from __future__ import annotations

import html
import json
import os
import shutil
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.batch import (BATCH_OUTPUTS, DONE_MARKER, BatchOptions, BatchSummary, TaskResult, find_raws,
                               output_names, process_raw, run_batch, task_key, write_summary)
from plenodecode.cli.main import cli
from plenodecode.report.batch import error_text

SHAPE = (200, 280)
SEEDS = (1, 2, 3)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Three good raws (one folder each, as the generator writes them), bad files, a calibration database."""
    from plenodecode.calib.store import build_database
    from plenodecode.io import lytro
    from plenodecode.synthetic import PRESETS, simulate, write_simulation

    root = tmp_path_factory.mktemp("batch")
    shoot = root / "shoot"
    for seed in SEEDS:
        sim = simulate("illum-mini", seed=seed, shape=SHAPE)
        write_simulation(sim, shoot / f"take{seed}", name=f"scene{seed}")
    whites = root / "whites"
    whites.mkdir()
    for f in (shoot / "take1").glob("MOD_0000.*"):
        shutil.copy(f, whites / f.name)
    db = root / "db"
    db.mkdir()     # calib.store resolves white paths through the database folder, so it must exist first
    build_database(whites, db)

    bad = root / "bad"
    bad.mkdir()
    good = (shoot / "take1" / "scene1.lfr").read_bytes()
    (bad / "corrupt.lfr").write_bytes(good[: len(good) // 2])          # truncated container
    stranger = simulate(replace(PRESETS["illum-mini"], serial="B0000000001"), seed=4, shape=SHAPE)
    lytro.write_lfr(bad / "stranger.LFR", stranger.raw)                   # a camera the database lacks
    other = simulate("illum-mini", seed=5, shape=(160, 240))
    lytro.write_lfr(bad / "cropped.LFR", other.raw)                       # known camera, no white of its size
    return {"root": root, "shoot": shoot, "bad": bad, "db": db}


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in ("summary.json", "index.html")}


# ------------------------------------------------------------------------------ discovery
def test_find_raws_skips_whites_truth_sidecars_outputs(data, tmp_path):
    shoot = data["shoot"]
    listed = sorted(p.name for p in shoot.rglob("*") if p.is_file())
    assert any(".truth." in n for n in listed) and any(n.startswith("MOD_") for n in listed)  # generator wrote them
    found = find_raws([shoot])
    assert [p.name for p in found] == ["scene1.lfr", "scene2.lfr", "scene3.lfr"]
    # explicit files are taken as given, duplicates removed, the output folder excluded
    out = shoot / "decoded"
    out.mkdir()
    try:
        (out / "x.lfr").write_bytes(b"")
        assert find_raws([shoot, shoot / "take1" / "scene1.lfr"], exclude=[out]) == found
        # a folder written by a batch (it has a marker) is never searched
        (out / DONE_MARKER).write_text("{}")
        assert find_raws([shoot]) == found
    finally:
        shutil.rmtree(out)


def test_output_names_are_unique(tmp_path):
    files = [tmp_path / "a" / "IMG_1.LFR", tmp_path / "b" / "IMG_1.LFR", tmp_path / "b" / "IMG_2.LFR",
             tmp_path / "c" / "IMG_3.lfr", tmp_path / "c" / "IMG_3.LFP"]
    names = output_names(files)
    assert names == ["a__IMG_1", "b__IMG_1", "IMG_2", "IMG_3_lfr", "IMG_3_lfp"]
    assert len(set(names)) == len(names)


def test_task_key_depends_on_bytes_and_options(tmp_path):
    a = tmp_path / "a.lfr"
    a.write_bytes(b"123")
    opt = BatchOptions(outputs=("centre",), database=str(tmp_path))
    k = task_key(a, opt)
    assert len(k) == 64 and k == task_key(a, BatchOptions(outputs=("centre",), database=str(tmp_path)))
    assert k == task_key(a, replace(opt, slope=0.5))                  # no refocus product: slope is irrelevant
    with_refocus = replace(opt, outputs=("centre", "refocus"))
    assert task_key(a, with_refocus) != task_key(a, replace(with_refocus, slope=0.5))
    assert k != task_key(a, replace(opt, outputs=("centre", "refocus")))
    a.write_bytes(b"124")
    assert k != task_key(a, opt)


def test_refocus_by_alpha_or_distance_replaces_the_slope(tmp_path):
    from plenodecode.batch import _image_product_options

    raw = tmp_path / "a.lfr"
    raw.write_bytes(b"123")
    opt = BatchOptions(outputs=("refocus",), database=str(tmp_path))
    assert "alpha" not in opt.as_key_dict() and "distance_m" not in opt.as_key_dict()   # earlier keys unchanged
    assert task_key(raw, opt) != task_key(raw, replace(opt, alpha=1.01))
    assert _image_product_options("refocus", opt) == {"slope": 0.0}
    assert _image_product_options("refocus", replace(opt, alpha=1.01)) == {"alpha": 1.01}
    assert _image_product_options("refocus", replace(opt, focus_distance=2.0)) == {"focus_distance": 2.0}
    for bad in ({"alpha": 0.0}, {"focus_distance": float("inf")}, {"slope": float("nan")},
                {"alpha": 1.0, "focus_distance": 2.0}):
        with pytest.raises(ValueError):
            BatchOptions(outputs=("refocus",), **bad)


def test_old_option_names_still_work_with_a_deprecation_warning_and_keep_the_task_key(tmp_path):
    """BatchOptions(db_dir=, lightfield_format=, distance_m=) became database=, format=, focus_distance= (the
    --database, --format, --focus-distance of 'plenodecode batch'); the old keywords and attributes warn naming the
    new one, and the task key keeps the old names, so an earlier run's outputs are still done."""
    raw = tmp_path / "a.lfr"
    raw.write_bytes(b"123")
    new = BatchOptions(outputs=("refocus", "lightfield"), database=str(tmp_path), format="npy", focus_distance=2.0)
    with pytest.warns(DeprecationWarning) as caught:
        old = BatchOptions(outputs=("refocus", "lightfield"), db_dir=str(tmp_path), lightfield_format="npy",
                           distance_m=2.0)
    assert [str(w.message) for w in caught] == [
        "BatchOptions(db_dir=) is deprecated: pass database=",
        "BatchOptions(lightfield_format=) is deprecated: pass format=",
        "BatchOptions(distance_m=) is deprecated: pass focus_distance="]
    assert old == new and task_key(raw, old) == task_key(raw, new)
    with pytest.warns(DeprecationWarning, match="read database"):
        assert old.db_dir == str(tmp_path)
    key = new.as_key_dict()         # the names of the keys written by earlier versions
    assert key["db_dir"] == str(tmp_path.resolve()) and key["lightfield_format"] == "npy"
    assert key["distance_m"] == 2.0 and not {"database", "format", "focus_distance"} & set(key)
    with pytest.raises(ValueError, match="pass format, not both format and lightfield_format"):
        BatchOptions(format="npy", lightfield_format="npy")


def test_run_batch_takes_output_as_batch_its_old_out_dir_with_a_warning(tmp_path):
    """run_batch(out_dir=) became output= (``plenodecode batch -o/--output``); the old keyword still works."""
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "bad.lfr").write_bytes(b"xx")          # fails fast: the run reaches the raw, not its decoding
    with pytest.warns(DeprecationWarning, match=r"run_batch\(out_dir=\) is deprecated: pass output="):
        old, = run_batch([tmp_path / "in"], out_dir=tmp_path / "old", jobs=1).results
    new, = run_batch([tmp_path / "in"], output=tmp_path / "new", jobs=1).results
    assert old.source == new.source == str((tmp_path / "in" / "bad.lfr").resolve())
    assert old.status == new.status == "failed" and old.error == new.error
    with pytest.raises(TypeError, match="unexpected keyword argument 'outdir'"):
        run_batch([tmp_path / "in"], outdir=tmp_path / "x")
    with pytest.raises(ValueError, match="pass output, not both"):
        run_batch([tmp_path / "in"], tmp_path / "a", out_dir=tmp_path / "b")


def test_options_validate_arguments():
    with pytest.raises(ValueError, match="outputs"):
        BatchOptions(outputs=("centre", "thumbnail"))
    with pytest.raises(ValueError, match="outputs"):
        BatchOptions(outputs=())
    with pytest.raises(ValueError, match="bit_depth"):
        BatchOptions(bit_depth=12)
    with pytest.raises(ValueError, match="format"):
        BatchOptions(format="hdf5")
    assert set(BATCH_OUTPUTS) >= {"centre", "refocus", "depth", "views", "lightfield"}


# ------------------------------------------------------------------------------ a local run
@pytest.fixture(scope="module")
def local_run(data, tmp_path_factory):
    """One in-process run over good and bad raws; products: centre, refocus, depth, lightfield (npy)."""
    out = tmp_path_factory.mktemp("local")
    opts = BatchOptions(outputs=("centre", "refocus", "depth", "lightfield"), database=str(data["db"]), slope=0.3,
                        format="npy", depth_method="fast")
    calls = []
    summary = run_batch([data["shoot"], data["bad"]], out, opts, jobs=1, progress=lambda d, t: calls.append((d, t)))
    write_summary(summary, out)
    return {"out": out, "opts": opts, "summary": summary, "calls": calls}


def test_local_run_decodes_good_raws_and_reports_bad_ones(data, local_run):
    summary, out = local_run["summary"], local_run["out"]
    by_name = {Path(r.source).name: r for r in summary.results}
    assert sorted(by_name) == ["corrupt.lfr", "cropped.LFR", "scene1.lfr", "scene2.lfr", "scene3.lfr",
                               "stranger.LFR"]
    for seed in SEEDS:
        r = by_name[f"scene{seed}.lfr"]
        assert r.status == "done", r.error
        names = [Path(o).name for o in r.outputs]
        assert names == ["centre.png", "refocus_s+0.30.png", "disparity.pfm", "disparity.png",
                         "disparity_confidence.png", "disparity_confidence.exr", "disparity.exr", "lightfield.npy"]
        assert all(Path(o).parent == out / f"scene{seed}" for o in r.outputs)
        # a thumbnail per product; the depth map's other files are links under it
        assert [t is not None and Path(t).is_file() for t in r.thumbnails] == [True] * 3 + [False] * 4 + [True]
        assert r.worker_peak_mb and r.worker_peak_mb > 10 and ":" in r.worker
    # the library's message alone, as 'plenodecode RAW' prints it after 'error:' (the rows began 'FormatError: ',
    # 'CalibrationError: ', a Python class a photographer cannot act on)
    corrupt = by_name["corrupt.lfr"]
    assert corrupt.status == "failed" and corrupt.error.startswith(f"{corrupt.source}: the LFC section at offset 16 ")
    assert corrupt.error.endswith("the file is truncated or damaged"), corrupt.error
    assert by_name["stranger.LFR"].status == "failed"
    assert by_name["stranger.LFR"].error.startswith("no white image of camera B0000000001 in "), by_name["stranger.LFR"]
    assert by_name["cropped.LFR"].status == "failed"
    assert by_name["cropped.LFR"].error.startswith("the white image ../whites/MOD_0000.RAW is 280x200 but the raw is "
                                                   "240x160"), by_name["cropped.LFR"]
    for r in summary.failed:
        assert "\n" not in r.error and not (out / Path(r.source).stem).exists()
    # progress: (0, n) first, then one call per raw, counts increasing to n
    assert local_run["calls"] == [(i, 6) for i in range(7)]


def test_products_match_a_direct_decode(data, local_run):
    """The batch writes what decode + refocus give for that raw with the database's calibration."""
    from plenodecode.calib.store import calibration_for
    from plenodecode.decoding import decode
    from plenodecode.io import read_raw
    from plenodecode.io.images import read_image
    from plenodecode.io.lightfield import load_lightfield
    from plenodecode.render import refocus

    raw = read_raw(data["shoot"] / "take2" / "scene2.lfr")
    grid, white = calibration_for(raw, data["db"])
    assert white.metadata.is_white_image and white.shape == raw.shape
    lf = decode(raw, grid, white=white)
    folder = local_run["out"] / "scene2"
    saved = load_lightfield(folder / "lightfield.npy")
    np.testing.assert_array_equal(saved.data, lf.data)
    photo = refocus(lf, slope=0.3)
    png = read_image(folder / "refocus_s+0.30.png").astype(np.float64) / 65535.0
    from plenodecode.io.images import srgb_encode
    expect = srgb_encode(np.clip(photo, 0, 1))
    assert png.shape == expect.shape
    assert np.abs(png - expect).max() <= 0.5 / 65535 + 1e-6     # 16-bit quantisation only
    from plenodecode.depth import estimate_depth
    from plenodecode.io.pfm import read_pfm
    np.testing.assert_array_equal(read_pfm(folder / "disparity.pfm"), estimate_depth(lf, method="fast").disparity)


def test_batch_uses_the_right_calibration(data, local_run):
    """Against the generator's truth: the database grid is the camera's, and the white was used.

    Decoded with the white the centre view is ~34 dB from the true one; without it ~21 dB.
    """
    from plenodecode.calib.store import calibration_for
    from plenodecode.io import read_raw
    from plenodecode.synthetic import load_truth

    truth = load_truth(data["shoot"] / "take2" / "scene2.truth.json")
    grid, _ = calibration_for(read_raw(data["shoot"] / "take2" / "scene2.lfr"), data["db"])
    assert grid.shape == truth.grid.shape
    assert np.abs(grid.centres() - truth.grid.centres()).max() < 0.05
    got = np.load(local_run["out"] / "scene2" / "lightfield.npy")
    vc, uc = got.shape[0] // 2, got.shape[1] // 2
    err = got[vc, uc, 2:-2, 2:-2] - truth.lightfield.data[vc, uc, 2:-2, 2:-2]
    assert 10 * np.log10(1.0 / np.mean(err.astype(np.float64) ** 2)) > 30.0


def test_summary_json_and_index(local_run):
    out, summary = local_run["out"], local_run["summary"]
    doc = json.loads((out / "summary.json").read_text())
    assert (doc["total"], doc["done"], doc["skipped"], doc["failed"]) == (6, 3, 0, 3)
    assert [r["status"] for r in doc["results"]] == [r.status for r in summary.results]
    page = (out / "index.html").read_text()
    for r in summary.results:
        if r.status == "done":
            for t in filter(None, r.thumbnails):
                rel = Path(t).relative_to(out).as_posix()
                assert f'src="{rel}"' in page
        else:   # the message, without the raw's path its card names (summary.json keeps the whole line)
            assert html.escape(error_text(r)) in page and r.error in [d["error"] for d in doc["results"]]
    assert page.count("<img") == 12 and "<script" not in page


def test_depth_thumbnail_has_a_colour_bar_and_greys_low_confidence(local_run):
    """The disparity thumbnail: the map, then the colour bar of ``plenodecode depth``'s PNG (its colour map, the
    highest value at the top) with its unit; the pixels below the default min_confidence are the mask grey."""
    from matplotlib import colormaps

    from plenodecode.io.depthio import DEFAULT_MIN_CONFIDENCE, DEPTH_CMAP, MASK_GREY
    from plenodecode.io.images import read_image

    thumb = read_image(local_run["out"] / "scene1" / "thumbs" / "disparity.png")[..., :3].astype(np.float64) / 255
    h, w = thumb.shape[:2]
    assert max(h, w) <= 256 and w > h
    cmap = colormaps[DEPTH_CMAP](np.linspace(0, 1, 256))[:, :3]
    # the colour bar: a column in the right third whose colours run down the colour map from its top to its bottom
    found = False
    for x in range(2 * w // 3, w):
        col = thumb[:, x]
        coloured = np.flatnonzero(np.abs(col - col.mean(axis=1, keepdims=True)).max(axis=1) > 0.08)
        if coloured.size < h // 3:
            continue
        index = np.argmin(((col[coloured, None, :] - cmap[None]) ** 2).sum(-1), axis=1)
        if np.corrcoef(coloured, index)[0, 1] < -0.95 and index.max() - index.min() > 180:
            found = True
            break
    assert found
    grey = np.all(np.abs(thumb - np.array(MASK_GREY)) < 2.5 / 255, axis=-1)
    assert DEFAULT_MIN_CONFIDENCE > 0 and grey[:, : 2 * w // 3].any()
    # the index shows the depth thumbnails (one per decoded raw) wider, so the colour bar's text stays legible
    page = (local_run["out"] / "index.html").read_text()
    assert page.count('<img class="legend"') == len(SEEDS) and "img.legend{width:240px}" in page


def test_min_confidence_option(tmp_path):
    from plenodecode.io.depthio import DEFAULT_MIN_CONFIDENCE

    opt = BatchOptions(outputs=("depth",), database=str(tmp_path))
    assert "min_confidence" not in opt.as_key_dict()          # the default keeps the keys of earlier runs
    assert "min_confidence" not in replace(opt, min_confidence=DEFAULT_MIN_CONFIDENCE).as_key_dict()
    assert replace(opt, min_confidence=0.5).as_key_dict()["min_confidence"] == 0.5
    assert "min_confidence" not in BatchOptions(outputs=("centre",), min_confidence=0.5).as_key_dict()
    for bad in (1.5, -0.1, float("nan")):
        with pytest.raises(ValueError, match="min_confidence"):
            BatchOptions(outputs=("depth",), min_confidence=bad)
    r = CliRunner().invoke(cli, ["batch", str(tmp_path), "-o", str(tmp_path / "out"), "--min-confidence", "nan"],
                           obj={})
    assert r.exit_code == 2 and "--min-confidence" in r.output and not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- resuming
def test_second_run_skips_finished_raws_and_keeps_files(data, local_run, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(local_run["out"], out)
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    again = run_batch([data["shoot"], data["bad"]], out, local_run["opts"], jobs=1)
    status = {Path(r.source).name: r.status for r in again.results}
    assert [status[f"scene{s}.lfr"] for s in SEEDS] == ["skipped"] * 3
    assert status["corrupt.lfr"] == "failed"
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == stamps
    skipped = next(r for r in again.results if r.status == "skipped")
    assert [Path(o).name for o in skipped.outputs] == ["centre.png", "refocus_s+0.30.png", "disparity.pfm",
                                                        "disparity.png", "disparity_confidence.png",
                                                        "disparity_confidence.exr", "disparity.exr", "lightfield.npy"]
    # a changed option would replace the folders: refused before any work, the files untouched
    changed = replace(local_run["opts"], slope=-0.2)
    with pytest.raises(FileExistsError, match=r"^3 of 3 raws already have an output folder in .*overwrite"):
        run_batch([data["shoot"]], out, changed, jobs=1)
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == stamps
    # overwrite re-runs and replaces the folder (the old refocus is gone, the new one there)
    third = run_batch([data["shoot"]], out, changed, jobs=1, overwrite=True)
    assert [r.status for r in third.results] == ["done"] * 3
    assert (out / "scene1" / "refocus_s-0.20.png").is_file()
    assert not (out / "scene1" / "refocus_s+0.30.png").exists()


def test_changed_input_reruns(data, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(data["shoot"] / "take1" / "scene1.lfr", src / "a.LFR")
    opts = BatchOptions(outputs=("centre",), database=str(data["db"]))
    out = tmp_path / "out"
    assert run_batch([src], out, opts, jobs=1).results[0].status == "done"
    assert run_batch([src], out, opts, jobs=1).results[0].status == "skipped"
    shutil.copy(data["shoot"] / "take2" / "scene2.lfr", src / "a.LFR")
    with pytest.raises(FileExistsError, match="1 of 1 raws"):      # its folder holds the other input's outputs
        run_batch([src], out, opts, jobs=1)
    assert run_batch([src], out, opts, jobs=1, overwrite=True).results[0].status == "done"


def test_refuses_a_foreign_folder_without_overwrite(data, tmp_path):
    out = tmp_path / "out"
    (out / "scene1").mkdir(parents=True)
    (out / "scene1" / "mine.txt").write_text("keep me")
    opts = BatchOptions(outputs=("centre",), database=str(data["db"]))
    with pytest.raises(FileExistsError, match="not from a batch; pass --overwrite"):
        run_batch([data["shoot"] / "take1"], out, opts, jobs=1)
    assert (out / "scene1" / "mine.txt").read_text() == "keep me"
    # a task meeting such a folder (made after the check) fails, and keeps it
    r = process_raw(data["shoot"] / "take1" / "scene1.lfr", out, opts)
    assert r.status == "failed" and "was not written by a batch run; pass --overwrite" in r.error
    assert (out / "scene1" / "mine.txt").read_text() == "keep me"
    r = run_batch([data["shoot"] / "take1"], out, opts, jobs=1, overwrite=True).results[0]
    assert r.status == "done" and not (out / "scene1" / "mine.txt").exists()


# ------------------------------------------------------------------- no half-written outputs
def _final_files(out: Path) -> set[str]:
    """Files under final names (hidden staging folders excluded)."""
    rels = [p.relative_to(out) for p in out.rglob("*") if p.is_file()]
    return {str(r) for r in rels if not any(part.startswith(".") and part != DONE_MARKER for part in r.parts)}


def test_writer_failing_mid_write_leaves_nothing_under_final_names(data, tmp_path, monkeypatch):
    import plenodecode.io.images as images

    real = images.write_image
    state = {"n": 0}

    def failing(path, image, **kw):
        state["n"] += 1
        if state["n"] == 7:        # raw 2, its refocus image: half a file, then the disk is full
            Path(path).write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)
            raise OSError(28, "No space left on device")
        return real(path, image, **kw)

    monkeypatch.setattr(images, "write_image", failing)
    out = tmp_path / "out"
    opts = BatchOptions(outputs=("centre", "refocus"), database=str(data["db"]))
    summary = run_batch([data["shoot"]], out, opts, jobs=1)
    assert [r.status for r in summary.results] == ["done", "failed", "done"]
    assert summary.results[1].error == "No space left on device"     # was 'OSError: [Errno 28] No space left ...'
    assert not (out / "scene2").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]          # staging removed
    assert all(not f.startswith("scene2") for f in _final_files(out))


def test_killed_run_leaves_no_partial_output_and_resumes(data, tmp_path):
    """A real SIGKILL in the middle of writing the 2nd raw's refocus image."""
    out = tmp_path / "out"
    script = textwrap.dedent(f"""
        import os, signal
        from pathlib import Path
        import plenodecode.io.images as images
        from plenodecode.batch import BatchOptions, run_batch
        real, n = images.write_image, [0]
        def dying(path, image, **kw):
            n[0] += 1
            if n[0] == 7:
                Path(path).write_bytes(b"\\x89PNG\\r\\n\\x1a\\n" + b"\\0" * 64)
                os.kill(os.getpid(), signal.SIGKILL)
            return real(path, image, **kw)
        images.write_image = dying
        run_batch([{str(data["shoot"])!r}], {str(out)!r},
                  BatchOptions(outputs=("centre", "refocus"), database={str(data["db"])!r}), jobs=1)
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == -9, proc.stderr
    assert (out / "scene1" / DONE_MARKER).is_file()
    assert not (out / "scene2").exists() and not (out / "scene3").exists()
    staging = [p for p in out.iterdir() if p.name.startswith(".")]
    assert len(staging) == 1 and staging[0].name.startswith(".scene2.")   # the half-written files are here only
    assert _final_files(out) == {f"scene1/{n}" for n in ("centre.png", "refocus_s+0.00.png", DONE_MARKER,
                                                          "thumbs/centre.png", "thumbs/refocus_s+0.00.png")}
    again = run_batch([data["shoot"]], out, BatchOptions(outputs=("centre", "refocus"), database=str(data["db"])),
                      jobs=1)
    assert [r.status for r in again.results] == ["skipped", "done", "done"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_a_new_run_removes_leftovers_of_dead_runs_only(data, tmp_path):
    """Staging folders and summary temporaries of a live run (here: this process) survive a new run in the same
    folder; those of a finished process and the owner-less leftovers of earlier versions are removed."""
    from plenodecode.io.atomic import temporary_sibling

    out = tmp_path / "out"
    out.mkdir()
    live = [temporary_sibling(out / "scene7", folder=True), temporary_sibling(out / "summary.json")]
    make = ("from pathlib import Path; from plenodecode.io.atomic import temporary_sibling; "
            f"out = Path({str(out)!r}); temporary_sibling(out / 'scene8', folder=True); "
            "temporary_sibling(out / 'index.html')")
    subprocess.run([sys.executable, "-c", make], check=True)
    dead = sorted(set(out.iterdir()) - set(live))
    assert len(dead) == 2
    legacy = [out / ".scene9.partial", out / ".scene6.old"]
    for p in legacy:
        p.mkdir()
    (out / ".summary.json.tmp").write_text("{}")
    opts = BatchOptions(outputs=("centre",), database=str(data["db"]))
    assert run_batch([data["shoot"] / "take1"], out, opts, jobs=1).results[0].status == "done"
    assert sorted(p for p in out.iterdir() if p.name.startswith(".")) == sorted(live)


# ---------------------------------------------------------------------------------- CLI
def test_cli_runs_reports_and_exits_1_on_failures(data, tmp_path):
    out = tmp_path / "out"
    args = ["batch", str(data["shoot"]), str(data["bad"]), "-o", str(out), "--database", str(data["db"]),
            "--jobs", "1", "--outputs", "centre,refocus,views", "--slope", "0.25", "--bit-depth", "8"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 1, res.output
    assert "decoding 6 raws" in res.stderr
    lines = res.stdout.splitlines()
    for name in ("scene1.lfr", "scene2.lfr", "scene3.lfr"):
        assert any(line.startswith(name) and " done " in line for line in lines)
    # the message without the raw's path the row names (summary.json keeps it)
    for name, what in (("corrupt.lfr", "  the LFC section at offset 16 declares"),
                       ("stranger.LFR", "  no white image of camera B0000000001 in ")):
        assert any(line.startswith(name) and "failed" in line and what in line for line in lines), res.stdout
    assert "3 done, 0 skipped, 3 failed" in res.stdout
    # start-up (imports, kernels) apart from the steady state, and the memory of the worker
    lat = {k: json.loads((out / "summary.json").read_text())[k] for k in ("first_task_s", "steady_task_s",
                                                                         "worker_peak_mb")}
    assert lat["worker_peak_mb"] > 10 and lat["first_task_s"] > 0 and lat["steady_task_s"] > 0
    assert (f"(first task {lat['first_task_s']:.1f} s, then {lat['steady_task_s']:.1f} s per raw; "
            f"peak {lat['worker_peak_mb']:.0f} MB per worker)") in res.stdout
    assert res.stderr.strip().splitlines()[-1].startswith("error: 3 of 6 raws failed")
    assert (out / "scene1" / "refocus_s+0.25.png").is_file() and (out / "index.html").is_file()
    views = sorted((out / "scene1" / "views").glob("view_*.png"))      # the pictures 'plenodecode views' writes
    assert len(views) == 15 * 15 and views[0].name == "view_00_00.png"
    from plenodecode.io.images import read_image
    assert read_image(views[0]).dtype == np.uint8 and read_image(out / "scene1" / "centre.png").shape == (17, 22, 3)
    # again, only the good ones: all skipped, exit 0
    res = CliRunner().invoke(cli, ["-q", *args[:2], *args[3:]])
    assert res.exit_code == 0, res.output
    assert res.stdout == ""
    assert json.loads((out / "summary.json").read_text())["skipped"] == 3


def test_cli_second_run_with_other_options_is_refused_up_front_and_overwrite_replaces(data, tmp_path):
    """'batch FOLDER -o OUT' again with other options replaced every raw's folder without --overwrite (data
    loss).  Now the run is refused in one line before any work, counting the folders it would replace; the
    same options resume (skip), and --overwrite replaces them."""
    out = tmp_path / "out"
    base = ["batch", str(data["shoot"]), "-o", str(out), "--database", str(data["db"]), "--jobs", "1",
            "--outputs", "refocus", "--bit-depth", "8"]
    assert CliRunner().invoke(cli, base).exit_code == 0
    first = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.parent.parent == out}
    assert sorted(p.name for p in first if p.suffix == ".png") == ["refocus_s+0.00.png"] * 3
    res = CliRunner().invoke(cli, [*base, "--slope", "0.25"])
    assert res.exit_code == 2, res.output
    error = res.stderr.strip().splitlines()[-1]
    assert error == (f"Error: 3 of 3 raws already have an output folder in {out} (scene1, scene2, scene3) from a "
                     "run with other options or inputs, or not from a batch; pass --overwrite to replace them, or "
                     "choose another -o folder"), error
    assert "decoding" not in res.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.parent.parent == out} == first
    res = CliRunner().invoke(cli, base)                    # the same options: resumed, nothing replaced
    assert res.exit_code == 0 and "0 done, 3 skipped" in res.stdout, res.output
    res = CliRunner().invoke(cli, [*base, "--slope", "0.25", "--overwrite"])
    assert res.exit_code == 0 and "3 done" in res.stdout, res.output
    assert sorted(p.name for p in (out / "scene2").glob("*.png")) == ["refocus_s+0.25.png"]


@pytest.mark.parametrize("extra", [["--outputs", "centre,bogus"], ["--jobs", "0"], ["--database", "/nonexistent"],
                                   ["--format", "hdf5"]])
def test_cli_usage_errors_exit_2(data, tmp_path, extra):
    args = ["batch", str(data["shoot"]), "-o", str(tmp_path / "o"), "--database", str(data["db"]), *extra]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2, res.output


def test_cli_no_raws_is_a_usage_error(data, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    res = CliRunner().invoke(cli, ["batch", str(empty), "-o", str(tmp_path / "o"), "--database", str(data["db"])])
    assert res.exit_code == 2 and "no raws" in res.output


def test_cli_folder_of_unrecognised_images_says_to_name_the_raw(tmp_path):
    """A microscope's raw beside its white and dark frames (as in ../shared/data/lf-microscopy-antleg): the folder
    yields no raw, and the error names the images passed over and how to pass the raw."""
    import cv2

    shoot = tmp_path / "scope"
    shoot.mkdir()
    for name in ("light_field.png", "radiometry_frame.png", "dark_frame.tif"):
        cv2.imwrite(str(shoot / name), np.full((64, 80), 1000, np.uint16))
    res = CliRunner().invoke(cli, ["batch", str(shoot), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2 and "no raws found" in res.output
    assert "3 image(s) (dark_frame.tif, light_field.png, radiometry_frame.png) were not taken" in res.output
    assert f"plenodecode batch {shoot}/RAW_IMAGE -o OUT" in res.output.replace("\n", "")
    assert not (tmp_path / "o").exists()
    # the batch's own output folder inside the input is not searched, so its thumbnails are not listed
    (shoot / "out" / "a").mkdir(parents=True)
    cv2.imwrite(str(shoot / "out" / "a" / "centre.png"), np.full((8, 8), 1000, np.uint16))
    res = CliRunner().invoke(cli, ["batch", str(shoot), "-o", str(shoot / "out")])
    assert res.exit_code == 2 and "3 image(s) (dark_frame.tif, light_field.png, radiometry_frame.png)" in res.output


def test_cli_real_desktop_exports_fail_for_their_reason_and_passed_over_images_are_named(tmp_path):
    """``batch`` over the real Lytro Desktop exports and the ant-leg folder, with no calibration database: a
    folder of exports yields no raw and the refusal names them and 'plenodecode extract' (before: the whole
    batch refused, '--database: calib is not a folder'); an export named as a file fails for its own reason;
    the images the folders held without a sidecar are named (before: not a word)."""
    from tests.conftest import shared_path

    containers, scope = shared_path("lytro-containers"), shared_path("lf-microscopy-antleg")
    res = CliRunner().invoke(cli, ["batch", str(containers), str(scope), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2, res.output
    flat = " ".join(res.output.split())
    assert "no raws found" in flat and "4 Lytro Desktop export(s)" in flat and "plenodecode extract" in flat
    assert "3 image(s) (dark_frame.tif, light_field.png, radiometry_frame.png) were not taken" in flat
    assert not (tmp_path / "o").exists()
    res = CliRunner().invoke(cli, ["batch", str(containers / "IMG_0002-dm.lfp"), "-o", str(tmp_path / "o")])
    assert res.exit_code == 1, res.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["total"] == 1 and summary["failed"] == 1
    assert "holds no raw image" in summary["results"][0]["error"]


def test_cli_lytro_library_folder_takes_the_raws_and_names_the_desktop_exports(tmp_path):
    """A Lytro library keeps IMG_0001-stk.lfp and -dm.lfp (Lytro Desktop exports, no raw inside) beside the raw
    IMG_0001.lfp. ``batch LIBRARY`` decodes the raw, passes over the real exports with one note naming them and
    'plenodecode extract', and exits 0 (before: 1 done, 4 failed in red in index.html, exit code 1)."""
    from tests.conftest import ROOT, shared_path

    containers = shared_path("lytro-containers")
    lib = tmp_path / "Lytro Library"
    lib.mkdir()
    for f in sorted(containers.iterdir()):
        if f.suffix.lower() == ".lfp":
            shutil.copy(f, lib / f.name)
    shutil.copy(ROOT / "sample_raws" / "f01-mini" / "scene.lfp", lib / "IMG_0003.lfp")
    res = CliRunner().invoke(cli, ["batch", str(lib), "-o", str(tmp_path / "o"), "--database", str(ROOT / "calib"),
                                   "--jobs", "1"])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert (summary["total"], summary["done"], summary["failed"]) == (1, 1, 0)
    assert Path(summary["results"][0]["source"]).name == "IMG_0003.lfp"
    flat = " ".join(res.output.split())
    assert "note: 4 Lytro Desktop export(s) (IMG_0001-stk.lfp, IMG_0002-dm.lfp, IMG_0002-stk.lfp and 1 more)" in flat
    assert "plenodecode extract" in flat
    assert "holds no raw" not in (tmp_path / "o" / "index.html").read_text()


def test_cli_exposure_brightens_the_photo_and_its_thumbnail(tmp_path, monkeypatch):
    """``batch --exposure auto`` on the real ant-leg capture (a dim specimen over a bright radiometry frame): the
    photo's brightest 0.5 % reach full scale and so does the thumbnail's, where the default leaves both dark, from
    one measurement of the photo (it was measured twice, for the file and for the thumbnail); BatchOptions refuses
    a bad exposure (and the CLI, naming --exposure, before any work)."""
    from tests.conftest import shared_path
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float
    from plenodecode.pipeline import output

    measured = []
    real_level = output.image_level
    monkeypatch.setattr(output, "image_level", lambda rendered: measured.append(1) or real_level(rendered))

    scope = shared_path("lf-microscopy-antleg")
    base = ["batch", str(scope / "light_field.png"), "-w", str(scope / "radiometry_frame.png"), "--dark",
            str(scope / "dark_frame.tif"), "--outputs", "photo"]
    level = {}
    for exposure in ("0", "auto"):
        out = tmp_path / exposure
        measured.clear()
        res = CliRunner().invoke(cli, base + ["-o", str(out), "--exposure", exposure, "--jobs", "1"])
        assert res.exit_code == 0, res.output
        assert len(measured) == (exposure == "auto")          # in this process: --jobs 1
        photo, = (out / "light_field").glob("*.png")
        thumb, = (out / "light_field" / "thumbs").glob("*.png")
        level[exposure] = [float(np.percentile(srgb_decode(to_unit_float(read_image(p))), 99.5))
                           for p in (photo, thumb)]
    assert max(level["0"]) < 0.25 and min(level["auto"]) > 0.9, level          # measured 0.14 / 1.0
    with pytest.raises(ValueError, match="exposure"):
        BatchOptions(exposure="bright")
    res = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "bad"), "--exposure", "99"])
    assert res.exit_code == 2 and "--exposure" in res.output and not (tmp_path / "bad").exists()


# -------------------------------------------------------------------- processes and Dask
def test_latency_separates_each_workers_first_task():
    def res(worker, started, seconds, status="done"):
        return TaskResult(f"{worker}{started}.lfr", status, seconds=seconds, worker=worker, started=started,
                          worker_peak_mb=100.0 + started)

    # input order is not start order: w1's first task is the one that started first
    s = BatchSummary((res("w1", 5.0, 1.0), res("w1", 1.0, 4.0), res("w2", 2.0, 3.0), res("w2", 6.0, 2.0),
                      res("w1", 9.0, 0.5), res("w2", 0.5, 9.0, "skipped")))
    # both workers are up at 5.0 (w1's first task ends then, w2's at 5.0 too); after it start w1's tasks at 5.0
    # and 9.0 and w2's at 6.0, the last ending at 9.5: 3 tasks in 4.5 s.  The skipped one does not count.
    assert s.latency() == {"first_task_s": 4.0, "steady_task_s": 1.0, "steady_raws_per_s": 3 / 4.5,
                           "worker_peak_mb": 109.0}
    assert BatchSummary((res("w1", 1.0, 2.0, "failed"),)).latency()["first_task_s"] is None
    assert s.to_dict()["steady_task_s"] == 1.0


def _openblas_threads():
    """Threads of the OpenBLAS bundled with numpy (None when numpy uses another BLAS)."""
    import ctypes
    import glob

    libs = glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs", "lib*openblas*"))
    for lib in map(ctypes.CDLL, libs):
        for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads"):
            if hasattr(lib, name):
                return int(getattr(lib, name)())
    return None


def _pool_probe(_):
    import time

    from plenodecode.threads import thread_counts

    time.sleep(0.3)                       # long enough that every worker takes a probe
    return os.getpid(), {**thread_counts(), "openblas": _openblas_threads()}


def test_pool_workers_together_use_at_most_the_cores():
    """numba, OpenCV and BLAS of each of 2 workers get cores // 2 threads (measured in the workers)."""
    from plenodecode.threads import THREAD_ENV_VARS, worker_pool

    before = {v: os.environ.get(v) for v in THREAD_ENV_VARS}
    jobs = 2
    threads = max(1, (os.cpu_count() or 1) // jobs)
    with worker_pool(jobs, threads) as pool:
        seen = dict(pool.map(_pool_probe, range(4)))
    assert len(seen) == jobs
    for counts in seen.values():
        assert counts["numba"] == threads and counts["opencv"] == threads and counts["blas"] == threads
        assert counts["openblas"] in (None, threads)
    assert {v: os.environ.get(v) for v in THREAD_ENV_VARS} == before       # this process keeps its settings


def test_process_pool_and_dask_cluster_equal_the_local_run(data, local_run, tmp_path):
    """jobs=2 and a two-worker LocalCluster write the same bytes as the in-process run (PNG, PFM, npy, markers)."""
    from distributed import Client, LocalCluster

    good = [data["shoot"] / "take1", data["shoot"] / "take2"]
    expect = {k: v for k, v in _files(local_run["out"]).items() if k.startswith(("scene1/", "scene2/"))}
    assert sum(k.endswith((".png", ".pfm", ".npy")) for k in expect) >= 2 * 7
    pool_out = tmp_path / "pool"
    s = run_batch(good, pool_out, local_run["opts"], jobs=2)
    assert [r.status for r in s.results] == ["done"] * 2
    assert len({r.worker for r in s.results}) == 2                         # one raw on each worker process
    dask_out = tmp_path / "dask"
    calls = []
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        # through the scheduler's address, as the CLI does (run_batch opens and closes its own Client)
        def progress(done, total):      # bounded submission: never more than max_in_flight batch tasks queued/running
            active = [t for k, t in cluster.scheduler.tasks.items() if str(k).startswith("plenodecode-batch")
                      and t.state in ("waiting", "queued", "processing", "no-worker")]
            calls.append((done, len(active)))

        d = run_batch(good, dask_out, local_run["opts"], scheduler=cluster.scheduler_address, max_in_flight=1,
                      progress=progress)
        # a second run through a caller's Client skips everything
        with Client(cluster) as client:
            again = run_batch(good, dask_out, local_run["opts"], scheduler=client)
    assert [r.status for r in d.results] == ["done"] * 2 and [c[0] for c in calls] == [0, 1, 2]
    assert max(c[1] for c in calls) == 0      # with max_in_flight=1 the next task is submitted only after this one
    assert [r.status for r in again.results] == ["skipped"] * 2
    assert all(r.worker_peak_mb > 10 and r.worker != s.results[0].worker for r in d.results)
    for out in (pool_out, dask_out):
        got = _files(out)
        assert sorted(got) == sorted(expect)
        assert [k for k in expect if got[k] != expect[k]] == []


def test_foreign_summary_files_are_not_replaced(data, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "index.html").write_text("<html>someone's page</html>")
    args = ["batch", str(data["shoot"] / "take1"), "-o", str(out), "--database", str(data["db"]), "--jobs", "1"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2 and "index.html" in res.output
    assert (out / "index.html").read_text() == "<html>someone's page</html>" and not (out / "scene1").exists()
    with pytest.raises(FileExistsError, match="index.html"):
        write_summary(BatchSummary(), out)
    res = CliRunner().invoke(cli, [*args, "--overwrite"])
    assert res.exit_code == 0, res.output
    assert "plenodecode batch" in (out / "index.html").read_text()


def test_index_renders_in_a_browser(local_run, tmp_path):
    """Headless Chromium shows the index without console errors; the screenshot has the thumbnails."""
    from tests.conftest import browser_screenshot

    from plenodecode.io.images import read_image

    shot = tmp_path / "index.png"
    console = browser_screenshot(local_run["out"] / "index.html", shot, size=(1200, 900))
    assert console == []
    img = read_image(shot).astype(np.float64)
    assert img.shape[:2] == (900, 1200)
    rgb = img[..., :3] / (255.0 if img.max() > 1 else 1.0)
    assert rgb.std() > 0.05                                         # not blank
    red = (rgb[..., 0] > 0.6) & (rgb[..., 1] < 0.3) & (rgb[..., 2] < 0.3)
    green = (rgb[..., 1] > 0.5) & (rgb[..., 0] < 0.3) & (rgb[..., 2] < 0.3)
    assert red.sum() > 200 and green.sum() > 200                    # failed and done cards' borders drawn


def test_cli_unreachable_scheduler_exits_1_with_one_line(data, tmp_path):
    import dask

    args = ["batch", str(data["shoot"] / "take1"), "-o", str(tmp_path / "o"), "--database", str(data["db"]),
            "--scheduler", "tcp://127.0.0.1:9"]
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        res = CliRunner().invoke(cli, args)
    assert res.exit_code == 1
    err = res.stderr.strip().splitlines()
    assert err[-1].startswith("error: cannot use the Dask scheduler tcp://127.0.0.1:9")
    assert "Traceback" not in res.output
    assert not (tmp_path / "o").exists()        # the scheduler is reached before the output folder is made


def test_output_folders_follow_the_umask(local_run):
    mode = (local_run["out"] / "scene1").stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o777 & ~umask


def test_find_raws_takes_mosaics_but_not_their_whites(tmp_path):
    """'square' (PNG + sidecar) and 'raytrix' (PNG + RayCalibData XML) as the generator writes them."""
    from plenodecode.synthetic import simulate, write_simulation

    write_simulation(simulate("square", seed=1, shape=(120, 140)), tmp_path / "sq", name="lfm")
    write_simulation(simulate("raytrix", seed=1, shape=(110, 150)), tmp_path / "rx", name="rtx")
    (tmp_path / "sq" / "notes.png").write_bytes(b"\x89PNG")                 # an image without a sidecar
    assert [p.relative_to(tmp_path).as_posix() for p in find_raws([tmp_path])] == ["rx/rtx.png", "sq/lfm.png"]


def test_cli_geometry_rectifies_every_raw_and_is_hashed(tmp_path):
    """``batch --geometry``: the light field of a generated board raw is rectified (straight corner lines);
    the calibration's values enter the task key; a calibration of another shape fails the raw."""
    from plenodecode.io.calinfo import load_geometric_calibration, save_geometric_calibration
    from plenodecode.io.lightfield import load_lightfield
    from tests.geometry_scenes import detect_corners, line_residual_rms, write_board_raw

    files, cal, board = write_board_raw(tmp_path / "in")
    out = tmp_path / "out"
    args = ["-q", "batch", files["raw"], "-o", str(out), "--white", files["white"], "--outputs", "lightfield",
            "--format", "npy"]
    res = CliRunner().invoke(cli, [*args, "--geometry", files["cal"]], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    lf = load_lightfield(next(out.rglob("lightfield.npy")))
    assert lf.geometry.ray_model["rectified"]
    assert line_residual_rms(detect_corners(lf.data[4, 4].mean(axis=-1), board)) < 0.05
    loaded = load_geometric_calibration(files["cal"])
    plain, rectified = BatchOptions(), BatchOptions(geometry=loaded.to_dict())
    assert task_key(files["raw"], plain) != task_key(files["raw"], rectified)
    assert "geometry" not in plain.as_key_dict()
    other = save_geometric_calibration(replace(cal, lf_shape=(11, 11, 70, 69)), tmp_path / "other.json")
    res = CliRunner().invoke(cli, [*args, "--geometry", str(other), "--overwrite"], catch_exceptions=False)
    assert res.exit_code == 1
    summary = json.loads((out / "summary.json").read_text())
    assert "11x11x70x69" in json.dumps(summary)


def test_cli_alpha_fails_a_raw_without_focal_length_before_decoding_and_goes_on(data, tmp_path, monkeypatch):
    """--alpha on a raw whose metadata has no focal length: that raw fails at once (its calibration and decoding
    never start, no folder is written), the batch goes on to the next raw and exits 1 naming the missing constant."""
    from plenodecode.io import lytro
    from plenodecode.pipeline import source
    from plenodecode.synthetic import PRESETS, simulate

    bad = tmp_path / "in" / "nofocal.lfr"
    bad.parent.mkdir()
    lytro.write_lfr(bad, simulate(replace(PRESETS["illum-mini"], focal_length_m=None), seed=6, shape=SHAPE).raw)
    decoded = []
    real = source.decode_raw
    monkeypatch.setattr(source, "decode_raw", lambda raw, *a, **kw: decoded.append(raw.path) or real(raw, *a, **kw))
    out = tmp_path / "out"
    good = data["shoot"] / "take1" / "scene1.lfr"
    res = CliRunner().invoke(cli, ["batch", str(bad), str(good), "-o", str(out), "--database", str(data["db"]),
                                   "--jobs", "1", "--outputs", "refocus", "--alpha", "1.005", "--bit-depth", "8"])
    assert res.exit_code == 1, res.output
    lines = res.stdout.splitlines()
    # the row, summary.json and index.html say it as 'plenodecode refocus' does: the option to use, no class name
    # (they said 'MissingConstantsError: nofocal.lfr: ...; refocus by slope instead')
    said = ("nofocal.lfr: alpha (Ng's film depth -> slope) needs the camera constant focal_length_m, which its "
            "metadata does not have; use --slope S (px per view step) instead")
    row, = [line for line in lines if line.startswith("nofocal.lfr")]
    assert row.split()[1] == "failed" and row.endswith(f"  {said}"), res.stdout
    assert json.loads((out / "summary.json").read_text())["results"][0]["error"] == said
    assert html.escape(said) in (out / "index.html").read_text()
    assert any(line.startswith("scene1.lfr") and " done " in line for line in lines), res.stdout
    assert [Path(p).name for p in decoded] == ["scene1.lfr"]
    assert not (out / "nofocal").exists() and len(list((out / "scene1").glob("refocus_a1.005.png"))) == 1


def test_cli_focus_distance_no_raw_can_serve_is_refused_before_decoding(data, tmp_path, monkeypatch):
    """--focus-distance on raws that cannot turn metres into a slope (one without a focal length, one without the
    distance it was focused at): each failed on its row and the batch wrote a summary of that; now, as no raw can
    serve it, one usage error names --focus-distance and what the first lacks, none is decoded, nothing written."""
    from plenodecode.io import lytro
    from plenodecode.pipeline import source
    from plenodecode.synthetic import PRESETS, simulate

    bad = tmp_path / "in" / "nofocal.lfr"
    bad.parent.mkdir()
    lytro.write_lfr(bad, simulate(replace(PRESETS["illum-mini"], focal_length_m=None), seed=6, shape=SHAPE).raw)
    decoded = []
    monkeypatch.setattr(source, "decode_raw", lambda raw, *a, **kw: decoded.append(raw.path))
    out = tmp_path / "out"
    good = data["shoot"] / "take1" / "scene1.lfr"
    res = CliRunner().invoke(cli, ["batch", str(bad), str(good), "-o", str(out), "--database", str(data["db"]),
                                   "--jobs", "1", "--outputs", "refocus", "--focus-distance", "0.5"])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == (
        "Error: Invalid value for --focus-distance: none of the 2 raws has what it needs (nofocal.lfr, scene1.lfr): "
        "nofocal.lfr has no focal_length_m in its metadata, which a focus distance (metres -> slope) needs; use "
        "--slope S (px per view step) instead")
    assert decoded == [] and not out.exists()


def test_cli_without_a_database_decodes_what_needs_none_and_fails_the_rest_with_the_reason(data, tmp_path,
                                                                                              monkeypatch):
    """No ``calib/`` folder and no ``--database``: a Raytrix raw (its XML is its calibration) is decoded, the
    Lytro raws that need the database fail with what to pass, a damaged ``.lfr`` says it is no Lytro container.
    With only raws that need it, the missing database is a usage error naming --database, before any work."""
    from plenodecode import synthetic
    from tests.cli.test_total_focus import COLOUR_RAYTRIX

    shoot = tmp_path / "mixed"
    sim = synthetic.simulate(COLOUR_RAYTRIX, seed=2, shape=(210, 300), noise=False)
    synthetic.write_simulation(sim, shoot / "raytrix", name="scene")
    shutil.copytree(data["shoot"] / "take1", shoot / "take1")
    (shoot / "damaged.lfr").write_bytes(b"not a container at all")
    monkeypatch.chdir(tmp_path)                                   # no calib/ here
    out = tmp_path / "out"
    # (--views-anyway: the Raytrix raw's centre view, one pixel per lens, is what this test decodes)
    res = CliRunner().invoke(cli, ["batch", str(shoot), "-o", str(out), "--jobs", "1", "--outputs", "centre",
                                   "--views-anyway"])
    assert res.exit_code == 1, res.output
    rows = {Path(r["source"]).name: r for r in json.loads((out / "summary.json").read_text())["results"]}
    assert rows["scene.png"]["status"] == "done"
    centre = out / "scene" / "centre.png"
    assert centre.is_file()
    from plenodecode.io.images import read_image
    assert read_image(centre).std() > 0                            # a picture, not a constant
    assert rows["scene1.lfr"]["status"] == "failed" and (
        f"no calibration database (looked for its index.json in {tmp_path / 'calib'} (the current folder's), then "
        f"calib/ in {shoot / 'take1'} and each folder above it)") in rows["scene1.lfr"]["error"]
    assert "--database DIR" in rows["scene1.lfr"]["error"]
    assert rows["damaged.lfr"]["status"] == "failed" and "not a Lytro container" in rows["damaged.lfr"]["error"]
    # only raws that need the database: refused before any work, nothing written
    res = CliRunner().invoke(cli, ["batch", str(shoot / "take1"), "-o", str(tmp_path / "none")])
    assert res.exit_code == 2 and "--database" in res.output, res.output
    assert f"no calibration database (looked for its index.json in {tmp_path / 'calib'} (the current folder's), then " \
           f"calib/ in {shoot / 'take1'} and each folder above it)" in " ".join(res.output.split())
    assert f"'plenodecode calibrate --database calib {shoot / 'take1'}'" in res.output    # its white images
    assert not (tmp_path / "none").exists()


def test_cli_without_the_default_database_says_how_to_build_it_from_the_whites_beside_the_raws(tmp_path,
                                                                                                 monkeypatch):
    """'plenodecode batch sample_raws -o out' where there is no ./calib said "Invalid value for --database: calib
    is not a folder; build the database with `plenodecode calibrate --database`": an option the user did not type,
    a command without its folder.  It says the default is missing and gives the command that builds it from the
    white images beside the raws, which then lets the same batch decode every raw; --self-calibrate, which the
    single-file error offers, needs no database and is no longer refused."""
    import shlex

    root = Path(__file__).resolve().parents[1]
    samples = tmp_path / "sample_raws"                          # not beside the project's calib/, which is found
    shutil.copytree(root / "sample_raws", samples)
    monkeypatch.chdir(tmp_path)                                   # no calib/ here
    runner = CliRunner()
    res = runner.invoke(cli, ["batch", str(samples), "-o", "out"])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1 and not (tmp_path / "out").exists(), res.output
    assert errors[0].startswith("Error: Invalid value for --database: no calibration database (looked for its "
                                f"index.json in {tmp_path / 'calib'} (the current folder's), then calib/ in "), errors
    assert "and every raw here needs one" in errors[0]
    assert "--self-calibrate" in errors[0] and "--white WHITE_IMAGE" in errors[0]
    command = shlex.split(errors[0].split(" with '", 1)[1].split("'", 1)[0])
    assert command == ["plenodecode", "calibrate", "--database", "calib", str(samples)]
    assert runner.invoke(cli, command[1:]).exit_code == 0
    res = runner.invoke(cli, ["-q", "batch", str(samples), "-o", "out", "--jobs", "1"])
    rows = json.loads((tmp_path / "out" / "summary.json").read_text())["results"]
    assert res.exit_code == 0 and len(rows) == 3 and {r["status"] for r in rows} == {"done"}, res.output

    (tmp_path / "other").mkdir()
    monkeypatch.chdir(tmp_path / "other")                         # no calib/ here either
    res = runner.invoke(cli, ["-q", "batch", str(samples / "illum-mini" / "scene.lfr"), "-o", "out", "--jobs", "1",
                              "--self-calibrate"])
    from plenodecode.io.images import read_image

    photo = read_image(next((tmp_path / "other" / "out" / "scene").glob("*.png")))
    assert res.exit_code == 0 and photo.ndim == 3 and photo.std() > 0, res.output


def test_cli_batch_depth_writes_the_depth_commands_pictures_on_a_real_f01_capture(tmp_path):
    """'batch --outputs depth' wrote only disparity.pfm per raw, which no picture viewer opens, and the index linked
    its thumbnail to that PFM; now the folder holds what 'plenodecode depth' writes (PFM, EXR, colour-mapped PNG and
    the confidence map), pixel for pixel, and the thumbnail opens the PNG. On the real F01 JPEG IMG_2.jpg."""
    from tests.conftest import shared_path

    from plenodecode.io.images import read_image

    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_2.jpg")
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["-q", "batch", str(jpeg), "-o", str(out), "--jobs", "1", "--outputs", "depth"])
    assert res.exit_code == 0, res.output
    folder = out / "IMG_2"
    assert sorted(p.name for p in folder.iterdir() if p.is_file() and p.name != ".done.json") == [
        "disparity.exr", "disparity.pfm", "disparity.png", "disparity_confidence.exr", "disparity_confidence.png"]
    res = CliRunner().invoke(cli, ["-q", "depth", str(jpeg), "-o", str(tmp_path / "d.pfm")])
    assert res.exit_code == 0, res.output
    for name, single in (("disparity.png", "d.png"), ("disparity_confidence.exr", "d_confidence.exr")):
        np.testing.assert_array_equal(read_image(folder / name), read_image(tmp_path / single))
    # the confidence figure's title names its depth PNG (disparity.png, d.png): the same below it
    np.testing.assert_array_equal(read_image(folder / "disparity_confidence.png")[40:],
                                  read_image(tmp_path / "d_confidence.png")[40:])
    png = read_image(folder / "disparity.png")
    assert png.dtype == np.uint8 and png.shape[2] >= 3 and len(np.unique(png.reshape(-1, png.shape[2]), axis=0)) > 200
    page = (out / "index.html").read_text()
    assert '<a href="IMG_2/disparity.png"><img class="legend"' in page


def test_batch_depth_of_a_raytrix_raw_is_the_depth_commands_virtual_depth(tmp_path):
    """'batch --outputs depth' on a focused-plenoptic raw: the same virtual depth map as 'plenodecode depth' (the
    total focus's grid, not the decoded views' one pixel per lens), written as virtual_depth.pfm with its
    colour-mapped thumbnail."""
    from plenodecode import synthetic
    from plenodecode.io.pfm import read_pfm

    sim = synthetic.simulate("raytrix", seed=3, shape=(280, 380), noise=False)
    paths = synthetic.write_simulation(sim, tmp_path / "shoot", name="scene")
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["-q", "batch", str(paths["raw"]), "-o", str(out), "--jobs", "1",
                                   "--outputs", "depth"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    folder = out / "scene"
    assert sorted(p.name for p in folder.glob("*.pfm")) == ["virtual_depth.pfm"]
    assert (folder / "thumbs" / "virtual_depth.png").is_file()
    res = CliRunner().invoke(cli, ["-q", "depth", str(paths["raw"]), "-o", str(tmp_path / "d.pfm")])
    assert res.exit_code == 0, res.output

    def values(path):
        v = read_pfm(path)
        return v[0] if isinstance(v, tuple) else v

    batch, single = values(folder / "virtual_depth.pfm"), values(tmp_path / "d.pfm")
    np.testing.assert_array_equal(batch, single)
    assert batch.shape[0] > 4 * sim.grid.shape[0] and np.isfinite(batch).mean() > 0.9
    # the truth at every output pixel's sensor position q / scale of the total focus
    import cv2

    from plenodecode import pipeline

    scale = pipeline.render_product(pipeline.open_source(paths["raw"]), "total-focus").data["render"].scale
    qy, qx = np.mgrid[0:batch.shape[0], 0:batch.shape[1]].astype(np.float32)
    truth = cv2.remap(sim.truth["virtual_depth"], qx / scale, qy / scale, cv2.INTER_NEAREST)
    assert np.nanmedian(np.abs(batch - truth) / truth) < 0.03


def test_cli_photo_and_refocus_at_the_same_focus_write_one_file(data, tmp_path):
    """'--outputs photo,refocus' failed every raw after decoding it (FileExistsError: both are the photograph
    focused as captured, refocus_s+0.00.png); the image is now written once and listed once."""
    raw = data["shoot"] / "take1" / "scene1.lfr"
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(raw), "-o", str(out), "--jobs", "1", "--database", str(data["db"]),
                                   "--outputs", "photo,refocus"])
    assert res.exit_code == 0, res.output
    folder = out / "scene1"
    assert sorted(p.name for p in folder.glob("*.png")) == ["refocus_s+0.00.png"]
    summary = json.loads((out / "summary.json").read_text())
    assert [Path(o).name for o in summary["results"][0]["outputs"]] == ["refocus_s+0.00.png"]
    single = tmp_path / "single.png"
    assert CliRunner().invoke(cli, [str(raw), "--database", str(data["db"]), "-o", str(single)]).exit_code == 0
    from plenodecode.io.images import read_image

    np.testing.assert_array_equal(read_image(folder / "refocus_s+0.00.png"), read_image(single))


def test_cli_white_images_skipped_on_purpose_are_not_named_as_passed_over(tmp_path):
    """'batch sample_raws/' said 'scene_white.png were not taken: ... name the raw image itself' of the white
    image that its sidecar flags (skipped on purpose); only images skipped for want of a sidecar are named."""
    from plenodecode.synthetic import simulate, write_simulation

    paths = write_simulation(simulate("square", seed=1, shape=(330, 400)), tmp_path / "sq", name="lfm")
    assert Path(paths["white"]).name == "lfm_white.png"
    (tmp_path / "sq" / "notes.png").write_bytes(b"\x89PNG")                 # an image without a sidecar
    res = CliRunner().invoke(cli, ["batch", str(tmp_path / "sq"), "-o", str(tmp_path / "out"), "--jobs", "1",
                                   "--outputs", "centre", "--white", str(paths["white"])])
    assert res.exit_code == 0, res.output
    assert "note: 1 image(s) (notes.png) were not taken" in res.output and "lfm_white" not in res.output
    assert (tmp_path / "out" / "lfm" / "centre.png").is_file()


def test_cli_light_field_folders_are_named_as_light_fields_not_as_images_to_name(tmp_path):
    """'batch ../shared/data' listed the 81 views of the HCI scene among the images 'not taken: ... name the raw
    image itself', and 'batch hci-antinous' said to run 'plenodecode batch hci-antinous/RAW_IMAGE'; a folder of
    views (HCI scene, saved 'views' light field) is now named as a light field, to give to refocus, views or
    depth."""
    from plenodecode.io.lightfield import save_lightfield
    from plenodecode.types import LightField
    from tests.conftest import shared_path

    hci = shared_path("hci-antinous")
    res = CliRunner().invoke(cli, ["batch", str(hci), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2 and "no raws found" in res.output, res.output
    assert f"{hci} is a light field (views), not a raw" in res.output and "RAW_IMAGE" not in res.output
    assert not (tmp_path / "o").exists()
    saved = save_lightfield(LightField(np.zeros((3, 3, 8, 8, 1), np.float32), None, "srgb", {}), tmp_path / "lf",
                            format="views")
    scope = tmp_path / "scope"
    scope.mkdir()
    import cv2

    cv2.imwrite(str(scope / "light_field.png"), np.full((64, 80), 1000, np.uint16))
    res = CliRunner().invoke(cli, ["batch", str(saved), str(scope), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2, res.output
    assert "1 image(s) (light_field.png) were not taken" in res.output
    assert f"{saved} is a light field (views), not a raw" in res.output


def test_a_slope_past_a_raws_picture_fails_that_raw_in_one_line_naming_the_option(tmp_path, caplog):
    """'batch ... --slope 2000' reported 'internal error: ValueError: slope ...' per raw with a logged traceback.
    A bad option value is the user's error: each raw it does not suit fails in one line naming --slope and its
    bound, before decoding; the batch goes on (the real R42's photograph is its total focus, which has no slope)."""
    from tests.conftest import shared_path

    root = Path(__file__).resolve().parents[1]
    jpeg, r42 = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), shared_path("raytrix-r42", "sc2_klein.png")
    illum = root / "sample_raws" / "illum-mini" / "scene.lfr"
    res = CliRunner().invoke(cli, ["batch", str(jpeg), str(illum), str(r42), "-o", str(tmp_path / "out"),
                                   "--slope", "2000", "--database", str(root / "calib"), "--jobs", "1"])
    assert res.exit_code == 1, res.output
    rows = {line.split()[0]: line for line in res.output.splitlines() if line.split()[:1] in
            (["IMG_1.jpg"], ["scene.lfr"], ["sc2_klein.png"])}
    for name, bound in (("IMG_1.jpg", "383 x 382 picture (|slope| <= 95.8 here)"),
                        ("scene.lfr", "87 x 125 picture (|slope| <= 17.9 here)")):
        assert " failed " in rows[name] and f"--slope 2000 does not suit {name}: slope 2000 px/view" in rows[name]
        assert bound in rows[name] and "internal error" not in rows[name], rows[name]
    assert " done " in rows["sc2_klein.png"], res.output
    assert "Traceback" not in res.output + caplog.text and "unexpected error" not in caplog.text


def test_a_slope_past_the_picture_fails_before_decoding(tmp_path, monkeypatch):
    """The slope is checked against the decoded shape the calibration gives, before the raw is decoded; an alpha,
    which failed only when rendered (after decoding), too: the calibration gives the constants that make it a
    slope, in the same one line naming --alpha."""
    from plenodecode import pipeline
    from plenodecode.batch import process_raw

    root = Path(__file__).resolve().parents[1]
    illum = root / "sample_raws" / "illum-mini" / "scene.lfr"
    decoded = []
    real = pipeline.source.decode_raw
    monkeypatch.setattr(pipeline.source, "decode_raw", lambda *a, **k: decoded.append(a) or real(*a, **k))
    (tmp_path / "a").mkdir()
    result = process_raw(illum, tmp_path / "a", BatchOptions(outputs=("refocus",), slope=18.0,
                                                             database=str(root / "calib")))
    assert result.status == "failed" and decoded == [] and list((tmp_path / "a").iterdir()) == []
    assert result.error.startswith("--slope 18 does not suit scene.lfr: slope 18 px/view"), result.error
    (tmp_path / "b").mkdir()
    result = process_raw(illum, tmp_path / "b", BatchOptions(outputs=("refocus",), alpha=1.5,
                                                             database=str(root / "calib")))
    assert result.status == "failed" and decoded == [], result
    assert result.error.startswith("--alpha 1.5 does not suit scene.lfr: slope 20.27 px/view"), result
    ok = process_raw(illum, tmp_path / "b",
                     BatchOptions(outputs=("refocus",), slope=17.5, database=str(root / "calib")))
    assert ok.status == "done", ok


def test_cli_raws_of_one_file_name_are_told_apart_in_the_table_and_the_index(tmp_path):
    """Two raws named scene.lfr (folders a/ and b/) were both 'scene.lfr' in the terminal table and on the index
    page, while their outputs went to a__scene and b__scene: now each is named by as many of its last folders as
    tell it apart, and a raw whose name is unique keeps its bare file name."""
    import re
    import shutil

    root = Path(__file__).resolve().parents[1]
    illum, f01 = root / "sample_raws" / "illum-mini" / "scene.lfr", root / "sample_raws" / "f01-mini" / "scene.lfp"
    shoot = tmp_path / "shoot"
    for folder in ("a", "b"):
        (shoot / folder).mkdir(parents=True)
        shutil.copy(illum, shoot / folder / "scene.lfr")
    shutil.copy(f01, shoot / "scene.lfp")
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(shoot), "-o", str(out), "--database", str(root / "calib"),
                                   "--jobs", "1"])
    assert res.exit_code == 0, res.output
    rows = [line.split()[0] for line in res.output.splitlines() if " done " in line]
    assert sorted(rows) == ["a/scene.lfr", "b/scene.lfr", "scene.lfp"], res.output
    page = (out / "index.html").read_text()
    shown = dict(re.findall(r'class="name" title="([^"]+)">([^<]+)<', page))
    assert shown == {str(shoot / "a" / "scene.lfr"): "a/scene.lfr", str(shoot / "b" / "scene.lfr"): "b/scene.lfr",
                     str(shoot / "scene.lfp"): "scene.lfp"}
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["a__scene", "b__scene", "scene"]


def test_cli_exposure_brightens_the_views_folder_as_the_views_command_does(tmp_path):
    """'batch --outputs views --exposure auto' wrote the views (and their thumbnail) as decoded, dark for the ant
    leg, while centre.png beside them was brightened; now the views take the gain 'plenodecode views' takes (from
    the centre view): the centre view's brightest 0.5 % reach full scale as centre.png's do."""
    from tests.conftest import shared_path
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float

    scope = shared_path("lf-microscopy-antleg")
    base = ["batch", str(scope / "light_field.png"), "-w", str(scope / "radiometry_frame.png"), "--dark",
            str(scope / "dark_frame.tif"), "--outputs", "centre,views", "--jobs", "1"]
    level = {}
    for exposure in ("0", "auto"):
        out = tmp_path / exposure / "light_field"
        res = CliRunner().invoke(cli, base + ["-o", str(out.parent), "--exposure", exposure])
        assert res.exit_code == 0, res.output
        names = sorted(p.name for p in (out / "views").glob("view_*.png"))
        v, u = (int(n) // 2 for n in names[-1][5:-4].split("_"))      # view_VV_UU of the last one: V-1, U-1
        centre_view = out / "views" / f"view_{v:02d}_{u:02d}.png"
        level[exposure] = [float(np.percentile(srgb_decode(to_unit_float(read_image(p))), 99.5))
                           for p in (centre_view, out / "centre.png", out / "thumbs" / "views.png")]
    assert max(level["0"]) < 0.25 and min(level["auto"]) > 0.9, level


def test_cli_a_slope_past_every_raws_picture_is_refused_up_front_before_decoding(tmp_path, monkeypatch):
    """'batch ... --slope 2000' decoded nothing but still ran every raw into a per-raw failure.  A slope that
    suits none of the raws is a usage error before any raw is decoded, in the line 'plenodecode refocus' gives
    (of the raw allowing the most); one that suits some raws runs them and fails the rest per raw."""
    from plenodecode import pipeline

    root = Path(__file__).resolve().parents[1]
    raws = [str(root / "sample_raws" / "illum-mini" / "scene.lfr"), str(root / "sample_raws" / "square")]
    decoded = []
    real = pipeline.source.decode_raw
    monkeypatch.setattr(pipeline.source, "decode_raw", lambda *a, **k: decoded.append(a) or real(*a, **k))
    out = tmp_path / "out"
    base = ["batch", *raws, "-o", str(out), "--database", str(root / "calib"), "--jobs", "1"]
    single = CliRunner().invoke(cli, ["refocus", raws[0], "-o", str(tmp_path / "r.png"), "--slope", "2000",
                                      "--database", str(root / "calib")])
    line = single.stderr.strip().splitlines()[-1]
    decoded.clear()
    res = CliRunner().invoke(cli, [*base, "--slope", "2000"])
    assert res.exit_code == 2, res.output
    assert line.startswith("Error: Invalid value for --slope: slope 2000 px/view") and "(|slope| <= 17.9 here)" in line
    assert res.stderr.strip().splitlines()[-1] == f"{line} (every one of the 2 raws; scene.lfr allows the most)"
    assert decoded == [] and not out.exists()
    # a slope within one raw's picture only: that raw is decoded, the other fails in its line
    res = CliRunner().invoke(cli, [*base, "--slope", "12", "--outputs", "refocus"])
    # both raws are 'scene': the rows name their folders, as the output folders do
    rows = {line.split()[0]: line for line in res.stdout.splitlines() if "/scene." in line}
    assert res.exit_code == 1 and " done " in rows["illum-mini/scene.lfr"], res.output
    square = rows["square/scene.png"]
    assert " failed " in square and "--slope 12 does not suit scene.png" in square, rows
    # an alpha past the picture, too (it decoded every raw first): the line 'plenodecode refocus --alpha' gives
    single = CliRunner().invoke(cli, ["refocus", raws[0], "-o", str(tmp_path / "a.png"), "--alpha", "5",
                                      "--database", str(root / "calib")])
    decoded.clear()
    res = CliRunner().invoke(cli, ["batch", raws[0], "-o", str(tmp_path / "alpha"), "--database", str(root / "calib"),
                                   "--jobs", "1", "--outputs", "refocus", "--alpha", "5"])
    assert res.exit_code == 2 and decoded == [] and not (tmp_path / "alpha").exists(), res.output
    expected = ("Error: Invalid value for --alpha: slope 48.66 px/view moves the outermost views 341 px, past the "
                "whole 87 x 125 picture (|slope| <= 17.9 here): no view would overlap the centre one; refocus within "
                "the refocusable range")
    refocus_line = single.stderr.strip().splitlines()[-1].replace("--refocus / --alpha", "--alpha")
    assert res.stderr.strip().splitlines()[-1] == refocus_line == expected, res.stderr


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_cli_warnings_of_each_raw_name_it(tmp_path, jobs):
    """Warnings printed by the batch's workers did not say which raw they were about ('slope 1.5 px/view is
    outside the refocusable range ...' twice, once per raw, interleaved).  Each now starts with the raw's name,
    in this process (--jobs 1) and from the worker processes (--jobs 2)."""
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    res = subprocess.run([sys.executable, "-m", "plenodecode", "batch", str(root / "sample_raws" / "illum-mini"),
                          str(root / "sample_raws" / "square"), "-o", str(tmp_path / "out"), "--database",
                          str(root / "calib"), "--outputs", "refocus", "--slope", "1.5", "--jobs", jobs],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    lines = [line for line in res.stderr.splitlines() if "outside the refocusable range" in line]
    assert len(lines) == 2, res.stderr
    assert sorted(line.split("warning: ")[-1].split(":")[0] for line in lines) == \
        ["scene.lfr", "scene.png"]
    assert any("scene.png: slope 1.5 px/view is outside the refocusable range (slope -1.00..+1.00" in line
               for line in lines), lines


def test_cli_a_folder_that_appears_after_the_up_front_check_fails_its_raw_naming_only_the_option(data, tmp_path,
                                                                                                   monkeypatch):
    """A raw's output folder made after the up-front check (another process, between the check and its task) failed
    the raw with 'pass --overwrite (overwrite=True) to replace it' in the table, summary.json and index.html: the
    library's keyword beside the option.  The command's outputs now name --overwrite only; the others are done."""
    import plenodecode.batch as batch

    out = tmp_path / "out"
    check = batch.check_outputs_to_replace
    calls = []

    def check_then_a_folder_appears(*args, **kwargs):      # the command's check, then run_batch's
        check(*args, **kwargs)
        calls.append(1)
        if len(calls) == 2:
            (out / "scene2").mkdir(parents=True)
            (out / "scene2" / "notes.txt").write_text("someone else's")

    monkeypatch.setattr(batch, "check_outputs_to_replace", check_then_a_folder_appears)
    res = CliRunner().invoke(cli, ["batch", str(data["shoot"]), "-o", str(out), "--database", str(data["db"]),
                                   "--jobs", "1", "--outputs", "centre", "--bit-depth", "8"])
    assert res.exit_code == 1 and "2 done, 0 skipped, 1 failed" in res.stdout, res.output
    row = next(line for line in res.stdout.splitlines() if line.startswith("scene2"))
    assert row.endswith(f"{out / 'scene2'} exists and was not written by a batch run; pass --overwrite to replace it")
    summary = json.loads((out / "summary.json").read_text())
    errors = [r["error"] for r in summary["results"] if r["error"]]
    assert len(errors) == 1 and errors[0].endswith("pass --overwrite to replace it"), errors
    page = (out / "index.html").read_text()
    assert "overwrite=True" not in res.output + json.dumps(summary) + page and "pass --overwrite" in page
    assert (out / "scene2" / "notes.txt").read_text() == "someone else's"


def test_cli_folders_that_appear_before_the_run_starts_are_refused_as_the_up_front_check_refuses_them(
        data, tmp_path, monkeypatch):
    """A folder made between the command's check and run_batch's own said 'error: cannot use OUT: 1 of 3 raws
    already have ... pass --overwrite (overwrite=True) ... or choose another output folder' (as if the folder were
    unreachable; exit 1).  It is now the up-front refusal's usage error, in the option names, nothing decoded."""
    import plenodecode.batch as batch

    out = tmp_path / "out"
    check = batch.check_outputs_to_replace

    def check_then_a_folder_appears(*args, **kwargs):
        check(*args, **kwargs)
        (out / "scene2").mkdir(parents=True, exist_ok=True)

    monkeypatch.setattr(batch, "check_outputs_to_replace", check_then_a_folder_appears)
    res = CliRunner().invoke(cli, ["batch", str(data["shoot"]), "-o", str(out), "--database", str(data["db"]),
                                   "--jobs", "1", "--outputs", "centre"])
    assert res.exit_code == 2, res.output
    assert res.stderr.strip().splitlines()[-1] == (
        f"Error: 1 of 3 raws already have an output folder in {out} (scene2) from a run with other options or "
        "inputs, or not from a batch; pass --overwrite to replace them, or choose another -o folder"), res.stderr
    assert "decoding" not in res.stderr and sorted(p.name for p in out.iterdir()) == ["scene2"]


@pytest.mark.slow
def test_cli_compile_notice_of_the_workers_appears_once(tmp_path):
    """A first batch (kernels not in the cache yet) with --jobs 2 said nothing while its workers compiled the
    calibration and depth kernels (their notices went to each worker's log, shown only with -v, then once per
    worker): its first task took ~10 s longer with no word why.  The workers now relay each group to the command,
    which says it once, as the single-file path does."""
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    res = subprocess.run([sys.executable, "-m", "plenodecode", "batch", str(root / "sample_raws" / "illum-mini"),
                          str(root / "sample_raws" / "f01-mini"), "-o", str(tmp_path / "out"), "--database",
                          str(root / "calib"), "--outputs", "depth", "--jobs", "2"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert res.returncode == 0, res.stderr
    notices = [line for line in res.stderr.splitlines() if line.startswith("compiling ")]
    assert notices.count("compiling depth kernels (first run only, ~4 s)...") == 1, res.stderr
    assert len(notices) == len(set(notices)), notices
    assert len(json.loads((tmp_path / "out" / "summary.json").read_text())["results"]) == 2


def test_cli_a_focal_stack_no_raw_can_use_is_refused_before_any_work(tmp_path):
    """'batch --outputs focal-stack --focal-stack 30:40:3' over the Illum sample (|slope| <= 17.9) failed each raw
    after reading and calibrating it.  A stack past every raw's picture is now refused up front, in one line naming
    --focal-stack, as --slope is; nothing is written.  A stack one raw can use goes on."""
    root = Path(__file__).resolve().parents[1]
    illum = root / "sample_raws" / "illum-mini" / "scene.lfr"
    base = ["batch", str(illum), "--outputs", "focal-stack", "--database", str(root / "calib"), "--jobs", "1"]
    res = CliRunner().invoke(cli, [*base, "--focal-stack", "30:40:3", "-o", str(tmp_path / "bad")])
    assert res.exit_code == 2, res.output
    err = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(err) == 1 and "--focal-stack" in err[0] and "(|slope| <= 17.9 here)" in err[0], res.output
    assert not (tmp_path / "bad").exists()
    res = CliRunner().invoke(cli, [*base, "--focal-stack", "-2:2:3", "-o", str(tmp_path / "ok")])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "ok" / "scene" / "focal_stack").glob("*.png"))) >= 3


def test_cli_a_synthetic_raytrix_raw_beside_a_lytro_one_leaves_out_only_its_views(tmp_path):
    """The sample raws: a synthetic Raytrix raw beside the Illum sample, --outputs photo,centre: the Raytrix raw is
    done with its total focus, 'centre' left out on its row; alone, 'centre' is refused before any work."""
    from plenodecode import synthetic
    from tests.cli.test_total_focus import COLOUR_RAYTRIX

    root = Path(__file__).resolve().parents[1]
    synthetic.write_simulation(synthetic.simulate(COLOUR_RAYTRIX, seed=2, shape=(210, 300), noise=False),
                               tmp_path / "rx", name="rtx")
    illum = root / "sample_raws" / "illum-mini" / "scene.lfr"
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(tmp_path / "rx"), str(illum), "-o", str(out), "--outputs",
                                   "photo,centre", "--database", str(root / "calib"), "--jobs", "1"])
    assert res.exit_code == 1, res.output
    row = [line for line in res.output.splitlines() if line.startswith("rtx.png")]
    assert len(row) == 1 and " done " in row[0] and "1 output; centre: not for a focused-plenoptic" in row[0], row
    assert [p.name for p in (out / "rtx").glob("*.png")] == ["total_focus.png"]
    assert sorted(p.name for p in (out / "scene").glob("*.png")) == ["centre.png", "refocus_s+0.00.png"]
    res = CliRunner().invoke(cli, ["batch", str(tmp_path / "rx"), "-o", str(tmp_path / "none"), "--outputs",
                                   "photo,centre"])
    assert res.exit_code == 2 and "Invalid value for --outputs: centre: no raw here can serve it" in res.output
    assert not (tmp_path / "none").exists()


def test_cli_quiet_batch_workers_keep_their_warnings(tmp_path):
    """'plenodecode batch F01_JPEGS -o out --jobs 2 -q' printed every worker's warnings ('IMG_1.jpg: no JSON
    sidecar ...'): the workers start with no logging set up, and Python's last-resort handler prints warnings whatever
    the command's level.  They now log at the command's level and in its format: nothing with -q; without it the
    command's 'warning: <raw>: ...' lines (the form of its 'note:' and 'error:' lines; 'WARNING plenodecode.<module>:'
    before, which the module's name only is now shown with -v)."""
    from tests.conftest import shared_path

    folder = shared_path("lytro-f01-lenslet-jpg")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    base = [sys.executable, "-m", "plenodecode", "batch", str(folder), "--outputs", "centre", "--jobs", "2"]
    quiet = subprocess.run([*base, "-o", str(tmp_path / "q"), "-q"], capture_output=True, text=True, env=env,
                           timeout=600)
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == "", quiet.stderr
    assert (tmp_path / "q" / "IMG_1" / "centre.png").is_file() and (tmp_path / "q" / "IMG_2" / "centre.png").is_file()
    loud = subprocess.run([*base, "-o", str(tmp_path / "l")], capture_output=True, text=True, env=env, timeout=600)
    warnings = [line for line in loud.stderr.splitlines() if "no JSON sidecar" in line]
    assert loud.returncode == 0 and len(warnings) == 2, loud.stderr
    assert all(line.startswith("warning: IMG_") for line in warnings), warnings
    verbose = subprocess.run([*base, "-o", str(tmp_path / "v"), "-v"], capture_output=True, text=True, env=env,
                             timeout=600)
    named = [line for line in verbose.stderr.splitlines() if "no JSON sidecar" in line]
    assert verbose.returncode == 0 and len(named) == 2, verbose.stderr
    assert all(line.startswith("warning plenodecode.io.generic: IMG_") for line in named), named


def test_a_failed_row_says_the_message_and_keeps_the_class_only_for_a_bug(tmp_path, monkeypatch):
    """A raw's row gave the Python class first ('FileNotFoundError: [Errno 2] No such file or directory: ...'). The
    library's errors and OSErrors now read as 'plenodecode RAW' prints them after 'error:' (a raw removed after
    the batch listed it: 'No such file or directory: PATH'); an unexpected exception (a bug) keeps its class, after
    'internal error: ', as the clue for a bug report."""
    from plenodecode import pipeline
    from plenodecode.batch import process_raw

    root = Path(__file__).resolve().parents[1]
    gone = tmp_path / "gone.lfr"
    (tmp_path / "out").mkdir()
    options = BatchOptions(outputs=("centre",), database=str(root / "calib"))
    result = process_raw(gone, tmp_path / "out", options)
    assert result.status == "failed" and result.error == f"No such file or directory: {gone}", result.error

    def bug(*args, **kwargs):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(pipeline, "open_raw", bug)
    result = process_raw(root / "sample_raws" / "illum-mini" / "scene.lfr", tmp_path / "out", options)
    assert result.error == "internal error: ZeroDivisionError: division by zero", result.error


def test_index_card_notes_a_dark_first_picture_as_the_terminal_does(tmp_path):
    """The index page had no word on a raw whose pictures are dark (the terminal notes it): its card now says the
    terminal's sentence (one helper, :func:`plenodecode.pipeline.dark_note`), naming the picture measured but not
    the raw (the card is titled by it); not for a bright picture, nor without a measured one (a failed raw)."""
    from plenodecode.report.batch import render_batch_index

    results = (TaskResult(str(tmp_path / "dim.lfr"), "done", level=0.104, level_of="views"),
               TaskResult(str(tmp_path / "bright.lfr"), "done", level=0.6, level_of="photo"),
               TaskResult(str(tmp_path / "bad.lfr"), "failed", error="bad.lfr is not an LFP container"))
    page = render_batch_index(BatchSummary(results=results), tmp_path)
    said = ("note: the centre view is dark (its brightest 0.5 % reach 10 % of full scale, in linear light); "
            "--exposure auto brightens it to full scale, --exposure 2 by two stops")
    assert page.count('class="note"') == 1 and f'<div class="note">{html.escape(said)}</div>' in page
    assert results[0].dark_note("dim.lfr") == said.removeprefix("note: ").replace("view is", "view of dim.lfr is")


@pytest.mark.parametrize("level_of, level_file, what", [
    ("photo", "refocus_s+0.00.png", "refocus_s+0.00.png"), ("photo", "total_focus.png", "total_focus.png"),
    ("views", "views/", "the centre view of views/"),
    ("focal-stack", "focal_stack/", "the middle slice of focal_stack/"),
    ("parallax", "parallax.gif", "the middle frame of parallax.gif"), ("photo", None, "the photo")])
def test_dark_note_names_the_picture_as_the_card_captions_it(tmp_path, level_of, level_file, what):
    """The card under a thumbnail captioned 'refocus_s+0.00.png' said 'the photo is dark': the note names the file
    measured as the caption does (the picture it holds for a folder or an animation); a result written before
    level_file (None) keeps naming the product."""
    from plenodecode.report.batch import render_batch_index

    r = TaskResult(str(tmp_path / "dim.lfr"), "done", level=0.104, level_of=level_of, level_file=level_file)
    tail = " is dark (its brightest 0.5 % reach 10 % of full scale, in linear light); --exposure auto brightens it"
    assert r.dark_note().startswith(what + tail) and r.dark_note("dim.lfr").startswith(f"{what} of dim.lfr{tail}")
    page = render_batch_index(BatchSummary(results=(r,)), tmp_path)
    assert f'<div class="note">note: {html.escape(what + tail)}' in page


def test_cli_a_damaged_containers_warning_is_said_once_naming_the_raw(tmp_path):
    """A container of version 0 beside a good raw: its 'container version 0' warning came three times, twice from
    the discovery's probes of the headers (is it a Lytro Desktop export?) before 'decoding 2 raws' and once from its
    task as 'corrupt.lfr: /tmp/.../corrupt.lfr: container version 0 ...'.  Now once, from the task, by its name."""
    import shutil

    root = Path(__file__).resolve().parents[1]
    shoot = tmp_path / "shoot"
    shoot.mkdir()
    (shoot / "corrupt.lfr").write_bytes(b"\x89LFP\r\n\x1a\n" + bytes(64))
    shutil.copy(root / "sample_raws" / "illum-mini" / "scene.lfr", shoot / "scene.lfr")
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "plenodecode", "batch", str(shoot), "-o", str(tmp_path / "out"),
                          "--outputs", "centre", "--database", str(root / "calib"), "--jobs", "1"],
                         capture_output=True, text=True)
    assert res.returncode == 1, res.stderr                   # the damaged raw fails, the other is decoded
    said = [line for line in res.stderr.splitlines() if "container version 0" in line]
    assert said == ["warning: corrupt.lfr: container version 0 (expected 1); reading anyway"], res.stderr
    assert (tmp_path / "out" / "scene" / "centre.png").is_file()


def test_cli_a_file_that_is_no_image_leaves_no_openimageio_message_at_exit(tmp_path):
    """A text file named notes.png beside a raw: the discovery's probe of its header (a known sensor's size?) left
    OpenImageIO's error pending, and the command ended with 'OpenImageIO exited with a pending error message that
    was never retrieved ... Not a PNG file'.  Now the probe takes the error; the raw is decoded and nothing else said."""
    import shutil
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    shoot = tmp_path / "shoot"
    shoot.mkdir()
    (shoot / "notes.png").write_text("not a picture\n")
    shutil.copy(root / "sample_raws" / "illum-mini" / "scene.lfr", shoot / "scene.lfr")
    res = subprocess.run([sys.executable, "-m", "plenodecode", "batch", str(shoot), "-o", str(tmp_path / "out"),
                          "--outputs", "centre", "--database", str(root / "calib"), "--jobs", "1"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    # OpenImageIO printed it on stdout
    assert "pending error" not in res.stdout + res.stderr, (res.stdout, res.stderr)
    assert (tmp_path / "out" / "scene" / "centre.png").is_file()
