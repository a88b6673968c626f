"""``plenodecode RAW -o photo.png`` without a focus option: the camera's own photograph, focused as captured
(slope 0, the default of batch's 'refocus' product) or, for a focused-plenoptic (Raytrix) raw, its total focus
(the slope-0 rendering of a Raytrix raw's decoded light field is a 31 x 22 px thumbnail)."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.images import read_image
from tests.conftest import shared_path

CHOOSE = "choose the focus with --slope or --focus-at"      # the F01 JPEGs: no camera constants, no focus distance


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_real_f01_jpeg_without_a_focus_option_is_its_photograph_focused_as_captured(tmp_path):
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    res = run(jpeg, "-o", tmp_path / "photo.png")
    assert res.exit_code == 0, res.output
    assert "focused as captured: slope +0.000 px/view" in res.output and CHOOSE in res.output
    photo = read_image(tmp_path / "photo.png")
    explicit = run(jpeg, "--slope", "0", "-o", tmp_path / "slope0.png")
    assert explicit.exit_code == 0, explicit.output
    np.testing.assert_array_equal(photo, read_image(tmp_path / "slope0.png"))
    # a photograph of the decoded views' size with the scene's tones, not a grey field
    assert photo.shape == (383, 382, 3)
    grey = photo.astype(np.float64).mean(axis=-1) / 65535.0
    low, high = np.percentile(grey, [1, 99])
    assert high - low > 0.6, (low, high)


def test_real_raytrix_without_a_focus_option_is_its_total_focus(tmp_path):
    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    res = run(r42, "-o", tmp_path / "photo.png")
    assert res.exit_code == 0, res.output
    # its focus is chosen by virtual depth, not by the options of a light field, which it refuses
    assert " px, 16-bit; the camera's total focus; refocus it at a virtual depth" in res.output
    assert CHOOSE not in res.output
    total = run(r42, "--total-focus", "-o", tmp_path / "total.png")
    assert total.exit_code == 0, total.output
    photo = read_image(tmp_path / "photo.png")
    np.testing.assert_array_equal(photo, read_image(tmp_path / "total.png"))
    assert photo.shape[0] > 100 and photo.shape[1] > 150, photo.shape


def test_a_refocus_option_without_a_focus_asks_for_the_refocus_and_two_focus_options_are_refused(tmp_path):
    """On a Raytrix raw ``--method`` means a refocus of the decoded light field (slope 0), not the total focus:
    a light field of one pixel per lens, which is refused in one line as decode refuses it, unless --views-anyway;
    two focus options stay a usage error naming them, with nothing written."""
    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    res = run(r42, "--method", "shift-sum", "-o", tmp_path / "refocus.png")
    assert res.exit_code == 2 and "focused-plenoptic" in res.output and "--views-anyway" in res.output, res.output
    assert "total focus" not in res.output.split("Error:")[0] and not (tmp_path / "refocus.png").exists()
    res = run(r42, "--method", "shift-sum", "--views-anyway", "-o", tmp_path / "refocus.png")
    assert res.exit_code == 0, res.output
    assert "focused as captured: slope +0.000 px/view" in res.output
    assert read_image(tmp_path / "refocus.png").shape[:2] == (22, 31)
    two = run(r42, "--slope", "0", "--total-focus", "-o", tmp_path / "two.png")
    assert two.exit_code == 2
    assert "pass at most one of" in two.output and "--slope S and --total-focus" in two.output
    assert not (tmp_path / "two.png").exists()


def test_refocus_command_without_a_focus_option_is_focused_as_captured(tmp_path):
    """``plenodecode refocus RAW -o photo.png`` takes the same default as the one-liner (the real F01 JPEG)."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_2.jpg")
    res = run("refocus", jpeg, "-o", tmp_path / "photo.png")
    assert res.exit_code == 0, res.output
    assert "focused as captured: slope +0.000 px/view" in res.output
    assert "choose the focus with --slope or --focus-at" in res.output
    explicit = run("refocus", jpeg, "--slope", "0", "-o", tmp_path / "slope0.png")
    assert explicit.exit_code == 0, explicit.output
    photo = read_image(tmp_path / "photo.png")
    np.testing.assert_array_equal(photo, read_image(tmp_path / "slope0.png"))
    grey = photo.astype(np.float64).mean(axis=-1) / 65535.0
    assert np.percentile(grey, 99) - np.percentile(grey, 1) > 0.3
    two = run("refocus", jpeg, "--slope", "0", "--alpha", "1", "-o", tmp_path / "two.png")
    assert two.exit_code == 2 and "pass at most one of" in two.output and "--slope and --alpha" in two.output


def test_the_focus_options_named_after_a_photograph_are_those_its_input_serves(tmp_path):
    """'focused as captured: ...; choose the focus with --refocus, --slope, --focus-at or --focus-distance' named
    every way on every input, and the next command refused half of them ('has no focal_length_m, f_number,
    lens_pitch_m in its metadata'): alpha on the F01 JPEG, HCI antinous and the microscope, a distance on all but
    HCI.  The line now names alpha and a distance only where the refocusable range is given in them; each named
    option renders, each left out is refused naming it (exit 2)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    inputs = {"illum-mini": (root / "sample_raws" / "illum-mini" / "scene.lfr", "--refocus, --slope or --focus-at"),
              "f01-jpeg": (shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), "--slope or --focus-at"),
              "hci": (shared_path("hci-antinous"), "--slope, --focus-at or --focus-distance")}
    values = {"--refocus": "1.01", "--slope": "0.3", "--focus-at": "0.5,0.5", "--focus-distance": "7"}
    for name, (path, named) in inputs.items():
        res = run(path, "--database", root / "calib", "-o", tmp_path / f"{name}.png")
        assert res.exit_code == 0, res.output
        line = next(ln for ln in res.output.splitlines() if ln.startswith("wrote"))
        assert line.endswith(f"choose the focus with {named})"), line
        offered = set(re.findall(r"--[a-z-]+", named))
        for option, value in values.items():
            got = run(path, "--database", root / "calib", option, value, "-o", tmp_path / f"{name}{option}.png")
            assert got.exit_code == (0 if option in offered else 2), (name, option, got.output)
            assert option in offered or f"Invalid value for {option}" in got.output, got.output
