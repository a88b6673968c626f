"""Self-calibration from scene raws, Raytrix grids, and the real captures of ../shared/data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.conftest import shared_path
from scipy.spatial import cKDTree

from plenodecode.calib import calibrate, calibrate_from_scene, calibrate_raytrix
from plenodecode.calib import centroids as C
from plenodecode.calib.selfcal import refine_grid
from plenodecode.errors import CalibrationError
from plenodecode.synthetic import simulate, simulate_white
from plenodecode.types import RawCapture


def _rms_to_truth(grid, truth):
    H, W = truth.sensor_shape
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= -0.5) & (t[:, 0] + R <= H - 0.5) & (t[:, 1] - R >= -0.5) & (t[:, 1] + R <= W - 0.5)
    d, _ = cKDTree(grid.centres()).query(t[full])
    return float(np.sqrt(np.mean(d ** 2))), float(d.max())


def test_self_calibration_of_a_synthetic_f01_scene():
    """Measured: rim RMS 0.010 px (max 0.017) against the true grid; intensity peaks ('dog') 0.090 px."""
    sim = simulate("f01-mini", seed=2, rotation=0.006, offset=(0.3, -0.7), shape=(400, 500))
    grid = calibrate_from_scene(sim.raw)
    rms, worst = _rms_to_truth(grid, sim.grid)
    assert rms < 0.03 and worst < 0.06
    assert grid.info["self_calibrated"] is True and grid.info["method"] == "rim"
    assert abs(grid.rotation - 0.006) < 5e-5
    assert abs(grid.pitch - sim.grid.pitch) < 1e-3
    # the white-image estimator is still available by name (and biased by the scene, as documented)
    peaks = calibrate_from_scene(sim.raw, method="dog")
    assert peaks.info["method"] == "dog" and 0.25 > _rms_to_truth(peaks, sim.grid)[0] > rms
    with pytest.raises(ValueError, match="'dog', 'parabolic', 'rim'"):
        calibrate_from_scene(sim.raw, method="centroid")


def test_self_calibration_accepts_arrays_and_rejects_black_scenes():
    sim = simulate("f01-mini", seed=3, shape=(300, 300))
    arr = (sim.raw.normalised() * 255).clip(0, 255).astype(np.uint8)
    grid = calibrate_from_scene(arr)
    assert _rms_to_truth(grid, sim.grid)[0] < 0.03          # measured 0.011 px
    black = RawCapture(np.full((200, 200), 168, np.uint16), "BGGR", 168.0, 4095.0)
    with pytest.raises(CalibrationError):
        calibrate_from_scene(black)
    with pytest.raises(ValueError):
        calibrate_from_scene(np.zeros((3, 3, 3, 3)))
    with pytest.raises(ValueError, match="lattice"):
        calibrate_from_scene(arr, lattice="triangular")


# preset, seed, RMS tolerance, pitch tolerance.  Measured over seeds 0-6 at the default sensor sizes
# (the whole sample camera): illum-mini RMS 0.003-0.011 px, pitch error <= 2e-4 px; square (40 x 40 lenses of
# 27.5 px, defocused scene edges inside every micro-image) RMS 0.016-0.071 px, pitch error <= 1.6e-3 px,
# row-spacing error <= 6e-3 px.  Intensity peaks gave 0.07-0.08 px (illum-mini) and 0.4-2.6 px (square).
SCENES = [("illum-mini", 1, 0.03, 1e-3), ("square", 1, 0.1, 5e-3)]


@pytest.mark.parametrize("preset,seed,rms_tol,pitch_tol", SCENES, ids=[s[0] for s in SCENES])
def test_self_calibration_from_rims_of_illum_and_square_scenes(preset, seed, rms_tol, pitch_tol):
    sim = simulate(preset, seed=seed)
    grid = calibrate_from_scene(sim.raw)
    assert grid.lattice == sim.grid.lattice
    rms, worst = _rms_to_truth(grid, sim.grid)
    assert rms <= rms_tol and worst <= 2 * rms_tol, (rms, worst)
    assert abs(grid.pitch - sim.grid.pitch) <= pitch_tol
    assert abs(grid.row_spacing - sim.grid.row_spacing) <= 2 * pitch_tol
    assert abs(grid.rotation - sim.grid.rotation) <= 1e-4
    # the rim radius it chose (minimum of the centre scatter) is the disk radius of the simulation
    assert grid.info["rim_radius_px"] == pytest.approx(sim.grid.radius, abs=0.01 * sim.grid.pitch)
    scan = grid.info["rim_radius_scan"]
    assert min(v for v in scan.values() if v is not None) < 0.5 * max(v for v in scan.values() if v is not None)


@pytest.mark.realdata
def test_real_f01_jpeg_matches_the_published_lenslet_centres():
    """IMG_1.jpg (dark lossy JPEG of a BGGR mosaic): >= 99 % of image_cords within 1 px (measured: rim 99.90 %,
    IMG_2.jpg 99.93 %; intensity peaks 99.69 %).  image_cords are integers, so a median of ~0.4 px is rounding."""
    import scipy.io as sio
    folder = shared_path("lytro-f01-lenslet-jpg")
    ref = sio.loadmat(folder / "image_cords.mat")["image_cords"].astype(np.float64).reshape(-1, 2) - 1.0
    grid = calibrate_from_scene(folder / "IMG_1.jpg")
    assert grid.lattice == "hex"
    d, _ = cKDTree(grid.centres()).query(ref)
    matched = float(np.mean(d < 1.0))
    assert matched >= 0.99, matched
    assert grid.pitch == pytest.approx(9.93, abs=0.02)
    assert grid.row_spacing == pytest.approx(8.60, abs=0.02)


@pytest.mark.realdata
def test_real_microscope_square_grid_every_lens_found():
    from plenodecode.io import read_raw
    raw = read_raw(shared_path("lf-microscopy-antleg", "radiometry_frame.png"))
    grid = calibrate(raw)
    assert grid.lattice == "square"
    assert grid.pitch == pytest.approx(27.5, abs=0.15)
    assert grid.row_spacing == pytest.approx(27.5, abs=0.15)
    # every lens at least one pitch inside the sensor (the outermost columns are cut by a black band)
    # has a disk peak near its grid centre, and every such peak has a grid lens: a one-to-one match
    img = C.devignette(C.flatten_white(raw), grid.pitch)
    peaks, _ = C.detect_peaks(img, grid.pitch, margin=1)
    peaks = peaks.astype(np.float64)
    c = grid.centres()
    H, W = raw.shape
    m = grid.pitch
    inner = (c[:, 0] >= m) & (c[:, 0] <= H - 1 - m) & (c[:, 1] >= m) & (c[:, 1] <= W - 1 - m)
    d, _ = cKDTree(peaks).query(c[inner])
    assert inner.sum() > 7000
    assert d.max() < 0.15 * grid.pitch                  # measured max 2.5 px (integer peaks, real lens jitter)
    assert np.mean(d < 1.5) > 0.99
    pin = (peaks[:, 0] >= m) & (peaks[:, 0] <= H - 1 - m) & (peaks[:, 1] >= m) & (peaks[:, 1] <= W - 1 - m)
    d2, _ = cKDTree(c).query(peaks[pin])
    assert d2.max() < 0.15 * grid.pitch
    assert grid.info["n_refined"] > 0          # the microscope's smooth distortion is kept per lens


@pytest.mark.realdata
def test_real_microscope_scene_self_calibration_agrees_with_its_white():
    """The ant-leg scene (defocused texture in every micro-image) against the lattice fitted to its own
    radiometry (white) frame, over lenses 30 px inside the sensor.  Measured: rim RMS 0.41 px, median
    0.36 px (the real lens distortion, 0.56 px RMS in the white's refined centres, is not in a lattice);
    intensity peaks ('dog') RMS 1.25 px."""
    from plenodecode.io import read_raw
    folder = shared_path("lf-microscopy-antleg")
    white = calibrate(read_raw(folder / "radiometry_frame.png"))
    scene = read_raw(folder / "light_field.png")
    grid = calibrate_from_scene(scene)
    assert grid.lattice == "square"
    assert grid.pitch == pytest.approx(white.pitch, abs=0.02)
    assert grid.row_spacing == pytest.approx(white.row_spacing, abs=0.02)
    H, W = scene.shape
    ref = white.lattice_centres().reshape(-1, 2)
    inner = (ref[:, 0] > 30) & (ref[:, 0] < H - 30) & (ref[:, 1] > 30) & (ref[:, 1] < W - 30)
    d, _ = cKDTree(grid.centres()).query(ref[inner])
    assert np.sqrt(np.mean(d ** 2)) < 0.6 and np.median(d) < 0.5


def test_raytrix_grid_from_calibration_and_refinement(tmp_path):
    from plenodecode.io import read_raw
    from plenodecode.io.raytrix import write_raytrix
    white, truth = simulate_white("raytrix", seed=1)
    start = truth.replace(origin=(truth.origin[0] + 1.3, truth.origin[1] - 0.9), rotation=truth.rotation + 0.002,
                          pitch=truth.pitch * 1.002, row_spacing=truth.row_spacing * 1.002)
    write_raytrix(tmp_path / "white.png", white, start)
    raw = read_raw(tmp_path / "white.png")
    as_given = calibrate_raytrix(raw)
    assert as_given.lens_type is not None and set(np.unique(as_given.lens_type)) == {0, 1, 2}
    np.testing.assert_allclose(as_given.pitch, start.pitch, rtol=1e-6)
    assert _rms_to_truth(as_given, truth)[0] > 1.0           # the XML we wrote is off by design
    refined = calibrate_raytrix(raw, refine=True)
    rms, _ = _rms_to_truth(refined, truth)
    assert rms < 0.02
    assert refined.info["refit"]["method"] == "disks"
    np.testing.assert_array_equal(refined.lens_type, as_given.lens_type)
    assert refined.shape == as_given.shape
    with pytest.raises(CalibrationError, match="Raytrix calibration"):
        calibrate_raytrix(white)                               # no RayCalibData anywhere


def test_refine_grid_phase_method_improves_a_perturbed_grid():
    white, truth = simulate_white("raytrix", seed=2)
    start = truth.replace(origin=(truth.origin[0] + 1.3, truth.origin[1] - 0.9), rotation=truth.rotation + 0.002)
    img = C.flatten_white(white, equalise=False)
    out = refine_grid(start, img, method="phase")
    assert _rms_to_truth(out, truth)[0] < 0.25 < _rms_to_truth(start, truth)[0]
    with pytest.raises(ValueError, match="method"):
        refine_grid(start, img, method="magic")


@pytest.mark.realdata
def test_real_raytrix_r42_uses_the_xml_grid_with_three_lens_types():
    from plenodecode.io import read_raw
    raw = read_raw(shared_path("raytrix-r42", "sc2_klein.png"))
    grid = calibrate_raytrix(raw)
    assert grid.pitch == pytest.approx(34.8647, abs=1e-3)
    assert abs(grid.rotation) < 1e-9
    counts = np.bincount(grid.lens_type.ravel(), minlength=3)
    assert (counts > 150).all()
    # refinement on this focused scene is not trustworthy: 'auto' keeps the XML grid and says so
    kept = calibrate_raytrix(raw, refine=True)
    if kept.info["refit"]["method"] == "none":
        np.testing.assert_allclose(kept.centres(), grid.centres())
        assert kept.info["warnings"]
    else:  # if it did refine, it must stay close to the XML grid
        d = np.hypot(*(kept.centres() - grid.centres()).T)
        assert d.max() < 2.0
    assert math.isfinite(kept.pitch)
