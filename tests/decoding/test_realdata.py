"""Decoding real captures from ../shared/data (skipped when absent)."""

from __future__ import annotations

import numpy as np
import pytest
from tests.conftest import shared_path

from plenodecode.decoding import decode

pytestmark = pytest.mark.realdata


def phase_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Shift (dy, dx) of b relative to a by phase correlation (Hann window), px."""
    import cv2

    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    win = cv2.createHanningWindow(a.shape[::-1], cv2.CV_64F)
    (dx, dy), _ = cv2.phaseCorrelate(a, b, win)
    return dy, dx


@pytest.fixture(scope="module")
def antleg():
    folder = shared_path("lf-microscopy-antleg")
    from plenodecode.calib import calibrate
    from plenodecode.io import read_raw

    raw = read_raw(folder / "light_field.png")
    white = read_raw(folder / "radiometry_frame.png")
    dark = read_raw(folder / "dark_frame.tif")
    grid = calibrate(white)
    return raw, white, dark, grid, decode(raw, grid, white=white, dark=dark)


def test_microscope_decodes_square_grid_with_white_and_dark(antleg):
    raw, white, dark, grid, lf = antleg
    assert grid.lattice == "square"
    assert grid.pitch == pytest.approx(27.5, abs=0.3)         # 125 um / 4.55 um
    v, u, y, x, c = lf.shape
    assert (v, u, c) == (27, 27, 1)
    assert abs(y - 2160 / 27.5) < 3 and abs(x - 2592 / 27.5) < 3
    assert lf.metadata["dark_subtracted"] and lf.metadata["devignetted"]
    vc, uc = lf.centre_index
    assert lf.weight[vc, uc, 2:-2, 2:-2].mean() > 0.9
    assert np.isfinite(lf.data).all()


def test_microscope_views_show_consistent_parallax(antleg):
    *_, lf = antleg
    vc, uc = lf.centre_index
    d = lf.data[..., 0]
    # the views are not identical
    assert np.mean(np.abs(d[vc, uc - 9] - d[vc, uc + 9])) > 0.1 * np.mean(np.abs(d[vc, uc]))
    # opposite views shift against each other along x (u) and y (v); the shift grows with the baseline
    sx = [phase_shift(d[vc, uc - k], d[vc, uc + k])[1] for k in (2, 5, 8, 11)]
    sy = [phase_shift(d[vc - k, uc], d[vc + k, uc])[0] for k in (2, 5, 8, 11)]
    for s in (sx, sy):
        assert np.sign(s[-1]) == np.sign(s[-2]) == np.sign(s[-3]) != 0
        assert abs(s[-1]) > abs(s[1]) > 0.2 and abs(s[-1]) > 1.0
        assert np.corrcoef([2, 5, 8, 11], np.abs(s))[0, 1] > 0.9
    # and the shift changes sign between views on either side of the centre
    left = phase_shift(d[vc, uc], d[vc, uc - 10])[1]
    right = phase_shift(d[vc, uc], d[vc, uc + 10])[1]
    assert np.sign(left) == -np.sign(right) != 0
    up = phase_shift(d[vc, uc], d[vc - 10, uc])[0]
    down = phase_shift(d[vc, uc], d[vc + 10, uc])[0]
    assert np.sign(up) == -np.sign(down) != 0


def f01_jpeg_raw():
    from plenodecode.io.images import read_image
    from plenodecode.types import CameraMetadata, RawCapture

    path = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    img = read_image(path)
    mosaic = (img if img.ndim == 2 else img[..., 0]).astype(np.uint16)
    # Tao et al. saved the BGGR mosaic as an 8-bit JPEG: levels 0..255, no white image, no colour metadata
    return RawCapture(mosaic, "BGGR", 0, 255, CameraMetadata(make="Lytro", model="F01"), path=str(path))


def test_real_f01_jpeg_decodes_with_self_calibrated_grid():
    from plenodecode.calib.selfcal import calibrate_from_scene

    raw = f01_jpeg_raw()
    grid = calibrate_from_scene(raw)
    assert grid.lattice == "hex" and grid.pitch == pytest.approx(9.93, abs=0.1)
    lf = decode(raw, grid)
    v, u, y, x, c = lf.shape
    assert (v, u, c) == (9, 9, 3)
    assert abs(y - 381) <= 3 and abs(x - 380) <= 3
    assert lf.colour == "camera"                              # no colour matrix in a JPEG
    centre = lf.centre_view()
    g = centre.mean(-1)
    # structure: the centre view is a picture, not noise or a flat field
    assert g.std() > 0.1 * g.mean()
    gy, gx = np.gradient(g)
    nb = np.corrcoef(g[:, :-1].ravel(), g[:, 1:].ravel())[0, 1]   # neighbouring samples are correlated
    assert nb > 0.9
    # smooth at the sample scale: no lenslet-disk pattern (row-to-row jumps) left in the view
    assert np.mean(np.abs(gy)) < 0.2 * g.mean() and np.mean(np.abs(gx)) < 0.2 * g.mean()



def test_python_decode_refuses_a_bright_frame_given_as_the_dark(antleg):
    """'decode(raw, grid, dark=white)' (the frames swapped) returned an all-black light field without a word, while
    the CLI's --dark refused it; the Python API now raises a ValueError naming the frame and what it leaves of the
    range (0.0 %), before any decoding, the same check as --dark."""
    raw, white, dark, grid, lf = antleg
    for bright, name in ((white, "radiometry_frame.png"), (raw.mosaic, "the frame given as dark")):
        with pytest.raises(ValueError, match=f"{name} is no dark frame for light_field.png: subtracted from it, the "
                                             r"brightest 0.1 % keep 0.0% of the range"):
            decode(raw, grid, white=white, dark=bright)
    assert float(np.percentile(lf.centre_view(), 99.5)) > 0.1         # the real dark frame: the specimen
