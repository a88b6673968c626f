"""The colour label of light fields written for viewing, through the CLI.

A real Lytro F01 JPEG (Tao et al.) decodes without a white image or colour matrix: its light field is camera RGB.
Its 8-bit views, 8-bit ESLF and ``export --srgb`` were labelled 'srgb', so ``info``, a reload in Python and an export
of them said sRGB and linearising took camera RGB for sRGB colours.  They are 'camera-srgb-curve' now (camera RGB
with the sRGB tone curve), read back so and linearise to 'camera'; a Lytro raw decoded with its white image (and so
its colour matrix) still writes 'srgb'.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.lightfield import linearise, load_lightfield
from tests.conftest import shared_path

CAMERA_WORDS = "camera RGB with the sRGB tone curve"
#: Largest |linearised - linear| in [0, 1]: half a step of the stored code (plus float32 rounding of the encoding)
#: through the inverse curve's steepest slope, 2.4 / 1.055 at full scale (measured on IMG_1.jpg: 8-bit 0.004455,
#: 16-bit 1.74e-5, against the bounds 0.004463 and 1.96e-5).
TOL8, TOL16 = (0.5 / 255 + 1e-6) * 2.4 / 1.055, (0.5 / 65535 + 1e-6) * 2.4 / 1.055
ILLUM_MINI = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini"


def run(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res.output


@pytest.fixture(scope="module")
def f01_lf(tmp_path_factory):
    """IMG_1.jpg decoded as a user types it (no white image): a camera-RGB zarr light field."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    out = tmp_path_factory.mktemp("f01") / "lf.zarr"
    run("-q", "decode", jpeg, "-o", out)
    return out


def stored_colour(path: Path) -> tuple[str, str]:
    """(colour, geometry colour) in the JSON a views folder or an ESLF image keeps beside its pictures."""
    doc = json.loads((path / "lightfield.json" if path.is_dir() else path.with_suffix(".json")).read_text())
    return doc["colour"], doc["geometry"]["colour"]


def test_f01_jpeg_views_and_eslf_for_viewing_are_labelled_camera_rgb(f01_lf, tmp_path):
    lf = load_lightfield(f01_lf)
    assert lf.colour == "camera"
    linear = np.clip(lf.data, 0.0, 1.0)
    cases = [(("--format", "views", "--bit-depth", "8"), "v8", TOL8), (("--bit-depth", "8"), "e8.png", TOL8),
             (("--format", "views", "--srgb"), "v16", TOL16)]
    for args, name, tol in cases:
        out = tmp_path / name
        said = run("export", f01_lf, "-o", out, *args)
        assert f"views of 383x382, {CAMERA_WORDS})" in said and "sRGB)" not in said, said
        assert stored_colour(out) == ("camera-srgb-curve", "camera-srgb-curve"), name
        info = run("info", out).splitlines()[0]
        assert info.endswith(f"(V, U, Y, X, C), {CAMERA_WORDS}"), info
        back = load_lightfield(out)
        assert back.colour == "camera-srgb-curve" and back.geometry.display_encoded
        lin = linearise(back)
        assert lin.colour == "camera"
        err = np.abs(lin.data - linear).max()
        assert err <= tol, (name, err)
        # it is the curve, not the colours: the encoded values are far from the linear ones
        assert np.median(back.centre_view()) > 1.5 * np.median(lf.centre_view()) > 0
    # an export of the 8-bit views keeps the label (a reader and a writer in a row), and --srgb is refused on them
    said = run("export", tmp_path / "v8", "-o", tmp_path / "v8.mat")
    assert CAMERA_WORDS in said and load_lightfield(tmp_path / "v8.mat").colour == "camera-srgb-curve"
    res = CliRunner().invoke(cli, ["export", str(tmp_path / "v8"), "-o", str(tmp_path / "again"), "--srgb"])
    assert res.exit_code == 2 and "--srgb: v8 is sRGB-encoded already (colour 'camera-srgb-curve')" in res.output
    assert not (tmp_path / "again").exists()


def test_decode_to_8_bit_views_labels_camera_rgb_and_srgb_apart(tmp_path):
    """'decode' itself: a Lytro raw with its white image (so its colour matrix) still writes 'srgb' and says sRGB;
    the same raw with --colour camera writes 'camera-srgb-curve' and says so."""
    base = ["decode", ILLUM_MINI / "scene.lfr", "-w", ILLUM_MINI / "MOD_0000.RAW", "--format", "views",
            "--bit-depth", "8"]
    said = run(*base, "-o", tmp_path / "srgb")
    assert "views of 87x125, sRGB)" in said, said
    said_cam = run(*base, "-o", tmp_path / "cam", "--colour", "camera")
    assert f"views of 87x125, {CAMERA_WORDS})" in said_cam, said_cam
    assert stored_colour(tmp_path / "srgb") == ("srgb", "srgb")
    assert stored_colour(tmp_path / "cam") == ("camera-srgb-curve", "camera-srgb-curve")
    assert run("info", tmp_path / "srgb").splitlines()[0].endswith("(V, U, Y, X, C), sRGB")
    srgb, cam = load_lightfield(tmp_path / "srgb"), load_lightfield(tmp_path / "cam")
    assert (srgb.colour, linearise(srgb).colour) == ("srgb", "linear-srgb")
    assert (cam.colour, linearise(cam).colour) == ("camera-srgb-curve", "camera")
    # the colour matrix is what differs: the two files hold different colours of the same picture
    assert np.abs(srgb.centre_view() - cam.centre_view()).max() > 0.05


def test_pictures_carry_the_colour_space_of_their_pixels(f01_lf, tmp_path):
    """The files' own colour tag (OpenImageIO ``oiio:ColorSpace``): camera RGB no longer claims sRGB primaries.
    A PNG tagged sRGB gets sRGB + cHRM (sRGB primaries) chunks; camera RGB gets neither, so a colour-managed viewer
    is not told its sensor colours are sRGB ones; linear sRGB in a float EXR reads back as linear Rec.709."""
    from tests.io.test_images import png_chunks, stored_colour_space

    srgb_claim = {"sRGB", "cHRM"}
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    run("-q", jpeg, "-o", tmp_path / "f01.png")                                # the photograph, camera RGB
    run("-q", jpeg, "-o", tmp_path / "f01.exr", "--bit-depth", "32")
    run("export", f01_lf, "-o", tmp_path / "v8", "--format", "views", "--bit-depth", "8")
    run("export", f01_lf, "-o", tmp_path / "eslf.png", "--bit-depth", "8")
    for png in (tmp_path / "f01.png", tmp_path / "v8" / "input_Cam040.png", tmp_path / "eslf.png"):
        assert not srgb_claim & set(png_chunks(png)), png
    assert stored_colour_space(tmp_path / "f01.exr") == "unknown"
    # a Lytro raw decoded with its white image (and colour matrix) is sRGB, and says so
    run("-q", ILLUM_MINI / "scene.lfr", "-w", ILLUM_MINI / "MOD_0000.RAW", "-o", tmp_path / "illum.png")
    run("-q", ILLUM_MINI / "scene.lfr", "-w", ILLUM_MINI / "MOD_0000.RAW", "-o", tmp_path / "illum.exr",
        "--bit-depth", "32")
    assert srgb_claim <= set(png_chunks(tmp_path / "illum.png"))
    assert stored_colour_space(tmp_path / "illum.exr") == "lin_rec709_scene"
