"""Raytrix raws through the command line (issue 18, items 2 and 7): where the RayCalibData XML comes from
(same stem, the only XML in the folder, --raytrix-xml, an ambiguity named), colour kept, total focus and a
refocus at a virtual depth, decode's one-line refusal of a focused raw, batch; and the real R42 crop."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import pipeline, synthetic
from plenodecode.cli.main import cli
from plenodecode.decoding.focused import render_focused
from plenodecode.io.images import read_image
from plenodecode.io.raytrix import read_raytrix_linear_rgb
from tests.cli.test_total_focus import COLOUR_RAYTRIX, srgb_to_linear
from tests.conftest import shared_path


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def error_lines(res) -> list[str]:
    return [line for line in res.output.splitlines() if line.lower().startswith("error:")]


def channels_differ(image: np.ndarray) -> float:
    """Smallest mean absolute difference between two channels of an (H, W, 3) image, relative to its mean."""
    x = image.astype(np.float64)
    pairs = [(0, 1), (1, 2), (0, 2)]
    return min(float(np.mean(np.abs(x[..., a] - x[..., b]))) for a, b in pairs) / float(x.mean())


@pytest.fixture(scope="module")
def shoot(tmp_path_factory):
    """A small colour Raytrix-like raw with its RayCalibData XML and JSON sidecar (and its white image's)."""
    sim = synthetic.simulate(COLOUR_RAYTRIX, seed=2, shape=(210, 300), noise=False)
    folder = tmp_path_factory.mktemp("raytrix") / "shoot"
    paths = synthetic.write_simulation(sim, folder, name="scene")
    return paths


def copy_raw(shoot, folder, xml_names=(), other_xml=()):
    """``folder/scene.png`` (+ its sidecar) with the raw's RayCalibData copied under ``xml_names`` and
    non-calibration XMLs ``other_xml``."""
    folder.mkdir()
    raw = folder / "scene.png"
    shutil.copy(shoot["raw"], raw)
    shutil.copy(shoot["raw_json"], folder / "scene.json")
    for name in xml_names:
        shutil.copy(shoot["raw_xml"], folder / name)
    for name in other_xml:
        (folder / name).write_text("<Settings><exposure>10</exposure></Settings>\n")
    return raw


def assert_refused_as_focused(res, raw) -> None:
    """decode's one line: the XML was found (the grid has lens types) and the raw is focused-plenoptic."""
    assert res.exit_code == 2, res.output
    err = error_lines(res)
    assert len(err) == 1 and "focused-plenoptic" in err[0]
    assert f"plenodecode render {raw} --total-focus" in err[0] and "--views-anyway" in err[0]


def test_xml_beside_the_image_by_stem(shoot, tmp_path):
    # the generator's folder holds two XMLs (scene.xml, scene_white.xml): the stem decides
    res = run("decode", shoot["raw"], "-o", tmp_path / "lf.zarr")
    assert_refused_as_focused(res, shoot["raw"])
    assert not (tmp_path / "lf.zarr").exists()


def test_the_only_xml_in_the_folder(shoot, tmp_path):
    raw = copy_raw(shoot, tmp_path / "only", xml_names=["camera_calibration.xml"], other_xml=["notes.xml"])
    assert_refused_as_focused(run("decode", raw, "-o", tmp_path / "lf.zarr"), raw)
    out = tmp_path / "tf.png"
    res = run("render", raw, "--total-focus", "-o", out)
    assert res.exit_code == 0, res.output
    png = read_image(out)
    assert png.ndim == 3 and png.shape[2] == 3 and channels_differ(png) > 0.05        # colour, not grey


def test_two_xmls_are_ambiguous_until_raytrix_xml_names_one(shoot, tmp_path):
    raw = copy_raw(shoot, tmp_path / "two", xml_names=["a.xml", "b.xml"])
    res = run("decode", raw, "-o", tmp_path / "lf.zarr")
    err = error_lines(res)
    assert res.exit_code == 1 and len(err) == 1
    assert "a.xml" in err[0] and "b.xml" in err[0] and "--raytrix-xml" in err[0]
    res = run("refocus", raw, "--virtual-depth", 4.5, "-o", tmp_path / "v.png")
    assert res.exit_code == 1 and "--raytrix-xml" in error_lines(res)[0]
    assert_refused_as_focused(run("decode", raw, "--raytrix-xml", raw.parent / "a.xml", "-o", tmp_path / "lf.zarr"),
                              raw)
    out = tmp_path / "v.png"
    res = run("refocus", raw, "--raytrix-xml", raw.parent / "b.xml", "--virtual-depth", 4.5, "-o", out)
    assert res.exit_code == 0, res.output
    assert "virtual depth 4.5" in res.output and "patch 7.75 px" in res.output        # 34.86 px / 4.5
    png = read_image(out)
    assert png.ndim == 3 and png.shape[2] == 3 and channels_differ(png) > 0.05
    assert f"wrote {out} ({png.shape[1]} x {png.shape[0]} px, 16-bit; virtual depth" in res.output   # as --slope's
    # an XML that is no RayCalibData: a usage error naming the option, before any work
    (raw.parent / "notes.txt").write_text("<Settings/>")
    res = run("decode", raw, "--raytrix-xml", raw.parent / "notes.txt", "-o", tmp_path / "lf.zarr")
    assert res.exit_code == 2 and "--raytrix-xml" in error_lines(res)[0]


def test_virtual_depth_is_checked_before_any_work(shoot, tmp_path):
    out = tmp_path / "v.png"
    # no depth ranges in the generator's XML: P = 34.86 / V below the micro-image diameter and at least 2 px
    for bad in (0.9, 30.0):
        res = run("refocus", shoot["raw"], "--virtual-depth", bad, "-o", out)
        err = error_lines(res)
        assert res.exit_code == 2 and len(err) == 1 and "--virtual-depth" in err[0] and "17.4" in err[0]
    res = run("refocus", shoot["raw"], "--virtual-depth", 4.5, "--slope", 0.5, "-o", out)
    assert res.exit_code == 2 and "--slope" in error_lines(res)[0]
    from plenodecode.io.lightfield import save_lightfield
    from plenodecode.types import LightField

    lf = save_lightfield(LightField(np.zeros((3, 3, 4, 5, 1), np.float32), None, "srgb", {}), tmp_path / "lf.npy")
    res = run("refocus", lf, "--virtual-depth", 4.5, "-o", out)
    assert res.exit_code == 2 and "--virtual-depth" in error_lines(res)[0]
    assert not out.exists()


# ------------------------------------------------------------------------------------------ the real R42 crop
@pytest.fixture(scope="module")
def r42():
    return shared_path("raytrix-r42", "sc2_klein.png")


def test_r42_is_an_rgb_export_rendered_in_colour_and_sharper_than_any_single_patch_size(r42, tmp_path):
    # what the file is: an 8-bit RGB export (demosaiced by RxLive; no Bayer pattern left), three distinct channels
    rgb = read_image(r42)
    assert rgb.shape == (670, 964, 3) and rgb.dtype == np.uint8
    means = rgb.reshape(-1, 3).mean(0)
    np.testing.assert_allclose(means, (105.5, 78.1, 71.5), atol=0.5)
    tiles = [rgb[i::2, j::2, 1].mean() for i in (0, 1) for j in (0, 1)]
    assert np.ptp(tiles) < 1.0                                        # a mosaic's 2 x 2 positions would differ

    out = tmp_path / "tf.png"
    res = run("render", r42, "--total-focus", "-o", out)
    assert res.exit_code == 0, res.output
    png = read_image(out)
    assert png.dtype == np.uint16 and png.ndim == 3 and png.shape[2] == 3
    image = srgb_to_linear(png)
    assert channels_differ(image) > 0.2                               # measured 0.41; grey would be 0
    red, green, blue = image.reshape(-1, 3).mean(0)
    assert red > 1.5 * green and red > 2.0 * blue                     # a red textile and a blue cable

    # sharpness: the per-lens patch sizes of the total focus against every single patch size P over the range the
    # lenses measured (render_focused, same output grid); measured 0.098 against at most 0.071 (P = 6)
    src = pipeline.open_source(r42)
    render = pipeline.render_product(src, "total-focus").data["render"]
    assert render.image.shape == png.shape
    grid = src.calibration.grid
    sensor = read_raytrix_linear_rgb(r42)
    mask = render.weight > 0.5
    b = int(2 * render.spacing)
    mask[:b], mask[-b:], mask[:, :b], mask[:, -b:] = False, False, False, False

    def gradient_energy(img, m):
        g = img.mean(-1)
        gy, gx = np.gradient(g)
        return float(np.mean((gy ** 2 + gx ** 2)[m]) / np.mean(g[m]) ** 2)

    lo, hi = float(render.patch.min()), float(render.patch.max())
    assert 3.0 < lo < hi < 12.0
    for p in np.linspace(0.8 * lo, 1.25 * hi, 9):
        fixed = render_focused(sensor, grid, patch=p, spacing=render.spacing, keplerian=render.keplerian)
        m = mask & (fixed.weight > 0.5)
        assert gradient_energy(image, m) > 1.2 * gradient_energy(fixed.image, m), p


def test_r42_decode_says_in_one_line_what_to_run(r42, tmp_path):
    res = run("decode", r42, "-o", tmp_path / "lf.zarr")
    assert_refused_as_focused(res, r42)
    assert not (tmp_path / "lf.zarr").exists()
    res = run("decode", r42, "--views-anyway", "-o", tmp_path / "lf.zarr")        # asked for: colour views
    assert res.exit_code == 0, res.output
    assert "views of 22x31, linear sRGB" in res.output         # three channels, not the grey mosaic


def test_r42_refocus_at_a_virtual_depth_in_the_lens_types_range(r42, tmp_path):
    res = run("refocus", r42, "--virtual-depth", 0.9, "-o", tmp_path / "x.png")
    err = error_lines(res)
    assert res.exit_code == 2 and "--virtual-depth" in err[0] and "[1.07, 100]" in err[0]
    out = tmp_path / "v.png"
    res = run("refocus", r42, "--virtual-depth", 3.5, "-o", out, "--raytrix-xml", r42.with_suffix(".xml"))
    assert res.exit_code == 0, res.output
    png = read_image(out)
    assert png.shape == (192, 276, 3) and channels_differ(png.astype(np.float64)) > 0.1   # 964 x 670 at 9.96 / 34.86


def test_r42_batch_total_focus_with_colour_thumbnails(r42, tmp_path):
    db = tmp_path / "db"
    db.mkdir()
    res = run("batch", r42.parent, "-o", tmp_path / "batch", "--outputs", "total-focus", "--database", db,
              "--jobs", 1)
    assert res.exit_code == 0, res.output
    assert "decoding 1 raw" in res.stderr and "1 raws" not in res.stderr, res.stderr   # said 'decoding 1 raws'
    folder = tmp_path / "batch" / "sc2_klein"
    thumb = read_image(folder / "thumbs" / "total_focus.png")
    assert thumb.ndim == 3 and thumb.shape[2] == 3 and channels_differ(thumb) > 0.2
    assert read_image(folder / "total_focus.png").shape[2] == 3


def test_real_r42_rgb_export_decodes_with_one_progress_and_one_warning(tmp_path, caplog):
    """An RGB export is decoded channel by channel; the user sees one progress bar that runs once from 0 to its
    total (it ran three times) and the decoder's 'no white image' warning once (it was shown three times)."""
    from plenodecode.pipeline.source import open_source

    seen = []
    src = open_source(shared_path("raytrix-r42", "sc2_klein.png"),
                      progress=lambda done, total: seen.append((done, total)))
    assert src.lightfield.shape[-1] == 3
    done = [d for d, _ in seen]
    assert len({t for _, t in seen}) == 1 and done == sorted(done) and done[-1] == seen[0][1], seen
    assert sum("no white image" in r.getMessage() for r in caplog.records) == 1
    res = run("views", shared_path("raytrix-r42", "sc2_klein.png"), "--views-anyway", "-o", tmp_path / "views")
    assert res.exit_code == 0, res.output
    assert res.output.count("decoding") == 1, res.output
    assert "wrote 1225 views (35x35, each " in res.output      # asked for with --views-anyway: one pixel per lens
    assert read_image(tmp_path / "views" / "view_17_17.png").shape == (22, 31, 3)


def test_batch_default_is_the_cameras_photograph_as_the_one_liner_writes_it(tmp_path):
    """'plenodecode batch FOLDER -o OUT' with no --outputs wrote each raw's centre view: for the real R42 a
    31 x 22 px thumbnail.  Its default is now 'photo', the one-liner's photograph: the R42's total focus and the
    F01 JPEG focused as captured, the same files the one-liner writes."""
    r42, jpeg = shared_path("raytrix-r42", "sc2_klein.png"), shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    res = run("batch", r42, jpeg, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "out" / "sc2_klein").glob("*.png")) == ["total_focus.png"]
    assert sorted(p.name for p in (tmp_path / "out" / "IMG_1").glob("*.png")) == ["refocus_s+0.00.png"]
    for raw, written in ((r42, tmp_path / "out" / "sc2_klein" / "total_focus.png"),
                         (jpeg, tmp_path / "out" / "IMG_1" / "refocus_s+0.00.png")):
        single = run(raw, "-o", tmp_path / f"{raw.stem}.png")
        assert single.exit_code == 0, single.output
        np.testing.assert_array_equal(read_image(written), read_image(tmp_path / f"{raw.stem}.png"))
    assert read_image(tmp_path / "out" / "sc2_klein" / "total_focus.png").shape[1] > 150


# ------------------------------------------------------------------------------------------ depth of a focused raw
def read_depth(path):
    from plenodecode.io.pfm import read_pfm

    values = read_pfm(path)
    return values[0] if isinstance(values, tuple) else values


def test_depth_of_a_focused_raw_is_virtual_depth_on_the_total_focus_grid(shoot, tmp_path):
    """'plenodecode depth' on a Raytrix raw wrote the decoded views' one-pixel-per-lens disparity; now its virtual
    depth on the total-focus image's grid, said so; metric options and light-field options are usage errors naming
    the option, before any work."""
    raw = shoot["raw"]
    out = tmp_path / "d.pfm"
    res = run("depth", raw, "-o", out)
    assert res.exit_code == 0, res.output
    assert "focused-plenoptic raw: virtual depth" in res.output
    photo = tmp_path / "photo.png"
    assert run(raw, "-o", photo).exit_code == 0
    v = read_depth(out)
    assert v.shape == read_image(photo).shape[:2]
    lf_shape = pipeline.open_source(raw).calibration.grid.shape
    assert v.shape[0] > 4 * lf_shape[0] and v.shape[1] > 4 * lf_shape[1]
    conf = read_image(tmp_path / "d_confidence.exr").squeeze()
    assert np.mean(conf >= 0.1) > 0.5
    for option in (["--metric"], ["--ply", tmp_path / "c.ply"], ["--method", "fast"], ["--disparity-range", "0:1"]):
        target = tmp_path / f"refused{len(option)}{option[0][2:]}.pfm"
        res = run("depth", raw, "-o", target, *option)
        err = error_lines(res)
        assert res.exit_code == 2 and len(err) == 1 and option[0] in err[0], res.output
        assert "virtual depth" in err[0]
        assert not target.exists() and not (tmp_path / "c.ply").exists()


def test_r42_depth_at_total_focus_resolution_agrees_with_the_per_lens_patch_sizes(r42, tmp_path):
    """The R42 crop's depth map was 31 x 22 px; now the total focus's 176 x 122.  Per lens, the median of its
    confident output pixels (within half a lens spacing of the lens) against estimate_patch_sizes' v = D / P:
    measured over 442 lenses r = 0.78, median difference 1.8 %; confident values (1st..99th percentile 5.0 ..
    7.3) within the lenses' range 3.65 .. 7.77."""
    from plenodecode.decoding.focused import estimate_patch_sizes

    out = tmp_path / "d.pfm"
    res = run("depth", r42, "-o", out)
    assert res.exit_code == 0, res.output
    v = read_depth(out)
    conf = read_image(tmp_path / "d_confidence.exr").squeeze()
    src = pipeline.open_source(r42)
    render = pipeline.render_product(src, "total-focus").data["render"]
    assert v.shape == render.image.shape[:2] == (122, 176)
    grid = src.calibration.grid
    p, score = estimate_patch_sizes(read_raytrix_linear_rgb(r42), grid, keplerian=render.keplerian)
    centres = grid.centres_2d() * render.scale
    qy, qx = np.mgrid[0:v.shape[0], 0:v.shape[1]]
    sure = (conf >= 0.1) & np.isfinite(v)
    ours, theirs = [], []
    for i, j in np.ndindex(grid.shape):
        near = sure & ((qy - centres[i, j, 0]) ** 2 + (qx - centres[i, j, 1]) ** 2 < (0.5 * render.spacing) ** 2)
        # lenses matched confidently and not at the patch search's lower end (0.12 D)
        if near.sum() >= 10 and score[i, j] >= 0.5 and p[i, j] > 0.12 * grid.pitch + 0.3:
            ours.append(np.median(v[near]))
            theirs.append(grid.pitch / p[i, j])
    ours, theirs = np.array(ours), np.array(theirs)
    assert ours.size > 300
    assert np.corrcoef(ours, theirs)[0, 1] > 0.6
    assert np.median(np.abs(ours - theirs) / theirs) < 0.04
    lo, hi = np.percentile(v[sure], [1, 99])
    assert theirs.min() <= lo < hi <= 1.05 * theirs.max()
    assert np.mean(sure) > 0.7


# ------------------------------------------------------------------------------------------ one rule, one rendering
def test_the_photographs_focus_rule_is_the_pipelines_for_the_one_liner_and_batch(shoot, tmp_path, monkeypatch):
    """'focused raw -> total focus, else slope 0' was written twice (cli.render.default_focus and
    pipeline.products.render_photo); both now ask pipeline.products.photo_focus: changing it changes what the
    one-liner and batch's 'photo' write (the decoded views' one-pixel-per-lens thumbnail instead of the total focus)."""
    from plenodecode.pipeline import products

    assert products.photo_focus(True) == {"total_focus": True}
    assert products.photo_focus(True, refocus=True) == products.photo_focus(False) == {"slope": 0.0}
    lenses = pipeline.open_source(shoot["raw"]).calibration.grid.shape
    monkeypatch.setattr(products, "photo_focus", lambda focused, refocus=False: {"slope": 0.0})
    res = run(shoot["raw"], "-o", tmp_path / "photo.png")
    assert res.exit_code == 0 and "focused as captured" in res.output, res.output
    res = run("batch", shoot["raw"], "-o", tmp_path / "out", "--jobs", 1, "--database", tmp_path)
    assert res.exit_code == 0, res.output
    written = tmp_path / "out" / "scene" / "refocus_s+0.00.png"
    for image in (read_image(tmp_path / "photo.png"), read_image(written)):
        assert abs(image.shape[0] - lenses[0]) <= 2 and abs(image.shape[1] - lenses[1]) <= 2, (image.shape, lenses)


def test_batch_photo_total_focus_and_depth_of_a_focused_raw_render_the_total_focus_once(shoot, tmp_path,
                                                                                         monkeypatch):
    """'batch --outputs photo,total-focus,depth' on a Raytrix raw rendered the total focus once per product (and
    failed: 'photo' and 'total-focus' both wrote total_focus.png); now once per raw, written once, and the depth
    map is the one 'plenodecode depth' writes, aligned with it."""
    from plenodecode.decoding import focused
    from plenodecode.io.pfm import read_pfm

    single = tmp_path / "d.pfm"
    assert run("-q", "depth", shoot["raw"], "-o", single).exit_code == 0
    calls = []
    real = focused.render_total_focus
    monkeypatch.setattr(focused, "render_total_focus", lambda *a, **k: calls.append(1) or real(*a, **k))
    res = run("batch", shoot["raw"], "-o", tmp_path / "out", "--jobs", 1, "--database", tmp_path,
              "--outputs", "photo,total-focus,depth")
    assert res.exit_code == 0, res.output
    assert len(calls) == 1
    folder = tmp_path / "out" / "scene"
    assert sorted(p.name for p in folder.iterdir() if p.is_file()) == [
        ".done.json", "total_focus.png", "virtual_depth.exr", "virtual_depth.pfm", "virtual_depth.png",
        "virtual_depth_confidence.exr", "virtual_depth_confidence.png"]
    depth = read_pfm(folder / "virtual_depth.pfm")
    depth = depth[0] if isinstance(depth, tuple) else depth
    reference = read_pfm(single)
    np.testing.assert_array_equal(depth, reference[0] if isinstance(reference, tuple) else reference)
    assert depth.shape == read_image(folder / "total_focus.png").shape[:2]


def test_metric_depth_of_a_focused_raw_calibrated_by_hand_is_refused(shoot, tmp_path):
    """Without its XML beside it a Raytrix raw reads as a plain mosaic, and with a grid that has lens types
    (--calibration) it is focused: 'depth --metric --focus-distance 1' wrote virtual depth and said nothing of
    --metric; now the one check (check_product, given the grid's lens types by render_product) refuses it, from
    the command line and from Python, with nothing written."""
    from plenodecode.errors import MissingConstantsError

    grid = tmp_path / "grid.json"
    assert run("calibrate", shoot["white"], "-o", grid).exit_code == 0
    raw = copy_raw(shoot, tmp_path / "noxml")
    for option in (["--metric"], ["--ply", tmp_path / "c.ply"]):
        res = run("depth", raw, "--calibration", grid, "--focus-distance", 1, "-o", tmp_path / "z.pfm", *option)
        err = error_lines(res)
        assert res.exit_code == 2 and len(err) == 1 and option[0] in err[0] and "virtual depth" in err[0], res.output
        assert not list(tmp_path.glob("z*")) and not (tmp_path / "c.ply").exists()
    src = pipeline.open_source(raw, grid=grid)
    assert src.focused
    with pytest.raises(MissingConstantsError, match="virtual depth"):
        pipeline.render_product(src, "depth", metric=True, focus_distance=1.0)


def test_info_on_the_r42_says_it_is_an_rgb_export_not_a_monochrome_raw(r42):
    """'plenodecode info' called the R42's 8-bit RGB export 'monochrome, black 0, white 65535' (the luminance
    its reader makes to locate the lenses), though every rendering of it is in colour."""
    res = run("info", r42)
    assert res.exit_code == 0, res.output
    line = next(line for line in res.output.splitlines() if line.strip().startswith("raw "))
    assert "964 x 670, RGB export (3 channels" in line and "monochrome" not in line and "65535" not in line


def test_views_parallax_and_refocus_by_slope_of_a_focused_raw_are_refused_as_decode_refuses_it(tmp_path, monkeypatch):
    """views, parallax and a refocus by slope of the real R42 crop silently wrote 22 x 31 px outputs (35 x 35
    views, one pixel per lens); like decode they now stop in one usage line before decoding anything, saying what
    to type instead, unless --views-anyway (which parallax and refocus then honour: a 22 x 31 px photograph)."""
    from plenodecode.pipeline import source

    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    decoded = []
    real = source.decode_raw
    monkeypatch.setattr(source, "decode_raw", lambda *a, **k: decoded.append(a) or real(*a, **k))
    photo = f"'plenodecode render {r42} --total-focus -o photo.png'"
    cases = {("views", r42, "-o", tmp_path / "views"): photo,
             ("parallax", r42, "-o", tmp_path / "p.gif"): photo,
             ("refocus", r42, "--slope", 0.5, "-o", tmp_path / "r.png"): f"'plenodecode refocus {r42} --virtual-depth V",
             ("refocus", r42, "-o", tmp_path / "r.png"): "--virtual-depth V",
             (r42, "--slope", 0.5, "-o", tmp_path / "s.png"): "--virtual-depth V",
             ("decode", r42, "-o", tmp_path / "lf.zarr"): photo}
    for args, instead in cases.items():
        res = run(*args)
        err = error_lines(res)
        assert res.exit_code == 2 and len(err) == 1, (args, res.output)
        assert err[0].startswith("Error: sc2_klein.png is a focused-plenoptic (Raytrix) raw"), err
        assert "one pixel per lens" in err[0] and instead in err[0] and "(or pass --views-anyway)" in err[0], err
    assert decoded == [] and list(tmp_path.iterdir()) == []
    res = run("refocus", r42, "--slope", 0.5, "--views-anyway", "-o", tmp_path / "r.png")
    assert res.exit_code == 0, res.output
    assert read_image(tmp_path / "r.png").shape[:2] == (22, 31)
    res = run("parallax", r42, "--views-anyway", "--frames", 3, "--no-frames", "-o", tmp_path / "p.gif")
    assert res.exit_code == 0 and (tmp_path / "p.gif").stat().st_size > 0, res.output
    # a refocus at a virtual depth is the focused raw's own: --views-anyway means nothing there
    res = run("refocus", r42, "--virtual-depth", 3.5, "--views-anyway", "-o", tmp_path / "v.png")
    assert res.exit_code == 2 and "--views-anyway refocuses a light field" in res.output, res.output


def test_the_one_liner_on_the_r42_points_to_its_virtual_depth_not_to_the_refused_slope(tmp_path, monkeypatch):
    """The one-liner's photograph of the real R42 crop said 'choose the focus with --refocus, --slope, --focus-at or
    --focus-distance', each of which that raw refuses; --refocus and --focus-distance said 'use --slope S instead',
    which is refused too.  Now the photograph's line names --virtual-depth and its range (1.07 .. 100, the lens
    types' 1.0609 .. 100 rounded inwards: the message said [1.06, 100] and refused 1.06), and alpha or a distance
    names the virtual depth, or --slope only with --views-anyway, before decoding."""
    from plenodecode.pipeline import source

    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    out = tmp_path / "photo.png"
    res = run(r42, "-o", out)
    assert res.exit_code == 0, res.output
    line = next(ln for ln in res.output.splitlines() if ln.startswith("wrote"))
    assert "--slope" not in line and "--refocus" not in line and "--focus-at" not in line, line
    assert "virtual depth V of 1.07 .. 100" in line and f"'plenodecode refocus {r42} --virtual-depth V" in line
    assert read_image(out).shape == (122, 176, 3)                   # the total focus
    # the command it suggests, V filled in, runs as given and leaves the photograph alone (it said '-o photo.png',
    # the file just written: refused without --overwrite, and replaced with it)
    suggested = re.search(r"'plenodecode (refocus .*)'\)$", line).group(1)
    suggested = suggested.replace(" V ", " 3.5 ").replace("_vV.", "_v3.5.")
    before = out.read_bytes()
    res = run(*suggested.split())
    assert res.exit_code == 0, res.output
    assert out.read_bytes() == before and read_image(tmp_path / "photo_v3.5.png").shape == (192, 276, 3)
    # the range it names is the one --virtual-depth accepts: its ends render, past them is refused
    for v, code in ((1.07, 0), (100, 0), (1.06, 2), (100.5, 2)):
        res = run("refocus", r42, "--virtual-depth", v, "-o", tmp_path / f"v{v}.png")
        assert res.exit_code == code, (v, res.output)
        assert code == 0 or "must lie in [1.07, 100]" in error_lines(res)[0]

    decoded = []
    real = source.decode_raw
    monkeypatch.setattr(source, "decode_raw", lambda *a, **k: decoded.append(a) or real(*a, **k))
    for args, option in (((r42, "--refocus", 1.01), "--refocus"), (("refocus", r42, "--alpha", 1.01), "--alpha"),
                         ((r42, "--focus-distance", 2), "--focus-distance"),
                         (("refocus", r42, "--focal-stack", "1:1.1:3", "--stack-units", "alpha"), "--stack-units")):
        target = tmp_path / ("stack" if "--focal-stack" in args else "r.png")
        res = run(*args, "-o", target)
        err = error_lines(res)
        assert res.exit_code == 2 and len(err) == 1 and option in err[0], (args, res.output)
        assert "--virtual-depth V" in err[0] and "--slope S --views-anyway" in err[0], err
        assert "use --slope S (px per view step) instead" not in err[0]
        assert not target.exists()
    assert decoded == []


def test_batch_leaves_out_a_focused_raws_view_outputs_unless_asked(tmp_path):
    """'batch --outputs centre,photo,depth' over the real R42 wrote its centre view as a 31 x 22 px thumbnail
    (the commands refuse such views); then the R42 failed whole, though its photo (total focus) and depth (virtual
    depth) can be written.  It is now done with those two, the centre view left out and said on its row, in
    summary.json and on the index page; the exit status and the last line still say something was left out.  With
    only focused raws no raw can serve 'centre': refused in one line before any work.  --views-anyway: as before."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    r42, illum = shared_path("raytrix-r42", "sc2_klein.png"), root / "sample_raws" / "illum-mini" / "scene.lfr"
    base = ["batch", r42, illum, "--outputs", "centre,photo,depth", "--database", root / "calib", "--jobs", 1]
    out = tmp_path / "out"
    res = run(*base, "-o", out)
    assert res.exit_code == 1, res.output
    row = [line for line in res.output.splitlines() if line.startswith("sc2_klein.png")]
    note = "centre: not for a focused-plenoptic (Raytrix) raw (its views have one pixel per lens; --views-anyway"
    assert len(row) == 1 and " done " in row[0] and f"6 outputs; {note}" in row[0], res.output
    assert "2 done, 0 skipped, 0 failed (1 leaving out outputs) in " in res.output, res.output
    assert "error: 1 of 2 raws left out outputs they cannot serve" in res.output and "Traceback" not in res.output
    assert sorted(p.name for p in (out / "sc2_klein").iterdir() if p.is_file() and p.name != ".done.json") == [
        "total_focus.png", "virtual_depth.exr", "virtual_depth.pfm", "virtual_depth.png",
        "virtual_depth_confidence.exr", "virtual_depth_confidence.png"]
    assert read_image(out / "sc2_klein" / "total_focus.png").std() > 0
    assert sorted(p.name for p in (out / "scene").glob("*.png")) == ["centre.png", "disparity.png",
                                                                     "disparity_confidence.png", "refocus_s+0.00.png"]
    summary = json.loads((out / "summary.json").read_text())
    rows = {Path(r["source"]).name: r for r in summary["results"]}
    assert summary["left_out"] == 1 and rows["scene.lfr"]["left_out"] == []
    assert rows["sc2_klein.png"]["status"] == "done" and rows["sc2_klein.png"]["left_out"][0].startswith(note)
    assert [Path(o).name for o in rows["sc2_klein.png"]["outputs"]][:2] == ["total_focus.png", "virtual_depth.pfm"]
    page = (out / "index.html").read_text()
    assert "left out: centre: not for a focused-plenoptic" in page and "<b>1</b> left out outputs" in page
    # the same run again: skipped, still saying what it left out
    res = run(*base, "-o", out)
    assert res.exit_code == 1 and "0 done, 2 skipped, 0 failed (1 leaving out outputs)" in res.output, res.output
    # no raw that can serve 'centre': refused before any work, naming --outputs
    res = run("batch", r42, "--outputs", "centre,photo", "-o", tmp_path / "none")
    assert res.exit_code == 2 and "--outputs" in res.output and "no raw here can serve it" in res.output, res.output
    assert "--views-anyway" in res.output and not (tmp_path / "none").exists()
    res = run(*base, "-o", tmp_path / "anyway", "--views-anyway")
    assert res.exit_code == 0, res.output
    assert read_image(tmp_path / "anyway" / "sc2_klein" / "centre.png").shape[:2] == (22, 31)


def test_the_real_r42_rotation_prints_as_zero_not_minus_zero(tmp_path):
    """The R42's RayCalibData has rotation -0.0: 'info' of its XML and of the grid, 'calibrate' and the HTML report
    printed 'rotation -0.000000 rad'.  Angles now print as 0.00000 rad (0.000 deg) everywhere, 5 decimals in rad
    and 3 in degrees."""
    png = shared_path("raytrix-r42", "sc2_klein.png")
    res = run("calibrate", png, "-o", tmp_path / "grid.json", "--report", tmp_path / "grid.html")
    assert res.exit_code == 0, res.output
    shown = [res.output, run("info", png.with_suffix(".xml"), tmp_path / "grid.json").output,
             (tmp_path / "grid.html").read_text(encoding="utf-8")]
    for text in shown:
        assert "rotation 0.00000 rad (0.000 deg)" in text.replace("</td><td>", " ") and "-0.0" not in text, text[:600]


def test_virtual_depth_png_marks_near_at_the_warm_top_as_the_disparity_png_does(shoot, r42, tmp_path, monkeypatch):
    """The virtual-depth PNG had no near / far marks on its colour bar and coloured high v warm whatever the
    camera.  A nearer object's main-lens image lies farther behind the main lens: behind the MLA (Galilean,
    upright micro-images, the real R42) that is a larger v; in front of it (Keplerian, inverted: the synthetic
    preset, whose front disk has the smallest v) a smaller v.  Through 'plenodecode depth' the nearest tenth of
    the confident pixels is now warm and the farthest tenth cold on both (red - blue measured 166 / -62 on the
    synthetic raw, 176 / -88 on the R42), and the colour bar says near at the top."""
    from plenodecode.io import depthio
    from tests.cli.test_depth import _map_pixels

    asked = []
    figure = depthio.colour_map_figure
    monkeypatch.setattr(depthio, "colour_map_figure", lambda *a, **k: asked.append(k.get("near")) or figure(*a, **k))
    for raw, near_end in ((shoot["raw"], "low"), (r42, "high")):
        out = tmp_path / f"{near_end}.pfm"
        res = run("depth", raw, "-o", out)
        assert res.exit_code == 0, res.output
        assert asked[-2:] == [near_end, None], asked      # the depth PNG's bar says near / far (not the confidence's)
        v = read_depth(out)
        conf = read_image(tmp_path / f"{near_end}_confidence.exr").squeeze()
        ok = np.isfinite(v) & (conf >= 0.1)
        nearness = -v if near_end == "low" else v
        near, far = ok & (nearness >= np.quantile(nearness[ok], 0.9)), ok & (nearness <= np.quantile(nearness[ok], 0.1))
        rgb, _ = _map_pixels(out.with_suffix(".png"), v.shape)
        warmth = rgb[..., 0].astype(np.float64) - rgb[..., 2]
        assert np.mean(warmth[near]) > 100 and np.mean(warmth[far]) < -50, (near_end, np.mean(warmth[near]),
                                                                            np.mean(warmth[far]))
