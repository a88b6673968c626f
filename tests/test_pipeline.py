"""The workflow layer: the single-purpose commands and ``plenodecode batch`` write the same bytes for the same raw
and options; the calibration policy; failed folder products leave no folder.

Generated 'illum-mini' raws on a tiny 200 x 280 sensor (17 x 20 lenses) keep it fast.
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.errors import CalibrationError
from plenodecode.cli.main import cli
from plenodecode.io.images import read_image, srgb_encode
from plenodecode.types import LightField

SHAPE = (200, 280)
SLOPE = "0.3"


@pytest.fixture(scope="module")
def shoot(tmp_path_factory):
    """One raw in its own folder and a calibration database built from its camera's white image."""
    from plenodecode.calib.store import build_database
    from plenodecode.synthetic import simulate, write_simulation

    root = tmp_path_factory.mktemp("pipeline")
    files = write_simulation(simulate("illum-mini", seed=1, shape=SHAPE), root / "take", name="scene")
    whites = root / "whites"
    whites.mkdir()
    for f in (root / "take").glob("MOD_0000.*"):
        shutil.copy(f, whites / f.name)
    (root / "db").mkdir()
    build_database(whites, root / "db")
    return {"root": root, "raw": Path(files["raw"]), "db": root / "db"}


def run(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


def commands_and_batch(shoot, out: Path) -> tuple[Path, Path]:
    """The raw through decode, refocus, views and depth, and through batch with the same options."""
    raw, db = shoot["raw"], shoot["db"]
    single = out / "single"
    run("-q", "decode", raw, "--database", db, "-o", single / "lf.zarr")
    run("-q", "refocus", raw, "--slope", SLOPE, "--database", db, "-o", single / "refocus.png")
    run("-q", "views", raw, "--database", db, "-o", single / "views")
    run("-q", "depth", raw, "--method", "fast", "--database", db, "-o", single / "disparity.pfm")
    run("-q", "batch", raw, "-o", out / "batch", "--jobs", 1, "--database", db, "--slope", SLOPE,
        "--outputs", "lightfield,centre,refocus,depth,views", "--depth-method", "fast")
    return single, out / "batch" / raw.stem


def test_commands_and_batch_write_the_same_bytes(shoot, tmp_path):
    from plenodecode.io.lightfield import load_lightfield

    single, batch = commands_and_batch(shoot, tmp_path)
    assert (single / "refocus.png").read_bytes() == (batch / "refocus_s+0.30.png").read_bytes()
    assert (single / "disparity.pfm").read_bytes() == (batch / "disparity.pfm").read_bytes()
    lf = load_lightfield(single / "lf.zarr")
    np.testing.assert_array_equal(lf.data, load_lightfield(batch / "lightfield.zarr").data)
    vc, uc = lf.shape[0] // 2, lf.shape[1] // 2
    assert (single / "views" / f"view_{vc:02d}_{uc:02d}.png").read_bytes() == (batch / "centre.png").read_bytes()
    # batch's 'views' are the views command's pictures (they were a views light field, input_CamNNN.png)
    names = sorted(p.name for p in (single / "views").iterdir())
    assert names == sorted(p.name for p in (batch / "views").iterdir()) and len(names) == lf.shape[0] * lf.shape[1]
    assert all((single / "views" / n).read_bytes() == (batch / "views" / n).read_bytes() for n in names)


def test_float_outputs_are_the_same_bytes_too(shoot, tmp_path):
    """--bit-depth 32: the refocused photograph and the centre view are linear float EXRs, identical from both."""
    raw, db = shoot["raw"], shoot["db"]
    single = tmp_path / "single"
    run("-q", "refocus", raw, "--slope", SLOPE, "--database", db, "--bit-depth", 32, "-o", single / "refocus.exr")
    run("-q", "views", raw, "--database", db, "--bit-depth", 32, "--ext", "exr", "-o", single / "views")
    run("-q", "batch", raw, "-o", tmp_path / "batch", "--jobs", 1, "--database", db, "--slope", SLOPE,
        "--outputs", "centre,refocus", "--bit-depth", 32)
    batch = tmp_path / "batch" / raw.stem
    assert (single / "refocus.exr").read_bytes() == (batch / "refocus_s+0.30.exr").read_bytes()
    views = sorted((single / "views").glob("view_*.exr"))
    centre = views[len(views) // 2]
    assert (single / "views" / centre.name).read_bytes() == (batch / "centre.exr").read_bytes()
    photo = read_image(batch / "refocus_s+0.30.exr")
    assert photo.dtype == np.float32 and float(photo.max()) > 0.05    # linear, not display-encoded 16-bit


def test_batch_refocus_by_alpha_matches_the_one_liner(shoot, tmp_path):
    """--refocus ALPHA means the same in `plenodecode RAW` and in `plenodecode batch`: the same file bytes."""
    raw, db = shoot["raw"], shoot["db"]
    run("-q", raw, "--refocus", "1.005", "--database", db, "-o", tmp_path / "one.png")
    run("-q", "batch", raw, "-o", tmp_path / "batch", "--jobs", 1, "--database", db, "--outputs", "refocus",
        "--refocus", "1.005")
    written = sorted((tmp_path / "batch" / raw.stem).glob("refocus*.png"))
    assert len(written) == 1
    assert written[0].read_bytes() == (tmp_path / "one.png").read_bytes()
    res = CliRunner().invoke(cli, ["batch", str(raw), "-o", str(tmp_path / "b2"), "--database", str(db),
                                   "--alpha", "1.0", "--focus-distance", "2"])
    assert res.exit_code == 2 and "--focus-distance" in res.output and not (tmp_path / "b2").exists()


def test_camera_rgb_light_fields_are_encoded_alike(shoot, tmp_path, monkeypatch):
    """A light field in camera RGB: batch used to write it without the sRGB encoding, the commands with it."""
    real = pipeline.decode_raw

    def camera_rgb(*args, **kw):
        return real(*args, **kw).replace(colour="camera")

    monkeypatch.setattr(pipeline.source, "decode_raw", camera_rgb)     # what Source.lightfield calls
    single, batch = commands_and_batch(shoot, tmp_path)
    assert (single / "refocus.png").read_bytes() == (batch / "refocus_s+0.30.png").read_bytes()
    lf = pipeline.Source(raw=pipeline.open_input(shoot["raw"]),
                         calibration=pipeline.choose_calibration(pipeline.open_input(shoot["raw"]),
                                                                 database=shoot["db"])).lightfield
    assert lf.colour == "camera"
    centre = read_image(batch / "centre.png") / 65535.0
    np.testing.assert_allclose(centre, srgb_encode(np.clip(lf.centre_view(), 0, 1)), atol=1e-4)


def test_display_encoding_rule():
    assert pipeline.display_encoding("linear-srgb", 16) and pipeline.display_encoding("camera", 8)
    assert not pipeline.display_encoding("camera", 32) and not pipeline.display_encoding("srgb", 16)


def test_calibration_policy_logs_one_line(shoot, tmp_path, caplog):
    raw = pipeline.open_input(shoot["raw"])
    with caplog.at_level(logging.INFO, logger="plenodecode.pipeline"):
        cal = pipeline.choose_calibration(raw, database=shoot["db"])
    assert cal.source == "database" and cal.white is not None
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("calibration:")]
    assert lines == [f"calibration: database {shoot['db']}/ (white MOD_0000.RAW, cached grid)"]
    grid = tmp_path / "grid.json"
    grid.write_text(cal.grid.to_json(), encoding="utf-8")
    explicit = pipeline.choose_calibration(raw, grid=grid, database=shoot["db"])      # an explicit grid wins
    assert explicit.source == "grid file" and explicit.white is None
    with pytest.raises(CalibrationError, match="--self-calibrate"):
        pipeline.choose_calibration(raw, database=tmp_path / "nothing")
    scene = pipeline.choose_calibration(raw, database=tmp_path / "nothing", self_calibrate=True)
    assert scene.source == "self-calibration" and scene.white is None
    assert abs(scene.grid.pitch - cal.grid.pitch) < 0.05 * cal.grid.pitch


def test_products_registry_names():
    assert set(pipeline.PRODUCTS) == {"photo", "centre", "views", "refocus", "focal-stack", "all-in-focus", "parallax",
                                      "depth", "total-focus", "focused-refocus"}
    with pytest.raises(ValueError, match="product must be one of"):
        pipeline.render_product(pipeline.Source(lightfield=small_lf()), "thumbnail")


def small_lf(colour="srgb"):
    data = np.random.default_rng(0).random((5, 5, 14, 18, 3), dtype=np.float32)
    return LightField(data, None, colour, {"spatial_step_px": 12.37, "view_step_px": 1.0})


def test_failed_parallax_and_focal_stack_leave_no_folder(tmp_path):
    from plenodecode.io.lightfield import save_lightfield

    src = save_lightfield(small_lf(), tmp_path / "lf.npy")
    before = sorted(p.name for p in tmp_path.iterdir())
    res = CliRunner().invoke(cli, ["parallax", str(src), "-o", str(tmp_path / "w.gif"), "--radius", "5"])
    assert res.exit_code == 2
    assert not (tmp_path / "w_frames").exists() and not (tmp_path / "w.gif").exists()
    # alpha units need the camera constants, which this light field lacks: a usage error naming --stack-units
    res = CliRunner().invoke(cli, ["refocus", str(src), "--focal-stack", "0.99:1.01:3", "--stack-units", "alpha",
                                   "-o", str(tmp_path / "stack")])
    assert res.exit_code == 2 and "--stack-units" in res.output, res.output
    assert not (tmp_path / "stack").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_folder_product_into_an_existing_folder_keeps_other_files(tmp_path):
    folder = tmp_path / "views"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    rendered = pipeline.render_product(pipeline.Source(lightfield=small_lf()), "views")
    written = pipeline.write_product(rendered, folder, bit_depth=8)
    assert len(written) == 25 and (folder / "notes.txt").read_text() == "mine"
    with pytest.raises(FileExistsError):
        pipeline.write_product(rendered, folder, bit_depth=8)
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == []


@pytest.mark.parametrize("change, missing", [
    ({}, ()),
    ({"focal_length_m": None}, ("focal_length_m",)),
    ({"focal_length_m": None, "f_number": None}, ("focal_length_m", "f_number")),
    ({"lens_pitch_m": None}, ()),                                 # the calibrated pitch times the pixel pitch
    ({"lens_pitch_m": None, "pixel_pitch_m": None}, ("lens_pitch_m",)),
])
def test_constants_missing_from_a_raw_are_those_its_light_field_lacks(change, missing):
    """The check before calibration (:func:`missing_refocus_constants` of the raw's metadata) predicts what the
    decoded light field lacks, so alpha is refused exactly when the conversion would fail after decoding."""
    from dataclasses import replace as dc_replace

    from plenodecode.errors import MetadataError, MissingConstantsError
    from plenodecode.render import alpha_to_slope
    from plenodecode.render.alpha import missing_refocus_constants
    from plenodecode.synthetic import simulate

    sim = simulate("illum-mini", seed=1, shape=(200, 280), noise=False)
    raw = dc_replace(sim.raw, metadata=dc_replace(sim.raw.metadata, **change))
    assert missing_refocus_constants(raw.metadata) == missing
    src = pipeline.Source(raw=raw, calibration=pipeline.Calibration(sim.grid, None, "grid file"))
    if missing:
        with pytest.raises(MissingConstantsError) as info:
            pipeline.check_product(raw, "refocus", alpha=1.01)
        assert info.value.missing == missing
        assert "lightfield" not in src.__dict__                   # refused without decoding
    else:
        pipeline.check_product(raw, "refocus", alpha=1.01)
    lf = src.lightfield
    assert missing_refocus_constants(lf) == missing
    if missing:
        with pytest.raises(MetadataError, match=missing[0]):
            alpha_to_slope(1.01, lf)
    else:
        assert alpha_to_slope(1.01, lf) > 0


def test_views_partly_outside_the_micro_images_are_black():
    """``ViewImages`` (the ``views`` product) writes a view whose samples carry data in under
    :data:`~plenodecode.imaging.MIN_VIEW_DATA` of the pixels black, and every other view as ``perspective``."""
    from plenodecode.imaging import MIN_VIEW_DATA, view_data_share
    from plenodecode.pipeline.products import ViewImages
    from plenodecode.render import perspective

    rng = np.random.default_rng(0)
    data = rng.uniform(0.2, 0.8, (3, 3, 20, 24, 3)).astype(np.float32)
    weight = np.ones((3, 3, 20, 24), np.float32)
    weight[0, 0, ::2] = 0.005       # half the rows below MIN_DATA_WEIGHT: the lens edges of a corner view
    weight[0, 2, :1] = 0.0          # one row without data: the frame's edge
    lf = LightField(data=data, weight=weight)
    share = view_data_share(weight)
    assert share[0, 0] == pytest.approx(0.5) and share[0, 2] == pytest.approx(19 / 20) and share[1, 1] == 1.0
    images = ViewImages(lf)
    assert images.dark == [(0, 0)] and share[0, 2] >= MIN_VIEW_DATA
    assert len(images) == 9 and not images[0][1].any() and images[0][0] == "view_00_00"
    for k in range(1, 9):
        np.testing.assert_array_equal(images[k][1], perspective(lf, k // 3, k % 3))


def test_exposure_scales_linear_light_of_every_colour_state():
    """``exposure`` multiplies the linear light by 2^EV: directly for linear states, through the sRGB curve for
    display-encoded ('srgb') images; 'auto' puts the middle image's brightest 0.5 % at full scale; a bad value
    is a ValueError naming exposure."""
    from plenodecode.io.images import srgb_decode, srgb_encode
    from plenodecode.pipeline import AUTO_EXPOSURE, Rendered, expose, exposure_gain

    rng = np.random.default_rng(0)
    linear = rng.uniform(0.0, 0.2, (16, 16, 3)).astype(np.float32)
    lin = Rendered("refocus", (("photo", linear),), "linear-srgb")
    enc = Rendered("refocus", (("photo", srgb_encode(linear)),), "srgb")
    assert exposure_gain(lin, 1.5) == pytest.approx(2 ** 1.5)
    np.testing.assert_allclose(expose(linear, "camera", 4.0), 4.0 * linear, rtol=1e-6)
    np.testing.assert_allclose(srgb_decode(expose(srgb_encode(linear), "srgb", 4.0)), 4.0 * linear, atol=2e-4)
    for r in (lin, enc):
        gain = exposure_gain(r, AUTO_EXPOSURE)
        assert gain == pytest.approx(1.0 / np.percentile(linear.max(axis=-1), 99.5), rel=1e-3)
    for bad in ("bright", 11.0, float("nan")):
        with pytest.raises(ValueError, match="exposure"):
            exposure_gain(lin, bad)
