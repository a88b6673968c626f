"""The calibration report tells the truth (issue 18, item 5): it names the grid's source and judges
the grid by what that source can show, with one RMS figure defined once."""

from __future__ import annotations

import re

import pytest

from plenodecode.calib import calibrate
from plenodecode.calib.selfcal import calibrate_from_scene
from plenodecode.report.calibration import RMS_DEFINITION, rms_text, write_calibration_report
from plenodecode.synthetic import simulate, simulate_white

SHAPE = (300, 320)


def _text(path) -> str:
    """The page's visible text (figures and markup removed)."""
    html = path.read_text()
    html = re.sub(r"<style>.*?</style>", "", html, flags=re.S)
    html = re.sub(r'data:image/png;base64,[^"]+', "", html)
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


@pytest.fixture(scope="module")
def white():
    return simulate_white("f01-mini", seed=4, shape=SHAPE, rotation=0.003, offset=(0.4, -0.2))


def test_self_calibration_report_says_so_and_good(tmp_path):
    sim = simulate("f01-mini", seed=1, shape=SHAPE)
    grid = calibrate_from_scene(sim.raw)
    assert grid.info["source_kind"] == "self-calibration"
    text = _text(write_calibration_report(grid, sim.raw, tmp_path / "self.html"))
    assert "source: self-calibration from a scene" in text
    assert "verdict: good" in text and "high" not in text and "more than 0.5 px" not in text
    assert "local misfit" in text and "lenses found" in text
    assert "Thresholds measured on generated scenes" in text   # the rules say where they come from


def test_raytrix_grid_reported_as_given(tmp_path):
    from plenodecode.calib.selfcal import calibrate_raytrix
    from plenodecode.io.raytrix import raycalib_from_grid

    sim = simulate("raytrix", seed=0)
    grid = calibrate_raytrix(sim.raw, raycalib_from_grid(sim.grid))   # the camera's RayCalibData of the truth
    assert grid.info["source_kind"] == "camera-file"
    text = _text(write_calibration_report(grid, sim.raw, tmp_path / "raytrix.html"))
    assert "used as given" in text and "verdict: as given" in text
    assert "no residual or off-grid judgement" in text
    assert "px off" not in text and "more than 0.5 px" not in text and not re.search(r"\d\s?%", text)
    assert "RMS n/a (grid used as given)" in text and rms_text(grid) == "n/a (grid used as given)"


def test_white_fit_shifted_by_half_a_pitch_is_bad(white, tmp_path):
    raw, _ = white
    grid = calibrate(raw)
    good = _text(write_calibration_report(grid, raw, tmp_path / "good.html"))
    assert "source: fitted to white image(s)" in good and "verdict: good" in good
    e_row, e_col = grid.axes()
    o = tuple(float(v) for v in grid.origin + 0.5 * grid.pitch * e_col)
    bad = _text(write_calibration_report(grid.replace(origin=o), raw, tmp_path / "bad.html"))
    assert "verdict: bad" in bad and "does not match this white image" in bad


def test_one_rms_defined_once(white, tmp_path):
    raw, _ = white
    grid = calibrate(raw)
    text = _text(write_calibration_report(grid, raw, tmp_path / "r.html"))
    assert text.count(RMS_DEFINITION) == 1
    figure = rms_text(grid)
    assert f"RMS {figure}" in text                       # the header
    assert f"{figure} (of the fit)" in text              # the table, the same figure
    assert text.count("RMS") == 3                        # header, table row, definition
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.io.lytro import write_raw_pair
    path, _ = write_raw_pair(tmp_path / "MOD_0000.RAW", raw)
    r = CliRunner().invoke(cli, ["calibrate", str(path), "-o", str(tmp_path / "g.json")], obj={})
    assert r.exit_code == 0 and f"RMS {figure})" in r.output   # the CLI's one line, the same figure
