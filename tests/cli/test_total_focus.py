"""``plenodecode RAW --total-focus``: the focused-plenoptic (Raytrix) renderer from the command line and batch,
measured against the generator's ground-truth all-in-focus image."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import pipeline, synthetic
from plenodecode.cli.main import cli
from plenodecode.io.images import read_image

#: The 'raytrix' preset with a Bayer sensor and a camera colour (white balance + CCM), so that the total-focus
#: image is demosaiced within the micro-images and converted to linear sRGB.
ILLUM_CCM = ((1.6182, -0.5113, -0.1069), (-0.2261, 1.4870, -0.2609), (0.0452, -0.6216, 1.5764))
COLOUR_RAYTRIX = dataclasses.replace(synthetic.PRESETS["raytrix"], name="raytrix-colour", cfa="GRBG",
                                     wb_gains=(1.8, 1.0, 1.0, 1.5), ccm=ILLUM_CCM)


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def shoot(tmp_path_factory):
    """A colour Raytrix-like raw + RayCalibData XML, its white image (+ XML) and the ground truth in a folder."""
    sim = synthetic.simulate(COLOUR_RAYTRIX, seed=2, shape=(350, 500), noise=False)
    folder = tmp_path_factory.mktemp("raytrix") / "shoot"
    paths = synthetic.write_simulation(sim, folder, name="scene")
    return {"raw": paths["raw"], "white": paths["white"], "folder": folder, "truth": sim.truth["total_focus"]}


def srgb_to_linear(png: np.ndarray) -> np.ndarray:
    """A 16-bit display-encoded PNG back to linear values (the inverse sRGB transfer function)."""
    v = png.astype(np.float64) / 65535.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def psnr_and_correlation(image: np.ndarray, render, truth: np.ndarray) -> tuple[float, np.ndarray]:
    """PSNR (dB) and per-channel correlation of ``image`` against the ground-truth total focus resampled at the
    rendering's scale (output px ``q`` shows sensor position ``q / scale``); the measure of
    tests/decoding/test_focused.py: pixels covered by the lenses (weight > 0.3), two lens spacings from the border."""
    ho, wo = image.shape[:2]
    qy, qx = np.mgrid[0:ho, 0:wo].astype(np.float32)
    ref = np.stack([cv2.remap(np.ascontiguousarray(truth[..., c]), qx / render.scale, qy / render.scale,
                              cv2.INTER_LINEAR) for c in range(truth.shape[2])], -1)
    m = render.weight > 0.3
    b = int(2 * render.spacing)
    m[:b], m[-b:], m[:, :b], m[:, -b:] = False, False, False, False
    psnr = -10 * np.log10(np.mean((image[m] - ref[m]) ** 2))
    corr = np.array([np.corrcoef(image[..., c][m], ref[..., c][m])[0, 1] for c in range(ref.shape[2])])
    return float(psnr), corr


def test_total_focus_one_liner_matches_the_ground_truth_in_colour(shoot, tmp_path):
    out = tmp_path / "tf.png"
    res = run(shoot["raw"], "--total-focus", "--white", shoot["white"], "-o", out)
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output and "total focus" in res.output
    png = read_image(out)
    assert png.dtype == np.uint16 and png.ndim == 3 and png.shape[2] == 3          # colour, 16 bits
    # the same rendering through the pipeline gives the geometry (scale, lens coverage) to resample the truth at
    src = pipeline.open_source(shoot["raw"], white=shoot["white"])
    assert src.calibration.source == "white image" and src.focused
    rendered = pipeline.render_product(src, "total-focus")
    render = rendered.data["render"]
    assert rendered.colour == "linear-srgb" and png.shape == rendered.images[0][1].shape
    psnr, corr = psnr_and_correlation(srgb_to_linear(png), render, shoot["truth"])
    # measured 29.5 dB and correlations 0.96 / 0.99 / 0.97; camera RGB (no colour matrix) gives 15 dB,
    # flipped micro-images 19 dB, no devignetting 19 dB, swapped red and blue 15 dB
    assert psnr > 27.0
    assert corr.min() > 0.94


def test_total_focus_uses_the_raytrix_xml_and_batch_writes_the_same_file(shoot, tmp_path):
    out = tmp_path / "tf.png"
    res = run(shoot["raw"], "--total-focus", "-o", out)
    assert res.exit_code == 0, res.output
    src = pipeline.open_source(shoot["raw"])
    assert src.calibration.source == "camera" and src.calibration.white is None      # the RayCalibData XML
    render = pipeline.render_product(src, "total-focus").data["render"]
    psnr, corr = psnr_and_correlation(srgb_to_linear(read_image(out)), render, shoot["truth"])
    # not devignetted (no white image): the corners are darker, the structure and colour are right
    # (measured 19 dB and correlations 0.96 / 0.98 / 0.96; flipped micro-images 0.38 .. 0.60, camera RGB 0.89)
    assert 15.0 < psnr < 27.0
    assert corr.min() > 0.94
    # batch: the raw is found beside its XML (the white image and the ground truth are not raws)
    db = tmp_path / "db"
    db.mkdir()
    res = run("batch", shoot["folder"], "-o", tmp_path / "batch", "--outputs", "total-focus", "--database", db,
              "--jobs", 1)
    assert res.exit_code == 0, res.output
    assert "1 done" in res.output
    assert (tmp_path / "batch" / "scene" / "total_focus.png").read_bytes() == out.read_bytes()


def test_total_focus_patch_option(shoot, tmp_path):
    out = tmp_path / "p.png"
    res = run(shoot["raw"], "--total-focus", "--patch", 7.5, "-o", out)
    assert res.exit_code == 0, res.output
    src = pipeline.open_source(shoot["raw"])
    render = pipeline.render_product(src, "total-focus", patch=7.5).data["render"]
    assert np.all(render.patch == 7.5) and read_image(out).shape[:2] == render.image.shape[:2]
    assert render.spacing == 7.5                     # one patch size: the output lens spacing is P
    # above the micro-image diameter (2 * radius, 32.8 px here): named, before anything is written
    res = run(shoot["raw"], "--total-focus", "--patch", 40, "-o", tmp_path / "x.png")
    assert res.exit_code == 2 and "--patch" in res.output and "32.8" in res.output
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("args, option", [
    (["--total-focus", "--slope", 0.5], "--total-focus"),
    (["--total-focus", "--refocus", 1.0], "--total-focus"),
    (["--slope", 0.5, "--patch", 5], "--patch"),
    (["--total-focus", "--method", "shift-sum"], "--method"),
    (["--total-focus", "--aperture", 0.5], "--aperture"),
    (["--total-focus", "--patch", 0], "--patch"),
])
def test_total_focus_option_combinations_are_usage_errors(shoot, tmp_path, args, option):
    out = tmp_path / "x.png"
    res = run(shoot["raw"], *args, "-o", out)
    assert res.exit_code == 2
    error = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(error) == 1 and option in error[0]
    assert not out.exists()


def test_total_focus_refuses_a_light_field_input(tmp_path):
    from plenodecode.io.lightfield import save_lightfield
    from plenodecode.types import LightField

    lf = LightField(np.zeros((3, 3, 4, 5, 1), np.float32), None, "srgb", {})
    src = save_lightfield(lf, tmp_path / "lf.npy")
    res = run(src, "--total-focus", "-o", tmp_path / "x.png")
    assert res.exit_code == 2 and "--total-focus" in res.output and "lightfield" in res.output
    with pytest.raises(ValueError, match="light field"):
        pipeline.render_product(pipeline.Source(lightfield=lf), "total-focus")


def test_without_a_focus_option_a_focused_raw_gets_its_total_focus(shoot, tmp_path):
    """``plenodecode RAW -o photo.png`` (no focus option) on a focused-plenoptic raw: the total focus (its
    decoded light field has a few lenses' worth of pixels), as close to the ground truth as ``--total-focus``."""
    res = run(shoot["raw"], "--white", shoot["white"], "-o", tmp_path / "photo.png")
    assert res.exit_code == 0, res.output
    assert " px, 16-bit; the camera's total focus; refocus it at a virtual depth" in res.output
    explicit = run(shoot["raw"], "--white", shoot["white"], "--total-focus", "-o", tmp_path / "tf.png")
    assert explicit.exit_code == 0, explicit.output
    np.testing.assert_array_equal(read_image(tmp_path / "photo.png"), read_image(tmp_path / "tf.png"))


def test_total_focus_of_a_raw_without_lens_types_warns_once(tmp_path, caplog):
    """The warning that a grid without lens types is no focused-plenoptic raw was logged twice per photograph
    once the colour image and the total focus were shared between products; it is said once."""
    from pathlib import Path

    illum = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini" / "scene.lfr"
    with caplog.at_level("WARNING"):
        res = CliRunner().invoke(cli, [str(illum), "--total-focus", "-o", str(tmp_path / "tf.png")])
    assert res.exit_code == 0, res.output
    said = [r.getMessage() for r in caplog.records if "has no lens types" in r.getMessage()]
    assert len(said) == 1 and "total focus expects a focused-plenoptic raw" in said[0]
    assert read_image(tmp_path / "tf.png").ndim == 3
