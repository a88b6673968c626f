"""``--geometry CAL.json`` (cli/common.py) on ``decode`` and ``depth``: a generated checkerboard raw decoded
rectified, measured (straight corner lines, metric depth), and the usage errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.decoding.rectify import rectified_intrinsics
from plenodecode.raymodel import GeometricCalibration
from tests.geometry_scenes import detect_corners, line_residual_rms, write_board_raw

BOARD_Z = 0.5


@pytest.fixture(scope="module")
def board_files(tmp_path_factory):
    """A board raw facing the camera at 0.5 m, its white, grid and calibration (:func:`write_board_raw`)."""
    return write_board_raw(tmp_path_factory.mktemp("geometry_cli"), BOARD_Z)


def run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


def _inputs(files):
    return [files["raw"], "-g", files["grid"], "-w", files["white"]]


def test_decode_geometry_writes_a_rectified_light_field(board_files, tmp_path):
    from plenodecode.io.lightfield import load_lightfield

    files, cal, board = board_files
    out = tmp_path / "rect.npy"
    res = run(["decode", *_inputs(files), "--geometry", files["cal"], "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "rectified" in res.output
    lf = load_lightfield(out)
    model = lf.geometry.ray_model
    assert model["rectified"] and model["calibration"] == files["cal"]
    np.testing.assert_allclose(model["intrinsics"], rectified_intrinsics(cal), rtol=1e-12)
    for j, i in ((4, 4), (3, 3), (5, 5), (3, 5)):                 # measured: 0.010-0.012 px
        assert line_residual_rms(detect_corners(lf.data[j, i].mean(axis=-1), board)) < 0.05


def test_depth_geometry_metric_depth_of_the_board(board_files, tmp_path):
    from plenodecode.io.pfm import read_pfm

    files, cal, board = board_files
    out = tmp_path / "z.pfm"
    res = run(["depth", *_inputs(files), "--geometry", files["cal"], "--metric", "-o", str(out)])
    assert res.exit_code == 0, res.output
    z = read_pfm(out)
    h, w = z.shape[:2]
    assert np.median(z[h // 4:3 * h // 4, w // 4:3 * w // 4]) == pytest.approx(BOARD_Z, rel=0.01)   # 0.4975 m


def test_geometry_usage_errors_before_any_work(board_files, tmp_path):
    files, cal, board = board_files
    out = tmp_path / "lf.npy"
    missing = run(["decode", *_inputs(files), "--geometry", str(tmp_path / "nope.json"), "-o", str(out)])
    not_cal = tmp_path / "not_cal.json"
    not_cal.write_text(json.dumps({"hello": 1}))
    invalid = run(["decode", *_inputs(files), "--geometry", str(not_cal), "-o", str(out)])
    other = tmp_path / "other.json"
    from plenodecode.io.calinfo import save_geometric_calibration

    save_geometric_calibration(GeometricCalibration(cal.intrinsics, cal.distortion, (11, 11, 70, 69)), other)
    for command, output in (("decode", out), ("depth", tmp_path / "z.pfm")):
        mismatch = run([command, *_inputs(files), "--geometry", str(other), "-o", str(output)])
        assert mismatch.exit_code == 2, mismatch.output
        assert "--geometry" in mismatch.output and "11x11x70x69" in mismatch.output
        assert not output.exists()
    for res in (missing, invalid):
        assert res.exit_code == 2, res.output
        assert "--geometry" in res.output
    assert "not a geometric calibration" in invalid.output
    assert not out.exists()


def test_saved_light_field_rectified_on_load(board_files, tmp_path):
    """``depth LF --geometry``: a light field decoded without it is rectified when read; one already rectified
    is refused (usage error)."""
    from plenodecode.io.pfm import read_pfm

    files, cal, board = board_files
    plain, rectified = tmp_path / "plain.npy", tmp_path / "rect.npy"
    assert run(["-q", "decode", *_inputs(files), "-o", str(plain)]).exit_code == 0
    res = run(["-q", "depth", str(plain), "--geometry", files["cal"], "--metric", "-o", str(tmp_path / "z.pfm")])
    assert res.exit_code == 0, res.output
    z = read_pfm(tmp_path / "z.pfm")
    h, w = z.shape[:2]
    assert np.median(z[h // 4:3 * h // 4, w // 4:3 * w // 4]) == pytest.approx(BOARD_Z, rel=0.01)
    assert run(["-q", "decode", *_inputs(files), "--geometry", files["cal"], "-o", str(rectified)]).exit_code == 0
    again = run(["depth", str(rectified), "--geometry", files["cal"], "-o", str(tmp_path / "again.pfm")])
    assert again.exit_code == 2 and "already rectified" in again.output
