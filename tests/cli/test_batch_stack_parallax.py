"""'plenodecode batch --outputs focal-stack,parallax' and '--outputs depth --metric --ply': the files 'refocus
--focal-stack', 'parallax' and 'depth' write, pixel for pixel, inside each raw's folder, with thumbnails and the index;
their options named as the single commands name them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.batch import BatchOptions
from plenodecode.cli.main import cli
from plenodecode.io.images import read_image
from tests.conftest import ROOT, shared_path

RAW = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
DB = ["--database", str(ROOT / "calib")]


def _invoke(args) -> None:
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, (res.output, res.exception)


def _sharpness(path) -> float:
    import cv2

    img = read_image(path).astype(np.float32)
    return float(cv2.Laplacian(img.mean(-1) if img.ndim == 3 else img, cv2.CV_32F).var())


def test_batch_focal_stack_and_parallax_are_the_single_commands_files(tmp_path):
    _invoke(["refocus", RAW, "--focal-stack", "-1:1:5", "-o", tmp_path / "stack", *DB])
    _invoke(["parallax", RAW, "--frames", "6", "--fps", "5", "--radius", "2", "-o", tmp_path / "p.gif", *DB])
    _invoke(["batch", RAW, "-o", tmp_path / "b", "--outputs", "focal-stack,parallax", "--focal-stack", "-1:1:5",
             "--frames", "6", "--fps", "5", "--radius", "2", "-j", "1", *DB])
    out = tmp_path / "b" / "scene"
    names = sorted(p.name for p in (tmp_path / "stack").iterdir())
    assert sorted(p.name for p in (out / "focal_stack").iterdir()) == names
    assert len([n for n in names if n.startswith("slice_")]) == 5
    for name in names:
        if name.endswith(".png"):
            np.testing.assert_array_equal(read_image(out / "focal_stack" / name), read_image(tmp_path / "stack" / name))
    assert json.loads((out / "focal_stack" / "focal_stack.json").read_text())["slopes"] == [-1, -0.5, 0, 0.5, 1]
    from PIL import Image

    with Image.open(out / "parallax.gif") as gif, Image.open(tmp_path / "p.gif") as ref:
        assert gif.n_frames == ref.n_frames == 6
        assert gif.info["duration"] == ref.info["duration"] == 200          # 5 fps
    frames = sorted(p.name for p in (out / "parallax_frames").iterdir())
    assert frames == [f"frame_{i:03d}.png" for i in range(6)]
    for name in frames:
        np.testing.assert_array_equal(read_image(out / "parallax_frames" / name),
                                      read_image(tmp_path / "p_frames" / name))
    assert {p.name for p in (out / "thumbs").iterdir()} == {"focal_stack.png", "parallax.png"}
    index = (tmp_path / "b" / "index.html").read_text()
    assert "scene/thumbs/focal_stack.png" in index and "scene/thumbs/parallax.png" in index
    marker = json.loads((out / ".done.json").read_text())
    assert marker["outputs"] == ["focal_stack", "parallax.gif", "parallax_frames"]
    assert marker["options"]["focal_stack"] == [-1.0, 1.0, 5] and marker["options"]["frames"] == 6


def test_batch_no_frames_writes_only_the_animation(tmp_path):
    _invoke(["batch", RAW, "-o", tmp_path / "b", "--outputs", "parallax", "--frames", "4", "--no-frames",
             "--bit-depth", "32", "-j", "1", *DB])
    out = tmp_path / "b" / "scene"
    assert sorted(p.name for p in out.iterdir()) == [".done.json", "parallax.gif", "thumbs"]


def test_batch_focal_stack_spans_the_refocusable_range_of_a_real_capture(tmp_path):
    """Without --focal-stack: 9 slopes over the raw's refocusable range (Lytro F01: +-1.15 px/view); the slice focused
    as captured (slope 0) is the sharpest, the ends of the range many times softer (measured 8x and 30x)."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    _invoke(["batch", jpeg, "-o", tmp_path / "b", "--outputs", "focal-stack", "-j", "1", *DB])
    stack = tmp_path / "b" / "IMG_1" / "focal_stack"
    slopes = json.loads((stack / "focal_stack.json").read_text())["slopes"]
    assert len(slopes) == 9 and slopes[0] == pytest.approx(-1.15, abs=0.01) and slopes[-1] == -slopes[0]
    sharp = [_sharpness(stack / f"slice_{i:03d}.png") for i in range(9)]
    assert int(np.argmax(sharp)) == 4
    assert max(sharp[0], sharp[-1]) < 0.3 * sharp[4], sharp
    assert (tmp_path / "b" / "IMG_1" / "thumbs" / "focal_stack.png").is_file()


BAD = [(["--focal-stack", "0:1:1"], "--focal-stack"), (["--focal-stack", "1:2"], "--focal-stack"),
       (["--stack-units", "alpha"], "--stack-units"), (["--bit-depth", "32"], "--bit-depth"),
       (["--frames", "0"], "--frames"), (["--radius", "-1"], "--radius"), (["--fps", "0"], "--fps"),
       (["--interp", "nearest"], "--interp"),
       (["--focal-stack", "0.9:-1:3", "--stack-units", "alpha"], "--focal-stack")]


@pytest.mark.parametrize("args, option", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_batch_refuses_bad_stack_and_parallax_values_naming_the_option(tmp_path, args, option):
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(tmp_path / "b"), "--outputs", "focal-stack,parallax",
                                   *args, "-j", "1", *DB])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1 and option in errors[0], res.output
    assert not list(tmp_path.iterdir())


def test_batch_fails_a_raw_whose_view_grid_the_radius_or_stack_does_not_suit(tmp_path):
    """A --radius past the raw's view grid fails that raw (known once decoded); a --focal-stack past every raw's
    picture is refused before any work (usage error), as --slope is."""
    for args, code, text in (
            (["--radius", "50"], 1, "--radius 50 does not suit scene.lfr: radius must be within [0, 7]"),
            (["--focal-stack", "-100:100:3"], 2, "Invalid value for --focal-stack: slope 100 px/view")):
        out = tmp_path / args[0].strip("-")
        res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(out), "--outputs", "focal-stack,parallax", *args,
                                       "-j", "1", *DB])
        assert res.exit_code == code and text in res.output, res.output
        assert not (out / "scene").exists()


@pytest.mark.parametrize("kwargs, keyword", [
    ({"focal_stack": (0, 1, 1)}, "focal_stack"), ({"focal_stack": (0, 1)}, "focal_stack"),
    ({"stack_units": "alpha"}, "stack_units"), ({"frames": 0}, "frames"), ({"radius": -1}, "radius"),
    ({"fps": 0}, "fps"), ({"interp": "nearest"}, "interp"),
    ({"outputs": ("parallax",), "bit_depth": 32}, "bit_depth")])
def test_batch_options_name_the_bad_keyword(kwargs, keyword):
    with pytest.raises(ValueError) as err:
        BatchOptions(**kwargs)
    assert str(err.value).split()[0] == keyword, str(err.value)


def test_stack_and_parallax_options_key_only_their_outputs():
    """A run without these outputs keeps the task keys of earlier versions; with them, their options are keyed."""
    assert BatchOptions(frames=6, focal_stack=(0, 1, 3)).as_key_dict() == BatchOptions().as_key_dict()
    keyed = BatchOptions(outputs=("focal-stack", "parallax"), frames=6, focal_stack=(0, 1, 3)).as_key_dict()
    assert keyed["frames"] == 6 and keyed["focal_stack"] == [0.0, 1.0, 3]


def test_batch_metric_depth_and_point_cloud_are_the_depth_commands(tmp_path):
    """'batch --metric --ply --depth-focus-distance 0.5' writes depth.pfm and depth.ply equal to 'depth --metric --ply
    --focus-distance 0.5' (illum-mini's metadata has no focus distance: measured depths 0.41-0.58 m); without the
    distance, as no raw has it, one usage error names --metric and --depth-focus-distance, and nothing is written."""
    from plenodecode.io.depthio import read_ply
    from plenodecode.io.pfm import read_pfm

    _invoke(["depth", RAW, "-o", tmp_path / "d" / "z.pfm", "--metric", "--ply", tmp_path / "d" / "z.ply", "--method",
             "fast", "--focus-distance", "0.5", *DB])
    _invoke(["batch", RAW, "-o", tmp_path / "b", "--outputs", "depth", "--metric", "--ply", "--depth-method", "fast",
             "--depth-focus-distance", "0.5", "-j", "1", *DB])
    out = tmp_path / "b" / "scene"
    z = read_pfm(out / "depth.pfm")
    np.testing.assert_array_equal(z, read_pfm(tmp_path / "d" / "z.pfm"))
    lo, hi = np.nanpercentile(z, [2, 98])
    assert 0.35 < lo < hi < 0.65, (lo, hi)
    points, colours = read_ply(out / "depth.ply")
    ref_points, ref_colours = read_ply(tmp_path / "d" / "z.ply")
    np.testing.assert_array_equal(points, ref_points)
    np.testing.assert_array_equal(colours, ref_colours)
    assert len(points) > 0.5 * z.size
    assert json.loads((out / ".done.json").read_text())["outputs"] == [
        "depth.pfm", "depth.png", "depth_confidence.png", "depth_confidence.exr", "depth.ply", "depth.exr"]
    assert (out / "thumbs" / "depth.png").is_file()
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(tmp_path / "c"), "--outputs", "depth", "--metric",
                                   "-j", "1", *DB])
    assert res.exit_code == 2 and res.output.strip().splitlines()[-1] == (   # its only raw: refused before work
        "Error: Invalid value for --metric: scene.lfr has no focus_distance_m in its metadata, which metric depth "
        "needs; use --depth-focus-distance METRES (the distance in focus) instead")
    assert not (tmp_path / "c").exists()


def test_batch_options_refuse_a_bad_depth_focus_distance():
    with pytest.raises(ValueError, match="^depth_focus_distance must be"):
        BatchOptions(depth_focus_distance=-1)
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", "unused", "--depth-focus-distance", "0"])
    assert res.exit_code == 2 and "--depth-focus-distance" in res.output
