"""Centre detection building blocks: Bayer collapse, hot pixels, local mean, lattice vectors, peaks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from plenodecode.calib import centroids as C
from plenodecode.errors import CalibrationError
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


def _lopsided_disks(pitch=24.0, radius=11.0, n=5, border=16, seed=0):
    """Disks (raised-cosine rim of width 1.5 px at ``radius``) whose right part, beyond a straight
    scene edge 2 px off centre at the same angle in every disk, is 8x brighter than the rest:
    the coherent scene content that pulls intensity-based centres over whole regions."""
    rng = np.random.default_rng(seed)
    size = int(pitch * n) + 2 * border
    grid = border + (np.arange(n) + 0.5) * pitch
    centres = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2) + rng.uniform(-1, 1, (n * n, 2))
    ss = 4  # 4x4 supersampling of each pixel
    y, x = np.mgrid[0:size * ss, 0:size * ss]
    y = (y + 0.5) / ss - 0.5
    x = (x + 0.5) / ss - 0.5
    img = np.zeros_like(y)
    ang = rng.uniform(0, 2 * np.pi)
    for cy, cx in centres:
        r = np.hypot(y - cy, x - cx)
        disk = 0.5 * (1 + np.cos(np.pi * np.clip((r - (radius - 0.75)) / 1.5, 0, 1)))
        lit = (y - cy) * math.sin(ang) + (x - cx) * math.cos(ang) > 2.0
        img += disk * np.where(lit, 1.0, 0.12)
    return img.reshape(size, ss, size, ss).mean(axis=(1, 3)).astype(np.float32), centres


def test_rim_fit_centres_lopsided_disks_that_fool_intensity_peaks():
    """Measured: rim fit median 0.08 px, max 0.10 px; the DoG intensity peak is 5.7 px off."""
    pitch, radius = 24.0, 11.0
    img, truth = _lopsided_disks(pitch, radius)
    gy, gx = C.rim_gradients(img, pitch)
    start = truth + np.random.default_rng(1).uniform(-1.0, 1.0, truth.shape)
    cen, ok = C.refine_rims(gy, gx, start, radius)
    assert ok.all()
    err = np.hypot(*(cen - truth).T)
    assert np.median(err) < 0.15 and err.max() < 0.25, err
    # a wrong radius moves half-lit disks towards or away from their lit side (what the radius search sees)
    off, ok_off = C.refine_rims(gy, gx, start, radius + 0.5)
    assert np.median(np.hypot(*(off - truth).T)[ok_off]) > 0.3
    # the Hough votes peak within a pixel of every centre
    acc = C.rim_votes(gy, gx, radius)
    for cy, cx in truth:
        r0, c0 = int(cy) - 3, int(cx) - 3
        iy, ix = np.unravel_index(np.argmax(acc[r0:r0 + 8, c0:c0 + 8]), (8, 8))
        assert math.hypot(r0 + iy - cy, c0 + ix - cx) < 1.0
    # intensity peaks (the white-image estimator) sit on the lit side
    con = C.devignette(img, pitch)
    peaks, _ = C.detect_peaks(con, pitch, margin=1)
    dog, ok_d = C.refine_peaks(con, peaks, pitch)
    d, _ = cKDTree(truth).query(dog[ok_d])
    assert np.median(d) > 2.0
    # nothing to fit: an empty start, and a disk without a lit rim is rejected
    assert C.refine_rims(gy, gx, np.zeros((0, 2)), radius)[0].shape == (0, 2)
    flat = np.zeros_like(gy)
    assert not C.refine_rims(flat, flat, truth[:3], radius)[1].any()
