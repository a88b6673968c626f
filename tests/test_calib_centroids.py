"""Centre detection building blocks: Bayer collapse, hot pixels, local mean, lattice vectors, peaks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from plenodecode.calib import centroids as C
from plenodecode.errors import CalibrationError
from plenodecode.io.synthetic import simulate_white
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


def test_local_mean_reproduces_a_plane_up_to_the_borders():
    yy, xx = np.mgrid[0:300, 0:410]
    plane = (0.3 + 0.002 * yy - 0.0013 * xx).astype(np.float32)
    for sigma in (6.0, 21.0):
        lm = C.local_mean(plane, sigma)
        assert lm.shape == plane.shape
        np.testing.assert_allclose(lm, plane, atol=2e-3)


@pytest.mark.parametrize("preset,transpose", [("f01-mini", False), ("illum-mini", False), ("square", False),
                                              ("f01-mini", True)])
def test_lattice_vectors_from_the_autocorrelation(preset, transpose):
    white, truth = simulate_white(preset, seed=0, rotation=0.006, shape=(420, 460))
    img = C.flatten_white(white)
    if transpose:
        img = np.ascontiguousarray(img.T)
    est = C.estimate_lattice_vectors(img)
    assert est.lattice == truth.lattice
    assert abs(est.pitch - truth.pitch) < 0.05
    expected = (math.pi / 2 - 0.006) if transpose else 0.006
    assert abs(est.rotation - expected) < 2e-3
    with pytest.raises(ValueError, match="lattice"):
        C.estimate_lattice_vectors(img, lattice="tri")


def test_lattice_vectors_fail_on_structureless_images():
    with pytest.raises(CalibrationError):
        C.estimate_lattice_vectors(np.full((200, 200), 0.5, np.float32))


@pytest.mark.parametrize("method,tol", [("dog", 0.03), ("parabolic", 0.08)])
def test_subpixel_centres_of_single_lenses(method, tol):
    """Per-lens accuracy (noise-free white, interior lenses): DoG ~0.01 px, parabola ~0.03 px."""
    white, truth = simulate_white("f01-mini", seed=0, rotation=0.004, offset=(0.3, 0.6), noise=False,
                                  shape=(300, 340))
    p = truth.pitch
    img = C.devignette(C.flatten_white(white), p)
    peaks, contrast = C.detect_peaks(img, p)
    cen, ok = C.refine_peaks(img, peaks, p, method=method)
    cen = cen[ok]
    t = truth.centres()
    d, idx = cKDTree(t).query(cen)
    tt = t[idx]
    H, W = white.shape
    inner = (tt[:, 0] > 1.5 * p) & (tt[:, 1] > 1.5 * p) & (tt[:, 0] < H - 1.5 * p) & (tt[:, 1] < W - 1.5 * p)
    assert inner.sum() > 500
    assert np.sqrt(np.mean(d[inner] ** 2)) < tol
    with pytest.raises(ValueError, match="method"):
        C.refine_peaks(img, peaks, p, method="centroid-ish")
