"""The rendering commands: render (the card's one-liner), refocus, views, parallax, and input loading."""

import json

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.cli.refocus import REFOCUS_METHOD_CHOICE
from plenodecode.io.images import read_image, write_image
from plenodecode.pipeline import load_lightfield_input as load_input
from plenodecode.render import REFOCUS_METHODS, alpha_to_slope, perspective, refocus
from plenodecode.types import CameraMetadata, LightField

CAMERA = CameraMetadata(focal_length_m=0.0301, f_number=2.0, lens_pitch_m=2e-5, pixel_pitch_m=1.4e-6)


def small_lf(colour="srgb", camera=True, seed=0):
    rng = np.random.default_rng(seed)
    data = rng.random((5, 5, 14, 18, 3), dtype=np.float32)
    meta = {"spatial_step_px": 12.37, "view_step_px": 1.0}
    if camera:
        meta["camera"] = CAMERA.to_dict()
    return LightField(data, None, colour, meta)


def save_npy(tmp_path, lf, name="lf.npy"):
    from plenodecode.io.lightfield import save_lightfield

    return save_lightfield(lf, tmp_path / name)


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_method_choices_match_the_registry():
    METHOD_NAMES = REFOCUS_METHOD_CHOICE.choices
    assert set(METHOD_NAMES) == set(REFOCUS_METHODS)


def test_load_input_reads_saved_light_fields_and_hci_folders(tmp_path):
    lf = small_lf()
    back = load_input(save_npy(tmp_path, lf))
    np.testing.assert_array_equal(back.data, lf.data)
    hci = tmp_path / "scene"
    hci.mkdir()
    for i in range(9):
        write_image(hci / f"input_Cam{i:03d}.png", lf.data[i // 3, i % 3], bit_depth=8)
    got = load_input(hci)
    assert got.shape == (3, 3, 14, 18, 3) and got.colour == "srgb"
    np.testing.assert_allclose(got.data[1, 2], lf.data[1, 2], atol=0.5 / 255 + 1e-6)


def test_card_one_liner_refocus_by_alpha(tmp_path):
    lf = small_lf()
    src = save_npy(tmp_path, lf)
    out = tmp_path / "out.png"
    res = run(src, "--refocus", 1.01, "-o", out)
    assert res.exit_code == 0, res.output
    img = read_image(out)
    assert img.dtype == np.uint16 and img.shape == (14, 18, 3)       # default --bit-depth 16
    expect = refocus(lf, slope=alpha_to_slope(1.01, lf))             # 'srgb' colour: written as is
    np.testing.assert_allclose(img / 65535.0, np.clip(expect, 0, 1), atol=0.5 / 65535 + 1e-6)


def test_refocus_slope_exr_is_exact_and_linear_data_is_not_encoded_at_32_bit(tmp_path):
    lf = small_lf(colour="linear-srgb")
    src = save_npy(tmp_path, lf)
    out = tmp_path / "p.exr"
    res = run("refocus", src, "--slope", 0.7, "--method", "fourier-slice", "--bit-depth", 32, "-o", out)
    assert res.exit_code == 0, res.output
    np.testing.assert_allclose(read_image(out), refocus(lf, slope=0.7, method="fourier-slice"), atol=1e-6)


def test_linear_light_fields_are_display_encoded_in_png(tmp_path):
    lf = small_lf(colour="linear-srgb")
    src = save_npy(tmp_path, lf)
    out = tmp_path / "p.png"
    assert run("refocus", src, "--slope", 0.0, "-o", out).exit_code == 0
    lin = np.clip(lf.data.mean((0, 1)), 0, 1)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(read_image(out) / 65535.0, srgb, atol=1e-4)


def test_focal_stack_writes_slices_all_in_focus_and_json(tmp_path):
    src = save_npy(tmp_path, small_lf())
    out = tmp_path / "stack"
    res = run("refocus", src, "--focal-stack", "-1:1:3", "-o", out, "--bit-depth", 8)
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "focal_stack.json").read_text())
    assert doc["slopes"] == [-1.0, 0.0, 1.0] and len(doc["alphas"]) == 3
    for name in doc["files"] + [doc["all_in_focus"]]:
        assert read_image(out / name).dtype == np.uint8
    # alpha units
    res = run("refocus", src, "--focal-stack", "0.99:1.01:2", "--stack-units", "alpha", "-o", tmp_path / "s2")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "s2" / "focal_stack.json").read_text())
    np.testing.assert_allclose(doc["alphas"], [0.99, 1.01], rtol=1e-9)
    # refuses to overwrite
    res = run("refocus", src, "--focal-stack", "-1:1:3", "-o", out)
    assert res.exit_code == 2 and "--overwrite" in res.output
    assert run("refocus", src, "--focal-stack", "-1:1", "-o", tmp_path / "s3").exit_code == 2


def test_alpha_without_camera_metadata_is_a_usage_error_in_one_line(tmp_path):
    src = save_npy(tmp_path, small_lf(camera=False))
    res = run("refocus", src, "--alpha", 1.01, "-o", tmp_path / "x.png")
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert all(word in res.output for word in ("focal_length_m", "--alpha", "--slope")), res.output
    assert not (tmp_path / "x.png").exists()


def test_existing_output_is_kept_without_overwrite(tmp_path):
    src = save_npy(tmp_path, small_lf())
    out = tmp_path / "out.png"
    out.write_bytes(b"keep")
    res = run(src, "--slope", 0.2, "-o", out)
    assert res.exit_code == 2 and out.read_bytes() == b"keep"
    assert run(src, "--slope", 0.2, "-o", out, "--overwrite").exit_code == 0
    assert out.read_bytes() != b"keep"


def test_usage_errors(tmp_path):
    src = save_npy(tmp_path, small_lf())
    assert run("refocus", src, "--slope", 1, "--alpha", 1, "-o", tmp_path / "a.png").exit_code == 2
    assert run("refocus", src, "--slope", 0, "--aperture", 0, "-o", tmp_path / "a.png").exit_code == 2


def test_the_one_liner_without_a_focus_option_renders_the_focus_as_captured(tmp_path):
    """``plenodecode LF -o photo.png``: slope 0, the default of batch's 'refocus' product; the line says how to
    choose another focus."""
    src = save_npy(tmp_path, small_lf())
    res = run(src, "-o", tmp_path / "photo.png", "--bit-depth", 16)
    assert res.exit_code == 0, res.output
    assert "focused as captured: slope +0.000 px/view" in res.output and "--focus-at" in res.output
    assert run(src, "--slope", 0, "-o", tmp_path / "slope0.png", "--bit-depth", 16).exit_code == 0
    photo = read_image(tmp_path / "photo.png")
    np.testing.assert_array_equal(photo, read_image(tmp_path / "slope0.png"))
    assert photo.shape == (14, 18, 3) and photo.std() > 1000      # the mean of 25 random views, not a constant


def test_views_all_and_fractional(tmp_path):
    lf = small_lf()
    src = save_npy(tmp_path, lf)
    res = run("views", src, "-o", tmp_path / "views", "--bit-depth", 16)
    assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "views").glob("view_*.png"))
    assert len(files) == 25
    np.testing.assert_allclose(read_image(tmp_path / "views" / "view_03_01.png") / 65535.0, lf.data[3, 1],
                               atol=0.5 / 65535 + 1e-6)
    out = tmp_path / "p.exr"
    res = run("views", src, "--view", 1.5, 2.25, "-o", out, "--bit-depth", 32)
    assert res.exit_code == 0, res.output
    np.testing.assert_allclose(read_image(out), perspective(lf, 1.5, 2.25), atol=1e-6)
    assert run("views", src, "--view", 9, 0, "-o", tmp_path / "q.png").exit_code == 2


def test_parallax_writes_animation_and_numbered_frames(tmp_path):
    src = save_npy(tmp_path, small_lf())
    out = tmp_path / "wobble.gif"
    res = run("parallax", src, "-o", out, "--frames", 6, "--radius", 1.5, "--bit-depth", 8)
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 0 and out.read_bytes()[:3] == b"GIF"
    frames = sorted((tmp_path / "wobble_frames").glob("frame_*.png"))
    assert len(frames) == 6
    assert run("parallax", src, "-o", tmp_path / "w.mp4").exit_code == 2
    assert run("parallax", src, "-o", tmp_path / "w.gif", "--radius", 5).exit_code == 2


def test_parallax_bit_depth_and_frames_dir_are_checked_before_any_work(tmp_path, monkeypatch):
    """--bit-depth 32 was refused only after decoding and rendering, naming the keyword 'bit_depth' (the frames are
    PNGs); --frames-dir with --no-frames was silently ignored.  Both are usage errors naming the option now, before
    the input is even opened; without frames --bit-depth 32 means nothing to the GIF and passes."""
    from plenodecode import pipeline

    src = save_npy(tmp_path, small_lf())
    opened = []
    real = pipeline.open_source
    monkeypatch.setattr(pipeline, "open_source", lambda *a, **k: opened.append(a) or real(*a, **k))
    for args, option in ((("--bit-depth", 32), "--bit-depth"),
                         (("--no-frames", "--frames-dir", tmp_path / "f"), "--frames-dir")):
        res = run("parallax", src, "-o", tmp_path / "w.gif", *args)
        err = [ln for ln in res.output.splitlines() if ln.startswith("Error")]
        assert res.exit_code == 2 and len(err) == 1 and option in err[0] and "bit_depth" not in err[0], res.output
    assert opened == [] and sorted(p.name for p in tmp_path.iterdir()) == ["lf.json", "lf.npy"]
    res = run("parallax", src, "-o", tmp_path / "w.gif", "--frames", 1, "--no-frames", "--bit-depth", 32)
    assert res.exit_code == 0 and "(1 frame of " in res.output, res.output
    assert (tmp_path / "w.gif").read_bytes()[:3] == b"GIF" and not (tmp_path / "w_frames").exists()


def test_raw_is_decoded_then_refocused(tmp_path):
    """The card's form on a generated Illum raw: decode with a calibration (grid JSON, or the white image)."""
    from plenodecode import synthetic
    sim = synthetic.simulate("illum-mini", seed=1, shape=(400, 560), noise=False)
    files = synthetic.write_simulation(sim, tmp_path / "cam", lightfield=False)
    grid = tmp_path / "grid.json"
    grid.write_text(sim.grid.to_json())
    out = tmp_path / "photo.png"
    res = run(files["raw"], "--refocus", 1.0, "-o", out, "--calibration", grid)
    assert res.exit_code == 0, res.output
    lf = load_input(files["raw"], grid=grid)
    assert lf.shape[:2] == (15, 15)
    img = read_image(out)
    assert img.shape == (*lf.shape[2:4], 3) and img.std() > 1000          # a real picture, not flat
    # calibrated on the spot from the white image, which also devignets
    res = run("refocus", files["raw"], "--slope", 0.3, "-o", tmp_path / "w.png", "--white", files["white"])
    assert res.exit_code == 0, res.output
    # no calibration at all: one line naming what to pass, exit 1
    (tmp_path / "empty").mkdir()
    res = run(files["raw"], "--refocus", 1.0, "-o", tmp_path / "x.png", "--white-dir", tmp_path / "empty")
    assert res.exit_code == 1 and "--calibration" in res.output and not (tmp_path / "x.png").exists()


def test_alpha_outside_the_refocusable_range_writes_and_warns_in_one_line(tmp_path, caplog):
    src = save_npy(tmp_path, small_lf())
    out = tmp_path / "flat.png"
    with caplog.at_level("WARNING"):        # slope 5.5: outside the range, and the views still overlap (up to 9)
        res = run(src, "--refocus", 1.1, "-o", out)
    assert res.exit_code == 0, res.output
    assert out.is_file()
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "\n" not in warnings[0], warnings
    assert "outside the refocusable range" in warnings[0] and "alpha 0.98" in warnings[0] and "slope" in warnings[0]
    # inside the range: no warning, and the report line shows the range
    caplog.clear()
    with caplog.at_level("WARNING"):
        res = run(src, "--alpha", 1.01, "-o", tmp_path / "ok.png")
    assert res.exit_code == 0 and not [r for r in caplog.records if r.levelname == "WARNING"]
    assert "refocusable alpha 0.98" in res.output


def test_focus_at_pixels_and_fractions(tmp_path):
    lf = small_lf(colour="linear-srgb")
    src = save_npy(tmp_path, lf)
    for text, point in (("0.5,0.5", (6.5, 8.5)), ("8,6", (6.0, 8.0))):
        out = tmp_path / f"at_{text}.exr"
        res = run("refocus", src, "--focus-at", text, "--bit-depth", 32, "-o", out)
        assert res.exit_code == 0, res.output
        np.testing.assert_allclose(read_image(out), refocus(lf, at=point), atol=1e-6)
    res = run("refocus", src, "--focus-at", "100,2", "-o", tmp_path / "x.png")          # outside the picture
    assert res.exit_code == 2 and "--focus-at" in res.output and not (tmp_path / "x.png").exists()
    res = run("refocus", src, "--slope", 0, "--no-depth", "-o", tmp_path / "x.png")
    assert res.exit_code == 2 and "--no-depth" in res.output


def test_python_focus_at_is_x_y_as_the_option_and_the_old_at_row_column_still_works(tmp_path):
    """'--focus-at 8,6' (column 8, row 6) is render_product(src, 'refocus', focus_at=(8, 6)) in Python, the same
    order; the keyword was 'at' = (row, column), which still works with a DeprecationWarning."""
    import pytest

    from plenodecode import pipeline
    from plenodecode.errors import MissingConstantsError

    lf = small_lf(colour="linear-srgb")
    out = tmp_path / "cli.exr"
    assert run("refocus", save_npy(tmp_path, lf), "--focus-at", "8,6", "--bit-depth", 32, "-o", out).exit_code == 0
    src = pipeline.Source(lightfield=lf)
    py = pipeline.render_product(src, "refocus", focus_at=(8, 6))
    (_, image), = py.images
    np.testing.assert_allclose(image, read_image(out), atol=1e-6)
    swapped = pipeline.render_product(src, "refocus", focus_at=(6, 8)).data["slope"]
    assert abs(swapped - py.data["slope"]) > 0.05            # the order matters here
    with pytest.warns(DeprecationWarning, match=r"render_product\(at=\) is deprecated: pass focus_at=\(x, y\)"):
        old = pipeline.render_product(src, "refocus", at=(6, 8))
    assert old.data["slope"] == py.data["slope"]
    with pytest.warns(DeprecationWarning, match="pass focus_distance="), \
            pytest.raises(MissingConstantsError) as err:        # this light field has no focus distance
        pipeline.render_product(src, "refocus", distance_m=2.0)
    assert err.value.keyword == "focus_distance"
    with pytest.raises(ValueError, match="pass focus_at, not both"):
        pipeline.render_product(src, "refocus", at=(6, 8), focus_at=(8, 6))
    with pytest.raises(ValueError, match=r"focus_at must be an \(x, y\) pair inside the centre view \(x: column 0 "
                                         r"to 17, y: row 0 to 13\), got \(2, 16\)"):
        pipeline.render_product(src, "refocus", focus_at=(2, 16))        # row 16 of 14; as (row, column) inside
    with pytest.raises(ValueError, match=r"pass exactly one of slope, alpha, focus_at and focus_distance, got "
                                         r"\['slope', 'focus_at'\]"):
        pipeline.render_product(src, "refocus", slope=0.0, focus_at=(8, 6))


def test_info_on_a_light_field_shows_the_refocusable_range(tmp_path):
    src = save_npy(tmp_path, small_lf())
    res = run("info", src)
    assert res.exit_code == 0, res.output
    assert "5 x 5 x 14 x 18 x 3" in res.output and "refocus  alpha 0.98" in res.output


def test_a_slope_that_moves_the_views_past_the_picture_is_refused_naming_its_option(tmp_path):
    """'refocus --slope 2000' (a typo for 0.2000) padded every view by 14,000 px on the bundled Illum's light field
    and was killed for lack of memory after a minute; '--slope 1e9' raised a 17.7 TiB MemoryError with a
    traceback.  A slope whose outermost views move past the whole picture (no view overlaps the centre one) is now
    a usage error naming the option it came from, with nothing written; the slopes up to there still render."""
    from pathlib import Path

    lf_path = save_npy(tmp_path, small_lf())              # 5 x 5 views of 14 x 18: |slope| <= 18 / 2 = 9
    cases = [(["refocus", lf_path, "--slope", 2000], "--slope", "slope 2000 px/view moves the outermost views"),
             (["refocus", lf_path, "--slope", -9.5], "--slope", "(|slope| <= 9 here)"),
             (["refocus", lf_path, "--focal-stack", "-1e9:1e9:3"], "--focal-stack", "slope 1e+09 px/view"),
             ([lf_path, "--refocus", 0.2], "--refocus / --alpha", "slope 243.3 px/view moves the outermost views")]
    for i, (args, option, words) in enumerate(cases):
        out = tmp_path / (f"out{i}" if "--focal-stack" in args else f"out{i}.png")
        res = run(*args, "-o", out)
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert f"Invalid value for {option}:" in errors[0] and words in errors[0], res.output
        assert not out.exists()
    assert run("refocus", lf_path, "--slope", 9, "-o", tmp_path / "edge.png").exit_code == 0
    illum = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini" / "scene.lfr"
    res = run(illum, "--refocus", 1.5, "-o", tmp_path / "far.png")      # slope 20.3 on 87 x 125: the limit is 17.9
    assert res.exit_code == 2 and "Invalid value for --refocus / --alpha" in res.output, res.output
    assert not (tmp_path / "far.png").exists()


def test_alpha_beyond_the_picture_is_refused_without_the_out_of_range_warning(tmp_path, caplog):
    """'plenodecode sample_raws/illum-mini/scene.lfr --refocus 1.5' logged 'slope 20.3 px/view is outside the
    refocusable range' and then refused the slope (|slope| <= 17.9 on its 87 x 125 picture): only the refusal."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "x.png"
    with caplog.at_level("WARNING"):
        res = run(root / "sample_raws" / "illum-mini" / "scene.lfr", "--database", root / "calib", "--refocus", 1.5,
                  "-o", out)
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and "--refocus / --alpha" in errors[0] and "past the whole 87 x 125 picture" in errors[0]
    assert not [r.getMessage() for r in caplog.records if "refocusable range" in r.getMessage()], caplog.records
    assert not out.exists()


def test_one_liner_focus_at_with_no_depth_and_focus_distance_on_the_hci_scene(tmp_path):
    """'plenodecode RAW --focus-at X,Y --no-depth' was refused ('--no-depth applies to --focus-at only': the
    one-liner names its options with their metavars); --focus-distance's line did not say the distance; the depth
    way's depth map took 7 s without a word.  On hci-antinous both ways find the face's ground-truth disparity
    (1.784 px/view, 7 x 7 median) within 0.05 (measured 1.792 and 1.789), the depth way with a progress bar, and
    6.5 m reads as 'focus distance 6.5 m = slope ...'."""
    import re

    from plenodecode.io.pfm import read_pfm
    from tests.conftest import shared_path

    scene = shared_path("hci-antinous")
    truth = read_pfm(scene / "gt_disp_lowres.pfm")
    row, col = round(0.3 * 511), round(0.5 * 511)
    expected = float(np.median(truth[row - 3:row + 4, col - 3:col + 4]))
    for way in ([], ["--no-depth"]):
        out = tmp_path / f"face{len(way)}.png"
        res = run(scene, "--focus-at", "0.5,0.3", *way, "-o", out)
        assert res.exit_code == 0, res.output
        slope = float(re.search(r"slope ([+-][\d.]+) px/view", res.output).group(1))
        assert abs(slope - expected) < 0.05, (way, slope, expected)
        assert ("depth at --focus-at (fast)" in res.output) == (not way), res.output
        assert read_image(out).shape == (512, 512, 3)
    for args in (["--no-depth"], ["--slope", "1", "--no-depth"]):       # without --focus-at it means nothing
        res = run(scene, *args, "-o", tmp_path / "x.png")
        assert res.exit_code == 2 and "--no-depth applies to --focus-at only" in res.output
    assert not (tmp_path / "x.png").exists()
    res = run(scene, "--focus-distance", 6.5, "-o", tmp_path / "d.png")
    assert res.exit_code == 0, res.output
    assert re.search(r"px, 16-bit; focus distance 6\.5 m = slope \+1\.\d+ px/view", res.output), res.output


def test_a_slope_past_the_picture_of_a_raw_is_refused_before_decoding_it(tmp_path, monkeypatch):
    """'plenodecode refocus RAW --slope 2000' decoded the raw (a progress bar, about a second on the bundled Illum,
    minutes on a full-size one) and only then refused the slope.  The decoded shape (87 x 125, 15 x 15 views)
    and camera constants come from the calibration, so refocus, the one-liner and a focal stack refuse a slope,
    alpha or stack past the picture before decoding, with the message they gave after it (alpha 5 is slope
    48.66 on this raw, as decoded)."""
    from pathlib import Path

    from plenodecode.pipeline import source

    root = Path(__file__).resolve().parents[2]
    raw = root / "sample_raws" / "illum-mini" / "scene.lfr"
    decoded = []
    real_decode = source.decode_raw
    monkeypatch.setattr(source, "decode_raw", lambda *a, **k: decoded.append(1) or real_decode(*a, **k))
    cases = [(["refocus", raw, "--slope", 2000], "--slope", "slope 2000 px/view moves the outermost views 1.4e+04"),
             ([raw, "--slope", -2000], "--slope", "past the whole 87 x 125 picture (|slope| <= 17.9 here)"),
             ([raw, "--refocus", 5], "--refocus / --alpha", "slope 48.66 px/view moves the outermost views 341 px"),
             (["refocus", raw, "--alpha", 5], "--refocus / --alpha", "slope 48.66 px/view"),
             (["refocus", raw, "--focal-stack", "-2000:1:3"], "--focal-stack", "slope 2000 px/view"),
             (["refocus", raw, "--focal-stack", "0.5:5:3", "--stack-units", "alpha"], "--focal-stack",
              "slope 60.82 px/view")]
    for i, (args, option, words) in enumerate(cases):
        out = tmp_path / (f"out{i}" if "--focal-stack" in args else f"out{i}.png")
        res = run(*args, "--database", root / "calib", "-o", out)
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert f"Invalid value for {option}:" in errors[0] and words in errors[0], res.output
        assert "decoding" not in res.output and not decoded and not out.exists(), (args, res.output)
    res = run("refocus", raw, "--database", root / "calib", "--slope", 1, "-o", tmp_path / "ok.png")
    assert res.exit_code == 0 and decoded == [1], res.output       # a slope in reach is decoded as before


def test_no_depth_is_python_focus_at_method_sharpness_and_the_old_at_method_still_works(tmp_path):
    """'--focus-at 8,6 --no-depth' is render_product(..., focus_at_method='sharpness'), the same image; the keyword
    was 'at_method', which still works with a DeprecationWarning."""
    import pytest

    from plenodecode import pipeline

    lf = small_lf(colour="linear-srgb")
    out = tmp_path / "cli.exr"
    args = ("refocus", save_npy(tmp_path, lf), "--focus-at", "8,6", "--no-depth", "--bit-depth", 32, "-o", out)
    assert run(*args).exit_code == 0
    src = pipeline.Source(lightfield=lf)
    py = pipeline.render_product(src, "refocus", focus_at=(8, 6), focus_at_method="sharpness")
    (_, image), = py.images
    np.testing.assert_allclose(image, read_image(out), atol=1e-6)
    with pytest.warns(DeprecationWarning, match=r"render_product\(at_method=\) is deprecated: pass focus_at_method="):
        old = pipeline.render_product(src, "refocus", focus_at=(8, 6), at_method="sharpness")
    assert old.data["slope"] == py.data["slope"]
    with pytest.raises(ValueError, match="focus_at_method"):
        pipeline.render_product(src, "refocus", focus_at=(8, 6), focus_at_method="guess")
