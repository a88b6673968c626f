"""``plenodecode info`` gives the same facts for every camera's raw: the lens pitch (measured or read, and where
from), the calibration decoding will use and its files, the decoded shape and the refocusable range.

It used to show the pitch and the range for a Lytro container only (from its metadata): nothing for the real F01
JPEG mosaic, whose lattice self-calibration measures, and nothing of the Raytrix XML beside the R42 image that
decoding uses; the F01 and Illum focus stacks called Lytro's lambda 'lambda' and 'focus'.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import shared_path

ROOT = Path(__file__).resolve().parents[2]
FACTS = ("lenses", "calib", "refocus")


def info(path) -> str:
    res = CliRunner().invoke(cli, ["info", str(path)])
    assert res.exit_code == 0, res.output
    return res.output


def fields(out: str) -> dict[str, str]:
    """``{'lenses': 'hex, pitch ...', ...}``: the two-space indented lines of one file's description."""
    return {m.group(1): m.group(2) for m in re.finditer(r"^  (\w+) +(.*)$", out, re.M)}


def test_f01_jpeg_pitch_is_measured_and_matches_the_cameras_lens_table():
    """IMG_1.jpg has no metadata: the pitch is measured by self-calibration (9.933 px), which is the pitch of the
    camera's own lens-centre table image_cords.mat (9.932 px, a line through each row of it), and the refocusable
    range follows from it: +-pitch / row spacing = +-2 / sqrt(3) px/view on a hex lattice."""
    import scipy.io as sio

    f = fields(info(shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")))
    assert set(FACTS) <= set(f), f
    m = re.fullmatch(r"hex, pitch (\d+\.\d+) px measured in the scene by self-calibration; (\d+) x (\d+) lenses",
                     f["lenses"])
    assert m, f["lenses"]
    pitch = float(m.group(1))
    table = sio.loadmat(str(shared_path("lytro-f01-lenslet-jpg", "image_cords.mat")))["image_cords"].astype(float)
    k = np.arange(table.shape[1])
    table_pitch = np.median([np.polyfit(k, table[r, :, 1], 1)[0] for r in range(table.shape[0])])
    assert abs(pitch - table_pitch) < 0.01, (pitch, table_pitch)
    assert f["calib"].startswith("self-calibration from IMG_1.jpg (no white image or camera identity for a "
                                 "database: not devignetted; stays camera RGB")
    assert f["decodes"] == "9 x 9 views of 382 x 383 px"
    s = 2 / math.sqrt(3)
    assert f["refocus"].startswith(f"slope {-s:+.2f}..{s:+.2f} px/view (from the calibration; alpha needs "), f
    assert "focal_length_m" in f["refocus"]


def test_lytro_raw_gives_the_same_facts_with_the_pitch_read_and_measured():
    f = fields(info(ROOT / "sample_raws" / "illum-mini" / "scene.lfr"))
    assert set(FACTS) <= set(f), f
    assert "lenslet pitch 14.286 px (metadata)" in f["lens"] and "zoom step -312, focus step 417" in f["lens"]
    assert re.fullmatch(r"hex, pitch 14\.28\d px measured on the white image MOD_0000\.RAW \(the metadata: "
                        r"14\.286 px\); 87 x 109 lenses", f["lenses"]), f["lenses"]
    assert f["calib"] == f"database {ROOT / 'calib'}/ (white MOD_0000.RAW, cached grid)"
    assert f["decodes"] == "15 x 15 views of 125 x 87 px"
    assert f["refocus"] == "alpha 0.9814-1.0194 = slope -1.15..+1.15 px/view (from the calibration and the metadata)"


def test_raytrix_image_names_the_xml_it_is_decoded_with():
    f = fields(info(shared_path("raytrix-r42", "sc2_klein.png")))
    assert set(FACTS) <= set(f), f
    assert f["lenses"] == "hex, pitch 34.865 px read from sc2_klein.xml; 22 x 28 lenses, 3 lens types"
    assert f["calib"] == "camera (Raytrix RayCalibData sc2_klein.xml)"
    assert f["refocus"].startswith("virtual depth 1.07..100 (focused plenoptic: ")


def test_microscope_optics_file_and_measured_pitch():
    """The LFAnalyze README beside the ant-leg capture gives 125 um lenses on 4.55 um pixels (27.47 px);
    self-calibration measures 27.56 px."""
    f = fields(info(shared_path("lf-microscopy-antleg", "light_field.png")))
    assert set(FACTS) <= set(f), f
    assert f["optics"].startswith("lens-pitch-um 125 um, pixel-um 4.55 um") and f["optics"].endswith(
        "(read from README)")
    m = re.fullmatch(r"square, pitch (\d+\.\d+) px measured in the scene by self-calibration \(the optics: "
                     r"27\.473 px\); \d+ x \d+ lenses", f["lenses"])
    assert m and abs(float(m.group(1)) - 125 / 4.55) < 0.15, f["lenses"]
    assert f["calib"].startswith("self-calibration from light_field.png")
    assert "alpha" not in f["refocus"]               # a microscope refocuses by slope: no constants asked for


def test_focus_stacks_of_both_lytro_cameras_say_lambda():
    f01 = info(shared_path("lytro-containers", "IMG_0001-stk.lfp"))
    illum = info(shared_path("lytro-containers", "demo.LFP"))
    assert "refocus_00             jpeg 1080x1080 (lambda -8.923)" in f01
    assert "focus_stack_00         jpeg 704x480 (lambda -15)" in illum
    assert "(focus " not in f01 + illum


def test_no_database_says_where_it_looked(tmp_path, monkeypatch):
    import shutil

    shutil.copy(ROOT / "sample_raws" / "illum-mini" / "scene.lfr", tmp_path / "scene.lfr")
    monkeypatch.chdir(tmp_path)
    f = fields(info(tmp_path / "scene.lfr"))
    assert f["calib"].startswith("none found: no calibration for scene.lfr (camera ILLUM B5143909630): no "
                                 f"calibration database (looked for its index.json in {tmp_path / 'calib'}")
    assert f["refocus"] == "alpha 0.9814-1.0194 = slope -1.15..+1.15 px/view (from the metadata, hex lenslets)"


def test_dark_frame_is_named_as_such_without_self_calibrating_it():
    f = fields(info(shared_path("lf-microscopy-antleg", "dark_frame.tif")))
    assert f["calib"] == ("none: no micro-images (98 % of the values within 95..107); a dark frame is given to "
                          "decoding as --dark FRAME")
    assert "lenses" not in f and "refocus" not in f


def test_real_f01_frame_metadata_gives_the_range_its_metadata_allows():
    """The F01's real frame JSON names its make 'Lytro, Inc.', which the metadata range skipped ('Lytro' only)."""
    f = fields(info(shared_path("lytro-containers", "IMG_0001__frame.json")))
    assert f["refocus"].startswith("alpha 0.96") and f["refocus"].endswith(
        "slope -1.15..+1.15 px/view (from the metadata, hex lenslets)"), f


def test_mosaic_with_a_sidecar_names_it_and_its_database_white():
    out = info(ROOT / "sample_raws" / "square" / "scene.png")
    assert out.splitlines()[0].endswith("scene.png: raw image with metadata scene.json")
    f = fields(out)
    assert re.fullmatch(r"square, pitch 27\.5\d\d px measured on the white image scene_white\.png \(the metadata: "
                        r"27\.500 px\); 41 x 41 lenses", f["lenses"]), f["lenses"]
    assert f["calib"] == f"database {ROOT / 'calib'}/ (white scene_white.png, cached grid)"


def test_raytrix_image_between_two_xmls_says_which_choice_decoding_needs(tmp_path):
    """The R42 image beside two RayCalibData XMLs, neither of its stem: info said 'a single-channel mosaic is
    expected, found 3 channels'; it now gives the reason decoding gives, the XML choice to make."""
    import shutil

    shutil.copy(shared_path("raytrix-r42", "sc2_klein.png"), tmp_path / "scene.png")
    for name in ("a.xml", "b.xml"):
        shutil.copy(shared_path("raytrix-r42", "sc2_klein.xml"), tmp_path / name)
    res = CliRunner().invoke(cli, ["info", str(tmp_path / "scene.png")])
    assert res.exit_code == 1 and res.output.strip() == (
        "error: scene.png: 2 RayCalibData XMLs beside it (a.xml, b.xml) and none named scene.xml; say which one "
        "with --raytrix-xml FILE"), res.output


def test_raytrix_xml_option_follows_the_two_xml_hint(tmp_path):
    """info named '--raytrix-xml FILE' for the R42 image between two XMLs but had no such option: it now takes it
    as decoding does (the pitch and lens types read from the file chosen), and refuses it, as decoding does, for
    what is no XML and for a file that is no Raytrix image."""
    import shutil

    shutil.copy(shared_path("raytrix-r42", "sc2_klein.png"), tmp_path / "scene.png")
    shutil.copy(shared_path("raytrix-r42", "sc2_klein.xml"), tmp_path / "a.xml")
    shutil.copy(shared_path("raytrix-r42", "sc2_klein.xml"), tmp_path / "b.xml")
    res = CliRunner().invoke(cli, ["info", str(tmp_path / "scene.png"), "--raytrix-xml", str(tmp_path / "b.xml")])
    assert res.exit_code == 0, res.output
    f = fields(res.output)
    assert f["lenses"] == "hex, pitch 34.865 px read from b.xml; 22 x 28 lenses, 3 lens types", f
    assert f["calib"] == "camera (Raytrix RayCalibData b.xml)"
    bad = CliRunner().invoke(cli, ["info", str(tmp_path / "scene.png"), "--raytrix-xml", str(ROOT / "README.md")])
    assert bad.exit_code == 2 and "Invalid value for '--raytrix-xml'" in bad.output, bad.output
    lfr = CliRunner().invoke(cli, ["info", str(ROOT / "sample_raws" / "illum-mini" / "scene.lfr"), "--raytrix-xml",
                                   str(tmp_path / "a.xml")])
    assert lfr.exit_code == 1 and lfr.output.strip() == (
        "error: scene.lfr: --raytrix-xml applies to Raytrix images (.png, .tif, .tiff, .bmp, .jpg, .jpeg, .exr, "
        ".pgm, .ppm); this is not one"), lfr.output


def test_microscope_hints_name_the_radiometry_frame_beside_it():
    """The ant leg's info said '-w WHITE_IMAGE devignettes' with radiometry_frame.png beside it, and described that
    frame as a scene to devignette with a white image; each now names what to do with it."""
    folder = shared_path("lf-microscopy-antleg")
    f = fields(info(folder / "light_field.png"))
    assert f["calib"].endswith(f"; -w {folder / 'radiometry_frame.png'}, the flat-field frame beside it, calibrates "
                               "and devignettes)"), f["calib"]
    f = fields(info(folder / "radiometry_frame.png"))
    assert f["calib"] == ("self-calibration from radiometry_frame.png (by its name the flat-field frame: given as -w "
                          "to decode the light fields beside it, it calibrates and devignettes them)"), f["calib"]

