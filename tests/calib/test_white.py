"""calibrate() on generated white images against the true grid (issue #3's tolerances).

Tolerances (binding, from the issue): centre RMS <= 0.05 px over lenses whose disk is fully on
the sensor, rotation error <= 1e-4 rad, pitch error <= 1e-3 px, every such lens found (a grid
centre within 0.5 px).  Measured on these cases: RMS 0.001-0.004 px, pitch error <= 5e-4 px.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from plenodecode.calib import calibrate
from plenodecode.errors import CalibrationError
from plenodecode.synthetic import simulate_white
from plenodecode.types import LensletGrid, RawCapture

RMS_TOL = 0.05
ROT_TOL = 1e-4
PITCH_TOL = 1e-3


def compare(grid: LensletGrid, truth: LensletGrid) -> dict[str, float]:
    """Errors of a fitted grid against the true one, over lenses fully on the sensor."""
    H, W = truth.sensor_shape
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= -0.5) & (t[:, 0] + R <= H - 0.5) & (t[:, 1] - R >= -0.5) & (t[:, 1] + R <= W - 0.5)
    d, _ = cKDTree(grid.centres()).query(t[full])
    rot_err = abs(((grid.rotation - truth.rotation) + math.pi / 2) % math.pi - math.pi / 2)
    return {"rms": float(np.sqrt(np.mean(d ** 2))), "max": float(d.max()), "rot_err": rot_err,
            "pitch_err": abs(grid.pitch - truth.pitch), "n": int(full.sum())}


def assert_tolerances(grid: LensletGrid, truth: LensletGrid) -> dict[str, float]:
    c = compare(grid, truth)
    assert c["n"] > 100
    assert c["rms"] <= RMS_TOL, c
    assert c["rot_err"] <= ROT_TOL, c
    assert c["pitch_err"] <= PITCH_TOL, c
    assert c["max"] < 0.5, c  # every fully visible lens has a grid centre on it
    return c


CASES = [  # preset, sensor shape (small for speed; raytrix needs its own size for enough lenses)
    ("illum", (400, 500)),
    ("illum-mini", (400, 500)),
    ("f01", (400, 500)),
    ("f01-mini", (400, 500)),
    ("square", (560, 600)),
    ("raytrix", None),
]


@pytest.mark.parametrize("preset,shape", CASES, ids=[c[0] for c in CASES])
@pytest.mark.parametrize("seed", [0, 1])
def test_white_calibration_meets_issue_tolerances(preset, shape, seed):
    rng = np.random.default_rng(100 + seed + 7 * CASES.index((preset, shape)))
    rotation = float(rng.uniform(-0.01, 0.01))
    offset = tuple(float(v) for v in rng.uniform(-4.0, 4.0, 2))
    white, truth = simulate_white(preset, seed=seed, rotation=rotation, offset=offset, shape=shape)
    grid = calibrate(white)
    assert grid.lattice == truth.lattice
    c = assert_tolerances(grid, truth)
    assert c["rms"] < 0.02  # measured <= 0.004: a real regression shows long before the issue's limit
    # every lens with its centre on the sensor is in the grid's block
    H, W = truth.sensor_shape
    t = truth.centres()
    on = (t[:, 0] >= -0.5) & (t[:, 0] <= H - 0.5) & (t[:, 1] >= -0.5) & (t[:, 1] <= W - 0.5)
    d, _ = cKDTree(grid.centres()).query(t[on])
    assert d.max() < 0.5
    assert grid.sensor_shape == truth.sensor_shape
    assert grid.info["serial"] == white.metadata.serial


def test_moderate_size_illum_mini_full_sensor():
    white, truth = simulate_white("illum-mini", seed=5, rotation=-0.0063, offset=(0.41, -2.73))
    grid = calibrate(white)
    c = assert_tolerances(grid, truth)
    assert c["n"] > 9000
    assert c["rms"] < 0.01
    assert abs(grid.row_spacing - truth.row_spacing) < 1e-3
    assert grid.shape == truth.shape
    # the fit found nearly every lens and kept no spurious per-lens refinements
    assert grid.info["n_fit"] > 0.9 * grid.info["n_lenses"]
    assert grid.info["n_refined"] == 0


def test_column_packed_hex_grid_is_found():
    """A hex grid packed in columns (rotation ~ pi/2): the transposed sensor of a row-packed white."""
    white, truth = simulate_white("f01-mini", seed=3, rotation=0.004, offset=(0.2, 0.7), shape=(500, 400))
    tw = RawCapture(np.ascontiguousarray(white.mosaic.T), None, white.black.T, white.white.T, white.metadata)
    grid = calibrate(tw)
    assert abs(grid.rotation - math.pi / 2) < 0.05
    tc = truth.centres()[:, ::-1]  # transpose the true centres too
    H, W = tw.shape
    R = truth.radius
    full = (tc[:, 0] - R >= -0.5) & (tc[:, 0] + R <= H - 0.5) & (tc[:, 1] - R >= -0.5) & (tc[:, 1] + R <= W - 0.5)
    d, _ = cKDTree(grid.centres()).query(tc[full])
    assert np.sqrt(np.mean(d ** 2)) < RMS_TOL
    assert d.max() < 0.5
    assert abs(grid.pitch - truth.pitch) < PITCH_TOL


def test_dark_lenses_and_hot_pixels_do_not_pull_the_fit():
    white, truth = simulate_white("illum-mini", seed=2, rotation=0.003, offset=(1.3, -0.6), shape=(450, 520))
    m = white.mosaic.astype(np.float64)
    rng = np.random.default_rng(7)
    centres = truth.centres()
    H, W = white.shape
    inside = centres[(centres[:, 0] > 20) & (centres[:, 0] < H - 20) & (centres[:, 1] > 20) & (centres[:, 1] < W - 20)]
    rr, cc = np.mgrid[0:H, 0:W]
    for r, c in inside[rng.choice(len(inside), 25, replace=False)]:  # 25 dead (dark) lenses
        m[(rr - r) ** 2 + (cc - c) ** 2 <= (0.5 * truth.pitch) ** 2] = white.black[0, 0]
    hot = rng.choice(H * W, 400, replace=False)                    # 400 hot pixels
    m.reshape(-1)[hot] = white.white[0, 0]
    bad = RawCapture(m.astype(np.uint16), white.cfa, white.black, white.white, white.metadata)
    assert bad.mosaic.tobytes() != white.mosaic.tobytes()
    grid = calibrate(bad)
    assert_tolerances(grid, truth)
    assert white.mosaic.max() < white.white[0, 0] + 1  # inputs untouched


def test_several_whites_are_averaged():
    w1, truth = simulate_white("f01-mini", seed=1, rotation=0.002, offset=(0.5, 0.5), shape=(300, 360))
    w2, _ = simulate_white("f01-mini", seed=2, rotation=0.002, offset=(0.5, 0.5), shape=(300, 360))
    grid = calibrate([w1, w2])
    assert grid.info["n_whites"] == 2
    assert_tolerances(grid, truth)
    w3, _ = simulate_white("f01-mini", seed=1, shape=(200, 200))
    with pytest.raises(CalibrationError, match="differ in size"):
        calibrate([w1, w3])


def test_parabolic_method_and_forced_lattice():
    white, truth = simulate_white("f01-mini", seed=4, rotation=-0.005, offset=(0.1, 0.9), shape=(400, 400))
    calls = []
    g = calibrate(white, method="parabolic", lattice="hex", progress=lambda d, t: calls.append((d, t)))
    assert calls and calls[-1][0] == calls[-1][1] and [d for d, _ in calls] == sorted(d for d, _ in calls)
    c = compare(g, truth)
    assert c["rms"] < RMS_TOL and c["pitch_err"] < PITCH_TOL
    with pytest.raises(ValueError, match="method"):
        calibrate(white, method="nope")
    with pytest.raises(ValueError, match="lattice"):
        calibrate(white, lattice="triangle")


def test_grid_json_round_trip_of_a_fitted_grid():
    white, _ = simulate_white("square", seed=0, shape=(400, 420))
    grid = calibrate(white)
    back = LensletGrid.from_json(grid.to_json())
    np.testing.assert_allclose(back.centres(), grid.centres(), atol=1e-9)
    assert back.info["serial"] == grid.info["serial"]


def test_dark_and_flat_frames_raise_calibration_error():
    white, _ = simulate_white("f01-mini", seed=0, shape=(200, 240))
    dark = RawCapture(np.full(white.shape, int(white.black[0, 0]), np.uint16), white.cfa, white.black, white.white)
    with pytest.raises(CalibrationError, match="dark"):
        calibrate(dark)
    flat = RawCapture(np.full(white.shape, 2000, np.uint16), white.cfa, white.black, white.white)
    with pytest.raises(CalibrationError, match="uniform|lattice|periodic"):
        calibrate(flat)
    noise = RawCapture(np.random.default_rng(0).integers(500, 3000, white.shape).astype(np.uint16), None,
                       white.black, white.white)
    with pytest.raises(CalibrationError):
        calibrate(noise)


def test_scene_raw_as_white_gives_a_warning():
    from plenodecode.synthetic import simulate
    sim = simulate("f01-mini", seed=1, shape=(300, 300))
    grid = calibrate(sim.raw)
    assert any("scene" in w for w in grid.info["warnings"])
    grid_w = calibrate(sim.white)
    assert grid_w.info["warnings"] == []
