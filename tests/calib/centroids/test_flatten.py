"""Bayer collapse and hot pixels (:mod:`plenodecode.calib.centroids.flatten`)."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode.calib import centroids as C
from plenodecode.calib.centroids import flatten
from plenodecode.calib.centroids.flatten import fix_hot_pixels_reference
from plenodecode.synthetic import simulate_white
from plenodecode.types import RawCapture


def test_flatten_white_removes_the_cfa_pattern_and_keeps_the_input():
    rng = np.random.default_rng(0)
    gains = np.array([[0.7, 1.0], [1.0, 0.8]])                 # unequal channel responses
    level = 0.6 + 0.02 * rng.standard_normal((64, 80))
    mosaic = 64 + np.tile(gains, (32, 40)) * level * (1023 - 64)
    raw = RawCapture(np.round(mosaic).astype(np.uint16), "GRBG", 64.0, 1023.0)
    before = raw.mosaic.copy()
    flat = C.flatten_white(raw)
    assert flat.dtype == np.float32 and flat.shape == raw.shape
    # the 2x2 pattern is gone: the four phases have the same mean within noise
    means = [flat[r::2, c::2][4:-4, 4:-4].mean() for r in (0, 1) for c in (0, 1)]
    assert np.ptp(means) < 0.01 * np.mean(means)
    np.testing.assert_array_equal(raw.mosaic, before)
    binned = C.flatten_white(raw, binning=2)
    assert binned.shape == (32, 40)
    with pytest.raises(ValueError, match="binning"):
        C.flatten_white(raw, binning=3)


def test_fix_hot_pixels_touches_only_outliers():
    yy, xx = np.mgrid[0:50, 0:60]
    img = (0.5 + 0.3 * np.sin(xx / 3.0) * np.cos(yy / 4.0)).astype(np.float32)
    out = C.fix_hot_pixels(img)
    np.testing.assert_array_equal(out, img)                     # a smooth image is left alone
    bad = img.copy()
    bad[10, 10] = 1.0
    bad[30, 40] = 0.0
    fixed = C.fix_hot_pixels(bad)
    assert abs(fixed[10, 10] - img[10, 10]) < 0.05 and abs(fixed[30, 40] - img[30, 40]) < 0.05
    mask = np.ones_like(img, bool)
    mask[10, 10] = mask[30, 40] = False
    np.testing.assert_array_equal(fixed[mask], img[mask])
    assert bad[10, 10] == 1.0                                   # input not modified


def test_fix_hot_pixels_keeps_the_gaps_of_a_binned_white():
    """The bottom of each gap between disks is below its 8 neighbours too; it must survive (the test
    without the neighbour-spread term replaced ~1.2 pixels per lens of a binned Illum white)."""
    white, truth = simulate_white("illum-mini", seed=3, shape=(300, 400))
    raw = C.flatten_white(white, binning=2, hot_pixels=False)
    fixed = C.fix_hot_pixels(raw, threshold=0.05)
    n_lenses = truth.shape[0] * truth.shape[1]
    assert (fixed != raw).sum() < 0.02 * n_lenses
    # a defect inside a disk is still repaired
    c = np.round((truth.centres()[truth.shape[1] * 5 + 5] - 0.5) / 2).astype(int)
    bad = raw.copy()
    bad[c[0], c[1]] += 0.5
    again = C.fix_hot_pixels(bad, threshold=0.05)
    assert abs(again[c[0], c[1]] - raw[c[0], c[1]]) < 0.1


def test_fix_hot_pixels_kernel_matches_the_opencv_reference(monkeypatch):
    """The numba kernel and the cv2.dilate/erode reference repair the same pixels with the same medians,
    including defects on the border and in the corners (neighbours replicated there)."""
    monkeypatch.setattr(flatten, "_KERNEL_MIN_PIXELS", 0)              # the kernel even for this small image
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:61, 0:83]
    img = (0.5 + 0.3 * np.sin(xx / 2.1) * np.cos(yy / 2.7) + 0.01 * rng.standard_normal((61, 83))).astype(np.float32)
    rows = np.r_[0, 0, 60, 60, rng.integers(0, 61, 40)]
    cols = np.r_[0, 82, 0, 82, rng.integers(0, 83, 40)]
    img[rows, cols] = rng.choice([0.0, 1.5], len(rows))
    for threshold in (0.05, 0.1):
        fast, slow = C.fix_hot_pixels(img, threshold=threshold), fix_hot_pixels_reference(img, threshold=threshold)
        changed = fast != img
        assert changed.sum() >= 30
        np.testing.assert_array_equal(changed, slow != img)
        np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-6)
