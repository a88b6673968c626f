import numpy as np

from tests.conftest import shared_path
from plenodecode.io.hci import read_hci
from plenodecode.io.pfm import read_pfm, write_pfm


def test_pfm_round_trip_keeps_row_order(tmp_path):
    img = np.arange(12, dtype=np.float32).reshape(3, 4) - 5.5
    write_pfm(tmp_path / "a.pfm", img)
    np.testing.assert_array_equal(read_pfm(tmp_path / "a.pfm"), img)
    rgb = np.random.default_rng(0).normal(size=(5, 2, 3)).astype(np.float32)
    write_pfm(tmp_path / "b.pfm", rgb)
    np.testing.assert_array_equal(read_pfm(tmp_path / "b.pfm"), rgb)


def test_hci_antinous_disparity_matches_views():
    scene = read_hci(shared_path("hci-antinous"))
    lf, d = scene.lightfield, scene.disparity
    assert lf.shape == (9, 9, 512, 512, 3) and d.shape == (512, 512)
    assert -3.4 < d.min() < d.max() < 2.9
    # view[v,u](y - d (v-4), x - d (u-4)) = centre(y, x): warp view (4, 8) onto the centre with the GT disparity
    import cv2
    yy, xx = np.mgrid[0:512, 0:512].astype(np.float32)
    view = lf.data[4, 8].mean(-1)
    warped = cv2.remap(view, xx - d * 4, yy, cv2.INTER_LINEAR)
    centre = lf.data[4, 4].mean(-1)
    inner = np.s_[30:-30, 30:-30]
    err_gt = np.median(np.abs(warped - centre)[inner])
    err_flip = np.median(np.abs(cv2.remap(view, xx + d * 4, yy, cv2.INTER_LINEAR) - centre)[inner])
    assert err_gt < 0.01 and err_gt < 0.5 * err_flip


def test_read_hci_geometry_is_typed_and_the_legacy_keys_stay_readable(tmp_path):
    from tests.io.test_lightfield import write_hci_folder

    scene = read_hci(write_hci_folder(tmp_path / "scene", views=3, size=(6, 5)))
    g = scene.lightfield.geometry
    assert scene.lightfield.shape == (3, 3, 6, 5, 3) and scene.lightfield.colour == g.colour == "srgb"
    assert g.display_encoded and g.spatial_step_px == g.view_step_px == 1.0 and g.source == str(tmp_path / "scene")
    assert (g.hci.baseline_mm, g.hci.focal_length_mm, g.hci.sensor_size_mm, g.hci.focus_distance_m) == \
        (100.0, 100.0, 35.0, 7.0)
    assert g.hci.image_resolution_px == 512.0 and g.hci.disparity_range == (-3.3, 2.8)
    assert scene.lightfield.metadata["hci_parameters"] == scene.parameters
    assert scene.lightfield.metadata["source"] == str(tmp_path / "scene")
