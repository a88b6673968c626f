"""A white image that does not fit the raw is refused on the raw itself, in one line naming better choices."""

from __future__ import annotations

from dataclasses import replace

import pytest
from click.testing import CliRunner

from plenodecode.calib import calibrate
from plenodecode.calib.check import MAX_SHIFT_PITCH, WhiteMismatchError, check_white_fit, measure_lattice_fit
from plenodecode.cli.main import cli
from plenodecode.io.lytro import write_lfr, write_raw_pair
from plenodecode.synthetic import simulate, simulate_white

SHAPE = (400, 560)


@pytest.fixture(scope="module")
def camera():
    """An Illum-like scene raw, its right white image and one whose lattice is shifted by 0.3 pitch."""
    sim = simulate("illum-mini", seed=6, shape=SHAPE)
    pitch = sim.grid.pitch
    right, _ = simulate_white("illum-mini", seed=7, shape=SHAPE)
    shifted, _ = simulate_white("illum-mini", seed=8, shape=SHAPE,
                                offset=(sim.preset.offset[0] + 0.3 * pitch, sim.preset.offset[1]))
    return sim, right, calibrate(right), shifted, calibrate(shifted)


def test_shifted_lattice_is_measured_and_refused_in_one_line(camera):
    sim, _, _, shifted, grid = camera
    fit = measure_lattice_fit(sim.raw, grid)
    assert fit.n_lenses > 300
    assert abs(fit.offset_px[0] + 0.3 * sim.grid.pitch) < 0.15 * sim.grid.pitch * 0.5   # measured -0.3 pitch in rows
    assert 0.25 < fit.worst_shift_pitch < 0.35
    with pytest.raises(WhiteMismatchError) as err:
        check_white_fit(sim.raw, grid, shifted, white_name="MOD_0003.RAW", alternatives=["MOD_0001.RAW"])
    msg = str(err.value)
    assert "\n" not in msg and "MOD_0003.RAW does not fit" in msg
    assert "0.3" in msg and "pitch" in msg and "MOD_0001.RAW" in msg and "--self-calibrate" in msg


def test_right_white_is_accepted(camera):
    sim, right, grid, _, _ = camera
    fit = check_white_fit(sim.raw, grid, right)
    assert fit.measured and fit.worst_shift_pitch < MAX_SHIFT_PITCH / 2
    assert fit.spread_px < 0.15 * sim.grid.pitch


def test_scene_as_its_own_white_is_refused(camera):
    sim, *_ = camera
    grid = calibrate(sim.raw)                     # today: a warning, then a uniform pink decode
    with pytest.raises(WhiteMismatchError, match="itself, not a flat field.*--self-calibrate"):
        check_white_fit(sim.raw, grid, sim.raw)
    other_scene = simulate("illum-mini", seed=9, shape=SHAPE).raw
    with pytest.raises(WhiteMismatchError, match="is a scene, not a flat field"):
        check_white_fit(sim.raw, grid, other_scene)


def test_cli_refuses_the_database_white_that_does_not_fit(camera, tmp_path):
    sim, right, _, shifted, _ = camera
    (tmp_path / "whites").mkdir()
    write_raw_pair(tmp_path / "whites" / "MOD_0000.RAW", shifted)
    far = replace(right, metadata=replace(right.metadata, zoom_step=900.0))
    write_raw_pair(tmp_path / "whites" / "MOD_0001.RAW", far)
    scene = write_lfr(tmp_path / "scene.lfr", sim.raw)
    runner = CliRunner()
    res = runner.invoke(cli, ["calibrate", "--database", str(tmp_path / "db"), str(tmp_path / "whites")])
    assert res.exit_code == 0, res.output
    out = tmp_path / "lf.npy"
    res = runner.invoke(cli, ["decode", str(scene), "--database", str(tmp_path / "db"), "-o", str(out)])
    assert res.exit_code == 1 and not out.exists()
    line = res.output.strip()
    assert "\n" not in line, res.output
    assert "MOD_0000.RAW" in line and "does not fit scene.lfr" in line
    assert "MOD_0001.RAW at zoom 900" in line and "--self-calibrate" in line


def test_cli_refuses_the_scene_given_as_its_white(camera, tmp_path):
    sim, *_ = camera
    scene = write_lfr(tmp_path / "scene.lfr", sim.raw)
    out = tmp_path / "lf.npy"
    res = CliRunner().invoke(cli, ["decode", str(scene), "--white", str(scene), "-o", str(out)])
    assert res.exit_code == 1 and not out.exists()
    assert "is the picture scene.lfr itself" in res.output and "\n" not in res.output.strip()
