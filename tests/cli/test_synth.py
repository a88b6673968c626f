"""The synth command: a synthetic raw, its white image and the ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode import synthetic as syn


def test_cli_synth_writes_files_and_refuses_to_overwrite(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.cli.synth import PRESET_CHOICE

    assert set(PRESET_CHOICE.choices) == set(syn.PRESETS)
    args = ["synth", "f01-mini", "-o", str(tmp_path), "--seed", "3", "--offset", "0.25", "-0.4",
            "--shape", "96", "128", "--no-noise"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert "scene.lfp" in res.output and "MOD_0000.RAW" in res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.grid.to_dict() == syn.make_grid("f01-mini", offset=(0.25, -0.4), shape=(96, 128)).to_dict()
    assert truth.document["noise"] is False and truth.seed == 3
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = CliRunner().invoke(cli, [*args, "--overwrite"])
    assert res.exit_code == 0, res.output


def test_cli_synth_named_thin_scene(tmp_path):
    import numpy as np
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    args = ["synth", "illum-mini", "-o", str(tmp_path), "--shape", "420", "560", "--no-noise", "--no-lightfield"]
    res = CliRunner().invoke(cli, [*args, "--scene", "slits-h-j2-weak"])
    assert res.exit_code == 0, res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.scene.name == "slits-h-j2-weak" and truth.disparity_range == (-1.0, 1.0)
    far = truth.disparity == -1.0
    assert set(np.unique(truth.disparity)) == {-1.0, 1.0} and 0.15 < far.mean() < 0.45   # slits of 1..5 in 7..11 px
    left = far[:, : far.shape[1] // 2 - 1]                 # horizontal slits: rows of a panel are all far or all near
    assert (left.all(axis=1) | ~left.any(axis=1)).all() and left.all(axis=1).sum() >= 4
    for bad in (["--scene", "picket-fence"], ["--scene", "slats-v-j1-tex"]):
        argv = [*args, *bad] if bad[1] == "picket-fence" else ["synth", "raytrix", "-o", str(tmp_path / "r"), *bad]
        res = CliRunner().invoke(cli, argv)
        assert res.exit_code == 2 and "--scene" in res.output, res.output
    assert not (tmp_path / "r").exists()


def test_cli_synth_checkerboard_set(tmp_path):
    """``synth --checkerboard`` writes the raws, the white image and the truth; decoded, the board's dark and
    light squares sit where the truth projects them."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.io.calinfo import load_geometric_calibration
    from plenodecode.pipeline import choose_calibration, decode_raw, open_raw
    from plenodecode.raymodel import pose_transform
    from plenodecode.synthetic.checkerboard import BOARD_LEVELS, Board

    args = ["synth", "f01", "-o", str(tmp_path), "--checkerboard", "3x4x0.008", "--captures", "2", "--shape", "420",
            "500", "--distances", "0.4", "0.5", "--distortion", "0.1", "0", "0", "0", "0", "--no-noise"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert "board_01.lfp" in res.output and "MOD_0000.RAW" in res.output and "9x9x49x58" in res.output
    truth = load_geometric_calibration(tmp_path / "geometry_truth.json")
    assert truth.poses.shape == (2, 6) and truth.distortion[0] == 0.1 and truth.info["noise"] is False
    board = Board(3, 4, 0.008)
    assert truth.info["board"] == board.to_dict()
    white = open_raw(tmp_path / "MOD_0000.RAW")
    raw = open_raw(tmp_path / "board_00.lfp")
    centre = decode_raw(raw, choose_calibration(raw, white=white)).data[4, 4].mean(axis=-1)
    # the centres of the 4 x 5 squares: dark where (col + row) of the square is even
    s = board.square_m
    cols, rows = np.meshgrid(np.arange(-1, board.cols), np.arange(-1, board.rows))
    middles = np.stack([(cols.ravel() + 0.5) * s, (rows.ravel() + 0.5) * s, np.zeros(cols.size)], axis=-1)
    kl = truth.project(pose_transform(truth.poses[0], middles), (4, 4))
    values = centre[np.rint(kl[:, 1]).astype(int), np.rint(kl[:, 0]).astype(int)]
    dark = (cols.ravel() + rows.ravel()) % 2 == 0
    np.testing.assert_allclose(values[dark], BOARD_LEVELS["dark"], atol=0.03)
    np.testing.assert_allclose(values[~dark], BOARD_LEVELS["light"], atol=0.05)
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2 and "--overwrite" in res.output


def test_cli_synth_checkerboard_field_placement(tmp_path):
    """``--placement field`` aims the farther boards at the field's corners: their centres, seen in the central
    view, sit on its diagonals, about half way out (0.45-0.51 of the half field measured; the whole board must
    stay inside every view), where 'centre' keeps them anywhere near the middle."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.io.calinfo import load_geometric_calibration
    from plenodecode.raymodel import pose_transform
    from plenodecode.synthetic.checkerboard import Board

    board = Board(3, 4, 0.004)
    middle = np.array([[(board.cols - 1) / 2 * board.square_m, (board.rows - 1) / 2 * board.square_m, 0.0]])
    args = ["synth", "f01", "-o", str(tmp_path), "--checkerboard", "3x4x0.004", "--captures", "4", "--shape", "420",
            "500", "--distances", "0.4", "0.5", "--no-noise", "--placement", "field"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    truth = load_geometric_calibration(tmp_path / "geometry_truth.json")
    assert truth.info["placement"] == "field"
    _, _, ny, nx = truth.lf_shape
    far = truth.poses[np.argsort(truth.poses[:, 2])[2:]]
    for pose in far:
        k, l = truth.project(pose_transform(pose, middle), (4, 4))[0]
        fx, fy = abs(k - (nx - 1) / 2) / (nx / 2), abs(l - (ny - 1) / 2) / (ny / 2)
        assert fx > 0.35 and fy > 0.35 and abs(fx - fy) < 0.1, (fx, fy)
    res = CliRunner().invoke(cli, ["synth", "f01", "-o", str(tmp_path / "x"), "--placement", "field"])
    assert res.exit_code == 2 and "--placement needs --checkerboard" in res.output


@pytest.mark.parametrize("extra,message", [
    (["--checkerboard", "8x6"], "--checkerboard"),
    (["--checkerboard", "1x6x0.004"], "--checkerboard"),
    (["--checkerboard", "8x6x-0.004"], "--checkerboard"),
    (["--captures", "3"], "--captures needs --checkerboard"),
    (["--checkerboard", "3x4x0.008", "--captures", "0"], "--captures"),
    (["--checkerboard", "3x4x0.008", "--distances", "0.5", "0.4"], "--distances"),
    (["--checkerboard", "3x4x0.008", "--archive", "f01-datac"], "--archive"),
    (["--checkerboard", "8x10x0.02", "--shape", "300", "360"], "--checkerboard"),
    (["--checkerboard", "3x4x0.008", "--views", "8"], "--views"),
    (["--views", "7"], "--views needs --checkerboard"),
])
def test_cli_synth_checkerboard_refuses_bad_options(tmp_path, extra, message):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "f01", "-o", str(tmp_path / "out"), *extra])
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert not (tmp_path / "out").exists()


def test_cli_synth_checkerboard_refuses_a_focused_preset(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "raytrix", "-o", str(tmp_path), "--checkerboard", "3x4x0.008"])
    assert res.exit_code == 2 and "PRESET" in res.output and "unfocused" in res.output


def test_cli_synth_checkerboard_takes_the_camera_from_a_calibration_file(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.io.calinfo import load_geometric_calibration, save_geometric_calibration
    from plenodecode.raymodel import GeometricCalibration
    from plenodecode.synthetic.checkerboard import default_intrinsics

    h = default_intrinsics((7, 7, 49, 58), field_of_view=0.2, focus_distance_m=0.5)
    save_geometric_calibration(GeometricCalibration(h, [0.05, 0, 0, 0, 0]), tmp_path / "camera.json")
    (tmp_path / "bad.json").write_text("{}")
    args = ["synth", "f01", "-o", str(tmp_path / "set"), "--checkerboard", "3x4x0.008", "--captures", "1",
            "--shape", "420", "500", "--distances", "0.4", "0.5", "--views", "7", "--no-noise"]
    res = CliRunner().invoke(cli, [*args, "--geometry", str(tmp_path / "bad.json")])
    assert res.exit_code == 2 and "--geometry" in res.output
    res = CliRunner().invoke(cli, [*args, "--geometry", str(tmp_path / "camera.json"), "--distortion", "0.1", "0",
                                   "0", "0", "0"])
    assert res.exit_code == 0, res.output
    assert "7x7x49x58" in res.output and "--views 7" in res.output
    truth = load_geometric_calibration(tmp_path / "set" / "geometry_truth.json")
    np.testing.assert_array_equal(truth.intrinsics, h)
    assert truth.lf_shape == (7, 7, 49, 58) and truth.distortion[0] == 0.1


@pytest.mark.parametrize("extra, option, words", [
    (["--pitch", "0.5"], "'--pitch'", "not in the range x>2"),
    (["--rotation", "3"], "'--rotation'", "not in the range -0.5<x<0.5"),
    (["--shape", "10", "10"], "'--shape'", "10 is not in the range 16<=x<=16384"),
    (["--shape", "100000", "100000"], "'--shape'", "not in the range 16<=x<=16384"),
    (["--shape", "16000", "16000"], "--shape", "16000 x 16000 is 256 Mpx; at most 64 Mpx"),
    (["--checkerboard", "8x6x0.0036", "--shape", "9000", "9000"], "--shape", "at most 64 Mpx"),
], ids=["pitch", "rotation", "shape-small", "shape-huge", "shape-pixels", "board-shape"])
def test_cli_synth_geometry_out_of_bounds_names_the_option(tmp_path, extra, option, words):
    """'synth --pitch 0.5' said 'Invalid value: pitch must be > 2 px' (no option named) after parsing, and
    '--shape 100000 100000' ran until OpenCV failed to allocate 26 GB; both are usage errors naming the option now,
    while the command line is parsed, with nothing written."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "f01-mini", "-o", str(tmp_path / "out"), *extra])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert f"Invalid value for {option}:" in errors[0] and words in errors[0], errors
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, words", [
    ([], "the synthetic raw goes into a folder, and out.png names an image file; give a folder, e.g."),
    (["--checkerboard", "8x6x0.0036", "--captures", "3"], "the calibration set goes into a folder, and out.png"),
], ids=["scene", "checkerboard"])
def test_cli_synth_output_named_like_an_image_is_refused(tmp_path, extra, words):
    """'synth f01-mini -o out.png' made a folder called out.png holding scene.lfp ..., as other commands' folder
    outputs did before they were refused; it is a usage error naming -o now, with nothing made."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "f01-mini", "-o", str(tmp_path / "out.png"), *extra])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1 and "Invalid value for -o / --output:" in errors[0], res.output
    assert words in errors[0] and not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("preset, archive", [("raytrix", "illum-tar"), ("square", "f01-datac")])
def test_cli_synth_archive_of_a_camera_without_one_is_refused_before_writing(tmp_path, preset, archive):
    """A Lytro calibration archive of a non-Lytro preset: the old code wrote the raw and its truth, then failed
    with a 40-line 'raw.cfa is None' traceback, leaving the half-written set."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", preset, "-o", str(tmp_path / "out"), "--archive", archive])
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and "--archive" in errors[0] and "not a Lytro camera" in errors[0], res.output
    assert "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, error", [
    (["--offset", "1e9", "0"], "Invalid value for --offset: ROW and COL must each be within +-4.964 px (half the "
                               "9.928 px lens pitch; a shift by a whole lens draws the same lattice), got 1e+09 0"),
    (["--pitch", "20", "--offset", "0", "-10.5"], "Invalid value for --offset: ROW and COL must each be within +-10 px "
                                                  "(half the 20 px lens pitch; a shift by a whole lens draws the same "
                                                  "lattice), got 0 -10.5"),
    (["--pitch", "1e6"], "Invalid value for --pitch: 1e+06 px lenses on a 656 x 656 px sensor are 1 x 1 lenses; a "
                         "calibration is checked on at least 30 (a smaller pitch or a larger sensor)"),
    (["--shape", "16", "16"], "Invalid value for --shape: 9.928 px lenses on a 16 x 16 px sensor are 1 x 2 lenses; a "
                              "calibration is checked on at least 30 (a smaller pitch or a larger sensor)"),
    (["--checkerboard", "3x4x0.004", "--views", "99"], "Invalid value for --views: 99 is more than the 11 views per "
                                                       "axis that see a micro-image of 9.928 px lenses"),
])
def test_cli_synth_refuses_a_lattice_nothing_could_use_before_simulating(tmp_path, monkeypatch, extra, error):
    """'synth f01-mini --offset 1e9 0' simulated for 13 s and wrote mla_offset_m 4550 m into the metadata;
    '--pitch 1e6' wrote a raw of one lens; '--checkerboard --views 99' wrote truth for a decode that refuses 99."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    def no_work(*args, **kwargs):
        raise AssertionError("simulated before the options were checked")

    monkeypatch.setattr(syn, "simulate", no_work)
    monkeypatch.setattr("plenodecode.synthetic.checkerboard.simulate_checkerboard_set", no_work)
    res = CliRunner().invoke(cli, ["synth", "f01-mini", "-o", str(tmp_path / "out"), *extra])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == f"Error: {error}"
    assert list(tmp_path.iterdir()) == []


def test_cli_synth_offset_up_to_half_a_pitch_is_drawn(tmp_path):
    """The bound is half the pitch in effect: 4.9 px on the 9.928 px f01-mini lattice is written as given."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "f01-mini", "-o", str(tmp_path), "--offset", "4.9", "-4.9", "--shape",
                                   "96", "128", "--no-noise", "--no-lightfield"])
    assert res.exit_code == 0, res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.grid.to_dict() == syn.make_grid("f01-mini", offset=(4.9, -4.9), shape=(96, 128)).to_dict()


def test_cli_synth_board_bent_out_of_the_views_names_the_distortion(tmp_path):
    """'--distortion 1e9 0 0 0 0' said only '... use a smaller board or other distances (--distances)', sending the
    user to an option that was never the problem."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    res = CliRunner().invoke(cli, ["synth", "f01-mini", "-o", str(tmp_path / "out"), "--checkerboard", "3x4x0.004",
                                   "--captures", "1", "--distortion", "1e9", "0", "0", "0", "0"])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1].endswith(
        "(--distances; or the distortion of --distortion / --geometry bends it out of the views)")
    assert list(tmp_path.iterdir()) == []
